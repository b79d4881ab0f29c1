/* Contract between the shared FMI 2.0 Co-Simulation skeleton (skeleton.c) and one foreign test model. */
#ifndef FOREIGN_MODEL_H
#define FOREIGN_MODEL_H

#include "fmi2.h"

/* Every variable of these models is a Real; its value reference is its index in Instance.r. */
#define MAX_VARIABLES 8

typedef enum { PARAMETER, INPUT, OUTPUT } Kind;

typedef struct {
    const char *name;
    Kind kind;
    double start;
} Variable;

typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED } Phase;

typedef struct {
    char *name;
    fmi2CallbackFunctions cb;
    int debug;    /* fmi2SetDebugLogging / loggingOn: log "logAll" messages too */
    Phase phase;
    double start; /* start time from fmi2SetupExperiment */
    double time;  /* current communication point */
    double r[MAX_VARIABLES];
} Instance;

typedef struct {
    const char *guid;
    size_t count;
    const Variable *variables;
    /* Recompute the outputs from parameters, inputs, state and time (after every set and step). */
    void (*update)(Instance *inst);
    /* Check the parameters when leaving initialization mode; log and return fmi2Error if invalid.
     * NULL: every value is valid. */
    fmi2Status (*check)(Instance *inst);
    /* Advance the state over [t, t + h] with the inputs held; the skeleton then sets time and updates.
     * NULL: the model has no state. */
    void (*step)(Instance *inst, double t, double h);
    /* Log the parameters after `event` ("instantiated", "initialized") when debug logging is on. */
    void (*describe)(Instance *inst, const char *event);
} Model;

/* Defined by each model's source file, with FOREIGN_MODEL. */
extern const Model foreign_model;

/* Define the model from the file's VARIABLES array (at most MAX_VARIABLES, checked when compiling)
 * and its hooks (NULL where not needed). */
#define FOREIGN_MODEL(guid, update, check, step, describe)                                                  \
    typedef char foreign_variables_fit[sizeof VARIABLES / sizeof VARIABLES[0] <= MAX_VARIABLES ? 1 : -1];   \
    const Model foreign_model = {(guid), sizeof VARIABLES / sizeof VARIABLES[0], VARIABLES, (update), (check), \
                                 (step), (describe)}

/* Log through the master's callback, passing the printf arguments on unformatted:
 * errors and warnings always, everything else only with debug logging on. */
#define LOG(inst, status, category, ...)                                                                 \
    do {                                                                                                  \
        if ((inst)->cb.logger != NULL && ((status) != fmi2OK || (inst)->debug))                          \
            (inst)->cb.logger((inst)->cb.componentEnvironment, (inst)->name, (status), (category),       \
                              __VA_ARGS__);                                                               \
    } while (0)

#endif /* FOREIGN_MODEL_H */
