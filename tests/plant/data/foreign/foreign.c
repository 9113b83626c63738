/* ForeignCar: kinematic car in ISO axes for the bench's mapping test. */
#include <math.h>
#include <stddef.h>

#include "model.h"

#define P(name) (m->v[VR_##name])
#define DEG (M_PI / 180.0)

const char *model_check(const Model *m) { return P(tau_s) > 0.0 ? NULL : "tau_s must be positive"; }

void model_start(Model *m) {
    m->x[X_spd] = 0.0;
    m->x[X_yaw] = 0.0;
    m->x[X_th] = -P(slope_deg) * DEG;
}

void model_derivatives(const Model *m, const double *x, double *dx) {
    double target = P(pedal_pct) / 100.0 * P(vmax_kmh) / 3.6;
    dx[X_spd] = (target - x[X_spd]) / P(tau_s);
    dx[X_yaw] = x[X_spd] * tan(P(steer_deg) * DEG) / P(wheelbase);
    dx[X_th] = (-P(slope_deg) * DEG - x[X_th]) / 0.5;
}

void model_outputs(Model *m) {
    double dx[N_STATES];
    model_derivatives(m, m->x, dx);
    double th = m->x[X_th];
    P(vx_kmh) = m->x[X_spd] * 3.6;
    P(vy_kmh) = 0.0;
    P(vz_kmh) = 0.0;
    P(p_dps) = -dx[X_yaw] * sin(th) / DEG;
    P(q_dps) = dx[X_th] / DEG;
    P(r_dps) = dx[X_yaw] * cos(th) / DEG;
    P(theta_deg) = th / DEG;
    P(phi_deg) = 0.0;
    P(wheel_kmh) = m->x[X_spd] * 3.6;
}
