//! Tests of the case study III grid `ieee9_mv`: power flow, POC outputs, line R/X, events.

use fmi_export::harness::Harness;
use fmi_export::Status;
use grid_model::case::{BranchData, Event, LoadModel};
use grid_model::powerflow::C64 as C;
use grid_model::{Case, Grid, GridConfig, GridFmu};

fn mv_case(rx: f64) -> Case {
    let mut c = Case::builtin("ieee9_mv").expect("built-in ieee9_mv");
    c.mv.as_mut().expect("[mv] table").rx = rx;
    c
}

/// MV buses: ids above 100 (d1 = 101 ... d14 = 114).
fn is_mv(c: &Case, i: usize) -> bool {
    c.buses[i].id > 100
}

/// Complex powers entering a branch at both ends (as the grid computes them).
fn flows(br: &BranchData, v: &[C]) -> (C, C) {
    let ys = C::new(1.0, 0.0) / C::new(br.r, br.x);
    let hb = C::new(0.0, br.b / 2.0);
    let (vf, vt, t) = (v[br.from], v[br.to], br.tap);
    let i_f = (ys / (t * t) + hb) * vf - ys / t * vt;
    let i_t = (ys + hb) * vt - ys / t * vf;
    (vf * i_f.conj(), vt * i_t.conj())
}

/// The bus voltage phasors.
fn phasors(g: &Grid) -> Vec<C> {
    g.bus_voltages()
        .iter()
        .map(|&(m, a)| dvpp_math::cpolar(m, a))
        .collect()
}

/// The MV area's balance: (generation, constant-power load, losses of the MV lines), pu on
/// S_base. `extra_load` adds event loads at MV buses. The POCs measure at the transformers' MV
/// ends (`side = "area"`), so the transformers' losses are outside the balance.
fn area_balance(g: &Grid, extra_load: f64) -> (f64, f64, f64) {
    let c = g.case();
    let idx = c.bus_index();
    let v = phasors(g);
    let o = g.outputs();
    let gen: f64 = o.der.iter().map(|d| d.p).sum();
    let load: f64 = c
        .loads
        .iter()
        .filter(|l| is_mv(c, idx[&l.bus]))
        .map(|l| {
            assert_eq!(l.model, LoadModel::ConstantPower);
            l.p_mw / c.base_mva
        })
        .sum::<f64>()
        + extra_load;
    let mut loss = 0.0;
    for br in c.branches().iter().filter(|b| b.in_service) {
        if is_mv(c, br.from) && is_mv(c, br.to) {
            let (sf, st) = flows(br, &v);
            loss += sf.re + st.re;
        }
    }
    (gen, load, loss)
}

fn mv_voltage_range(g: &Grid) -> (f64, f64) {
    let c = g.case();
    g.bus_voltages()
        .iter()
        .enumerate()
        .filter(|(i, _)| is_mv(c, *i))
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), (_, &(m, _))| {
            (lo.min(m), hi.max(m))
        })
}

#[test]
fn power_flow_converges_with_mv_voltages_in_band() {
    let g = Grid::new(&mv_case(1.0)).expect("ieee9_mv builds");
    let c = g.case();
    let pf = g.power_flow();
    println!(
        "ieee9_mv, R/X = 1: {} iterations, mismatch {:.1e} pu",
        pf.iterations, pf.mismatch
    );
    let o = g.outputs();
    assert_eq!(o.poc.len(), 2);
    for (k, p) in o.poc.iter().enumerate() {
        println!(
            "POC {} (bus {}): p = {:+.4} q = {:+.4} v = {:.4} pu f = {}",
            k + 1,
            c.pocs[k].bus,
            p.p,
            p.q,
            p.v,
            p.f
        );
        assert!((p.f - 1.0).abs() < 1e-12);
    }
    for (i, b) in c.buses.iter().enumerate().filter(|(i, _)| is_mv(c, *i)) {
        let name = b.name.clone().unwrap_or_default();
        let (m, a) = (
            dvpp_math::cabs(pf.v[i]),
            dvpp_math::carg(pf.v[i]).to_degrees(),
        );
        println!(
            "  bus {} ({name}): v = {m:.4} pu, angle = {a:+.2} deg",
            b.id
        );
    }
    for (k, d) in o.der.iter().enumerate() {
        println!(
            "DER {} at bus {}: p = {:+.4} q = {:+.4} pu",
            k + 1,
            c.ders[k].bus,
            d.p,
            d.q
        );
    }
    let (lo, hi) = mv_voltage_range(&g);
    let (gen, load, loss) = area_balance(&g, 0.0);
    println!(
        "MV voltages {lo:.4} .. {hi:.4} pu; MV area: generation {gen:.4}, load {load:.4}, \
         losses {loss:.4} pu; system losses {:.4} pu; pcc.p = {:.4} pu",
        o.loss_p, o.pcc.p
    );
    assert!(lo > 0.9 && hi < 1.1, "MV voltages {lo} .. {hi}");
    // pcc.p sums the slots' own injections
    assert!((o.pcc.p - gen).abs() < 1e-12);
}

#[test]
fn poc_powers_add_up_to_the_area_balance() {
    let mut g = Grid::new(&mv_case(1.0)).unwrap();
    let check = |g: &Grid, extra: f64, when: &str| {
        let o = g.outputs();
        let sum: f64 = o.poc.iter().map(|p| p.p).sum();
        let (gen, load, loss) = area_balance(g, extra);
        let err = sum - (gen - load - loss);
        println!("{when}: sum of poc p = {sum:.6} pu, gen - load - losses = {:.6} pu, difference {err:.1e}", gen - load - loss);
        assert!(err.abs() < 1e-9, "{when}: {err:e}");
    };
    check(&g, 0.0, "power flow");
    // a 20 MW constant-power load step inside the area, then 1 s of dynamics
    g.add_event(Event::LoadStep {
        time: 0.1,
        bus: 105,
        dp_mw: 20.0,
        dq_mvar: 0.0,
        model: LoadModel::ConstantPower,
    })
    .unwrap();
    let h = 0.01;
    for _ in 0..100 {
        let t = g.time();
        g.step(t, h).unwrap();
    }
    check(&g, 0.2, "1 s after a 20 MW load step at d5");
}

#[test]
fn grid_side_pocs_deliver_the_area_side_export_less_the_transformer_losses() {
    let area = Grid::new(&mv_case(1.0)).unwrap();
    let mut c = mv_case(1.0);
    for p in &mut c.pocs {
        p.side = grid_model::case::PocSide::Grid;
    }
    let grid = Grid::new(&c).unwrap();
    let idx = c.bus_index();
    let v = phasors(&grid);
    for (k, p) in c.pocs.iter().enumerate() {
        let br = c
            .branches()
            .into_iter()
            .find(|b| b.name == p.branches[0])
            .unwrap();
        let (sf, st) = flows(&br, &v);
        let loss = sf + st;
        let (a, g) = (&area.outputs().poc[k], &grid.outputs().poc[k]);
        println!(
            "POC {}: area side {:+.4} {:+.4}j, grid side {:+.4} {:+.4}j, transformer loss {:.4} {:+.4}j pu",
            k + 1, a.p, a.q, g.p, g.q, loss.re, loss.im
        );
        assert!(idx[&p.bus] == br.from || idx[&p.bus] == br.to);
        assert!((a.p - g.p - loss.re).abs() < 1e-12 && (a.q - g.q - loss.im).abs() < 1e-12);
        assert!(
            loss.im > 10.0 * loss.re,
            "a transformer loses mostly reactive power"
        );
    }
}

#[test]
fn a_flat_start_stays_flat() {
    let mut g = Grid::new(&mv_case(1.0)).unwrap();
    assert!(g.events().is_empty());
    let v0 = g.bus_voltages();
    let (mut df, mut dv) = (0.0f64, 0.0f64);
    let h = 0.01;
    while g.time() < 5.0 - 1e-9 {
        let t = g.time();
        g.step(t, h).unwrap();
        let o = g.outputs();
        let fs = o
            .poc
            .iter()
            .map(|p| p.f)
            .chain([o.pcc.f, o.coi_f])
            .chain(o.sg.iter().map(|m| m.omega));
        for f in fs {
            df = df.max((f - 1.0).abs());
        }
        for (a, b) in g.bus_voltages().iter().zip(&v0) {
            dv = dv.max((a.0 - b.0).abs());
        }
    }
    println!("flat start, 5 s: max |df| = {df:.1e} pu, max |dv| = {dv:.1e} pu");
    assert!(df < 1e-9 && dv < 1e-9, "df {df:e}, dv {dv:e}");
}

#[test]
fn rx_changes_losses_and_the_power_flow_still_converges() {
    let mut losses = Vec::new();
    for rx in [0.4, 1.0, 2.0] {
        let g = Grid::new(&mv_case(rx)).unwrap_or_else(|e| panic!("R/X = {rx}: {e}"));
        let (gen, load, loss) = area_balance(&g, 0.0);
        let o = g.outputs();
        let (lo, hi) = mv_voltage_range(&g);
        println!(
            "R/X = {rx}: MV losses {loss:.4} pu, system losses {:.4} pu, poc p = {:+.4} / {:+.4}, \
             q = {:+.4} / {:+.4}, MV voltages {lo:.4} .. {hi:.4} (generation {gen:.4}, load {load:.4})",
            o.loss_p, o.poc[0].p, o.poc[1].p, o.poc[0].q, o.poc[1].q
        );
        assert!(lo > 0.9 && hi < 1.1);
        // |Z| of every MV line is kept
        let base = Case::builtin("ieee9_mv").unwrap();
        for (br, l) in g.case().branches().iter().zip(&base.lines) {
            let z0 = dvpp_math::hypot(l.r, l.x);
            assert!((dvpp_math::hypot(br.r, br.x) - z0).abs() < 1e-12 * z0.max(1.0));
            if base.mv.as_ref().unwrap().lines.contains(&base.line_name(l)) {
                assert!((br.r / br.x - rx).abs() < 1e-9);
            }
        }
        losses.push(loss);
    }
    assert!(losses[0] < losses[1] && losses[1] < losses[2], "{losses:?}");
    // per-line ratios drawn in [0.4, 2] (a fixed pseudo-random sequence)
    let mut seed = 12345u64;
    for draw in 0..24 {
        let mut c = mv_case(1.0);
        for i in c.mv_line_indices() {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            c.lines[i].rx = Some(0.4 + 1.6 * u);
        }
        let g = Grid::new(&c).unwrap_or_else(|e| panic!("draw {draw}: {e}"));
        let (lo, hi) = mv_voltage_range(&g);
        assert!(lo > 0.9 && hi < 1.1, "draw {draw}: {lo} .. {hi}");
    }
}

/// A 20 MW load increase at `bus` at t = 0.5 s, 3 s of dynamics with the DER inputs held.
fn load_step_run(bus: u32) -> (f64, [f64; 2], [f64; 2]) {
    let text = format!(
        "case = \"ieee9_mv\"\n[[event]]\ntype = \"load_step\"\ntime = 0.5\nbus = {bus}\n\
         dp_mw = 20.0\nmodel = \"constant_power\"\n"
    );
    let config: GridConfig = toml::from_str(&text).unwrap();
    let case = config.load_case(None).expect("the event is valid");
    let mut g = Grid::new(&case).unwrap();
    let p0 = [g.outputs().poc[0].p, g.outputs().poc[1].p];
    let mut f_min = 1.0f64;
    while g.time() < 3.0 - 1e-9 {
        let t = g.time();
        g.step(t, 0.01).unwrap();
        for p in &g.outputs().poc {
            f_min = f_min.min(p.f);
        }
    }
    let o = g.outputs();
    (f_min, p0, [o.poc[0].p, o.poc[1].p])
}

#[test]
fn load_steps_at_bus_4_and_at_d5_are_expressible() {
    for (bus, what) in [(4, "bus 4"), (105, "d5 (bus 105)")] {
        let (f_min, p0, p1) = load_step_run(bus);
        println!(
            "20 MW at {what}: lowest POC frequency {f_min:.6} pu in 3 s; poc p {:+.4}/{:+.4} -> \
             {:+.4}/{:+.4} pu",
            p0[0], p0[1], p1[0], p1[1]
        );
        assert!(f_min < 1.0 - 1e-4, "{what}: no frequency dip");
    }
}

#[test]
fn the_fmu_re_solves_the_power_flow_for_its_rx_parameters() {
    let config = "[model]\ncase = \"ieee9_mv\"\n";
    let mut h = Harness::<GridFmu>::from_toml(config);
    h.set("mv.rx", 2.0);
    h.set("mv.line[3].rx", 0.5);
    assert_eq!(h.init(), Status::Ok, "{:?}", h.log());
    let mut c = mv_case(2.0);
    let i = c.mv_line_indices()[2];
    c.lines[i].rx = Some(0.5);
    let g = Grid::new(&c).unwrap();
    let o = g.outputs();
    for k in 1..=2 {
        let p = h.get(&format!("poc[{k}].p"));
        assert!((p - o.poc[k - 1].p).abs() < 1e-12, "poc[{k}].p {p}");
    }
    for (k, init) in g.der_initial().iter().enumerate() {
        let grid_model::DerSetpoint::GridForming { theta0, e0 } = *init else {
            panic!("grid-forming slots")
        };
        let (theta, e) = (
            h.get(&format!("der[{}].theta", k + 1)),
            h.get(&format!("der[{}].E", k + 1)),
        );
        assert!((theta - theta0).abs() < 1e-12 && (e - e0).abs() < 1e-12);
    }
    // untouched inputs hold the re-solved set points: a flat start
    for _ in 0..1000 {
        h.step(1e-3);
    }
    for name in ["poc[1].f", "poc[2].f", "coi.f"] {
        let f = h.get(name);
        assert!((f - 1.0).abs() < 1e-9, "{name} = {f}");
    }
    // out-of-range ratios are refused
    let mut h = Harness::<GridFmu>::from_toml(config);
    assert_eq!(h.try_set("mv.rx", 50.0), Status::Error);
}

#[test]
fn a_snapshot_keeps_the_rx_ratios_and_the_poc_filters() {
    let mut c = mv_case(1.7);
    let first = c.mv_line_indices()[0];
    c.lines[first].rx = Some(0.6);
    let mut g = Grid::new(&c).unwrap();
    g.add_event(Event::LoadStep {
        time: 0.05,
        bus: 4,
        dp_mw: 20.0,
        dq_mvar: 0.0,
        model: LoadModel::ConstantImpedance,
    })
    .unwrap();
    for _ in 0..20 {
        let t = g.time();
        g.step(t, 0.01).unwrap();
    }
    let bytes = postcard::to_stdvec(&g).unwrap();
    let mut r: Grid = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(r.case(), g.case());
    assert_eq!(r.outputs(), g.outputs());
    for _ in 0..20 {
        let t = g.time();
        g.step(t, 0.01).unwrap();
        r.step(t, 0.01).unwrap();
    }
    assert_eq!(
        r.outputs(),
        g.outputs(),
        "the restored grid continues bit for bit"
    );
    assert!(g.outputs().poc[0].f < 1.0);
}

#[test]
fn bad_poc_and_rx_data_are_refused_by_name() {
    let text = grid_model::case::builtin_text("ieee9_mv").unwrap();
    let cases = [
        (
            text.replace("branches = [\"T4-d1\"]", "branches = [\"T9-d1\"]"),
            "T9-d1",
        ),
        (
            text.replace("branches = [\"T6-d12\"]", "branches = [\"T4-d1\"]"),
            "does not touch bus 6",
        ),
        (text.replace("[mv]\nrx = 1.0", "[mv]\nrx = -1.0"), "rx"),
        (
            text.replace("lines = [\"d1-d2\"", "lines = [\"d1-d9\""),
            "d1-d9",
        ),
    ];
    for (bad, what) in cases {
        assert_ne!(bad, text, "{what}: the edit did not apply");
        let e = Case::from_toml_str(&bad).unwrap_err().to_string();
        assert!(e.contains(what), "{what}: {e}");
    }
}

/// The area's load output counts the MV loads only: 44.7 MW at the power flow, 20 MW more
/// after a constant-power step at d5, unchanged by a step at bus 4 (outside the area).
#[test]
fn the_area_load_counts_the_loads_behind_the_pocs() {
    for (bus, inside) in [(105, true), (4, false)] {
        let mut g = Grid::new(&mv_case(1.0)).unwrap();
        let p0 = g.outputs().area_p_load;
        g.add_event(Event::LoadStep {
            time: 0.1,
            bus,
            dp_mw: 20.0,
            dq_mvar: 0.0,
            model: LoadModel::ConstantPower,
        })
        .unwrap();
        for _ in 0..50 {
            let t = g.time();
            g.step(t, 0.01).unwrap();
        }
        let dp = g.outputs().area_p_load - p0;
        println!(
            "area load {:.3} MW at the power flow; after 20 MW at bus {bus}: {:+.4} MW",
            p0 * 100.0,
            dp * 100.0
        );
        assert!((p0 * 100.0 - 44.7).abs() < 0.05, "area load {p0}");
        let want = if inside { 0.2 } else { 0.0 };
        assert!((dp - want).abs() < 1e-9, "bus {bus}: {dp}");
    }
}
