/* The FMI 2.0 Co-Simulation functions shared by the foreign test FMUs; the model itself is in model.h's Model. */
#include "model.h"

#include <math.h>
#include <string.h>

static const char *const PHASE_NAMES[] = {"instantiated", "initialization mode", "step mode", "terminated",
                                          "error"};

/* Bit masks of phases, for the checks of which function may be called when. */
#define IN(p) (1u << (p))
#define ANY_PHASE (IN(INSTANTIATED) | IN(INITIALIZATION) | IN(STEPPING) | IN(TERMINATED) | IN(FAILED))

/* The instance behind `c` if `fn` may be called in its phase; otherwise log and return NULL. */
static Instance *enter(fmi2Component c, const char *fn, unsigned phases) {
    Instance *inst = (Instance *)c;
    if (inst == NULL)
        return NULL;
    if (!(phases & IN(inst->phase))) {
        LOG(inst, fmi2Error, "logError", "%s: not allowed in %s", fn, PHASE_NAMES[inst->phase]);
        return NULL;
    }
    return inst;
}

static void load_start_values(Instance *inst) {
    size_t i;
    for (i = 0; i < foreign_model.count; i++)
        inst->r[i] = foreign_model.variables[i].start;
    inst->start = 0.0;
    inst->time = 0.0;
    inst->phase = INSTANTIATED;
    foreign_model.update(inst);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance probe; /* lets LOG report problems before the instance exists */
    Instance *inst;
    size_t length;
    (void)fmuResourceLocation; /* these models need no resources */
    (void)visible;
    if (functions == NULL)
        return NULL;
    memset(&probe, 0, sizeof probe);
    probe.cb = *functions;
    probe.name = (char *)(instanceName != NULL ? instanceName : "?");
    if (instanceName == NULL || instanceName[0] == '\0') {
        LOG(&probe, fmi2Error, "logError", "fmi2Instantiate: the instance name is empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        LOG(&probe, fmi2Error, "logError", "fmi2Instantiate of %s: fmuType %d is not fmi2CoSimulation (%d)",
            instanceName, (int)fmuType, (int)fmi2CoSimulation);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, foreign_model.guid) != 0) {
        LOG(&probe, fmi2Error, "logError", "fmi2Instantiate of %s: GUID %s does not match %s", instanceName,
            fmuGUID != NULL ? fmuGUID : "(null)", foreign_model.guid);
        return NULL;
    }
    if (functions->allocateMemory == NULL || functions->freeMemory == NULL) {
        LOG(&probe, fmi2Error, "logError", "fmi2Instantiate of %s: allocateMemory and freeMemory are required",
            instanceName);
        return NULL;
    }
    inst = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    length = strlen(instanceName);
    if (inst == NULL || (inst->name = (char *)functions->allocateMemory(length + 1, 1)) == NULL) {
        if (inst != NULL)
            functions->freeMemory(inst);
        LOG(&probe, fmi2Error, "logError", "fmi2Instantiate of %s: out of memory (%lu bytes)", instanceName,
            (unsigned long)(sizeof(Instance) + length + 1));
        return NULL;
    }
    memcpy(inst->name, instanceName, length + 1);
    inst->cb = *functions;
    inst->debug = loggingOn != fmi2False;
    load_start_values(inst);
    foreign_model.describe(inst, "instantiated");
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL)
        return;
    inst->cb.freeMemory(inst->name);
    inst->cb.freeMemory(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *inst = enter(c, "fmi2SetDebugLogging", ANY_PHASE);
    size_t i;
    if (inst == NULL)
        return fmi2Error;
    if (nCategories == 0) {
        inst->debug = loggingOn != fmi2False;
        return fmi2OK;
    }
    for (i = 0; i < nCategories; i++) {
        const char *category = categories != NULL ? categories[i] : NULL;
        if (category != NULL && strcmp(category, "logAll") == 0) {
            inst->debug = loggingOn != fmi2False;
        } else if (category == NULL || strcmp(category, "logError") != 0) {
            LOG(inst, fmi2Error, "logError", "fmi2SetDebugLogging: unknown log category %s",
                category != NULL ? category : "(null)");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = enter(c, "fmi2SetupExperiment", IN(INSTANTIATED));
    (void)toleranceDefined; /* the discretizations are exact: no tolerance to honour */
    (void)tolerance;
    if (inst == NULL)
        return fmi2Error;
    if (stopTimeDefined && stopTime < startTime) {
        LOG(inst, fmi2Error, "logError", "fmi2SetupExperiment: stop time %g is before start time %g", stopTime,
            startTime);
        return fmi2Error;
    }
    inst->start = startTime;
    inst->time = startTime;
    foreign_model.update(inst);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = enter(c, "fmi2EnterInitializationMode", IN(INSTANTIATED));
    if (inst == NULL)
        return fmi2Error;
    inst->phase = INITIALIZATION;
    foreign_model.update(inst);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = enter(c, "fmi2ExitInitializationMode", IN(INITIALIZATION));
    if (inst == NULL)
        return fmi2Error;
    if (foreign_model.check != NULL && foreign_model.check(inst) != fmi2OK) {
        inst->phase = FAILED;
        return fmi2Error;
    }
    foreign_model.update(inst);
    inst->phase = STEPPING;
    foreign_model.describe(inst, "initialized");
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = enter(c, "fmi2Terminate", IN(INITIALIZATION) | IN(STEPPING));
    if (inst == NULL)
        return fmi2Error;
    inst->phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = enter(c, "fmi2Reset", ANY_PHASE);
    if (inst == NULL)
        return fmi2Error;
    load_start_values(inst);
    return fmi2OK;
}

/* Log and return 0 unless `vr` names a variable. */
static int known(Instance *inst, const char *fn, fmi2ValueReference vr) {
    if (vr < foreign_model.count)
        return 1;
    LOG(inst, fmi2Error, "logError", "%s: unknown value reference %u", fn, vr);
    return 0;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = enter(c, "fmi2GetReal", ANY_PHASE);
    size_t i;
    if (inst == NULL || (nvr > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (!known(inst, "fmi2GetReal", vr[i]))
            return fmi2Error;
        value[i] = inst->r[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = enter(c, "fmi2SetReal", IN(INSTANTIATED) | IN(INITIALIZATION) | IN(STEPPING));
    size_t i;
    if (inst == NULL || (nvr > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const Variable *v;
        if (!known(inst, "fmi2SetReal", vr[i]))
            return fmi2Error;
        v = &foreign_model.variables[vr[i]];
        if (v->kind == OUTPUT) {
            LOG(inst, fmi2Error, "logError", "fmi2SetReal: %s (value reference %u) is an output", v->name, vr[i]);
            return fmi2Error;
        }
        if (v->kind == PARAMETER && inst->phase == STEPPING) {
            LOG(inst, fmi2Error, "logError", "fmi2SetReal: the fixed parameter %s cannot be set to %g in %s",
                v->name, value[i], PHASE_NAMES[inst->phase]);
            return fmi2Error;
        }
        inst->r[vr[i]] = value[i];
    }
    foreign_model.update(inst); /* direct feedthrough: outputs follow the inputs at once */
    return fmi2OK;
}

/* Integer, Boolean and String accessors: the models have no such variables. */
static fmi2Status no_variables(fmi2Component c, const char *fn, const fmi2ValueReference vr[], size_t nvr) {
    Instance *inst = enter(c, fn, ANY_PHASE);
    if (inst == NULL)
        return fmi2Error;
    if (nvr == 0)
        return fmi2OK;
    LOG(inst, fmi2Error, "logError", "%s: unknown value reference %u (the model has only Real variables)", fn,
        vr != NULL ? vr[0] : 0u);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)value;
    return no_variables(c, "fmi2GetInteger", vr, nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)value;
    return no_variables(c, "fmi2GetBoolean", vr, nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)value;
    return no_variables(c, "fmi2GetString", vr, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)value;
    return no_variables(c, "fmi2SetInteger", vr, nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)value;
    return no_variables(c, "fmi2SetBoolean", vr, nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)value;
    return no_variables(c, "fmi2SetString", vr, nvr);
}

/* Optional capabilities the modelDescription.xml declares absent. */
static fmi2Status unsupported(fmi2Component c, const char *fn, const char *capability) {
    Instance *inst = enter(c, fn, ANY_PHASE);
    if (inst != NULL)
        LOG(inst, fmi2Error, "logError", "%s is not supported (%s=\"false\")", fn, capability);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2GetFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    (void)state;
    return unsupported(c, "fmi2SetFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2FreeFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state;
    (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize", "canSerializeFMUstate");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serializedState[], size_t size) {
    (void)state;
    (void)serializedState;
    (void)size;
    return unsupported(c, "fmi2SerializeFMUstate", "canSerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *state) {
    (void)serializedState;
    (void)size;
    (void)state;
    return unsupported(c, "fmi2DeSerializeFMUstate", "canSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative", "providesDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives", "canInterpolateInputs");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = enter(c, "fmi2DoStep", IN(STEPPING));
    double t = currentCommunicationPoint, h = communicationStepSize;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL)
        return fmi2Error;
    if (!(h > 0.0)) {
        LOG(inst, fmi2Error, "logError", "fmi2DoStep: invalid communication step size h = %g at t = %g", h, t);
        return fmi2Error;
    }
    if (fabs(t - inst->time) > 1e-9 * (1.0 + fabs(inst->time))) {
        LOG(inst, fmi2Error, "logError", "fmi2DoStep: communication point t = %.17g, but the FMU is at t = %.17g", t,
            inst->time);
        return fmi2Error;
    }
    if (foreign_model.step != NULL)
        foreign_model.step(inst, t, h);
    inst->time = t + h;
    foreign_model.update(inst);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *inst = enter(c, "fmi2CancelStep", IN(STEPPING));
    if (inst != NULL)
        LOG(inst, fmi2Error, "logError", "fmi2CancelStep: no asynchronous step is running (fmi2DoStep never pends)");
    return fmi2Error;
}

/* The status queries are for asynchronous steps (fmi2Pending), which these models never make. */
static fmi2Status no_status(fmi2Component c, const char *fn) {
    Instance *inst = enter(c, fn, ANY_PHASE);
    if (inst == NULL)
        return fmi2Error;
    LOG(inst, fmi2Discard, "logError", "%s: no such status (fmi2DoStep never pends or discards)", fn);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (inst != NULL && s == fmi2LastSuccessfulTime && value != NULL) {
        *value = inst->time;
        return fmi2OK;
    }
    return no_status(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetStringStatus");
}
