//! Case study II end to end in our master: the hybrid DVPP at every grid-forming share ε
//! (`case2_load_eps000` … `eps100`, 42 MW at bus 2) matches `T_des` about equally well, a larger
//! ε lowers the centre-of-inertia RoCoF, no unit oscillates from one step to the next, and every
//! unit stays within its current limit, its dc link within its range and its energy account
//! closed; after the outage of SG1 and SG3 the island settles on the desired response with
//! grid-forming units, and without any (ε = 0) the grid-following units lose synchronism.

use der_model::ports;
use dvpp_cosim::master::{self, Options};
use dvpp_cosim::Table;
use dvpp_e2e::{der_units, scenario, units_with};
use dvpp_report::casestudy::Signals;

const EPS: [&str; 5] = ["000", "025", "050", "075", "100"];

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.column(name).unwrap_or_else(|| panic!("no column {name}"))
}

/// The DER units of scenario `name`, each checked to have a column `<unit>.<port>` in `t`.
fn units_of(name: &str, t: &Table, port: &str) -> Vec<String> {
    let expected = der_units(&scenario(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    units_with(&t.columns, port, &expected).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The largest second difference `|x[k+1] - 2 x[k] + x[k-1]|` from sample `from` on.
fn jitter(x: &[f64], from: usize) -> f64 {
    x[from..]
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .fold(0.0, f64::max)
}

#[test]
fn every_grid_forming_share_matches_t_des_without_step_to_step_oscillation() {
    let mut nrmse = Vec::new();
    let mut rocof = Vec::new();
    for eps in EPS {
        let name = format!("case2_load_eps{eps}");
        let t = master::System::builder(&scenario(&name))
            .simulate(&Options::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let signals = Signals::of(&t).unwrap_or_else(|e| panic!("{e}"));
        let units = units_of(&name, &t, ports::I_AC);
        let found: Vec<&str> = signals.der.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(found, units, "{name}: the DERs of the metrics");
        let m = signals.metrics();
        let time = column(&t, "time");
        let coi = column(&t, "grid.coi.f");
        let k = |s: f64| time.partition_point(|&x| x < s - 1e-9);
        let r = (coi[k(1.1)] - coi[k(1.0)]) / 0.1 * 50.0;
        // After 3 s no slot's power may alternate from one 1 ms step to the next.
        let mut worst = 0.0_f64;
        let mut slot = 1;
        while let Some(p) = t.column(&format!("grid.der[{slot}].p")) {
            worst = worst.max(jitter(&p, k(3.0)));
            slot += 1;
        }
        assert_eq!(
            slot - 1,
            der_units(&scenario(&name))
                .unwrap_or_else(|e| panic!("{e}"))
                .len(),
            "{name}: a grid slot 'grid.der[k].p' per DER unit"
        );
        println!(
            "{name}: f NRMSE {:.2} %, v NRMSE {:.1} %, COI RoCoF (100 ms) {r:.4} Hz/s, largest second difference of a slot's p after 3 s {worst:.1e} pu",
            m.f_nrmse * 100.0,
            m.v_nrmse * 100.0
        );
        assert!(m.f_nrmse <= 0.05, "{name}: f NRMSE {}", m.f_nrmse);
        assert!(worst < 1e-3, "{name}: step-to-step oscillation {worst}");
        for unit in &units {
            let port = |p: &str| column(&t, &format!("{unit}.{p}"));
            let (i, lim) = (port(ports::I_AC), port(ports::I_LIMIT));
            let ratio = i.iter().zip(&lim).map(|(a, b)| a / b).fold(0.0, f64::max);
            assert!(ratio <= 1.05, "{name} {unit}: current {ratio} x I_max");
            let v_dc = port(ports::V_DC);
            assert!(
                v_dc.iter().all(|v| (0.79..=1.21).contains(v)),
                "{name} {unit}: v_dc left its range"
            );
            let last = |v: &str| *port(v).last().unwrap();
            let w0 = port(ports::ENERGY_STORED)[0];
            let (src, ac) = (last(ports::ENERGY_SOURCE), last(ports::ENERGY_AC));
            let residual = src - ac - last(ports::ENERGY_LOSS) - (last(ports::ENERGY_STORED) - w0);
            assert!(
                residual.abs() <= 1e-6 * (src.abs() + ac.abs()),
                "{name} {unit}: energy residual {residual}"
            );
        }
        nrmse.push(m.f_nrmse);
        rocof.push(r);
    }
    let spread = nrmse.iter().cloned().fold(f64::MIN, f64::max)
        - nrmse.iter().cloned().fold(f64::MAX, f64::min);
    assert!(
        spread <= 0.01,
        "frequency NRMSE differs by {:.2} pp across ε",
        spread * 100.0
    );
    // A larger grid-forming share gives a smaller COI RoCoF (in magnitude).
    for w in rocof.windows(2) {
        assert!(w[1] > w[0], "COI RoCoF does not fall with ε: {rocof:?}");
    }
}

/// The outage of SG1 and SG3 (`case2_outage_eps*`, ratings ×3.5): with grid-forming units the
/// island settles on the desired response within the converters' limits (ε = 1 within its
/// ratings); with none (ε = 0) nothing holds the voltage, the grid reports it and every
/// grid-following unit reports the loss of synchronism, and the run goes on to its end.
#[test]
fn the_outage_settles_with_grid_forming_units_and_loses_synchronism_without() {
    for eps in EPS {
        let name = format!("case2_outage_eps{eps}");
        let t = master::System::builder(&scenario(&name))
            .simulate(&Options::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let time = column(&t, "time");
        assert!(
            (time.last().unwrap() - 20.0).abs() < 1e-9,
            "{name} ended early"
        );
        let after = time.partition_point(|&x| x < 1.0);
        let energized = column(&t, "grid.energized");
        let units = units_of(&name, &t, ports::I_AC);
        units_of(&name, &t, ports::SYNCHRONIZED);
        let lost: Vec<&String> = units
            .iter()
            .filter(|u| {
                column(&t, &format!("{u}.{}", ports::SYNCHRONIZED))[after..]
                    .iter()
                    .any(|&s| s < 0.5)
            })
            .collect();
        let mut worst = 0.0_f64;
        for u in &units {
            let (i, lim) = (
                column(&t, &format!("{u}.{}", ports::I_AC)),
                column(&t, &format!("{u}.{}", ports::I_LIMIT)),
            );
            let ratio = i.iter().zip(&lim).map(|(a, b)| a / b).fold(0.0, f64::max);
            assert!(ratio <= 1.0 + 1e-6, "{name} {u}: current {ratio} x I_max");
            worst = worst.max(i.iter().cloned().fold(0.0, f64::max));
        }
        let f = column(&t, "grid.pcc.f");
        let f_ref = column(&t, "operator.ref.df");
        let (f_end, ref_end) = (
            (f.last().unwrap() - 1.0) * 50.0,
            f_ref.last().unwrap() * 50.0,
        );
        println!(
            "{name}: energized at the end {}, units that lost synchronism {lost:?}, PCC f settles at {f_end:+.3} Hz (desired {ref_end:+.3} Hz), largest current {worst:.2} of rating",
            energized.last().unwrap()
        );
        if eps == "000" {
            assert!(
                energized[after..].iter().all(|&e| e < 0.5),
                "{name}: energized"
            );
            assert_eq!(
                lost.len(),
                units.len(),
                "{name}: every unit loses synchronism"
            );
            let v = column(&t, "grid.pcc.v");
            assert!(
                v[after..].iter().all(|&x| x == 0.0),
                "{name}: a dead island"
            );
        } else {
            assert!(energized.iter().all(|&e| e > 0.5), "{name}: de-energized");
            assert!(lost.is_empty(), "{name}: {lost:?} lost synchronism");
            assert!(
                (f_end - ref_end).abs() < 0.02,
                "{name}: settles at {f_end} Hz, desired {ref_end} Hz"
            );
        }
        if eps == "100" {
            assert!(worst <= 1.0, "{name}: {worst} of rated current");
        }
    }
}
