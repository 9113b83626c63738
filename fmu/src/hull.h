/* What the vehicle models share: the hull on its suspension over the terrain.
 *
 * For models whose states include th/thd (pitch and rate), ga/gad (roll and rate) and psi
 * (heading), with the parameters grade, bank, f_susp, zeta_susp and the outputs v_x, v_y,
 * v_z, omega_x, omega_y, omega_z, pitch, roll and heading (RFU body axes, ICD
 * conventions). Include after model.h; P(name) is a variable of the model m in scope.
 */
#ifndef BENCH_HULL_H
#define BENCH_HULL_H

#include <math.h>

#include "model.h"

#define G0 9.80665
#define P(name) (m->v[VR_##name])

static inline double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* v := Rx(a) v and v := Ry(a) v, active rotations (ICD convention) */
static inline void rot_x(double a, double *v) {
    double c = cos(a), s = sin(a), y = v[1], z = v[2];
    v[1] = c * y - s * z;
    v[2] = s * y + c * z;
}

static inline void rot_y(double a, double *v) {
    double c = cos(a), s = sin(a), x = v[0], z = v[2];
    v[0] = c * x + s * z;
    v[2] = -s * x + c * z;
}

/* Pitch and roll follow grade + pitch_in and bank + roll_in through a second-order
 * suspension; the heading follows the yaw rate r about body up
 * (omega_z = sin(ga) thd - cos(ga) cos(th) psi_dot). */
static inline void hull_rates(const Model *m, const double *x, double pitch_in, double roll_in, double r,
                              double *dx) {
    const double wn = 2.0 * M_PI * P(f_susp), z = P(zeta_susp);
    dx[X_th] = x[X_thd];
    dx[X_thd] = wn * wn * (P(grade) + pitch_in - x[X_th]) - 2.0 * z * wn * x[X_thd];
    dx[X_ga] = x[X_gad];
    dx[X_gad] = wn * wn * (P(bank) + roll_in - x[X_ga]) - 2.0 * z * wn * x[X_gad];
    dx[X_psi] = (sin(x[X_ga]) * x[X_thd] - r) / (cos(x[X_ga]) * cos(x[X_th]));
}

/* The body outputs from the velocity along the terrain (right, forward, 0), the heading
 * rate psid and the attitude states: velocity to body axes by Ry(-ga) Rx(grade - th)
 * Ry(bank), angular rate from the attitude rates. */
static inline void hull_outputs(Model *m, double right, double forward, double psid) {
    const double th = m->x[X_th], ga = m->x[X_ga], thd = m->x[X_thd], gad = m->x[X_gad];
    double vb[3] = {right, forward, 0.0};
    rot_y(P(bank), vb);
    rot_x(P(grade) - th, vb);
    rot_y(-ga, vb);
    P(v_x) = vb[0];
    P(v_y) = vb[1];
    P(v_z) = vb[2];
    const double st = sin(th), ct = cos(th), sg = sin(ga), cg = cos(ga);
    P(omega_x) = cg * thd + sg * ct * psid;
    P(omega_y) = gad - st * psid;
    P(omega_z) = sg * thd - cg * ct * psid;
    P(pitch) = th;
    P(roll) = ga;
    P(heading) = m->x[X_psi];
}

#endif
