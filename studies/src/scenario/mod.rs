//! Scenarios: one TOML file per study (grid case, `T_des`, DERs, events, experiment) bundled into
//! `dist/<scenario>/`: one FMU per component with the scenario's values as start values, and an
//! SSP system `<scenario>.ssp` that wires them by the signal contract (`docs/contract.md`).

mod emt;
mod job;
mod schema;
mod split;
mod ssd;
mod wiring;

pub use emt::EmtSpec;
pub use schema::{DerSpec, DvppSpec, Experiment, FleetSpec, GridSpec, Scenario, StartOnly, RECORD};

use model_description::ModelDescription;
use std::path::{Path, PathBuf};
use toml::Value;

use job::Job;
use split::split_ders;
use ssd::system;
use wiring::wiring;

/// A component-name part: letters, digits and `_`, not empty.
fn plain_name(name: &str) -> bool {
    !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The scenario's name: its file stem.
pub fn name_of(path: &Path) -> Result<String, String> {
    path.file_stem()
        .and_then(|s| s.to_str())
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .ok_or_else(|| format!("{}: not a scenario file name", path.display()))
}

/// How a component's FMU is made: package, staging name, config text, extra resource files.
pub struct Build {
    /// The FMU this component is an instance of.
    pub fmu: &'static dvpp_catalog::Fmu,
    pub staging: String,
    pub config: String,
    pub files: Vec<PathBuf>,
    pub out: PathBuf,
}

/// Bundles one component and returns its model description (the bundler's `bundle_one`).
pub type Bundler<'a> = dyn FnMut(&Build) -> Result<ModelDescription, String> + 'a;

fn real(x: f64) -> Value {
    Value::Float(x)
}

/// Start value of `name` in a model description, as f64.
fn start_of(md: &ModelDescription, name: &str) -> Option<f64> {
    md.variable(name)?.start_text()?.parse().ok()
}

/// The component names of the grid and the operator (a DER's is its scenario name).
const GRID: &str = "grid";
const OPERATOR: &str = "operator";

/// A bundler that builds nothing: the model description of `b` described in process from its
/// configuration (staged under `dir`), and an empty file in place of the FMU. Enough to compile a
/// scenario into its system (the tests and `cargo xtask fuzz`), not to run it.
pub fn described(dir: &Path, b: &Build) -> Result<ModelDescription, String> {
    use fmi_export::{describe, Config};
    let res = dir.join(&b.staging);
    std::fs::create_dir_all(&res).map_err(|e| e.to_string())?;
    std::fs::write(res.join(fmi_export::CONFIG_FILE), &b.config).map_err(|e| e.to_string())?;
    for f in &b.files {
        let name = f
            .file_name()
            .ok_or(format!("{}: not a file", f.display()))?;
        std::fs::copy(f, res.join(name)).map_err(|e| format!("{}: {e}", f.display()))?;
    }
    use dvpp_catalog::id;
    let md = match b.fmu.id {
        id::GRID => describe::<grid_model::GridFmu>(&Config::load(&res)?, Some(&res)),
        id::DER => describe::<der_model::Der>(&Config::load(&res)?, Some(&res)),
        id::OPERATOR => describe::<operator_model::Operator>(&Config::load(&res)?, Some(&res)),
        id::DER_EMT => describe::<der_model::emt::DerEmt>(&Config::load(&res)?, Some(&res)),
        id::EMT_PLANT => describe::<emt_plant_model::Plant>(&Config::load(&res)?, Some(&res)),
        other => Err(format!("no model to describe the FMU {other}")),
    }?;
    // The system only needs the file to exist.
    std::fs::write(&b.out, b"").map_err(|e| e.to_string())?;
    Ok(md)
}

/// The scenario at `path` with its DERs as the system has them: each split into its
/// grid-forming and grid-following parts by `[dvpp] eps`, and the fleets expanded.
fn resolved(path: &Path) -> Result<Scenario, String> {
    let mut sc = Scenario::read(path)?;
    if let Some(eps) = sc.dvpp.as_ref().and_then(|d| d.eps) {
        if !(0.0..=1.0).contains(&eps) {
            return Err(format!(
                "{}: [dvpp] eps = {eps}: the grid-forming share is in [0, 1]",
                path.display()
            ));
        }
        let scale = sc.dvpp.as_ref().and_then(|d| d.rating_scale).unwrap_or(1.0);
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(format!(
                "{}: [dvpp] rating_scale = {scale}: must be > 0",
                path.display()
            ));
        }
        sc.der = split_ders(&sc.der, eps);
    }
    sc.expand_fleets()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(sc)
}

/// The DER units (component names) of the scenario at `path`, in the grid's slot order.
pub fn units(path: &Path) -> Result<Vec<String>, String> {
    Ok(resolved(path)?.der.into_iter().map(|d| d.name).collect())
}

/// The PCC frequency meter's time constant the scenario at `path` sets (`[grid]
/// pcc_f_filter_t`, s), if it sets one.
pub fn pcc_f_filter_t(path: &Path) -> Result<Option<f64>, String> {
    Ok(resolved(path)?.grid.pcc_f_filter_t)
}

/// Bundle the scenario at `path` into `out_dir` and write `<name>.ssp` there.
pub fn bundle(path: &Path, out_dir: &Path, bundle_one: &mut Bundler) -> Result<PathBuf, String> {
    let name = name_of(path)?;
    let sc = resolved(path)?;
    let member = sc
        .membership()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let mut job = Job {
        path,
        name,
        sc,
        member,
        out_dir,
        bundle_one,
    };
    job.check_der_names()?;
    let emt = job.sc.emt.is_some();
    // The grid case: the grid FMU's, or (EMT level) the plant's data source.
    let mut grid = if emt && !job.sc.grid.has_case() {
        None
    } else {
        Some(job.grid(!emt)?)
    };
    let slots = match &grid {
        Some(g) => Job::slots(g),
        None => job.plant_slots()?,
    };
    let ders = job.ders(&slots)?;
    let mut operators = Vec::new();
    let mut named = Vec::new();
    if job.sc.operator.is_some() {
        let Some(grid) = &grid else {
            return Err(format!(
                "{}: an operator needs the power-flow point of a grid case ([grid] case); [emt] plant alone runs its units without one",
                path.display()
            ));
        };
        for (g, (name, component, _)) in job.groups().into_iter().enumerate() {
            operators.push(job.operator(grid, &ders, g)?);
            named.push((name, component));
        }
    }
    let pocs = grid.as_ref().map_or(0, |g| g.case.pocs.len());
    let (source, measured) = if emt {
        (emt::PLANT, job.plant(grid.as_ref(), &ders)?)
    } else {
        let unit = grid
            .as_mut()
            .and_then(|g| g.unit.take())
            .expect("the grid FMU");
        (GRID, unit)
    };
    let wires = wiring(&ders, &named, pocs, source);
    let mut units = vec![measured];
    units.extend(ders.into_iter().map(|d| d.unit));
    units.extend(operators);
    let system = system(&job.name, &job.sc, &units, wires)?;
    let fmus: Vec<(String, PathBuf)> = system
        .components
        .iter()
        .map(|c| (c.source.clone(), out_dir.join(format!("{}.fmu", c.name))))
        .collect();
    let out = out_dir.join(format!("{}.ssp", job.name));
    system
        .write_ssp(&fmus, &out)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use der_model::ports as der;
    use dvpp_cosim::ssp;
    use grid_model::ports as grid;
    use model_description::Causality;
    use operator_model::ports as op;
    use std::collections::BTreeMap;

    /// Every FMU of the catalog is described in process by a model of its identifier (the one
    /// place besides the catalog that adding an FMU touches).
    #[test]
    fn every_catalog_fmu_is_described_by_its_model() {
        let tmp = dvpp_cosim::tmp::TempDir::new("studies-catalog").unwrap();
        for fmu in dvpp_catalog::FMUS {
            let b = Build {
                fmu,
                staging: fmu.id.into(),
                config: "# defaults\n".into(),
                files: Vec::new(),
                out: tmp.path().join(format!("{}.fmu", fmu.id)),
            };
            let md = described(tmp.path(), &b).unwrap_or_else(|e| panic!("{}: {e}", fmu.id));
            assert_eq!(md.model_identifier(), Some(fmu.id));
        }
    }

    /// Bundle `scenario` with the FMUs described in process instead of built: the system, and
    /// the model description of each component.
    fn bundled(scenario: &Path) -> (ssp::System, BTreeMap<String, ModelDescription>) {
        try_bundled(scenario).unwrap()
    }

    /// [`bundled`], or the bundler's error.
    fn try_bundled(
        scenario: &Path,
    ) -> Result<(ssp::System, BTreeMap<String, ModelDescription>), String> {
        let name = name_of(scenario).unwrap();
        let tmp = dvpp_cosim::tmp::TempDir::new(&format!("studies-scenario-{name}")).unwrap();
        let dir = tmp.path().to_path_buf();
        let mut mds = BTreeMap::new();
        let mut one = |b: &Build| -> Result<ModelDescription, String> {
            let md = described(&dir, b)?;
            let component = b.out.file_stem().unwrap().to_string_lossy().into_owned();
            mds.insert(component, md.clone());
            Ok(md)
        };
        let ssp = bundle(scenario, &dir, &mut one);
        let system = ssp.map(|ssp| ssp::read(&ssp).unwrap().system.clone());
        let _ = std::fs::remove_dir_all(&dir);
        Ok((system?, mds))
    }

    /// Every connection runs from an output to an input of the model descriptions, and every
    /// input is driven once: a connector renamed on one side only fails here.
    fn assert_wired(scenario: &Path, connections: usize) {
        let (system, mds) = bundled(scenario);
        assert_eq!(
            system.connections.len(),
            connections,
            "{}",
            scenario.display()
        );
        let mut driven = std::collections::BTreeSet::new();
        for c in &system.connections {
            let causality = |component: &str, name: &str| {
                mds[component]
                    .variable(name)
                    .unwrap_or_else(|| panic!("{component} has no variable '{name}'"))
                    .causality()
            };
            let from = (&c.start_element, &c.start_connector);
            let to = (&c.end_element, &c.end_connector);
            assert_eq!(causality(from.0, from.1), Causality::Output, "{from:?}");
            assert_eq!(causality(to.0, to.1), Causality::Input, "{to:?}");
            assert!(driven.insert(to), "{to:?} driven twice");
        }
    }

    #[test]
    fn shipped_scenarios_wire_outputs_to_inputs() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        // Per DER: 4 measurements, 2 drives, 4 to the operator, mu_q, and the converter limits
        // (grid-forming: i_limit, p_min, p_max); mu_p of the 2 low-pass units, their 2 gains to
        // the complement; 4 PCC measurements.
        assert_wired(&dir.join("case1_load.toml"), 3 * (11 + 3) + 2 + 2 + 4);
        assert_wired(&dir.join("ieee9.toml"), 0);
        // Case study III: as case study I, and 4 measurements of each of the 2 POCs.
        for name in [
            "case3_ext_pf",
            "case3_ext_rot",
            "case3_int_pf",
            "case3_int_rot",
        ] {
            assert_wired(
                &dir.join(format!("{name}.toml")),
                3 * (11 + 3) + 2 + 2 + 4 + 2 * 4 + 2,
            );
        }
    }

    /// EMT-level systems: per DER its 10 measurements from the plant and 6 commands to it (the
    /// modulation, the dc source's command and its range); with
    /// an operator as case study I (4 measurements and mu_q per DER, mu_p of the 2 low-pass
    /// units, their 2 gains to the complement) and the plant's 4 PCC measurements.
    #[test]
    fn emt_scenarios_wire_outputs_to_inputs() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        for name in ["emt_island", "emt_island_hinf"] {
            assert_wired(&dir.join("scenarios").join(format!("{name}.toml")), 16);
        }
        for name in ["emt_thevenin", "emt_thevenin_hinf"] {
            assert_wired(
                &dir.join("scenarios").join(format!("{name}.toml")),
                3 * 16 + 3 * 5 + 2 + 2 + 4,
            );
        }
    }

    #[test]
    fn rot_rx_reaches_every_der_and_the_operator_of_a_poc_case() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        for (name, rx) in [("case3_ext_rot", 1.0), ("case3_int_pf", 0.0)] {
            let (system, mds) = bundled(&dir.join(format!("{name}.toml")));
            let bound = |c: &str, n: &str| {
                system
                    .components
                    .iter()
                    .find(|x| x.name == c)
                    .and_then(|x| x.parameters.iter().find(|p| p.name == n))
                    .map(|p| p.value.clone())
            };
            for c in ["wind", "pv", "bess", OPERATOR] {
                assert_eq!(bound(c, "rot.rx"), Some(ssp::Value::Real(rx)), "{name} {c}");
                assert_eq!(start_of(&mds[c], "rot.rx"), Some(rx), "{name} {c}");
            }
            assert!(mds[OPERATOR].variable(&op::poc_err_df(2)).is_some());
            assert!(mds[OPERATOR].variable(&op::poc_err_df(3)).is_none());
        }
        // Without POCs the operator has none of their variables.
        let (_, mds) = bundled(&dir.join("case1_load.toml"));
        assert!(mds[OPERATOR].variable(op::ROT_RX).is_none());
    }

    #[test]
    fn hybrid_dvpp_wires_grid_following_units_and_two_complements() {
        let tmp = dvpp_cosim::tmp::TempDir::new("studies-hybrid").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("hybrid.toml");
        let mut text = String::from(
            "description = \"hybrid\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
             [grid]\ncase = \"ieee9_hybrid\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
             Dq = 0.01\n[operator]\n",
        );
        for (name, preset) in [
            ("wind", "wind"),
            ("pv", "pv"),
            ("bess", "bess"),
            ("wind_gfl", "wind"),
            ("pv_gfl", "pv"),
            ("bess_gfl", "bess"),
        ] {
            text += &format!("[[der]]\nname = \"{name}\"\npreset = \"{preset}\"\n");
        }
        std::fs::write(&path, text).unwrap();
        // 6 DERs of 11 connections, 3 grid-forming with 3 limits and 3 grid-following with 1;
        // 4 low-pass mu_p; 2 complements closing the 2 low-pass units of their form; 4 PCC.
        assert_wired(&path, 6 * 11 + 3 * 3 + 3 + 4 + 2 * 2 + 4);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn eps_splits_every_unit_and_its_slot() {
        let tmp = dvpp_cosim::tmp::TempDir::new("studies-eps").unwrap();
        let dir = tmp.path().to_path_buf();
        for (eps, connections) in [
            // Both forms: as the hand-written hybrid DVPP.
            (0.25, 6 * 11 + 3 * 3 + 3 + 4 + 2 * 2 + 4),
            // One form only: three units, one complement closing both low-pass units.
            (0.0, 3 * 11 + 3 + 2 + 2 + 4),
            (1.0, 3 * (11 + 3) + 2 + 2 + 4),
        ] {
            let path = dir.join(format!("eps{}.toml", (eps * 100.0) as u32));
            let mut text = format!(
                "description = \"split\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
                 [grid]\ncase = \"ieee9_dvpp\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
                 Dq = 0.01\neps = {eps}\n[operator]\n"
            );
            for name in ["wind", "pv", "bess"] {
                text += &format!(
                    "[[der]]\nname = \"{name}\"\npreset = \"{name}\"\n[der.start]\nP_avail0 = 0.5\n"
                );
            }
            std::fs::write(&path, text).unwrap();
            assert_wired(&path, connections);
            let (system, mds) = bundled(&path);
            let ders: Vec<&str> = system
                .components
                .iter()
                .map(|c| c.name.as_str())
                .filter(|n| n.ends_with("_gfm") || n.ends_with("_gfl"))
                .collect();
            assert_eq!(ders.len(), if eps == 0.25 { 6 } else { 3 }, "{ders:?}");
            // Each part: rating and availability times its share of the unit.
            let start = |c: &str, n: &str| {
                system
                    .components
                    .iter()
                    .find(|x| x.name == c)
                    .and_then(|x| x.parameters.iter().find(|p| p.name == n))
                    .and_then(|p| match p.value {
                        ssp::Value::Real(x) => Some(x),
                        _ => None,
                    })
                    .or_else(|| start_of(&mds[c], n))
            };
            for (suffix, part) in [("_gfm", eps), ("_gfl", 1.0 - eps)] {
                if part == 0.0 {
                    continue;
                }
                let c = format!("pv{suffix}");
                assert_eq!(
                    start(&c, der::S_RATED),
                    Some(dvpp_control::fleet::PV.s_rated * part),
                    "{c}"
                );
                assert_eq!(start(&c, der::P_AVAIL0), Some(0.5 * part), "{c}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn fleets_and_named_dvpps_wire_each_operator_to_its_own_units() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        // Per static grid-forming fleet unit: 4 measurements, 2 drives, 3 limits, 4 to the
        // operator, mu_q and mu_p; 4 PCC measurements per operator.
        assert_wired(&dir.join("scale_fleet200.toml"), 200 * 15 + 4);
        // Case study I's DVPP as in case1_load, and 24 fleet units with their operator.
        assert_wired(
            &dir.join("scale_two_dvpps.toml"),
            3 * (11 + 3) + 2 + 2 + 4 + 24 * 15 + 4,
        );
        let (system, mds) = bundled(&dir.join("scale_two_dvpps.toml"));
        let operators: Vec<&str> = system
            .components
            .iter()
            .map(|c| c.name.as_str())
            .filter(|n| n.starts_with("operator"))
            .collect();
        assert_eq!(operators, ["operator_ci", "operator_fleet"]);
        // Each operator serves its own units, numbered from 1, with its own T_des.
        assert!(mds["operator_ci"].variable(&op::der_mu_p(3)).is_none());
        assert!(mds["operator_fleet"].variable(&op::der_mu_p(24)).is_some());
        assert_eq!(start_of(&mds["operator_fleet"], der::S_DVPP), Some(60.0));
        assert_eq!(start_of(&mds["f24"], der::S_DVPP), Some(60.0));
        assert_eq!(start_of(&mds["wind"], der::S_DVPP), Some(96.0));
        assert_eq!(start_of(&mds["f7"], der::S_RATED), Some(2.5));
        let from = |to: &str, input: &str| {
            system
                .connections
                .iter()
                .find(|c| c.end_element == to && c.end_connector == input)
                .map(|c| (c.start_element.clone(), c.start_connector.clone()))
        };
        assert_eq!(
            from("operator_fleet", op::PCC_F),
            Some((GRID.into(), grid::dvpp_pcc_f("fleet")))
        );
        assert_eq!(
            from("f3", der::MU_P),
            Some(("operator_fleet".into(), op::der_mu_p(3)))
        );
        assert_eq!(
            from("operator_fleet", &op::der_p(3)),
            Some((GRID.into(), grid::der_p(6)))
        );
        // The BESS closes the two low-pass units of its own DVPP only.
        assert_eq!(start_of(&mds["bess"], der::ADPF_P_N_LPF), Some(2.0));
    }

    /// The error bundling `text` (a scenario file body) gives.
    fn bundle_error(text: &str) -> String {
        let tmp = dvpp_cosim::tmp::TempDir::new("studies-bad").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("bad.toml");
        std::fs::write(&path, text).unwrap();
        let mut one = |_: &Build| -> Result<ModelDescription, String> { Err("built".into()) };
        let e = bundle(&path, &dir.join("out"), &mut one).unwrap_err();
        let _ = std::fs::remove_dir_all(&dir);
        e
    }

    #[test]
    fn a_complement_closing_more_low_pass_units_than_it_can_is_refused() {
        let tmp = dvpp_cosim::tmp::TempDir::new("studies-lpf").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("many_lpf.toml");
        let mut text = String::from(
            "description = \"many\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
             [grid]\ncase = \"ieee9_dvpp\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
             Dq = 0.01\n[operator]\n",
        );
        for name in ["wind", "pv", "bess"] {
            text += &format!("[[der]]\nname = \"{name}\"\npreset = \"{name}\"\n");
        }
        // Seven more low-pass units: the BESS would close nine.
        text += "[[fleet]]\nname = \"w\"\npreset = \"wind\"\ncount = 7\nbuses = [5]\nrating_mva = 70.0\n";
        std::fs::write(&path, text).unwrap();
        let e = try_bundled(&path).map(|_| ()).unwrap_err();
        assert!(
            e.contains("would close 9 low-pass units") && e.contains("at most 8"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_fleets_and_dvpp_names_are_refused_with_clear_errors() {
        let head = "description = \"bad\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
                    [grid]\ncase = \"ieee9_dvpp\"\ncase_slots = false\n[operator]\n";
        let one = "[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\nDq = 0.01\n";
        let named = "[dvpp.a]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\nDq = 0.01\n";
        let fleet = |extra: &str| {
            format!(
                "[[fleet]]\nname = \"u\"\ncount = 4\nbuses = [2, 5]\nrating_mva = 10.0\n{extra}"
            )
        };
        for (text, expected) in [
            (
                format!("{head}{one}{}", fleet("").replace("count = 4", "count = 0")),
                "count = 0",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("[2, 5]", "[2, 42]")),
                "bus 42 is not a bus",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("[2, 5]", "[]")),
                "buses is empty",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("10.0", "0.0")),
                "total rating is > 0",
            ),
            (
                format!("{head}{named}{}", fleet("dvpp = \"b\"\n")),
                "unknown DVPP 'b'",
            ),
            (
                format!("{head}{named}{}", fleet("")),
                "every DER names its DVPP",
            ),
            (
                format!("{head}{one}{}", fleet("dvpp = \"a\"\n")),
                "no named DVPPs",
            ),
            (
                format!(
                    "{head}{named}[dvpp.b]\nS_dvpp = 9.0\nH = 1.0\nD = 1.0\nDq = 0.01\n{}",
                    fleet("dvpp = \"a\"\n")
                ),
                "[dvpp.b]: no DER belongs to it",
            ),
            (
                format!("{head}{named}[dvpp.a.extra]\n{}", fleet("dvpp = \"a\"\n")),
                "extra",
            ),
            (
                format!("{head}[dvpp]\nH = 5.0\n{}", fleet("")),
                "'H' is neither",
            ),
            (
                format!(
                    "{head}{}",
                    one.replace("Dq = 0.01", "Dq = 0.01\npcc_bus = 2")
                ),
                "pcc_bus: only a named DVPP",
            ),
            (
                format!("{head}{one}"),
                "case_slots = false leaves no DER slot",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("\"u\"", "\"operator_\"")),
                "must be unique",
            ),
        ] {
            let e = bundle_error(&text);
            assert!(e.contains(expected), "expected '{expected}' in: {e}");
        }
    }

    /// `units` (what the case-study checks expect) names the DER components of the compiled
    /// system, in the grid's slot order, for every shipped scenario (none for `ieee9`).
    #[test]
    fn units_are_the_der_components_in_slot_order() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        assert!(files.len() > 10, "the shipped scenarios");
        for path in files {
            let (system, mds) = bundled(&path);
            let ders: Vec<String> = system
                .components
                .iter()
                .filter(|c| {
                    matches!(
                        mds[&c.name].model_identifier(),
                        Some(dvpp_catalog::id::DER | dvpp_catalog::id::DER_EMT)
                    )
                })
                .map(|c| c.name.clone())
                .collect();
            assert_eq!(units(&path).unwrap(), ders, "{}", path.display());
        }
    }
}
