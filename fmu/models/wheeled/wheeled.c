/* WheeledVehicle: longitudinal dynamics and a single-track lateral model.
 *
 * States (ISO axes inside: x forward, y left, z up): u forward and v lateral (left) body
 * speed (m/s), r yaw rate (rad/s, counter-clockwise), sig slip of the odometer wheel,
 * delta road-wheel angle (rad, left), th/thd pitch and rate, ga/gad roll and rate, psi heading.
 *
 * Longitudinal: m (du/dt - v r) = X_f cos(delta) - Y_f sin(delta) + X_r - F_res with the
 * rear (driven) axle force X_r = throttle * min(F_drive_max, P_max/|u|) - rear brake, the
 * front X_f = - front brake, each limited by the axle's friction mu Fz, and
 * F_res = f_roll W cos(grade) + m g sin(grade) + rho/2 CdA u|u|.
 * Lateral (single track): slip angles alpha_f = (u delta - v - a r)/u_e and
 * alpha_r = (b r - v)/u_e with u_e = sqrt(u^2 + 0.25 m^2/s^2) (exact kinematic turning at
 * walking pace, the classical model above it), axle forces mu Fz tanh(C alpha/(mu Fz)),
 *   m (dv/dt + u r) = X_f sin(delta) + Y_f cos(delta) + Y_r - m g cos(grade) sin(bank)
 *   Iz dr/dt = a (X_f sin(delta) + Y_f cos(delta)) - b Y_r.
 * In steady cornering this gives delta = L/R + K_us a_y with the understeer gradient
 * K_us = m/L (b/C_f - a/C_r). Static axle loads (no load transfer).
 * Odometer wheel: slip toward kappa_c atanh(X/(mu Fz)) of its axle (clamped to +-1: a
 * locked wheel reads zero) with time constant tau_wheel; v_wheel = u (1 + sig).
 */
#include <math.h>
#include <stddef.h>

#include "hull.h"
#include "model.h"

static double slip_of(double X_dem, double Fmax, double kappa_c) {
    double q = X_dem / Fmax;
    if (q >= 1.0) return 1.0;
    if (q <= -1.0) return -1.0;
    return clamp(kappa_c * atanh(q), -1.0, 1.0);
}

typedef struct {
    double du, dv, a_lat;
} Aux;

static void evaluate(const Model *m, const double *x, Aux *o, double *dx) {
    const double u = x[X_u], v = x[X_v], r = x[X_r], delta = x[X_delta];
    const double grade = P(grade), bank = P(bank), Lw = P(a) + P(b);
    const double W = P(m) * G0 * cos(grade);
    const double Fzf = W * P(b) / Lw, Fzr = W * P(a) / Lw;
    const double ue = sqrt(u * u + 0.25);
    const double alpha_f = (u * delta - v - P(a) * r) / ue;
    const double alpha_r = (P(b) * r - v) / ue;
    const double Yf = P(mu) * Fzf * tanh(P(C_f) * alpha_f / (P(mu) * Fzf));
    const double Yr = P(mu) * Fzr * tanh(P(C_r) * alpha_r / (P(mu) * Fzr));
    const double F_d = clamp(P(throttle), 0.0, 1.0) * fmin(P(F_drive_max), P(P_max) / fmax(fabs(u), 0.1));
    const double F_b = clamp(P(brake), 0.0, 1.0) * P(F_brake_max) * tanh(u / 0.05);
    const double Xf_dem = -P(brake_front) * F_b, Xr_dem = F_d - (1.0 - P(brake_front)) * F_b;
    const double Xf = clamp(Xf_dem, -P(mu) * Fzf, P(mu) * Fzf), Xr = clamp(Xr_dem, -P(mu) * Fzr, P(mu) * Fzr);
    const double F_res = P(f_roll) * W * tanh(u / 0.1) + P(m) * G0 * sin(grade) + 0.5 * P(rho_air) * P(CdA) * u * fabs(u);
    const double cd = cos(delta), sd = sin(delta);
    const double Fy = Xf * sd + Yf * cd + Yr - P(m) * G0 * cos(grade) * sin(bank);
    o->du = (Xf * cd - Yf * sd + Xr - F_res) / P(m) + v * r;
    o->dv = Fy / P(m) - u * r;
    o->a_lat = Fy / P(m);
    if (!dx) return;
    dx[X_u] = o->du;
    dx[X_v] = o->dv;
    dx[X_r] = (P(a) * (Xf * sd + Yf * cd) - P(b) * Yr) / P(Iz);
    const int front = lround(P(odometer_axle)) == 1;
    const double target = front ? slip_of(Xf_dem, P(mu) * Fzf, P(kappa_c)) : slip_of(Xr_dem, P(mu) * Fzr, P(kappa_c));
    dx[X_sig] = (target - x[X_sig]) / P(tau_wheel);
    dx[X_delta] = (P(steering) - delta) / P(tau_steer);
    hull_rates(m, x, P(k_pitch) * (o->du - v * r), P(k_roll) * o->a_lat, r, dx);
}

const char *model_check(const Model *m) {
    if (P(m) <= 0.0 || P(Iz) <= 0.0) return "mass and yaw inertia must be positive";
    if (P(a) <= 0.0 || P(b) <= 0.0) return "axle distances a and b must be positive";
    if (P(C_f) <= 0.0 || P(C_r) <= 0.0) return "cornering stiffnesses must be positive";
    if (P(tau_steer) <= 0.0 || P(tau_wheel) <= 0.0) return "time constants must be positive";
    if (P(solver_step) <= 0.0) return "solver_step must be positive";
    return NULL;
}

void model_start(Model *m) {
    for (int i = 0; i < N_STATES; i++) m->x[i] = 0.0;
    m->x[X_delta] = P(steering);
    m->x[X_th] = P(grade);
    m->x[X_ga] = P(bank);
    m->x[X_psi] = P(heading0);
}

void model_derivatives(const Model *m, const double *x, double *dx) {
    Aux o;
    evaluate(m, x, &o, dx);
}

void model_outputs(Model *m) {
    Aux o;
    double dx[N_STATES];
    evaluate(m, m->x, &o, dx);
    hull_outputs(m, -m->x[X_v], m->x[X_u], dx[X_psi]); /* v is to the left inside */
    P(slip) = m->x[X_sig];
    P(v_wheel) = m->x[X_u] * (1.0 + m->x[X_sig]);
    P(a_lat) = o.a_lat;
    P(delta) = m->x[X_delta];
}
