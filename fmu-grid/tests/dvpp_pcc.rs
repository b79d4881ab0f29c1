//! Tests of the grid's PCCs of several DVPPs (`[[dvpp_pcc]]`).
//!
//! Each sums its own slots and measures its bus as `[pcc]` does, and bad entries are refused.

use grid_model::case::DvppPcc;
use grid_model::{Case, Grid};

fn split(f_filter_t: f64) -> Case {
    let mut c = Case::builtin("ieee9_dvpp").unwrap();
    c.pcc.as_mut().unwrap().f_filter_t = f_filter_t;
    for (name, slots) in [("a", vec![1, 2]), ("b", vec![3])] {
        c.dvpp_pccs.push(DvppPcc {
            name: name.into(),
            bus: 2,
            slots,
            f_filter_t,
        });
    }
    c.validate().unwrap();
    c
}

#[test]
fn two_dvpp_pccs_at_the_case_pcc_bus_add_up_to_it_through_a_load_step() {
    let mut g = Grid::new(&split(0.02)).unwrap();
    let p0 = g.outputs().dvpp_pcc[0].p;
    let h = 1e-3;
    for i in 0..=1500 {
        let o = g.outputs();
        assert_eq!(o.dvpp_pcc.len(), 2);
        assert!(o.poc.is_empty());
        let (a, b) = (&o.dvpp_pcc[0], &o.dvpp_pcc[1]);
        let t = o.t;
        assert!((a.p + b.p - o.pcc.p).abs() < 1e-12, "t = {t}: p");
        assert!((a.q + b.q - o.pcc.q).abs() < 1e-12, "t = {t}: q");
        for m in [a, b] {
            assert_eq!(m.v, o.pcc.v, "t = {t}: v");
            assert!(
                (m.f - o.pcc.f).abs() < 1e-12,
                "t = {t}: f {} vs {}",
                m.f,
                o.pcc.f
            );
        }
        assert_eq!(a.p, o.der[0].p + o.der[1].p);
        if i < 1500 {
            g.step(i as f64 * h, h).unwrap();
        }
    }
    // The load step at 1 s (at bus 2, the slots held at their internal voltages) moved DVPP a.
    let p1 = g.outputs().dvpp_pcc[0].p;
    assert!((p1 - p0).abs() > 1e-3, "{p0} -> {p1}");
}

/// A change to a DVPP PCC.
type Edit = fn(&mut DvppPcc);

#[test]
fn bad_dvpp_pccs_are_refused() {
    let base = split(0.02);
    let cases: [(Edit, &str); 5] = [
        (|p| p.bus = 42, "42"),
        (|p| p.slots = vec![4], "slot 4"),
        (|p| p.slots.clear(), "no slot"),
        (|p| p.name = "a-b".into(), "letters, digits"),
        (|p| p.name = "b".into(), "unique"),
    ];
    for (edit, expected) in cases {
        let mut c = base.clone();
        edit(&mut c.dvpp_pccs[0]);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains(expected), "{e}");
    }
}
