/* Fixed-step classical Runge-Kutta (RK4) integration of a model's states.
 *
 * One communication step is split into equal substeps no longer than the model's
 * solver_step parameter. A state that becomes NaN or infinite stops the step with a
 * message naming the state and the time.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"

void model_reset(Model *m) {
    memcpy(m->v, VAR_START, sizeof(m->v));
    memset(m->x, 0, sizeof(m->x));
    m->time = 0.0;
    m->msg[0] = '\0';
}

int model_advance(Model *m, double h) {
    double hmax = m->v[VR_solver_step];
    int n = (int)ceil(h / hmax - 1e-9);
    if (n < 1) n = 1;
    const double dt = h / n;
    const double t0 = m->time;
    double k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES], y[N_STATES];
    for (int s = 0; s < n; s++) {
        m->time = t0 + s * dt;
        model_derivatives(m, m->x, k1);
        for (int i = 0; i < N_STATES; i++) y[i] = m->x[i] + 0.5 * dt * k1[i];
        m->time += 0.5 * dt;
        model_derivatives(m, y, k2);
        for (int i = 0; i < N_STATES; i++) y[i] = m->x[i] + 0.5 * dt * k2[i];
        model_derivatives(m, y, k3);
        for (int i = 0; i < N_STATES; i++) y[i] = m->x[i] + dt * k3[i];
        m->time = t0 + (s + 1) * dt;
        model_derivatives(m, y, k4);
        for (int i = 0; i < N_STATES; i++) {
            m->x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            if (!isfinite(m->x[i])) {
                snprintf(m->msg, sizeof(m->msg), "state %s became %g at t = %.6f s", STATE_NAMES[i], m->x[i],
                         m->time);
                return -1;
            }
        }
    }
    m->time = t0 + h;
    model_outputs(m);
    return 0;
}
