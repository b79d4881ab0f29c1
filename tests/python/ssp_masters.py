"""Run an .ssp (as written by dvpp_cosim::ssp) in two third-party masters: fmpy.ssp and libcosim.

Both helpers return ``(t, values)`` on the same grid: ``t[k-1] = t_k = t_0 + k*step`` for
k = 1..n, n = round((stop - t_0) / step), and ``values[name][k-1]`` is the value of output
connector ``name`` ("component.variable", split at the first dot) right after the step that
ends at t_k.  t_0 (the start time, 0.0 here) is not in the result: neither master hands out the
values right after initialization in a comparable way.

What the masters do (fmpy 0.3.32, libcosimpy 0.0.6 = libcosim 0.11.2):

* fmpy.ssp.simulate_ssp (fmpy/ssp/simulation.py) instantiates each FMU, sets the parameter set
  passed to it (it ignores the SSD's ParameterBindings), runs enter/exitInitializationMode with
  no propagation between FMUs, sets *every* connector to 0.0 before the first step, then does
  Jacobi steps (all doStep, then copy outputs to inputs).  It ignores LinearTransformation,
  records each row with the time before the step but the values after it, and advances time by
  accumulating ``time += step``.  Every input connector declared in the SSD must be connected
  (otherwise fmpy wires it to a stale connection).  ``run_fmpy`` passes the SSD's inline
  bindings as fmpy's parameter set (our FMUs carry the same values as start values anyway).
  The zeros of the first step are a real disturbance for our systems (see docs/architecture.md, "Third-party masters").  An SSD
  with a LinearTransformation is refused.
* libcosim reads the .ssp zip (unpacks it; a directory or an .ssd file work too), applies each
  component's first ParameterBinding as initial values (variables of causality parameter or
  input; others only give a warning), applies LinearTransformation (as a function between the
  FMUs), and initializes in initialization mode with #FMUs + #functions rounds of
  output -> input transfer before exitInitializationMode and one transfer after it, so the
  first step starts from consistent inputs.  Then fixed-step Jacobi steps.  The step size comes
  from ``step`` here; with ``step=None`` the SSD's OSP FixedStepAlgorithm annotation is used
  (without it libcosim 0.11.2 crashes, so this is checked first).  ``run_libcosim`` reads any
  variable of the FMUs; for an input it reports the value used during the step ending at t_k
  (inputs are set after the step, observers see them one step later).
"""

from __future__ import annotations

import zipfile

import numpy as np

OSP_STEP = "{http://opensimulationplatform.com/SSP/OSPAnnotations}FixedStepAlgorithm"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"


def _grid(start, stop, step):
    n = int(round((stop - start) / step))
    if n < 1:
        raise ValueError(f"no step between start {start} and stop {stop} (step {step})")
    return n, start + step * np.arange(1, n + 1)


def _ssd_root(ssp_path):
    from lxml import etree

    with zipfile.ZipFile(ssp_path) as z:
        return etree.fromstring(z.read("SystemStructure.ssd"))


def _fmpy_parameter_set(system):
    """The SSD's parameter bindings as one fmpy ParameterSet named "component.variable"."""
    from fmpy.ssp.ssd import Parameter, ParameterSet

    names = [c.name for c in system.elements]
    for a in names:
        for b in names:
            if a != b and b.startswith(a):
                # fmpy matches parameters to components with str.startswith
                raise RuntimeError(f"fmpy.ssp cannot tell components {a!r} and {b!r} apart")
    convert = {
        "Real": float,
        "Integer": int,
        "Boolean": lambda v: v.strip() in ("true", "1"),
    }
    out = ParameterSet(name="bindings")
    for owner in [system] + list(system.elements):
        prefix_owner = "" if owner is system else owner.name + "."
        for binding in owner.parameterBindings:
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    if p.type not in convert:
                        raise RuntimeError(f"fmpy.ssp cannot set {p.type} parameter {p.name!r}")
                    name = prefix_owner + (binding.prefix or "") + p.name
                    out.parameters.append(Parameter(name=name, type=p.type, value=convert[p.type](p.value)))
    return out


def run_fmpy(ssp_path, stop, step, signals, start=0.0):
    """Simulate with plain fmpy.ssp.simulate_ssp (the SSD's bindings passed as its parameter set)."""
    import fmpy.ssp.simulation as sim
    from fmpy.ssp.ssd import read_ssd

    ssp_path = str(ssp_path)
    if _ssd_root(ssp_path).find(f".//{{{SSC}}}LinearTransformation") is not None:
        raise RuntimeError(f"{ssp_path}: fmpy.ssp ignores LinearTransformation; refusing to run it")
    try:
        ssd = read_ssd(ssp_path, validate=True)
    except Exception as e:
        raise RuntimeError(f"fmpy.ssp rejects {ssp_path}: {e}") from e
    kinds = {f"{c.name}.{k.name}": k.kind for c in ssd.system.elements for k in c.connectors}
    for s in signals:
        if kinds.get(s) != "output":
            raise ValueError(f"{s!r} is not an output connector of {ssp_path}")
    n, t = _grid(start, stop, step)
    try:
        rows = sim.simulate_ssp(
            ssp_path,
            start_time=start,
            stop_time=stop,
            step_size=step,
            parameter_set=_fmpy_parameter_set(ssd.system),
        )
    except Exception as e:
        raise RuntimeError(f"fmpy.ssp failed on {ssp_path}: {e}") from e
    if len(rows) < n:
        raise RuntimeError(f"fmpy.ssp returned {len(rows)} rows, expected {n}")
    # rows[i]: time before step i+1, values after it (fmpy may run one extra step: time += step)
    return t, {s: np.asarray(rows[s][:n]) for s in signals}


def run_libcosim(ssp_path, stop, step, signals):
    """Simulate with libcosimpy from the .ssp; ``step=None``: the SSD's OSP annotation step."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy._internal import get_last_error_message

    ssp_path = str(ssp_path)
    log_output_level(CosimLogLevel.ERROR)
    if step is None:
        found = _ssd_root(ssp_path).find(f".//{OSP_STEP}")
        if found is None:
            raise RuntimeError(f"{ssp_path}: no OSP FixedStepAlgorithm annotation; give a step")
        step = float(found.get("baseStepSize"))
        execution = _create(lambda: CosimExecution.from_ssp_file(ssp_path), ssp_path)
    else:
        ns = int(round(step * 1e9))
        execution = _create(lambda: CosimExecution.from_ssp_file(ssp_path, step_size=ns), ssp_path)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)

    readers = {
        CosimVariableType.REAL.value: observer.last_real_values,
        CosimVariableType.INTEGER.value: observer.last_integer_values,
        CosimVariableType.BOOLEAN.value: observer.last_boolean_values,
    }
    slaves = {s.name.decode(): s.index for s in execution.slave_infos()}
    groups = {}  # (slave index, type) -> [(signal, value reference)]
    for s in signals:
        component, _, variable = s.partition(".")
        if component not in slaves:
            raise ValueError(f"{s!r}: no component {component!r} in {ssp_path}")
        found = [v for v in execution.slave_variables(slaves[component]) if v.name.decode() == variable]
        if not found:
            raise ValueError(f"{s!r}: component {component!r} has no variable {variable!r}")
        if found[0].type not in readers:
            raise ValueError(f"{s!r}: cannot read {CosimVariableType(found[0].type).name} values")
        groups.setdefault((slaves[component], found[0].type), []).append((s, found[0].reference))

    start = execution.status().current_time * 1e-9
    n, _ = _grid(start, stop, step)
    t = np.empty(n)
    values = {s: [] for s in signals}
    for k in range(n):
        if not execution.step():
            raise RuntimeError(f"libcosim step {k + 1} failed: {get_last_error_message()}")
        t[k] = execution.status().current_time * 1e-9
        for (slave, ty), members in groups.items():
            for (s, _), v in zip(members, readers[ty](slave, [vr for _, vr in members])):
                values[s].append(v)
    return t, {s: np.asarray(v) for s, v in values.items()}


def _create(make, ssp_path):
    from libcosimpy._internal import get_last_error_message

    try:
        execution = make()
    except AssertionError as e:
        raise RuntimeError(f"libcosim rejects {ssp_path}: {get_last_error_message() or e}") from e
    return execution
