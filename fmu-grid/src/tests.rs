//! Unit tests of the grid FMU: its configuration, variables and the golden model description.

use super::*;

#[test]
fn config_selects_built_in_cases_and_rejects_bad_selections() {
    for name in Case::builtin_names() {
        let c = GridConfig {
            case: Some(name.to_string()),
            ..Default::default()
        };
        assert_eq!(&c.load_case(None).unwrap().name, name);
    }
    assert_eq!(
        GridConfig::default().load_case(None).unwrap().name,
        DEFAULT_CASE
    );
    let both = GridConfig {
        case: Some("ieee9".into()),
        case_file: Some("x.toml".into()),
        ..Default::default()
    };
    assert!(both.load_case(None).unwrap_err().contains("both"));
    let unknown = GridConfig {
        case: Some("ieee14".into()),
        ..Default::default()
    };
    assert!(unknown
        .load_case(None)
        .unwrap_err()
        .contains("not a built-in case"));
    let escape = GridConfig {
        case_file: Some("../secret.toml".into()),
        ..Default::default()
    };
    assert!(escape
        .load_case(Some(Path::new("/tmp")))
        .unwrap_err()
        .contains("inside resources"));
}

#[test]
fn machines_declare_a_boolean_in_service_output() {
    let mut vars = fmi_export::Variables::default();
    let fmu = GridFmu::declare(&GridConfig::default(), None, &mut vars).unwrap();
    assert_eq!(fmu.machines.len(), 2);
    for j in 1..=2 {
        let name = format!("sg[{j}].in_service");
        let d = vars
            .declared()
            .iter()
            .find(|d| d.spec.name == name)
            .unwrap_or_else(|| panic!("{name} is not declared"));
        assert!(matches!(d.spec.start, fmi_export::Value::Boolean(_)));
        assert_eq!(
            d.spec.causality,
            fmi_export::model_description::Causality::Output
        );
    }
}

#[test]
fn extra_events_are_validated() {
    let text =
        "case = \"ieee9\"\n[[event]]\ntype = \"load_step\"\ntime = 1.0\nbus = 50\ndp_mw = 28.0\n";
    let c: GridConfig = toml::from_str(text).unwrap();
    let e = c.load_case(None).unwrap_err();
    assert!(e.contains("bus 50"), "{e}");
    let c: GridConfig = toml::from_str(&text.replace("bus = 50", "bus = 5")).unwrap();
    assert_eq!(c.load_case(None).unwrap().events.len(), 1);
}

mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<crate::GridFmu>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
