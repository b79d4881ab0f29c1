//! Systems and checks the tests of the SSP modules share.

use super::{
    parse_ssd, Component, Connection, Connector, Kind, LinearTransformation, Parameter, System,
    Type, Value,
};
use crate::tmp::TempDir;
use std::path::Path;

pub(super) fn connector(name: &str, kind: Kind, ty: Type) -> Connector {
    Connector {
        name: name.into(),
        kind,
        ty,
    }
}

pub(super) fn connect(a: &str, ac: &str, b: &str, bc: &str) -> Connection {
    Connection {
        start_element: a.into(),
        start_connector: ac.into(),
        end_element: b.into(),
        end_connector: bc.into(),
        transformation: None,
    }
}

/// Three components, a transformation, parameters of every type and awkward values.
pub(super) fn sample() -> System {
    let grid = Component {
        name: "grid".into(),
        source: "resources/grid.fmu".into(),
        connectors: vec![
            connector("der[1].p", Kind::Output, Type::Real),
            connector("der[1].theta", Kind::Input, Type::Real),
            connector("n_events", Kind::Output, Type::Integer),
        ],
        parameters: vec![
            Parameter {
                name: "event[1].time".into(),
                value: Value::Real(0.1 + 0.2),
            },
            Parameter {
                name: "event[1].enabled".into(),
                value: Value::Boolean(false),
            },
            Parameter {
                name: "tiny".into(),
                value: Value::Real(1e-300),
            },
            Parameter {
                name: "big".into(),
                value: Value::Real(-1.5e300),
            },
            Parameter {
                name: "inf".into(),
                value: Value::Real(f64::INFINITY),
            },
        ],
    };
    let der = Component {
        name: "der1".into(),
        source: "resources/der.fmu".into(),
        connectors: vec![
            connector("p", Kind::Input, Type::Real),
            connector("theta", Kind::Output, Type::Real),
            connector("mode", Kind::Parameter, Type::Integer),
        ],
        parameters: vec![
            Parameter {
                name: "mode".into(),
                value: Value::Integer(-2147483648),
            },
            Parameter {
                name: "S_base".into(),
                value: Value::Real(1e-3),
            },
        ],
    };
    let op = Component {
        name: "operator & co".into(),
        source: "resources/op \"x\".fmu".into(),
        connectors: vec![connector("count", Kind::Input, Type::Integer)],
        parameters: vec![Parameter {
            name: "label".into(),
            value: Value::String("a<b>&\"c\"\t'd'\nline2 ü".into()),
        }],
    };
    let mut c1 = connect("grid", "der[1].p", "der1", "p");
    c1.transformation = Some(LinearTransformation {
        factor: -2.5,
        offset: 1.0 / 3.0,
    });
    System {
        name: "demo <1>".into(),
        description: Some("a \"demo\" & test".into()),
        components: vec![grid, der, op],
        connections: vec![
            c1,
            connect("der1", "theta", "grid", "der[1].theta"),
            connect("grid", "n_events", "operator & co", "count"),
        ],
        start_time: 0.5,
        stop_time: Some(10.0),
        step_size: Some(1e-3),
        record: Vec::new(),
    }
}

pub(super) fn temp() -> TempDir {
    TempDir::new("test").unwrap()
}

pub(super) fn parse_err(xml: &str) -> String {
    match parse_ssd(xml, Path::new("/nonexistent")) {
        Ok(s) => panic!("accepted: {s:?}"),
        Err(e) => e.0,
    }
}

pub(super) fn assert_err(xml: &str, parts: &[&str]) {
    let e = parse_err(xml);
    for p in parts {
        assert!(e.contains(p), "error {e:?} lacks {p:?}");
    }
}
