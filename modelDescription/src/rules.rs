//! The FMI 2.0 rules a description must satisfy before it is written (and a master may apply on read).

use crate::{
    BaseType, Causality, Initial, ModelDescription, ScalarVariable, Variability, VariableKind,
};
use std::collections::{BTreeMap, BTreeSet, HashSet};
use std::fmt;

/// One rule a description breaks, with the element it concerns.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub element: String,
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.element, self.message)
    }
}

struct Report(Vec<Problem>);

impl Report {
    fn add(&mut self, element: impl Into<String>, message: impl Into<String>) {
        self.0.push(Problem {
            element: element.into(),
            message: message.into(),
        });
    }
}

/// Every problem found in `md` (empty when it follows the rules).
pub fn check(md: &ModelDescription) -> Vec<Problem> {
    let mut r = Report(Vec::new());
    check_header(md, &mut r);
    check_variables(md, &mut r);
    check_structure(md, &mut r);
    r.0
}

fn is_c_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c == '_' || c.is_ascii_alphabetic())
        && chars.all(|c| c == '_' || c.is_ascii_alphanumeric())
}

fn check_header(md: &ModelDescription, r: &mut Report) {
    if md.fmi_version != "2.0" {
        r.add(
            "fmiModelDescription",
            format!("fmiVersion is '{}', expected '2.0'", md.fmi_version),
        );
    }
    if md.model_name.is_empty() {
        r.add("fmiModelDescription", "modelName is empty");
    }
    match (&md.co_simulation, &md.model_exchange) {
        (None, None) => r.add(
            "fmiModelDescription",
            "neither CoSimulation nor ModelExchange",
        ),
        (Some(cs), _) if !is_c_identifier(&cs.model_identifier) => r.add(
            "CoSimulation",
            format!(
                "modelIdentifier '{}' is not a C identifier",
                cs.model_identifier
            ),
        ),
        _ => {}
    }
    if let Some(t) = &md.generation_date_and_time {
        let ok = t.len() == 20
            && t.char_indices().all(|(i, c)| match i {
                4 | 7 => c == '-',
                10 => c == 'T',
                13 | 16 => c == ':',
                19 => c == 'Z',
                _ => c.is_ascii_digit(),
            });
        if !ok {
            r.add(
                "fmiModelDescription",
                format!("generationDateAndTime '{t}' is not YYYY-MM-DDThh:mm:ssZ"),
            );
        }
    }
    if let Some(de) = &md.default_experiment {
        for (name, v) in [
            ("startTime", de.start_time),
            ("stopTime", de.stop_time),
            ("tolerance", de.tolerance),
        ] {
            if matches!(v, Some(x) if !x.is_finite()) {
                r.add(
                    "DefaultExperiment",
                    format!("{name} {} is not finite", v.unwrap_or_default()),
                );
            }
        }
        if let (Some(a), Some(b)) = (de.start_time, de.stop_time) {
            if b <= a {
                r.add(
                    "DefaultExperiment",
                    format!("stopTime {b} is not after startTime {a}"),
                );
            }
        }
        if matches!(de.step_size, Some(h) if !(h > 0.0 && h.is_finite())) {
            r.add("DefaultExperiment", "stepSize must be positive and finite");
        }
    }
}

/// The `initial` FMI 2.0 assumes when the attribute is absent, or `None` where none is allowed.
pub(crate) fn default_initial(c: Causality, v: Variability) -> Option<Initial> {
    use Causality::*;
    use Variability::*;
    match (c, v) {
        (_, Constant) => Some(Initial::Exact),
        (Parameter, _) => Some(Initial::Exact),
        (CalculatedParameter, _) => Some(Initial::Calculated),
        (Local, Fixed | Tunable) => Some(Initial::Calculated),
        (Output | Local, _) => Some(Initial::Calculated),
        (Input | Independent, _) => None,
    }
}

fn legal_combination(c: Causality, v: Variability) -> bool {
    use Causality::*;
    use Variability::*;
    match c {
        Parameter | CalculatedParameter => matches!(v, Fixed | Tunable),
        Input => matches!(v, Discrete | Continuous),
        Output => matches!(v, Constant | Discrete | Continuous),
        Local => true,
        Independent => v == Continuous,
    }
}

fn legal_initials(c: Causality, v: Variability) -> &'static [Initial] {
    use Causality::*;
    use Initial::*;
    use Variability::*;
    match (c, v) {
        (_, Constant) => &[Exact],
        (Parameter, _) => &[Exact],
        (CalculatedParameter, _) | (Local, Fixed | Tunable) => &[Calculated, Approx],
        (Output | Local, _) => &[Calculated, Exact, Approx],
        (Input | Independent, _) => &[],
    }
}

fn check_variables(md: &ModelDescription, r: &mut Report) {
    let declared_units: HashSet<&str> = md
        .unit_definitions
        .iter()
        .flat_map(|u| u.units.iter().map(|u| u.name.as_str()))
        .collect();
    let mut names = HashSet::new();
    let mut refs = HashSet::new();
    for (i, v) in md.model_variables.variables.iter().enumerate() {
        let el = format!("ScalarVariable {} '{}'", i + 1, v.name);
        if v.name.is_empty() {
            r.add(&el, "empty name");
        }
        if !names.insert(v.name.as_str()) {
            r.add(&el, "name is not unique");
        }
        if !refs.insert((v.base_type(), v.value_reference)) {
            r.add(
                &el,
                format!(
                    "valueReference {} is used twice for {}",
                    v.value_reference,
                    v.base_type()
                ),
            );
        }
        let (c, var) = (v.causality(), v.variability());
        if !legal_combination(c, var) {
            r.add(
                &el,
                format!("causality {c:?} with variability {var:?} is not allowed"),
            );
            continue;
        }
        if var == Variability::Continuous && v.base_type() != BaseType::Real {
            r.add(&el, "only Real variables can be continuous");
        }
        let initial = match v.initial {
            Some(init) if !legal_initials(c, var).contains(&init) => {
                r.add(
                    &el,
                    format!("initial {init:?} is not allowed for {c:?}/{var:?}"),
                );
                continue;
            }
            Some(init) => Some(init),
            None => default_initial(c, var),
        };
        let needs_start =
            matches!(initial, Some(Initial::Exact | Initial::Approx)) || c == Causality::Input;
        let has_start = v.start_text().is_some();
        if needs_start && !has_start {
            r.add(&el, "a start value is required");
        }
        if !needs_start && has_start {
            r.add(
                &el,
                "a start value is not allowed (initial calculated or independent)",
            );
        }
        check_ranges(v, &el, &declared_units, r);
    }
}

fn check_ranges(v: &ScalarVariable, el: &str, units: &HashSet<&str>, r: &mut Report) {
    match &v.kind {
        VariableKind::Real(t) => {
            if let Some(u) = &t.unit {
                if !units.contains(u.as_str()) {
                    r.add(el, format!("unit '{u}' is not declared in UnitDefinitions"));
                }
            }
            for (what, x) in [
                ("start", t.start),
                ("min", t.min),
                ("max", t.max),
                ("nominal", t.nominal),
            ] {
                if matches!(x, Some(x) if !x.is_finite()) {
                    r.add(el, format!("{what} is not finite"));
                }
            }
            if let (Some(lo), Some(hi)) = (t.min, t.max) {
                if lo > hi {
                    r.add(el, format!("min {lo} > max {hi}"));
                }
            }
            if let Some(s) = t.start {
                if t.min.is_some_and(|lo| s < lo) || t.max.is_some_and(|hi| s > hi) {
                    r.add(el, format!("start {s} outside [min, max]"));
                }
            }
        }
        VariableKind::Integer(t) | VariableKind::Enumeration(t) => {
            if let Some(s) = t.start {
                if t.min.is_some_and(|lo| s < lo) || t.max.is_some_and(|hi| s > hi) {
                    r.add(el, format!("start {s} outside [min, max]"));
                }
            }
        }
        _ => {}
    }
}

fn check_structure(md: &ModelDescription, r: &mut Report) {
    let vars = &md.model_variables.variables;
    let n = vars.len() as u32;
    let var = |i: u32| &vars[(i - 1) as usize];
    let expected_outputs: Vec<u32> = (1..=n)
        .filter(|&i| var(i).causality() == Causality::Output)
        .collect();
    let listed: Vec<u32> = md
        .model_structure
        .outputs()
        .iter()
        .map(|u| u.index)
        .collect();
    if listed != expected_outputs {
        r.add(
            "ModelStructure/Outputs",
            format!("must list exactly the outputs in index order {expected_outputs:?}, lists {listed:?}"),
        );
    }
    let expected_initial: Vec<u32> = (1..=n)
        .filter(|&i| {
            let v = var(i);
            let init = v
                .initial
                .or_else(|| default_initial(v.causality(), v.variability()));
            (v.causality() == Causality::Output
                && matches!(init, Some(Initial::Approx | Initial::Calculated)))
                || v.causality() == Causality::CalculatedParameter
        })
        .collect();
    let listed: Vec<u32> = md
        .model_structure
        .initial_unknowns()
        .iter()
        .map(|u| u.index)
        .collect();
    if listed != expected_initial {
        r.add(
            "ModelStructure/InitialUnknowns",
            format!("must list exactly {expected_initial:?} in index order, lists {listed:?}"),
        );
    }
    let sections = [
        ("Outputs", md.model_structure.outputs(), false),
        (
            "InitialUnknowns",
            md.model_structure.initial_unknowns(),
            true,
        ),
    ];
    for (section, unknowns, initial) in sections {
        let mut seen = BTreeSet::new();
        for u in unknowns {
            let el = format!("ModelStructure/{section}/Unknown index={}", u.index);
            if u.index == 0 || u.index > n {
                r.add(&el, format!("index outside 1..={n}"));
                continue;
            }
            if !seen.insert(u.index) {
                r.add(&el, "listed twice");
            }
            let deps = match u.dependency_indices() {
                None => continue,
                Some(Err(m)) => {
                    r.add(&el, m);
                    continue;
                }
                Some(Ok(d)) => d,
            };
            for d in deps {
                if d == 0 || d > n {
                    r.add(&el, format!("dependency {d} outside 1..={n}"));
                    continue;
                }
                let dv = var(d);
                let init = dv
                    .initial
                    .or_else(|| default_initial(dv.causality(), dv.variability()));
                let ok = dv.causality() == Causality::Input
                    || (initial
                        && init == Some(Initial::Exact)
                        && dv.variability() != Variability::Constant);
                if !ok {
                    r.add(&el, format!("may not depend on '{}'", dv.name));
                }
            }
        }
    }
}

/// Outputs grouped by the inputs they depend on directly (used by masters for ordering).
pub fn direct_feedthrough(md: &ModelDescription) -> BTreeMap<u32, Vec<u32>> {
    md.model_structure
        .outputs()
        .iter()
        .map(|u| {
            let deps = match u.dependency_indices() {
                Some(Ok(d)) => d,
                _ => (1..=md.model_variables.variables.len() as u32)
                    .filter(|&i| {
                        md.model_variables.variables[(i - 1) as usize].causality()
                            == Causality::Input
                    })
                    .collect(),
            };
            (u.index, deps)
        })
        .collect()
}
