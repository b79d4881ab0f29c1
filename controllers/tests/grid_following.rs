//! The grid-following EMT unit on weak and stiff grids: `EmtUnit` (mode 2) in closed loop with the EMT plant's circuit at SCR 1.5, 3, 10 and 500, stable from a flat start and settled after a 0.1 pu dip of the source, its current within I_max.
//!
//! The unit is the conformance test's generic 60 MVA unit (the paper's filter, transformer and
//! PLL gains 60, 240; a static ADPF carrying the whole DVPP's T_des, μ_p = μ_q = 1) in
//! grid-following mode with `vq.tau` = 2 s: the v-q droop `1/Dq` = 100 pu on S_dvpp is 160 pu on
//! the unit's rating, a loop gain of about 107 through an SCR 1.5 grid, which `vq.tau` = 0.5 s
//! (the FMU's start value) leaves unstable there (docs/emt.md, grid-following on weak grids).
//! It feeds 0.5 pu of its rating into a Thevenin source (X/R = 10) through its filter and
//! transformer, no load; the source dips to 0.9 (and 0.5) of its voltage for 0.15 s at 1 s.

use dvpp_control::converter::{Abc, InnerDesign};
use dvpp_controllers::emt::{
    EmtCommand, EmtMeasurement, EmtParams, EmtUnit, FilterParams, InnerKind, QPiParams,
};
use dvpp_controllers::layer::TDesParams;
use dvpp_controllers::{
    AdpfChannel, AdpfKind, AdpfParams, ComplementParams, DcLinkParams, Mode, OperatorGains,
    PllParams, Rating, SourceParams, MAX_LPF,
};
use emt_plant_model::Plant;
use fmi_export::harness::Harness;
use fmi_export::Status;

/// The step (s).
const H: f64 = 50e-6;
/// The source's dip: its start (s), duration (s) and depth (fraction of E).
const DIP_T: f64 = 1.0;
const DIP_DURATION: f64 = 0.15;
/// The run's end (s): 2.35 s after the dip ends.
const T_END: f64 = 3.5;
/// How far the phase currents may exceed I_max (fraction) in a 0.1 pu dip, and in a 0.5 pu dip,
/// where the reference is held at I_max and the dip's edges (dc offsets of the inductive
/// currents, which the PLL on the phasor estimate of the MV voltage reads as a 50 Hz swing of
/// its angle) carry the current past it for a few milliseconds (measured 1.17 I_max at SCR 10).
const I_TOLERANCE: f64 = 0.1;
const I_TOLERANCE_DEEP: f64 = 0.2;

const GAINS: OperatorGains = OperatorGains {
    mu_p: 1.0,
    mu_q: 1.0,
    mu_p_lpf: [0.0; MAX_LPF],
};

/// The conformance test's generic unit, grid-following, `vq.tau` = 2 s.
fn unit_params() -> EmtParams {
    let adpf = |channel, complement| AdpfParams {
        channel,
        kind: AdpfKind::Static,
        tau: 1.0,
        tau2: 0.1,
        order: 1,
        order2: 1,
        complement,
    };
    EmtParams {
        rating: Rating {
            s_rated: 60.0,
            s_base: 100.0,
            s_dvpp: 96.0,
            f_nom: 50.0,
        },
        mode: Mode::GridFollowing,
        tdes: TDesParams {
            h: 5.55,
            d: 33.33,
            dq: 0.01,
            tau_q: 0.01,
        },
        adpf_p: adpf(
            AdpfChannel::P,
            Some(ComplementParams {
                share: 1.0,
                n_lpf: 0,
                lpf_tau: [1.0; MAX_LPF],
                lpf_order: [1; MAX_LPF],
            }),
        ),
        adpf_q: adpf(AdpfChannel::Q, None),
        pll: PllParams {
            kp: 60.0,
            ki: 240.0,
            tau: 1.0 / 60.0,
            order: 2,
        },
        qpi: QPiParams {
            kp: 0.05,
            ki: 0.5,
            e_max: 1.5,
        },
        vq_tau: 2.0,
        filter: FilterParams {
            r_f: 0.01,
            l_f: 0.11,
            c_f: 0.0942,
            r_t: 0.01,
            l_t: 0.1,
        },
        vdc_ratio: 3.0,
        vi_r: 0.3,
        inner: InnerDesign::default(),
        inner_kind: InnerKind::OptionA,
        t_s: H,
        dc: DcLinkParams {
            tau_dc: 0.2,
            c_dc: 0.096,
            g_dc: 0.05,
            k_dc: 100.0,
            zeta: 0.7,
        },
        source: SourceParams {
            storage: false,
            deload: 1.0,
            p_avail0: 0.6,
            avail_t: 1.0,
            avail_dp: 0.0,
        },
    }
}

fn measure(plant: &mut Harness<Plant>, t: f64) -> EmtMeasurement {
    let mut three = |w: &str| {
        let [a, b, c] = ["a", "b", "c"].map(|ph| plant.get(&format!("der[1].{w}_{ph}")));
        Abc { a, b, c }
    };
    let (v_c, i_f, i_g) = (three("v"), three("i"), three("ig"));
    EmtMeasurement {
        t,
        v_c,
        i_f,
        i_g,
        v_dc: plant.get("der[1].v_dc"),
    }
}

fn command(plant: &mut Harness<Plant>, c: &EmtCommand) {
    for (ph, m) in ["a", "b", "c"].iter().zip(c.m_abc) {
        plant.set(&format!("der[1].m_{ph}"), m);
    }
    plant.set("der[1].i_dc_ref", c.i_dc_ref);
    plant.set("der[1].p_src_min", c.p_src_min);
    plant.set("der[1].p_src_max", c.p_src_max);
}

/// What a run shows, per window.
#[derive(Debug, Default)]
struct Window {
    /// Largest |df| (Hz), phase current peak (pu of the rated peak), |p - p0|, |q - q0|,
    /// |v - v0| (pu); mean q (pu on S_base).
    df: f64,
    i_peak: f64,
    dp: f64,
    dq: f64,
    dv: f64,
    q_sum: f64,
    n: usize,
}

impl Window {
    fn add(&mut self, c: &EmtCommand, i_peak: f64, init: &EmtCommand, f_nom: f64) {
        self.df = self.df.max((c.df * f_nom).abs());
        self.i_peak = self.i_peak.max(i_peak);
        self.dp = self.dp.max((c.p - init.p).abs());
        self.dq = self.dq.max((c.q - init.q).abs());
        self.dv = self.dv.max((c.v - init.v).abs());
        self.q_sum += c.q;
        self.n += 1;
    }

    fn q_mean(&self) -> f64 {
        self.q_sum / self.n as f64
    }
}

/// The unit on a Thevenin source of short-circuit ratio `scr` on its rating: the windows before
/// the dip (from 20 ms on), during it, and the last 0.5 s; and the whole run.
fn run(scr: f64, dip: f64) -> ([Window; 4], usize) {
    let params = unit_params();
    let toml = "[model]\ncase = \"island\"\nthevenin = true\nunits = [{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = 0.3 }]\nloads = []\n";
    let mut plant = Harness::<Plant>::from_toml(toml);
    assert_eq!(plant.setup_experiment(0.0, None), Status::Ok);
    let f = params.filter;
    for (name, value) in [
        ("R_f", f.r_f),
        ("L_f", f.l_f),
        ("C_f", f.c_f),
        ("R_t", f.r_t),
        ("L_t", f.l_t),
        ("C_dc", params.dc.c_dc),
        ("G_dc", params.dc.g_dc),
        ("tau_dc", params.dc.tau_dc),
    ] {
        plant.set(&format!("der[1].{name}"), value);
    }
    // X on S_base for the SCR on the unit's rating.
    let x = params.rating.s_base / (params.rating.s_rated * scr);
    plant.set("thevenin.X", x);
    plant.set("thevenin.R", x / 10.0);
    plant.set("thevenin.dip", dip);
    plant.set("thevenin.dip_t", DIP_T);
    plant.set("thevenin.dip_duration", DIP_DURATION);
    assert_eq!(plant.enter_initialization_mode(), Status::Ok);
    assert_eq!(
        plant.exit_initialization_mode(),
        Status::Ok,
        "SCR {scr}: {:?}",
        plant.log()
    );
    let (mut unit, mut cmd) =
        EmtUnit::initialize(&params, &measure(&mut plant, 0.0), &GAINS).expect("initialize");
    let init = cmd.clone();
    let f_nom = params.rating.f_nom;
    let mut w: [Window; 4] = Default::default();
    let mut limited = 0;
    let n = (T_END / H).round() as usize;
    for k in 0..n {
        let t = k as f64 * H;
        command(&mut plant, &cmd);
        let m = measure(&mut plant, t);
        cmd = unit
            .step(&m, &GAINS, H)
            .unwrap_or_else(|e| panic!("SCR {scr}: t = {t}: {e}"));
        assert_eq!(plant.do_step(t, H), Status::Ok, "SCR {scr}: plant at {t}");
        let i_peak = m.i_f.peak();
        limited += usize::from(cmd.limit_current);
        if (0.02..DIP_T).contains(&t) {
            w[0].add(&cmd, i_peak, &init, f_nom);
        } else if (DIP_T..DIP_T + DIP_DURATION).contains(&t) {
            w[1].add(&cmd, i_peak, &init, f_nom);
        } else if t >= T_END - 0.5 {
            w[2].add(&cmd, i_peak, &init, f_nom);
        }
        w[3].add(&cmd, i_peak, &init, f_nom);
    }
    let i_max = params.inner.i_max;
    println!(
        "SCR {scr}, dip {dip}: before the dip |df| <= {:.2e} Hz, |dp| <= {:.2e}, phase i <= {:.3}; during it q {:.3} (q0 {:.3}), phase i <= {:.3}; over the run |df| <= {:.3} Hz, phase i <= {:.3} = {:.3} I_max; the last 0.5 s |dp| <= {:.1e}, |dq| <= {:.1e}, |dv| <= {:.1e}, |df| <= {:.1e} Hz; {limited} samples limited",
        w[0].df, w[0].dp, w[0].i_peak, w[1].q_mean(), init.q, w[1].i_peak, w[3].df, w[3].i_peak,
        w[3].i_peak / i_max, w[2].dp, w[2].dq, w[2].dv, w[2].df
    );
    (w, limited)
}

/// Stable from the start, the current within I_max through the dip, the reactive current
/// injected during it, settled after it.
fn stable_and_settled(scr: f64, depth: f64, i_tolerance: f64, df_max: f64) -> usize {
    let ([before, dip, last, all], limited) = run(scr, depth);
    let i_max = unit_params().inner.i_max;
    // Flat start: the first second holds the operating point (a 200-300 Hz mode grew to
    // ±30 Hz within 20 ms before the fix).
    assert!(
        before.df < 0.01,
        "SCR {scr}: |df| {} Hz before the dip",
        before.df
    );
    assert!(
        before.dp < 0.005,
        "SCR {scr}: |dp| {} before the dip",
        before.dp
    );
    assert!(
        before.i_peak < 0.6,
        "SCR {scr}: phase current {} before the dip",
        before.i_peak
    );
    // Bounded through the dip; the current within I_max (1 + tolerance).
    assert!(all.df < df_max, "SCR {scr}: |df| {} Hz", all.df);
    assert!(
        all.i_peak <= i_max * (1.0 + i_tolerance),
        "SCR {scr}: phase current {} beyond I_max {i_max} (1 + {i_tolerance})",
        all.i_peak
    );
    // The v-q droop injects reactive power while the voltage is down.
    let q0 = 0.0;
    assert!(
        dip.q_mean() > q0 + 0.02,
        "SCR {scr}: mean q {} during the dip",
        dip.q_mean()
    );
    // Settled: the operating point again over the last 0.5 s (the reactive power within 0.05
    // pu: on a stiff grid the v-q droop's reference decays with vq.tau = 2 s).
    assert!(last.dp < 0.005, "SCR {scr}: |dp| {} at the end", last.dp);
    assert!(last.dq < 0.05, "SCR {scr}: |dq| {} at the end", last.dq);
    assert!(last.dv < 0.005, "SCR {scr}: |dv| {} at the end", last.dv);
    assert!(last.df < 0.005, "SCR {scr}: |df| {} Hz at the end", last.df);
    limited
}

#[test]
fn scr_1_5() {
    stable_and_settled(1.5, 0.1, I_TOLERANCE, 5.0);
}

#[test]
fn scr_3() {
    stable_and_settled(3.0, 0.1, I_TOLERANCE, 5.0);
}

#[test]
fn scr_10() {
    stable_and_settled(10.0, 0.1, I_TOLERANCE, 5.0);
}

/// A stiff grid (SCR 500; the plant's initialization does not converge at some stiffer ones).
#[test]
fn stiff() {
    stable_and_settled(500.0, 0.1, I_TOLERANCE, 5.0);
}

/// A dip to 0.5 pu on SCR 10 and on the stiff grid: the reactive reference asks more than
/// I_max, the limit holds it (reactive first) and the unit recovers. The PLL's frequency swings
/// by tens of Hz at the dip's edges (the phasor estimate of the MV voltage under the dc offsets;
/// not bounded here).
#[test]
fn deep_dip_is_limited_and_recovers() {
    for scr in [10.0, 500.0] {
        let limited = stable_and_settled(scr, 0.5, I_TOLERANCE_DEEP, f64::INFINITY);
        assert!(limited > 100, "SCR {scr}: {limited} samples limited");
    }
}
