//! What `cargo xtask` builds, bundles and benchmarks: the FMUs, their variants, the benchmarks.

/// An FMU crate: its package and its model identifier.
pub struct Fmu {
    pub package: &'static str,
    pub id: &'static str,
}

pub const FMUS: &[Fmu] = &[
    Fmu {
        package: "fmu-der",
        id: "dvpp_der",
    },
    Fmu {
        package: "fmu-operator",
        id: "dvpp_operator",
    },
    Fmu {
        package: "fmu-grid",
        id: "dvpp_grid",
    },
];

/// Another configuration of an FMU, bundled as `dist/variants/<id>-<name>.fmu`.
pub struct Variant {
    pub id: &'static str,
    pub name: &'static str,
    /// The `resources/config.toml` of the variant.
    pub config: &'static str,
    /// Files (relative to the workspace root) copied into the variant's `resources/`.
    pub files: &'static [&'static str],
}

pub const VARIANTS: &[Variant] = &[];

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
];
