//! The DER's limits in closed loop with a Thevenin bus (in-process): current limiting in a
//! voltage dip, the dc link running short, the energy account, and a start from zero voltage.

use der_model::Der;
use dvpp_control::Complex;
use fmi_export::harness::Harness;
use fmi_export::Status;

const DT: f64 = 1e-3;

/// A grid-following unit with its default settings.
const GFL: [(&str, f64); 1] = [("mode", 2.0)];

/// A bus behind a Thevenin source `V_th` and `Z_th` (pu on S_base) that the unit's `E∠θ`
/// feeds through its slot impedance (grid-forming), or that it injects `p_ref + j q_ref` into
/// (grid-following).
struct Bus {
    v_th: Complex<f64>,
    z_th: Complex<f64>,
}

impl Bus {
    /// The Thevenin voltage that puts the bus at `V = 1∠0` with the unit injecting `p + j q`.
    fn at_operating_point(p: f64, q: f64, z_th: Complex<f64>) -> Bus {
        let i = Complex::new(p, -q);
        Bus {
            v_th: Complex::new(1.0, 0.0) - z_th * i,
            z_th,
        }
    }

    /// The bus voltage and the unit's injection for its present outputs, with the converter's
    /// output stage holding the unit's `i_limit` and (grid-forming) `[p_min, p_max]` as the
    /// grid's slot does: a fixed point of `V = V_th + Z_th I(V)`.
    fn solve(&self, h: &mut Harness<Der>) -> (Complex<f64>, Complex<f64>) {
        let [e, theta, s_base, s_rated, r_f, x_f, i_lim, p_min, p_max] = h.get_many([
            "E", "theta", "S_base", "S_rated", "R_f", "X_f", "i_limit", "p_min", "p_max",
        ]);
        let i_max = i_lim * s_rated / s_base;
        let forming = h.get_int("mode") == 1;
        let [p_ref, q_ref] = h.get_many(["p_ref", "q_ref"]);
        let z_f = Complex::new(r_f, x_f) * (s_base / s_rated);
        let e = dvpp_math::cpolar(e, theta);
        let current = |v: Complex<f64>| {
            let mut i = if forming {
                let i = (e - v) / z_f;
                let u = v / dvpp_math::cabs(v);
                let local = i * u.conj();
                let ip = local
                    .re
                    .clamp(p_min / dvpp_math::cabs(v), p_max / dvpp_math::cabs(v));
                Complex::new(ip, local.im) * u
            } else if dvpp_math::cabs(v) > 1e-9 {
                (Complex::new(p_ref, q_ref) / v).conj()
            } else {
                Complex::new(0.0, 0.0)
            };
            if dvpp_math::cabs(i) > i_max {
                i *= i_max / dvpp_math::cabs(i);
            }
            i
        };
        let mut v = if forming {
            (z_f * self.v_th + self.z_th * e) / (z_f + self.z_th)
        } else {
            self.v_th
        };
        if dvpp_math::cabs(v) < 1e-9 {
            return (v, Complex::new(0.0, 0.0));
        }
        for _ in 0..500 {
            v = self.v_th + self.z_th * current(v);
        }
        (v, v * current(v).conj())
    }

    /// One Jacobi step: the unit's inputs from the bus, then the unit's step.
    fn step(&self, h: &mut Harness<Der>) -> Status {
        let (v, s) = self.solve(h);
        h.set("p", s.re);
        h.set("q", s.im);
        h.set("v", dvpp_math::cabs(v));
        h.set("v_angle", dvpp_math::carg(v));
        let t = h.time();
        h.do_step(t, DT)
    }
}

fn unit(params: &[(&str, f64)]) -> Harness<Der> {
    let mut h = Harness::<Der>::new();
    for &(name, x) in params {
        if name == "mode" || name == "pll.order" {
            h.set(name, x as i32);
        } else {
            h.set(name, x);
        }
    }
    h.set_debug_logging(true, &[]);
    assert_eq!(h.init(), Status::Ok, "{:#?}", h.log());
    h
}

/// The current the unit injects, pu of its rated current.
fn current(h: &mut Harness<Der>) -> f64 {
    h.get("i_ac")
}

/// `E_src - E_ac - E_loss - ΔW` and the energy moved, from the unit's outputs (MJ).
fn energy_account(h: &mut Harness<Der>, w0: f64) -> (f64, f64) {
    let [src, ac, loss, w] =
        h.get_many(["energy.source", "energy.ac", "energy.loss", "energy.stored"]);
    (src - ac - loss - (w - w0), src.abs() + ac.abs())
}

#[test]
fn a_deep_voltage_dip_is_ridden_through_at_the_current_limit() {
    for mode in [1.0, 2.0] {
        let mut h = if mode == 1.0 { unit(&[]) } else { unit(&GFL) };
        let z_th = Complex::new(0.0, 0.05);
        let mut bus = Bus::at_operating_point(h.get("p"), h.get("q"), z_th);
        let v_th0 = bus.v_th;
        let (mut worst_after, mut acted) = (0.0_f64, false);
        let mut warnings = 0;
        for k in 0..3000 {
            // The grid voltage dips to 30 % for 200 ms at t = 0.5 s.
            bus.v_th = if (500..700).contains(&k) {
                v_th0 * 0.3
            } else {
                v_th0
            };
            let status = bus.step(&mut h);
            assert!(status <= Status::Warning, "{:#?}", h.log());
            warnings += usize::from(status == Status::Warning);
            let limited = h.get_bool("limit.current");
            acted |= limited;
            // Two steps after the limiter first acts the current is within 5 % of I_max.
            if (503..700).contains(&k) {
                worst_after = worst_after.max(current(&mut h));
            }
        }
        assert!(
            acted,
            "mode {mode}: the dip never reached the current limit"
        );
        assert!(
            worst_after <= 1.2 * 1.05,
            "mode {mode}: current {worst_after:.3} pu in the dip (I_max 1.2)"
        );
        // After the dip the unit recovers its operating point and the limit episode ended.
        assert!(!h.get_bool("limit.current"));
        let p = h.get("p");
        assert!((p - 0.3).abs() < 0.01, "mode {mode}: p = {p} after the dip");
        assert!(
            warnings <= 3,
            "mode {mode}: {warnings} warnings: {:#?}",
            h.log()
        );
        let log = h.log();
        let entered = log
            .iter()
            .filter(|r| r.message.contains("acts from"))
            .count();
        let released = log
            .iter()
            .filter(|r| r.message.contains("released"))
            .count();
        assert!(entered >= 1 && entered == released, "{log:#?}");
    }
}

#[test]
fn an_empty_dc_link_gives_no_power_and_the_energy_account_closes() {
    // A PV-like unit (no storage) loses most of its source at t = 0.5 s while the grid's
    // frequency falls by 0.25 Hz: its droop asks for far more than the source gives. The link
    // runs down to v_dc_min and from then on the converter delivers what the source gives less
    // the link losses, still synchronized with the grid.
    let mut h = unit(&[("P_avail0", 0.6), ("avail.t_step", 0.5), ("avail.dP", -0.5)]);
    let mut bus = Bus::at_operating_point(h.get("p"), h.get("q"), Complex::new(0.0, 0.05));
    let v_th0 = bus.v_th;
    let w0 = h.get("energy.stored");
    let [s_base, s_rated, g_dc, v_min, r_f] =
        h.get_many(["S_base", "S_rated", "G_dc", "v_dc_min", "R_f"]);
    let to_rated = s_base / s_rated;
    let df = -0.005;
    let (mut lowest, mut worst_excess) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..6000 {
        let t = k as f64 * DT;
        let slip = 2.0 * std::f64::consts::PI * 50.0 * df * (t - 0.5).max(0.0);
        bus.v_th = v_th0 * dvpp_math::cpolar(1.0, slip);
        assert!(bus.step(&mut h) <= Status::Warning, "{:#?}", h.log());
        let [v_dc, p, q, v, p_dc] = h.get_many(["v_dc", "p", "q", "v", "p_dc"]);
        lowest = lowest.min(v_dc);
        if k > 4000 {
            // The ac side (terminal and R_f) against the source less the link losses.
            let ac = p * to_rated + r_f * to_rated * (p * p + q * q) / (v * v) * to_rated;
            let net = p_dc * to_rated - g_dc * v_dc * v_dc;
            worst_excess = worst_excess.max(ac - net);
        }
    }
    assert!(h.get_bool("limit.source") && h.get_bool("limit.dc"));
    assert!(
        lowest > v_min - 0.02,
        "v_dc fell to {lowest} (v_dc_min {v_min})"
    );
    assert!(
        worst_excess < 1e-3,
        "the ac side took {worst_excess} pu (on S_rated) more than the source gives"
    );
    let got = h.get("df");
    assert!((got - df).abs() < 1e-4, "not synchronized: df = {got}");
    let (residual, moved) = energy_account(&mut h, w0);
    assert!(
        residual.abs() <= 1e-9 * moved,
        "energy residual {residual:e} MJ of {moved} MJ"
    );
}

#[test]
fn a_unit_started_at_zero_voltage_waits_then_synchronizes_within_its_ratings() {
    for mode in [1.0, 2.0] {
        let start = [("v", 0.0), ("p", 0.3), ("q", 0.0)];
        let mut h = if mode == 1.0 {
            unit(&start)
        } else {
            unit(&[GFL.as_slice(), &start].concat())
        };
        assert!(!h.get_bool("synchronized"));
        let z_th = Complex::new(0.0, 0.05);
        let mut bus = Bus {
            v_th: Complex::new(0.0, 0.0),
            z_th,
        };
        let (mut worst_i, mut worst_q) = (0.0_f64, 0.0_f64);
        let mut synced_at = None;
        for k in 0..3000 {
            // The grid voltage rises from 0 to 1 pu over 100 ms from t = 0.1 s.
            let ramp = ((k as f64 * DT - 0.1) / 0.1).clamp(0.0, 1.0);
            bus.v_th = dvpp_math::cpolar(ramp, 0.2);
            assert!(bus.step(&mut h) <= Status::Warning, "{:#?}", h.log());
            worst_i = worst_i.max(current(&mut h));
            worst_q = worst_q.max(h.get("q_ref").abs());
            if synced_at.is_none() && h.get_bool("synchronized") {
                synced_at = Some(h.time());
            }
        }
        let t = synced_at.expect("never synchronized");
        println!(
            "mode {mode}: synchronized at t = {t:.3} s, largest current {worst_i:.3} pu, largest |q_ref| {worst_q:.3} pu"
        );
        assert!(
            (0.2..0.4).contains(&t),
            "mode {mode}: synchronized at {t} s"
        );
        assert!(worst_i <= 1.2, "mode {mode}: current {worst_i} pu");
        assert!(worst_q < 1.0, "mode {mode}: q_ref reached {worst_q} pu");
        // Three seconds later it delivers its dispatch at the grid's voltage.
        let [p, v] = h.get_many(["p", "v"]);
        assert!((p - 0.3).abs() < 0.01, "mode {mode}: p = {p}");
        assert!((v - 1.0).abs() < 0.05, "mode {mode}: v = {v}");
    }
}

/// The largest second difference `|x[k+1] - 2 x[k] + x[k-1]|`: what a step-to-step oscillation
/// shows and a smooth response does not.
fn jitter(x: &[f64]) -> f64 {
    x.windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_grid_following_unit_on_a_weak_bus_does_not_oscillate_from_step_to_step() {
    // The bus behind 0.05 pu; its angle jumps by 0.02 rad at t = 0.2 s. With currents that follow
    // their references at once (current.tau = 0), a first-order p-f roll-off (pll.order = 1: the
    // droop's inertial path reaches the current at the gain H/tau_pll through the PLL's
    // proportional path) and no lag ahead of the v-q droop (vq.tau = 0, gain 1/Dq), the loops
    // through the bus impedance oscillate from one 1 ms step to the next; with the defaults
    // (20 ms current response, second-order roll-off, 0.5 s voltage control) the unit settles
    // smoothly.
    let run = |settings: &[(&str, f64)]| -> (f64, f64) {
        let mut h = unit(&[GFL.as_slice(), settings].concat());
        let mut bus = Bus::at_operating_point(h.get("p"), h.get("q"), Complex::new(0.0, 0.05));
        let v_th0 = bus.v_th;
        let mut p = Vec::new();
        for k in 0..2000 {
            if k == 200 {
                bus.v_th = v_th0 * dvpp_math::cpolar(1.0, 0.02);
            }
            assert!(bus.step(&mut h) <= Status::Warning, "{:#?}", h.log());
            if k > 300 {
                p.push(h.get("p"));
            }
        }
        (jitter(&p), *p.last().unwrap())
    };
    let (immediate, _) = run(&[("current.tau", 0.0), ("pll.order", 1.0), ("vq.tau", 0.0)]);
    let (default, p_end) = run(&[]);
    println!("largest second difference of p: {immediate:.3e} (no lags), {default:.3e} (defaults)");
    assert!(
        immediate > 0.05,
        "the loop no longer oscillates without the lag: {immediate}"
    );
    assert!(default < 1e-3, "step-to-step oscillation: {default}");
    assert!((p_end - 0.3).abs() < 0.01, "p = {p_end} at the end");
}
