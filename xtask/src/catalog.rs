//! What `cargo xtask` builds, bundles and benchmarks: the FMUs (from `dvpp-catalog`), their variants, the benchmarks.

/// The FMUs: the workspace's one list (`dvpp-catalog`).
pub use dvpp_catalog::{id, Fmu, FMUS};

/// Another configuration of an FMU, bundled as `dist/variants/<id>-<name>.fmu`.
pub struct Variant {
    pub id: &'static str,
    pub name: &'static str,
    /// The `resources/config.toml` of the variant.
    pub config: &'static str,
    /// Files (relative to the workspace root) copied into the variant's `resources/`.
    pub files: &'static [&'static str],
}

pub const VARIANTS: &[Variant] = &[
    Variant {
        id: id::GRID,
        name: "ieee9",
        config: r#"# The IEEE 9-bus base system: three governed machines, no DER slot, PCC = SG2's output.
# Event 1 is the 28 MW load step at bus 5 that the grid tests use for the base system's
# frequency response (nadir, RoCoF, settling, droop check), off by default
# (set event[1].enabled = true to run it).
[model]
case = "ieee9"

[[model.event]]
type = "load_step"
time = 1.0
bus = 5
dp_mw = 28.0

[start]
"event[1].enabled" = false
"#,
        files: &[],
    },
    Variant {
        id: id::GRID,
        name: "ieee9_hybrid",
        config: r#"# Case study II: SG2 replaced by a hybrid DVPP at bus 2 (three grid-forming and three
# grid-following slots); 42 MW load step at bus 2 at t = 1 s.
[model]
case = "ieee9_hybrid"
"#,
        files: &[],
    },
    Variant {
        id: id::GRID,
        name: "ieee9_dvpp_file",
        config: r#"# The default case (ieee9_dvpp), read from a case file in resources/ instead of the
# built-in copy: same variables, same GUID as dist/default/dvpp_grid.fmu.
[model]
case_file = "ieee9_dvpp.toml"
"#,
        files: &["fmu-grid/cases/ieee9_dvpp.toml"],
    },
    Variant {
        id: id::DER,
        name: "wind",
        config: "# Case study I wind unit: low-pass ADPF with tau = tau_dc = 1.5 s, 46 MVA.\n[model]\npreset = \"wind\"\n",
        files: &[],
    },
    Variant {
        id: id::DER,
        name: "pv",
        config: "# Case study I PV unit: low-pass ADPF with tau = tau_dc = 0.6 s, 73 MVA.\n[model]\npreset = \"pv\"\n",
        files: &[],
    },
    Variant {
        id: id::DER,
        name: "bess",
        config: "# Case study I BESS: complement of the wind and PV low-pass ADPFs, 60 MVA.\n[model]\npreset = \"bess\"\n",
        files: &[],
    },
    Variant {
        id: id::EMT_PLANT,
        name: "island",
        config: r#"# The EMT plant as an island: one 60 MVA unit feeding a series R-L load of 0.5 + j0.1 pu
# on its rating, a step of 0.1 + j0.02 pu of its rating at t = 1 s, no Thevenin source.
[model]
case = "island"
"#,
        files: &[],
    },
];

/// A benchmark: ns per `fmi2DoStep` of a bundled FMU (path relative to `dist/`) at `h`, with
/// start values set before initialization.
pub struct Bench {
    pub label: &'static str,
    pub fmu: &'static str,
    pub h: f64,
    pub set: &'static [(&'static str, f64)],
}

pub const BENCHES: &[Bench] = &[
    Bench {
        label: "DER, grid-forming",
        fmu: "default/dvpp_der.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "operator, 3 DERs",
        fmu: "default/dvpp_operator.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "grid, default",
        fmu: "default/dvpp_grid.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "grid, ieee9_dvpp (target <= 20 us)",
        fmu: "variants/dvpp_grid-ieee9_dvpp_file.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "grid, ieee9 + 28 MW step",
        fmu: "variants/dvpp_grid-ieee9.fmu",
        h: 1e-3,
        set: &[("event[1].enabled", 1.0)],
    },
    Bench {
        label: "grid, ieee9_hybrid",
        fmu: "variants/dvpp_grid-ieee9_hybrid.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "DER, grid-following",
        fmu: "default/dvpp_der.fmu",
        h: 1e-3,
        set: &[("mode", 2.0)],
    },
    Bench {
        label: "DER BESS, grid-forming complement",
        fmu: "variants/dvpp_der-bess.fmu",
        h: 1e-3,
        set: &[],
    },
    Bench {
        label: "DER at EMT level, grid-forming, 50 us (target <= 1 us)",
        fmu: "default/dvpp_der_emt.fmu",
        h: 50e-6,
        set: &[],
    },
    Bench {
        label: "DER at EMT level, grid-forming, option B (H-infinity), 50 us (target <= 1 us)",
        fmu: "default/dvpp_der_emt.fmu",
        h: 50e-6,
        set: &[("inner.kind", 1.0)],
    },
    Bench {
        label: "DER at EMT level, grid-following, 50 us",
        fmu: "default/dvpp_der_emt.fmu",
        h: 50e-6,
        set: &[("mode", 2.0)],
    },
    Bench {
        label: "EMT plant, 3 units, 50 us",
        fmu: "default/dvpp_emt_plant.fmu",
        h: 50e-6,
        set: &[],
    },
    Bench {
        label: "DER BESS, grid-following complement",
        fmu: "variants/dvpp_der-bess.fmu",
        h: 1e-3,
        set: &[("mode", 2.0)],
    },
];
