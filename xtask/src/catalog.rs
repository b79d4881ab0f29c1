//! What `cargo xtask` builds, bundles and benchmarks: the FMUs (from `dvpp-catalog`), their variants, the benchmarks.

/// The FMUs: the workspace's one list (`dvpp-catalog`).
pub use dvpp_catalog::{id, Fmu, FMUS};
use dvpp_control::fleet::{Fleet, Shape};
use std::borrow::Cow;

/// Another configuration of an FMU, bundled as `dist/variants/<id>-<name>.fmu`.
pub struct Variant {
    pub id: &'static str,
    pub name: Cow<'static, str>,
    /// The `resources/config.toml` of the variant.
    pub config: Cow<'static, str>,
    /// Files (relative to the workspace root) copied into the variant's `resources/`.
    pub files: &'static [&'static str],
}

/// Every variant: the grid's, one DER per unit of case study I's fleet (its preset), the EMT
/// plant's island.
pub fn variants() -> Vec<Variant> {
    let mut all: Vec<Variant> = GRID_VARIANTS.iter().map(Variant::copy).collect();
    let fleet = Fleet::case_study_i();
    let low_pass: Vec<&str> = fleet
        .low_pass()
        .into_iter()
        .map(|k| fleet.units[k].name.as_str())
        .collect();
    for u in &fleet.units {
        let what = match u.kind.shape {
            Shape::LowPass => format!("low-pass ADPF with tau = tau_dc = {} s", u.kind.tau_dc),
            Shape::Complement => format!(
                "complement of the {} low-pass ADPFs",
                low_pass.join(" and ")
            ),
        };
        all.push(Variant {
            id: id::DER,
            name: u.name.clone().into(),
            config: format!(
                "# Case study I unit {}: {what}, {} MVA.\n[model]\npreset = \"{}\"\n",
                u.name, u.kind.s_rated, u.kind.name
            )
            .into(),
            files: &[],
        });
    }
    all.extend(PLANT_VARIANTS.iter().map(Variant::copy));
    all
}

impl Variant {
    fn copy(&self) -> Variant {
        Variant {
            id: self.id,
            name: self.name.clone(),
            config: self.config.clone(),
            files: self.files,
        }
    }
}

const GRID_VARIANTS: &[Variant] = &[
    Variant {
        id: id::GRID,
        name: Cow::Borrowed("ieee9"),
        config: Cow::Borrowed(
            r#"# The IEEE 9-bus base system: three governed machines, no DER slot, PCC = SG2's output.
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
        ),
        files: &[],
    },
    Variant {
        id: id::GRID,
        name: Cow::Borrowed("ieee9_hybrid"),
        config: Cow::Borrowed(
            r#"# Case study II: SG2 replaced by a hybrid DVPP at bus 2 (three grid-forming and three
# grid-following slots); 42 MW load step at bus 2 at t = 1 s.
[model]
case = "ieee9_hybrid"
"#,
        ),
        files: &[],
    },
    Variant {
        id: id::GRID,
        name: Cow::Borrowed("ieee9_dvpp_file"),
        config: Cow::Borrowed(
            r#"# The default case (ieee9_dvpp), read from a case file in resources/ instead of the
# built-in copy: same variables, same GUID as dist/default/dvpp_grid.fmu.
[model]
case_file = "ieee9_dvpp.toml"
"#,
        ),
        files: &["fmu-grid/cases/ieee9_dvpp.toml"],
    },
];

const PLANT_VARIANTS: &[Variant] = &[Variant {
    id: id::EMT_PLANT,
    name: Cow::Borrowed("island"),
    config: Cow::Borrowed(
        r#"# The EMT plant as an island: one 60 MVA unit feeding a series R-L load of 0.5 + j0.1 pu
# on its rating, a step of 0.1 + j0.02 pu of its rating at t = 1 s, no Thevenin source.
[model]
case = "island"
"#,
    ),
    files: &[],
}];

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
