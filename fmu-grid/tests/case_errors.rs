//! Each class of bad case file returns the right `CaseError`.
use grid_model::{case::builtin_text, Case, CaseError};

fn base() -> String {
    builtin_text("ieee9_af").unwrap().to_string()
}

fn err(text: &str) -> CaseError {
    let e = Case::from_toml_str(text).expect_err("case should be rejected");
    // Display names the problem
    assert!(!e.to_string().is_empty());
    e
}

#[test]
fn builtin_cases_are_valid() {
    for n in Case::builtin_names() {
        let c = Case::builtin(n).unwrap();
        assert_eq!(&c.name, n);
        assert!(!c.source.is_empty());
    }
}

#[test]
fn unknown_bus_in_load() {
    let t = base().replacen("[[load]]\nbus = 5", "[[load]]\nbus = 55", 1);
    match err(&t) {
        CaseError::UnknownBus { bus, element } => {
            assert_eq!(bus, 55);
            assert!(element.contains("load"));
        }
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn unknown_bus_in_line() {
    let t = base().replacen("from = 4\nto = 5", "from = 4\nto = 12", 1);
    assert!(matches!(err(&t), CaseError::UnknownBus { bus: 12, .. }));
}

#[test]
fn missing_bus_field_is_a_parse_error() {
    let t = base().replacen("[[load]]\nbus = 5\n", "[[load]]\n", 1);
    match err(&t) {
        CaseError::Parse(m) => assert!(m.contains("bus"), "{m}"),
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn duplicate_bus() {
    let t = base().replacen("id = 9\n", "id = 8\n", 1);
    assert_eq!(err(&t), CaseError::DuplicateBus(8));
}

#[test]
fn zero_impedance() {
    let t = base().replacen("r = 0.017\nx = 0.092", "r = 0.0\nx = 0.0", 1);
    assert!(matches!(err(&t), CaseError::NonPositiveImpedance { .. }));
}

#[test]
fn negative_impedance() {
    let t = base().replacen("x = 0.0576", "x = -0.0576", 1);
    match err(&t) {
        CaseError::NonPositiveImpedance { element, .. } => assert!(element.contains("transformer")),
        e => panic!("wrong error {e:?}"),
    }
    let t = base().replacen("r = 0.017", "r = -0.017", 1);
    assert!(matches!(err(&t), CaseError::NonPositiveImpedance { .. }));
}

#[test]
fn negative_slot_impedance() {
    let t = builtin_text("ieee9_dvpp")
        .unwrap()
        .replacen("\nx = 0.10\n", "\nx = -0.10\n", 1);
    assert!(matches!(err(&t), CaseError::NonPositiveImpedance { .. }));
}

#[test]
fn islanded_bus() {
    // bus 9 loses both its lines
    let t = base()
        .replacen(
            "from = 8\nto = 9\n",
            "from = 8\nto = 9\nin_service = false\n",
            1,
        )
        .replacen(
            "from = 9\nto = 4\n",
            "from = 9\nto = 4\nin_service = false\n",
            1,
        );
    assert_eq!(err(&t), CaseError::IslandedBus(9));
    // an extra bus with nothing connected
    let t = base().replacen("[[bus]]\nid = 9", "[[bus]]\nid = 10\n[[bus]]\nid = 9", 1);
    assert_eq!(err(&t), CaseError::IslandedBus(10));
}

#[test]
fn unknown_model_type() {
    let t = base().replacen("model = \"two_axis\"", "model = \"six_order\"", 1);
    match err(&t) {
        CaseError::Parse(m) => assert!(
            m.contains("six_order") || m.contains("unknown variant"),
            "{m}"
        ),
        e => panic!("wrong error {e:?}"),
    }
    let t = base().replacen("type = \"hygov\"", "type = \"ieeeg1\"", 1);
    assert!(matches!(err(&t), CaseError::Parse(_)));
    let t = base().replacen("type = \"ieee_t1\"", "type = \"st1a\"", 1);
    assert!(matches!(err(&t), CaseError::Parse(_)));
    let t = builtin_text("ieee9_dvpp")
        .unwrap()
        .replacen("grid_forming", "virtual_sync", 1);
    assert!(matches!(err(&t), CaseError::Parse(_)));
}

#[test]
fn parameter_out_of_range() {
    let t = base().replacen("h = 23.64", "h = -1.0", 1);
    match err(&t) {
        CaseError::OutOfRange {
            parameter, value, ..
        } => {
            assert_eq!(parameter, "h");
            assert_eq!(value, -1.0);
        }
        e => panic!("wrong error {e:?}"),
    }
    let t = base().replacen("\nr = 0.03\n", "\nr = 0.0\n", 1);
    assert!(
        matches!(err(&t), CaseError::OutOfRange { ref parameter, .. } if parameter == "governor.r")
    );
    let t = base().replacen("xd_p = 0.0608", "xd_p = 0.5", 1);
    assert!(matches!(err(&t), CaseError::OutOfRange { ref parameter, .. } if parameter == "xd"));
    let t = base().replacen("base_mva = 100.0", "base_mva = 0.0", 1);
    assert!(matches!(err(&t), CaseError::OutOfRange { .. }));
}

#[test]
fn slack_and_references() {
    let t = base().replacen("kind = \"slack\"", "kind = \"pq\"", 1);
    assert!(matches!(err(&t), CaseError::Slack(_)));
    let t =
        builtin_text("ieee9_dvpp")
            .unwrap()
            .replacen("slots = [1, 2, 3]", "slots = [1, 2, 7]", 1);
    assert!(matches!(err(&t), CaseError::UnknownReference { .. }));
    let t = base() + "\n[[event]]\ntype = \"line_trip\"\ntime = 1.0\nbranch = \"L4-99\"\n";
    assert!(matches!(err(&t), CaseError::UnknownReference { .. }));
    let t = base() + "\n[[event]]\ntype = \"generator_trip\"\ntime = 1.0\nmachine = 4\n";
    assert!(matches!(err(&t), CaseError::UnknownReference { .. }));
}

#[test]
fn pv_bus_without_source() {
    let t = base().replacen("id = 4\n", "id = 4\nkind = \"pv\"\n", 1);
    assert!(matches!(err(&t), CaseError::Inconsistent(_)));
}

#[test]
fn unknown_field_is_rejected() {
    let t = base().replacen("t_ch = 0.5", "t_chh = 0.5", 1);
    match err(&t) {
        CaseError::Parse(m) => assert!(m.contains("t_chh") || m.contains("unknown field"), "{m}"),
        e => panic!("wrong error {e:?}"),
    }
    let t = base().replacen("xd_p = 0.0608", "xd_p = 0.0608\nxdd = 0.1", 1);
    assert!(matches!(err(&t), CaseError::Parse(_)));
}

/// ieee9 with SG3 made a classical machine: no exciter, no q-axis data and no `xd`.
fn ieee9_classical_sg3() -> String {
    let t = base();
    let i = t.find("name = \"SG3\"").unwrap();
    let (head, sg3) = t.split_at(i);
    let sg3 = sg3
        .replacen("model = \"two_axis\"", "model = \"classical\"", 1)
        .replacen("xd = 1.3125\n", "", 1)
        .replacen(
            "xq = 1.2578\nxq_p = 0.25\ntd0_p = 5.89\ntq0_p = 0.6\n",
            "",
            1,
        );
    let a = sg3.find("[machine.exciter]").unwrap();
    let b = sg3.find("# PCC").unwrap();
    format!("{head}{}{}", &sg3[..a], &sg3[b..])
}

#[test]
fn classical_machine_needs_no_unused_data() {
    let t = ieee9_classical_sg3();
    assert!(!t[t.find("name = \"SG3\"").unwrap()..].contains("\nxd ="));
    let c = Case::from_toml_str(&t).unwrap();
    assert_eq!(c.machines[2].xd, None);
    // and runs: a flat start from the power flow
    let g = grid_model::Grid::new(&c).unwrap();
    assert!(g.max_derivative().unwrap() < 1e-10);
}

#[test]
fn two_axis_machine_without_its_data_is_refused_by_name() {
    let t = base().replacen("xd = 1.3125\n", "", 1);
    match err(&t) {
        CaseError::Inconsistent(m) => assert!(m.contains("two_axis") && m.contains("`xd`"), "{m}"),
        e => panic!("wrong error {e:?}"),
    }
    let t = base().replacen("td0_p = 5.89\n", "", 1);
    match err(&t) {
        CaseError::Inconsistent(m) => assert!(m.contains("`td0_p`"), "{m}"),
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn slot_reactance_only_needed_when_grid_forming() {
    // grid-following slots of ieee9_hybrid (4..6) may leave their informational x out
    let hybrid = builtin_text("ieee9_hybrid").unwrap();
    let c = Case::from_toml_str(hybrid).unwrap();
    let mut lines: Vec<&str> = hybrid.lines().collect();
    let mut slot = 0;
    let mut kind = "";
    lines.retain(|l| {
        if *l == "[[der]]" {
            slot += 1;
        }
        if l.starts_with("kind = ") {
            kind = l;
        }
        !(slot > 0 && kind.contains("grid_following") && l.starts_with("x = "))
    });
    let gfl_without_x = lines.join("\n");
    let c2 = Case::from_toml_str(&gfl_without_x).unwrap();
    assert_eq!(c2.ders.len(), c.ders.len());
    assert!(c2
        .ders
        .iter()
        .all(|d| (d.kind == grid_model::DerKind::GridForming) == d.x.is_some()));
    // a grid-forming slot without x is refused by name
    let t = builtin_text("ieee9_dvpp")
        .unwrap()
        .replacen("\nx = 0.10\n", "\n", 1);
    match err(&t) {
        CaseError::Inconsistent(m) => {
            assert!(m.contains("grid_forming") && m.contains("`x`"), "{m}")
        }
        e => panic!("wrong error {e:?}"),
    }
}
