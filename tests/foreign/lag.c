/* foreign_lag: first-order lag T y' = k u - y, exact for a zero-order-held input; a plain-C FMI 2.0 CS FMU. */
#include "model.h"

#include <math.h>

enum { U, Y, T, K, Y0 };

static const Variable VARIABLES[] = {
    {"u", INPUT, 0.0},
    {"y", OUTPUT, 0.0},
    {"T", PARAMETER, 1.0},
    {"k", PARAMETER, 1.0},
    {"y0", PARAMETER, 0.0},
};

/* Until step mode the state is its initial value; afterwards only fmi2DoStep changes it. */
static void update(Instance *inst) {
    if (inst->phase != STEPPING)
        inst->r[Y] = inst->r[Y0];
}

static fmi2Status check(Instance *inst) {
    if (!(inst->r[T] > 0.0)) {
        LOG(inst, fmi2Error, "logError", "%s: the time constant T = %g must be positive", inst->name, inst->r[T]);
        return fmi2Error;
    }
    return fmi2OK;
}

/* y(t + h) = e^(-h/T) y(t) + (1 - e^(-h/T)) k u, the exact solution for u constant on [t, t + h]. */
static void step(Instance *inst, double t, double h) {
    double *r = inst->r;
    double a = exp(-h / r[T]);
    (void)t;
    r[Y] = a * r[Y] + (1.0 - a) * r[K] * r[U];
}

static void describe(Instance *inst, const char *event) {
    const double *r = inst->r;
    LOG(inst, fmi2OK, "logAll", "%s %s (T = %g, k = %g, y0 = %g)", event, inst->name, r[T], r[K], r[Y0]);
}

FOREIGN_MODEL("{a1e4b7c0-3d62-4f8a-9e15-7b2c6d0f4e88}", update, check, step, describe);
