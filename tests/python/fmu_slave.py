"""One FMU instance through fmpy's FMU2Slave, initialized with given start values and its log
collected; shared by the DER tests and the DPsim host."""

_EXTRACTED = {}


class Slave:
    """The instance ``name`` of the FMU at ``path``, with ``params`` set before initialization
    (by the variables' types), through initialization mode and ready to step."""

    def __init__(self, path, name, params=None):
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.model_description import read_model_description

        path = str(path)
        if path not in _EXTRACTED:
            _EXTRACTED[path] = (read_model_description(path), extract(path))
        md, unzipdir = _EXTRACTED[path]
        self.vars = {v.name: v for v in md.modelVariables}
        self.messages = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, inst, status, cat, msg: self.messages.append((status, msg.decode()))
        )
        self.callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self.callbacks.freeMemory = defaultCallbacks.freeMemory
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(loggingOn=False, callbacks=self.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        for k, x in (params or {}).items():
            self.set(k, x)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def vr(self, name):
        return self.vars[name].valueReference

    def set(self, name, x):
        kind = self.vars[name].type
        if kind == "Integer":
            self.fmu.setInteger([self.vr(name)], [int(x)])
        elif kind == "Boolean":
            self.fmu.setBoolean([self.vr(name)], [bool(x)])
        else:
            self.fmu.setReal([self.vr(name)], [float(x)])

    def get(self, *names):
        return self.fmu.getReal([self.vr(n) for n in names])

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
