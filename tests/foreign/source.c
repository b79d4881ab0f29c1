/* foreign_source: a step y = offset + amplitude * (t >= t_step), a plain-C FMI 2.0 Co-Simulation FMU. */
#include "model.h"

enum { Y, AMPLITUDE, OFFSET, T_STEP };

static const Variable VARIABLES[] = {
    {"y", OUTPUT, 0.0},
    {"amplitude", PARAMETER, 1.0},
    {"offset", PARAMETER, 0.0},
    {"t_step", PARAMETER, 0.5},
};

/* The value at the current communication point: the start time, then the end of each step. */
static void update(Instance *inst) {
    double *r = inst->r;
    r[Y] = r[OFFSET] + r[AMPLITUDE] * (inst->time >= r[T_STEP] ? 1.0 : 0.0);
}

static void describe(Instance *inst, const char *event) {
    const double *r = inst->r;
    LOG(inst, fmi2OK, "logAll", "%s %s (amplitude = %g, offset = %g, t_step = %g)", event, inst->name,
        r[AMPLITUDE], r[OFFSET], r[T_STEP]);
}

/* Any amplitude, offset and step time are valid; no state: the output depends on time only. */
FOREIGN_MODEL("{5f3c2a8e-9b1d-4e27-a6f0-0c4d7e91b2a3}", update, NULL, NULL, describe);
