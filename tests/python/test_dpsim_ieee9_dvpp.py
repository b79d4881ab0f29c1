"""Case study I's nine-bus system in DPsim EMT with the DVPP's three EMT-level converters at bus 2
(tests/python/dpsim_ieee9_dvpp.py: fmu-grid/cases/ieee9_dvpp.toml, SG1 and SG3 as in
dpsim_ieee9.py, the bundled emt_thevenin system's wind, PV and BESS dvpp_der_emt FMUs and its
operator FMU hosted as dpsim_emt_thevenin.py hosts them) starts flat: over 2 s at 50 µs with no
event, neither machine's speed nor the PCC meter's frequency leaves f_nom by 1e-4 Hz, no unit's p
moves by 5e-4 pu (of 100 MVA), no converter limit acts, no FMU warns. Measured: SG1 3.4e-7, SG3
4.7e-7, PCC 4.1e-6 Hz; |p - p0| 5.0e-5 / 7.5e-5 / 3.4e-5 pu; ~6 s of wall time.
"""
import pytest

from conftest import require_dpsim  # noqa: E402

require_dpsim("test_dpsim_ieee9_dvpp.py")

import dpsim_ieee9_dvpp as dvpp  # noqa: E402

END = 2.0


def test_nine_bus_with_the_dvpp_starts_flat():
    root = dvpp.bundle()
    if not all((root / f"{n}.fmu").exists() for n in (*dvpp.UNITS, "operator", "plant")):
        pytest.skip(f"the bundled emt_thevenin system is missing ({root})")
    rec = dvpp.run(END)
    df, dp = dvpp.flat_figures(rec)
    print(f"\n{END} s at {rec['h'] * 1e6:g} µs, no event, wall {rec['wall']:.1f} s: "
          + ", ".join(f"{n} max |df| {x:.2e} Hz" for n, x in df.items()) + "; "
          + ", ".join(f"{n} max |p - p0| {x:.1e} pu" for n, x in dp.items()))
    assert set(df) == {"SG1", "SG3", "PCC"}
    for x in df.values():
        assert x < 1e-4
    for x in dp.values():
        assert x < 5e-4
    assert not any(on for flags in rec["flags"].values() for on in flags.values()), rec["flags"]
    assert rec["warnings"] == [], rec["warnings"]
