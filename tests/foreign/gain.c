/* foreign_gain: y = g * u with direct feedthrough, a plain-C FMI 2.0 Co-Simulation FMU. */
#include "model.h"

enum { U, Y, G };

static const Variable VARIABLES[] = {
    {"u", INPUT, 0.0},
    {"y", OUTPUT, 0.0},
    {"g", PARAMETER, 1.0},
};

/* Called after every fmi2SetReal, so y follows u at once (also in initialization mode). */
static void update(Instance *inst) {
    inst->r[Y] = inst->r[G] * inst->r[U];
}

static void describe(Instance *inst, const char *event) {
    LOG(inst, fmi2OK, "logAll", "%s %s (g = %g)", event, inst->name, inst->r[G]);
}

/* Any gain is valid; no state. */
FOREIGN_MODEL("{c9d2f6a4-7e38-4b1c-8d05-e6a3b9f1c724}", update, NULL, NULL, describe);
