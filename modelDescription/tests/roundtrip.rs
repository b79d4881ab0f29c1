//! The reader reads what the writer writes, and the rules catch what FMI 2.0 forbids.

use model_description::*;

const GOLDEN: &str = include_str!("../../fmu-der/modelDescription.xml");

#[test]
fn written_descriptions_read_back_identically() {
    let md = ModelDescription::from_xml(GOLDEN).unwrap();
    assert_eq!(md.to_xml().unwrap(), GOLDEN);
    assert_eq!(
        md.content_guid().unwrap(),
        md.guid,
        "GUID is the hash of the content"
    );
    assert!(check(&md).is_empty());
    // `dependencies=""` (depends on nothing) is kept apart from an absent attribute.
    let out = &md.model_structure.outputs()[0];
    assert_eq!(
        out.dependency_indices().unwrap().unwrap(),
        Vec::<u32>::new()
    );
}

#[test]
fn content_changes_change_the_guid() {
    let mut md = ModelDescription::from_xml(GOLDEN).unwrap();
    let before = md.content_guid().unwrap();
    md.model_variables.variables[0].description = Some("changed".into());
    assert_ne!(md.content_guid().unwrap(), before);
}

fn problems_after(edit: impl FnOnce(&mut ModelDescription)) -> Vec<String> {
    let mut md = ModelDescription::from_xml(GOLDEN).unwrap();
    edit(&mut md);
    check(&md).iter().map(|p| p.to_string()).collect()
}

#[test]
fn rules_catch_illegal_descriptions() {
    type Edit = Box<dyn FnOnce(&mut ModelDescription)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "name is not unique",
            Box::new(|m| {
                m.model_variables.variables[1].name = m.model_variables.variables[0].name.clone()
            }),
        ),
        (
            "is not allowed",
            Box::new(|m| {
                m.model_variables.variables[0].variability = Some(Variability::Continuous)
            }),
        ),
        (
            "a start value is required",
            Box::new(|m| {
                if let VariableKind::Real(r) = &mut m.model_variables.variables[0].kind {
                    r.start = None;
                }
            }),
        ),
        (
            "is not declared in UnitDefinitions",
            Box::new(|m| {
                if let VariableKind::Real(r) = &mut m.model_variables.variables[0].kind {
                    r.unit = Some("furlong".into());
                }
            }),
        ),
        (
            "must list exactly the outputs",
            Box::new(|m| {
                m.model_structure.outputs.as_mut().unwrap().unknowns.pop();
            }),
        ),
        (
            "may not depend on",
            Box::new(|m| {
                m.model_structure.outputs.as_mut().unwrap().unknowns[0].dependencies =
                    Some("1".into());
            }),
        ),
        (
            "not a C identifier",
            Box::new(|m| m.co_simulation.as_mut().unwrap().model_identifier = "9-lives".into()),
        ),
        (
            "stopTime inf is not finite",
            Box::new(|m| {
                m.default_experiment
                    .get_or_insert_with(Default::default)
                    .stop_time = Some(f64::INFINITY)
            }),
        ),
        (
            "startTime NaN is not finite",
            Box::new(|m| {
                m.default_experiment
                    .get_or_insert_with(Default::default)
                    .start_time = Some(f64::NAN)
            }),
        ),
        (
            "valueReference",
            Box::new(|m| {
                m.model_variables.variables[1].value_reference =
                    m.model_variables.variables[0].value_reference
            }),
        ),
    ];
    for (needle, edit) in cases {
        let problems = problems_after(edit);
        assert!(
            problems.iter().any(|p| p.contains(needle)),
            "expected '{needle}' in {problems:#?}"
        );
    }
}

#[test]
fn malformed_xml_is_a_clear_error() {
    let e = ModelDescription::from_xml("<fmiModelDescription fmiVersion=\"2.0\">").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("cannot read modelDescription.xml"),
        "{e}"
    );
}
