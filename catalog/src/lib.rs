//! The one list of the workspace's FMUs: what `cargo xtask` builds and bundles, what the studies compile scenarios into, what the tests load.
//!
//! An FMU is a model library (`<model>/`, with the golden `modelDescription.xml` its tests
//! compare against) and its binary package (in `binary`, usually `<model>/fmu/`: a cdylib
//! `lib<package>.so` and the printer `<package>-describe`). Adding an FMU is one entry in
//! [`FMUS`] (and, where scenarios use it, one arm of the studies' describe dispatch, keyed by
//! [`id`]).

/// The model identifiers, as constants a `match` can use.
pub mod id {
    /// The DER matching controller, phasor level.
    pub const DER: &str = "dvpp_der";
    /// The DER matching controller at EMT level.
    pub const DER_EMT: &str = "dvpp_der_emt";
    /// The DVPP operator.
    pub const OPERATOR: &str = "dvpp_operator";
    /// The reduced grid.
    pub const GRID: &str = "dvpp_grid";
    /// The EMT plant (the power stage of N converters).
    pub const EMT_PLANT: &str = "dvpp_emt_plant";
}

/// An FMU of the workspace.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fmu {
    /// `modelIdentifier`: the binary's name, `dist/default/<id>.fmu`.
    pub id: &'static str,
    /// The package of its binary: the cdylib and the `<package>-describe` printer.
    pub package: &'static str,
    /// The directory of that package, relative to the workspace root.
    pub binary: &'static str,
    /// The directory of its model library, relative to the workspace root.
    pub model: &'static str,
}

impl Fmu {
    /// The golden model description, relative to the workspace root.
    pub fn golden(&self) -> String {
        format!("{}/modelDescription.xml", self.model)
    }

    /// The name of the model-description printer binary.
    pub fn describe_binary(&self) -> String {
        format!("{}-describe", self.package)
    }

    /// The file name of the cdylib on Linux (`lib<package with _>.so`).
    pub fn linux_library(&self) -> String {
        format!("lib{}.so", self.package.replace('-', "_"))
    }

    /// The FMU with model identifier `id`.
    pub fn by_id(id: &str) -> Option<&'static Fmu> {
        FMUS.iter().find(|f| f.id == id)
    }
}

pub const DER: Fmu = Fmu {
    id: id::DER,
    package: "fmu-der",
    binary: "fmu-der/fmu",
    model: "fmu-der",
};

pub const DER_EMT: Fmu = Fmu {
    id: id::DER_EMT,
    package: "fmu-der-emt",
    binary: "fmu-der/emt",
    model: "fmu-der/emt",
};

pub const OPERATOR: Fmu = Fmu {
    id: id::OPERATOR,
    package: "fmu-operator",
    binary: "fmu-operator/fmu",
    model: "fmu-operator",
};

pub const GRID: Fmu = Fmu {
    id: id::GRID,
    package: "fmu-grid",
    binary: "fmu-grid/fmu",
    model: "fmu-grid",
};

pub const EMT_PLANT: Fmu = Fmu {
    id: id::EMT_PLANT,
    package: "fmu-emt-plant",
    binary: "fmu-emt-plant/fmu",
    model: "fmu-emt-plant",
};

/// Every FMU, in the order they are built, bundled and documented (`docs/variables.md`).
pub const FMUS: &[Fmu] = &[DER, DER_EMT, OPERATOR, GRID, EMT_PLANT];

/// The model identifiers of [`FMUS`], in its order.
pub const IDS: [&str; FMUS.len()] = {
    let mut ids = [""; FMUS.len()];
    let mut k = 0;
    while k < FMUS.len() {
        ids[k] = FMUS[k].id;
        k += 1;
    }
    ids
};

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// Every entry names a package, a library with its golden copy, and its own identifier.
    #[test]
    fn every_fmu_is_a_package_with_a_golden_model_description() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let workspace = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
        for (k, f) in FMUS.iter().enumerate() {
            assert!(
                root.join(f.golden()).is_file(),
                "{}: no {}",
                f.id,
                f.golden()
            );
            let golden = std::fs::read_to_string(root.join(f.golden())).unwrap();
            assert!(
                golden.contains(&format!("modelIdentifier=\"{}\"", f.id)),
                "{}: {} is another FMU's",
                f.id,
                f.golden()
            );
            let manifest = format!("{}/Cargo.toml", f.binary);
            let text = std::fs::read_to_string(root.join(&manifest)).unwrap_or_default();
            assert!(
                text.contains(&format!("name = \"{}\"", f.package)),
                "{}: {manifest} is not the package {}",
                f.id,
                f.package
            );
            assert!(
                workspace.contains(&format!("\"{}\"", f.binary)),
                "{}: {} is no workspace member",
                f.id,
                f.binary
            );
            assert_eq!(IDS[k], f.id);
            assert_eq!(Fmu::by_id(f.id), Some(f));
            assert_eq!(FMUS.iter().filter(|g| g.id == f.id).count(), 1, "{}", f.id);
        }
        assert!(workspace.contains("\"catalog\""));
    }
}
