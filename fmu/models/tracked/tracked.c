/* TrackedVehicle: a tracked vehicle steered by two levers, after Tang et al. (seed 002).
 *
 * States: vs governor set speed (m/s), vD drive speed (gearbox output as track speed at 1:1, m/s), gi governor
 * integrator (N), kl/kr engaged speed ratios of the left/right steering mechanisms,
 * u forward body speed (m/s), r yaw rate about body up (rad/s, counter-clockwise),
 * v lateral body speed (m/s, right), th/thd pitch and rate, ga/gad roll and rate, psi heading.
 *
 * Kinematics (seed 002 section 3). Sprocket speeds v_l = kl vD, v_r = kr vD with k = 1
 * (most former), 1/ratio_I (position I), 0 (position II). With S = (v_l + v_r)/2,
 * D = |v_r - v_l| and the slip coefficient c (below) the track kinematics ask for
 *   yaw rate   |r*| = (u - c|r|) D / (B S - c D)   so that u/|r| = B S / D   (eq. 4, R = B/2, 2.88 B)
 *   body speed  u_kin = S + c|r|                                            (eq. 7: c = (A2 - A1)/2)
 *   lateral     v* = -heading_rate L  (outward of the turn)                   (eq. 6)
 * c is the seed's (A2 - A1)/2 at the curve ratio 1/ratio_I, -i_pivot B / (2 (1 - i_pivot))
 * when one track is locked (the driven track idles by i_pivot, turning radius B/2), and
 * is interpolated linearly in the ratio of the slow to the fast sprocket between those
 * states and zero in straight running.
 *
 * Dynamics. The hull speed u follows u_kin through the track traction
 *   T = mu W sign(i) (1 - exp(-|i| / i_c)),  i = (u_kin - u) / max(|u_kin|, |u|, 1 m/s),
 * against rolling resistance, grade and air drag; the drive line (mass m_driveline) is
 * driven by a governed engine (set speed vs following throttle * v_gov_max with 0.2 s lag,
 * PI on vs - vD plus the force to accelerate the vehicle along vs; force and power
 * limited, no integration into a saturated engine) and
 * braked by the service brake, and carries the traction reaction kappa T (kappa the mean
 * speed ratio) and the turning power M_r |r| with M_r = mu_t(R) W L_track / 4 and Steeds'
 * mu_t(R) = mu_t / (0.925 + 0.15 R / B). Yaw rate and lateral skid follow their kinematic
 * values with first-order lags. Pitch and roll follow terrain grade and bank plus
 * acceleration-induced body attitude through a second-order suspension.
 */
#include <math.h>
#include <stddef.h>

#include "hull.h"
#include "model.h"

static double lever_ratio(double lever, double ratio_I) {
    long l = lround(lever);
    return l == 0 ? 1.0 : (l == 1 ? 1.0 / ratio_I : 0.0);
}

static double sabs(double x) { return sqrt(x * x + 1e-8) - 1e-4; } /* smooth |x| */

typedef struct {
    double vl, vr, c, u_kin, r_star, slip, du, psi_dot;
} Aux;

static void evaluate(const Model *m, const double *x, Aux *a, double *dx) {
    const double vD = x[X_vD], kl = x[X_kl], kr = x[X_kr], u = x[X_u], r = x[X_r], v = x[X_v];
    const double grade = P(grade), W = P(m) * G0 * cos(grade);
    a->vl = kl * vD;
    a->vr = kr * vD;
    /* slip coefficient as a function of the speed ratio of the slow to the fast side */
    const double kf = fmax(kl, kr), ks = fmin(kl, kr);
    const double rho = kf > 1e-9 ? ks / kf : 1.0;
    const double rho_I = 1.0 / P(ratio_I);
    const double c_I = 0.5 * (P(A2) - P(A1));
    const double c_P = -P(i_pivot) * P(B) / (2.0 * (1.0 - P(i_pivot)));
    a->c = rho <= rho_I ? c_P + (c_I - c_P) * rho / rho_I : c_I * (1.0 - rho) / fmax(1.0 - rho_I, 1e-9);
    const double S = 0.5 * (a->vl + a->vr), D = fabs(a->vr - a->vl);
    const double sgn = a->vr >= a->vl ? 1.0 : -1.0; /* right track faster: left turn, r > 0 */
    const double ar = sabs(r);
    a->u_kin = S + a->c * ar;
    const double den = P(B) * S - a->c * D;
    a->r_star = den > 1e-9 ? sgn * (u - a->c * ar) * D / den : 0.0;
    /* traction of the tracks */
    const double vref = fmax(fmax(fabs(a->u_kin), fabs(u)), 1.0);
    a->slip = (a->u_kin - u) / vref;
    const double T = P(mu) * W * (a->slip >= 0.0 ? 1.0 : -1.0) * (1.0 - exp(-fabs(a->slip) / P(i_c)));
    const double F_hull = P(f_roll) * W * tanh(u / 0.1) + P(m) * G0 * sin(grade) + 0.5 * P(rho_air) * P(CdA) * u * fabs(u);
    a->du = (T - F_hull) / P(m) - v * r;
    if (!dx) return;
    /* turning resistance power, taken from the drive line */
    const double mu_t = P(mu_t) * ar * P(B) / (0.925 * ar * P(B) + 0.15 * fabs(u) + 1e-9);
    const double F_turn = mu_t * W * P(L_track) / 4.0 * ar / sqrt(vD * vD + 0.01);
    /* governed engine and brake */
    const double kappa = 0.5 * (kl + kr);
    const double dvs = (clamp(P(throttle), 0.0, 1.0) * P(v_gov_max) - x[X_vs]) / 0.2; /* pedal to set speed */
    const double e = x[X_vs] - vD;
    const double F_ff = (P(m_driveline) + P(m) * kappa * kappa) * dvs; /* force to follow the set speed */
    const double F_cmd = P(K_gov) * e + x[X_gi] + F_ff;
    const double F_top = fmin(P(F_peak), P(P_max) / fmax(fabs(vD), 0.1));
    const double F_bot = -P(F_engine_brake) * tanh(vD / 0.2);
    const double F_e = clamp(F_cmd, F_bot, F_top);
    double dgi = P(Ki_gov) * e;
    if ((F_cmd >= F_top && e > 0.0) || (F_cmd <= F_bot && e < 0.0)) dgi = 0.0; /* anti-windup */
    const double F_b = clamp(P(brake), 0.0, 1.0) * P(F_brake_max) * tanh(vD / 0.05);
    dx[X_vs] = dvs;
    dx[X_vD] = (F_e - F_b - kappa * T - F_turn) / P(m_driveline);
    dx[X_gi] = dgi;
    dx[X_kl] = (lever_ratio(P(left_lever), P(ratio_I)) - kl) / P(tau_shift);
    dx[X_kr] = (lever_ratio(P(right_lever), P(ratio_I)) - kr) / P(tau_shift);
    dx[X_u] = a->du;
    dx[X_r] = (a->r_star - r) / P(tau_yaw);
    /* seed eq. (6): v_x = -heading_rate L; on level ground heading_rate = -r */
    dx[X_v] = (r * P(L) - v) / P(tau_lat);
    /* suspension: pitch toward grade + k_pitch a_x, roll toward bank + k_roll a_y */
    hull_rates(m, x, P(k_pitch) * a->du, P(k_roll) * u * r, r, dx);
}

const char *model_check(const Model *m) {
    if (P(i_pivot) >= 1.0 || P(i_pivot) < 0.0) return "i_pivot must be within [0, 1)";
    if (P(B) <= 2.0 * fabs(0.5 * (P(A2) - P(A1))) + 1e-6)
        return "track span B must exceed |A2 - A1| (the slip coefficients of seed 002 eq. 7)";
    if (P(ratio_I) <= 1.0) return "ratio_I must exceed 1";
    if (P(m) <= 0.0 || P(m_driveline) <= 0.0) return "masses must be positive";
    if (P(tau_shift) <= 0.0 || P(tau_yaw) <= 0.0 || P(tau_lat) <= 0.0) return "time constants must be positive";
    if (P(solver_step) <= 0.0) return "solver_step must be positive";
    return NULL;
}

void model_start(Model *m) {
    for (int i = 0; i < N_STATES; i++) m->x[i] = 0.0;
    m->x[X_kl] = lever_ratio(P(left_lever), P(ratio_I));
    m->x[X_kr] = lever_ratio(P(right_lever), P(ratio_I));
    m->x[X_th] = P(grade);
    m->x[X_ga] = P(bank);
    m->x[X_psi] = P(heading0);
}

void model_derivatives(const Model *m, const double *x, double *dx) {
    Aux a;
    evaluate(m, x, &a, dx);
}

void model_outputs(Model *m) {
    Aux a;
    double dx[N_STATES];
    evaluate(m, m->x, &a, dx);
    hull_outputs(m, m->x[X_v], m->x[X_u], dx[X_psi]); /* v is to the right already */
    P(v_sprocket_left) = a.vl;
    P(v_sprocket_right) = a.vr;
    P(v_drive) = m->x[X_vD];
    P(slip) = a.slip;
    switch (lround(P(odometer_source))) {
        case 1: P(v_odometer) = a.vl; break;
        case 2: P(v_odometer) = a.vr; break;
        case 3: P(v_odometer) = 0.5 * (a.vl + a.vr); break;
        default: P(v_odometer) = m->x[X_vD]; break;
    }
}
