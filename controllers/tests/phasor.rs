//! The phasor-level unit as a library, without FMI: a `PhasorUnit` stepped directly against an algebraic grid (a Thevenin source behind a reactance).

use dvpp_control::Complex;
use dvpp_controllers::layer::TDesParams;
use dvpp_controllers::phasor::{
    DcRange, OutputStage, PhasorCommand, PhasorMeasurement, PhasorParams, PhasorUnit, Priority,
    QPiParams, SlotImpedance, StartupParams,
};
use dvpp_controllers::{
    AdpfChannel, AdpfKind, AdpfParams, ComplementParams, DcLinkParams, Mode, Notice, OperatorGains,
    PllParams, Rating, SourceParams, MAX_LPF,
};
use std::f64::consts::PI;

const H: f64 = 5.55;
const D: f64 = 33.33;
const S_RATED: f64 = 60.0;
const S_BASE: f64 = 100.0;
const S_DVPP: f64 = 96.0;
const F_NOM: f64 = 50.0;
const STEP: f64 = 1e-3;
const MU_P: f64 = 0.5;

/// A static ADPF on one channel.
fn static_adpf(channel: AdpfChannel) -> AdpfParams {
    AdpfParams {
        channel,
        kind: AdpfKind::Static,
        tau: 1.0,
        tau2: 0.1,
        order: 1,
        order2: 1,
        complement: (channel == AdpfChannel::P).then_some(ComplementParams {
            share: 1.0,
            n_lpf: 0,
            lpf_tau: [1.0; MAX_LPF],
            lpf_order: [1; MAX_LPF],
        }),
    }
}

/// A 60 MVA unit with a static ADPF, the `dvpp_der` FMU's start values otherwise.
fn params(mode: Mode) -> PhasorParams {
    PhasorParams {
        rating: Rating {
            s_rated: S_RATED,
            s_base: S_BASE,
            s_dvpp: S_DVPP,
            f_nom: F_NOM,
        },
        mode,
        tdes: TDesParams {
            h: H,
            d: D,
            dq: 0.01,
            tau_q: 0.01,
        },
        slot: SlotImpedance {
            r_f: 0.01,
            x_f: 0.10,
        },
        adpf_p: static_adpf(AdpfChannel::P),
        adpf_q: static_adpf(AdpfChannel::Q),
        pll: PllParams {
            kp: 60.0,
            ki: 240.0,
            tau: 1.0 / 60.0,
            order: 2,
        },
        qpi: QPiParams {
            kp: 0.05,
            ki: 5.0,
            e_max: 1.5,
        },
        dc: DcLinkParams {
            tau_dc: 0.2,
            c_dc: 0.096,
            g_dc: 0.05,
            k_dc: 100.0,
            zeta: 0.7,
        },
        dc_range: DcRange {
            v_min: 0.8,
            v_max: 1.2,
            t_budget: 0.02,
        },
        source: SourceParams {
            storage: false,
            deload: 1.0,
            p_avail0: 0.6,
            avail_t: 1.0,
            avail_dp: 0.0,
        },
        stage: OutputStage {
            i_max: 1.2,
            priority: Priority::Active,
            delay_c: 0.5,
            current_tau: 0.02,
            vq_tau: 0.5,
        },
        vi_r: 0.0,
        startup: StartupParams {
            v_sync: 0.5,
            t_hold: 0.05,
            ramp: 1.0,
        },
        rot_rx: 0.0,
        redispatch: 0.0,
    }
}

fn gains() -> OperatorGains {
    OperatorGains {
        mu_p: MU_P,
        mu_q: 0.5,
        mu_p_lpf: [0.0; MAX_LPF],
    }
}

/// The grid: a Thevenin source `v_th` behind `z_th` (pu on S_base) at the unit's terminal bus.
/// A grid-forming unit's `E∠θ` feeds the bus through its slot impedance `z_f`; a
/// grid-following unit injects `p_ref + j q_ref` into it. Solved in closed form (grid-forming)
/// or by a contracting fixed point (grid-following).
struct Thevenin {
    v_th: Complex<f64>,
    z_th: Complex<f64>,
    z_f: Complex<f64>,
    mode: Mode,
}

impl Thevenin {
    /// The source that puts the bus at `1∠0` with the unit injecting `p + j q`.
    fn at_operating_point(p: f64, q: f64, z_th: Complex<f64>, unit: &PhasorParams) -> Thevenin {
        let zbase = unit.rating.s_base / unit.rating.s_rated;
        Thevenin {
            v_th: Complex::new(1.0, 0.0) - z_th * Complex::new(p, -q),
            z_th,
            z_f: Complex::new(unit.slot.r_f, unit.slot.x_f) * zbase,
            mode: unit.mode,
        }
    }

    /// The bus voltage and the unit's injection `p + j q` for its command `c`.
    fn solve(&self, c: &PhasorCommand) -> (Complex<f64>, Complex<f64>) {
        match self.mode {
            Mode::GridForming => {
                let e = dvpp_math::cpolar(c.e, c.theta);
                let v = (self.z_f * self.v_th + self.z_th * e) / (self.z_f + self.z_th);
                (v, v * ((e - v) / self.z_f).conj())
            }
            Mode::GridFollowing => {
                let s = Complex::new(c.p_ref, c.q_ref);
                let mut v = self.v_th;
                for _ in 0..100 {
                    v = self.v_th + self.z_th * (s / v).conj();
                }
                (v, s)
            }
        }
    }
}

/// What a run records: the unit's frequency and its power at the terminal after each step.
struct Run {
    df: Vec<f64>,
    p: Vec<f64>,
    last: PhasorCommand,
    warnings: Vec<String>,
}

/// A unit at `p0` (pu on S_base, unity power factor, bus at 1∠0) behind a grid of reactance
/// `x_th` whose frequency steps by `df_grid` (pu) at `t_step`; `steps` steps of `STEP`.
fn run(mode: Mode, p0: f64, x_th: f64, df_grid: f64, t_step: f64, steps: usize) -> Run {
    let params = params(mode);
    let mut grid = Thevenin::at_operating_point(p0, 0.0, Complex::new(0.0, x_th), &params);
    let v_th0 = grid.v_th;
    let at_start = PhasorMeasurement {
        t: 0.0,
        p: p0,
        q: 0.0,
        v: 1.0,
        v_angle: 0.0,
    };
    let (mut unit, mut command) =
        PhasorUnit::initialize(&params, &at_start, &gains(), None).expect("the unit initializes");
    let mut out = Run {
        df: vec![],
        p: vec![],
        last: command.clone(),
        warnings: vec![],
    };
    let mut v_angle = 0.0;
    for k in 0..steps {
        let t = k as f64 * STEP;
        grid.v_th =
            v_th0 * dvpp_math::cpolar(1.0, 2.0 * PI * F_NOM * df_grid * (t - t_step).max(0.0));
        let (v, s) = grid.solve(&command);
        // The angle continuous across ±π (the source's frequency offset turns it round).
        let turns = ((v_angle - dvpp_math::carg(v)) / (2.0 * PI)).round();
        v_angle = dvpp_math::carg(v) + 2.0 * PI * turns;
        let m = PhasorMeasurement {
            t,
            p: s.re,
            q: s.im,
            v: dvpp_math::cabs(v),
            v_angle,
        };
        command = unit.step(&m, &gains(), STEP).expect("the unit steps");
        out.warnings
            .extend(command.notices.iter().filter_map(|n| match n {
                Notice::Warning(w) => Some(w.clone()),
                Notice::Event(_) => None,
            }));
        out.df.push(command.df);
        out.p.push(m.p);
    }
    out.last = command;
    out
}

/// The droop a unit with the static ADPF `m = μ` shares of a grid frequency deviation `df` in
/// steady state, pu on S_base: `T_pf(0) = 1/D`, so `Δp = -μ D Δf` on S_dvpp.
fn droop_share(df: f64) -> f64 {
    -MU_P * D * df * S_DVPP / S_BASE
}

#[test]
fn a_grid_forming_unit_runs_at_the_grid_frequency_and_shares_its_droop() {
    let (p0, df_grid, t_step) = (0.3, -0.002, 0.1);
    let steps = 6000;
    let r = run(Mode::GridForming, p0, 0.05, df_grid, t_step, steps);
    // Before the grid moves the unit stays at its operating point: initialization put E∠θ
    // behind the slot at the measured power.
    let before = (t_step / STEP) as usize;
    for k in 0..before {
        assert!(r.df[k].abs() < 1e-12, "df at step {k}: {}", r.df[k]);
        assert!((r.p[k] - p0).abs() < 1e-9, "p at step {k}: {}", r.p[k]);
    }
    // The swing of the unit's inertia against the stiff grid decays at D/(2H) = 3 s⁻¹, so
    // 5.9 s after the step what is left of it is e^{-17.7} (2e-8) of the step's size; the
    // tolerance is 1e-6 of the step's size.
    let dp = droop_share(df_grid);
    let (df, p) = (r.df[steps - 1], r.p[steps - 1]);
    assert!(
        (df - df_grid).abs() <= 1e-6 * df_grid.abs(),
        "the unit's frequency {df} is the grid's {df_grid}"
    );
    assert!(
        (p - p0 - dp).abs() <= 1e-6 * dp.abs(),
        "the unit's power change {} is its droop share {dp}",
        p - p0
    );
    // Nothing limited the response, and its set point stayed the dispatch.
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.last.p_set, p0);
    assert!(r.last.synchronized && !r.last.limit_current && !r.last.limit_dc);
}

#[test]
fn a_grid_following_unit_locks_to_the_grid_frequency_and_shares_its_droop() {
    let (p0, df_grid, t_step) = (0.3, 0.001, 0.1);
    let steps = 8000;
    let r = run(Mode::GridFollowing, p0, 0.05, df_grid, t_step, steps);
    let before = (t_step / STEP) as usize;
    for k in 0..before {
        assert!(r.df[k].abs() < 1e-12, "df at step {k}: {}", r.df[k]);
        assert!((r.p[k] - p0).abs() < 1e-12, "p at step {k}: {}", r.p[k]);
    }
    // The PLL (type 2) locks to the grid's frequency ramp; the frequency it reports at a step's
    // end is its Δω = k_p e + k_i ∫e there, which the angle held over the step (the sampled
    // ramp) lowers below the ramp's slope by about k_p h / 2 (3 %): within k_p h of the grid's.
    let kp = params(Mode::GridFollowing).pll.kp;
    let (df, p) = (r.df[steps - 1], r.p[steps - 1]);
    assert!(
        (df - df_grid).abs() <= kp * STEP * df_grid.abs(),
        "the PLL's frequency {df} is the grid's {df_grid}"
    );
    // The power follows the reference behind the roll-off and the current's lag, settled within
    // 8 s to 1e-6: the unit injects its droop share of the frequency it measures.
    let dp = droop_share(df);
    assert!(
        (p - p0 - dp).abs() <= 1e-6 * dp.abs(),
        "the unit's power change {} is its droop share {dp} of its frequency {df}",
        p - p0
    );
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

#[test]
fn parameters_at_fault_are_named_as_the_fmu_names_them() {
    let m = PhasorMeasurement {
        t: 0.0,
        p: 0.3,
        q: 0.0,
        v: 1.0,
        v_angle: 0.0,
    };
    let refused = |p: PhasorParams| {
        PhasorUnit::initialize(&p, &m, &gains(), None)
            .err()
            .and_then(|e| e.field)
    };
    let mut p = params(Mode::GridForming);
    p.tdes.d = 0.0;
    assert_eq!(refused(p).as_deref(), Some("Tdes.D"));
    let mut p = params(Mode::GridForming);
    p.dc_range.v_min = 1.0;
    assert_eq!(refused(p).as_deref(), Some("v_dc_min"));
    let mut p = params(Mode::GridFollowing);
    p.pll.ki = 0.0;
    assert_eq!(refused(p).as_deref(), Some("pll.kp"));
    let mut p = params(Mode::GridForming);
    p.adpf_p.kind = AdpfKind::LowPass;
    p.adpf_p.tau = -1.0;
    assert_eq!(refused(p).as_deref(), Some("adpf.p.tau"));
    assert_eq!(
        Priority::from_code(2).unwrap_err().field.as_deref(),
        Some("limit.priority")
    );
}

/// A grid-forming unit (60 MVA at 0.3 pu on S_base, `vi.r` = 0.3 as case study I's units in
/// `phasor_thevenin`) on a stiff bus whose voltage dips to 0.5 pu from 0.1 s for 150 ms, its
/// current held at `I_max` in the direction of the slot's free current `(E∠θ - V)/z_f`, as the
/// grid FMU's slot holds it; with `limit.priority` `priority` and the dip (`dip`) or without.
/// Returns the commands and, over the dip after its first 20 ms, the mean current magnitude
/// (pu of the rated current) and the mean reactive share `i_q/|i|` (`q = |V| i_q`).
fn dip(priority: Priority, dip: bool) -> (Vec<PhasorCommand>, f64, f64) {
    let mut params = params(Mode::GridForming);
    params.vi_r = 0.3;
    params.stage.priority = priority;
    let to_base = S_RATED / S_BASE;
    let z_f = Complex::new(params.slot.r_f, params.slot.x_f) / to_base;
    let i_max = params.stage.i_max * to_base;
    let p0 = 0.3;
    let at_start = PhasorMeasurement {
        t: 0.0,
        p: p0,
        q: 0.0,
        v: 1.0,
        v_angle: 0.0,
    };
    let (mut unit, mut command) =
        PhasorUnit::initialize(&params, &at_start, &gains(), None).expect("the unit initializes");
    let (mut commands, mut i_sum, mut q_share, mut n) = (Vec::new(), 0.0, 0.0, 0.0f64);
    for k in 0..400 {
        let t = k as f64 * STEP;
        let in_dip = dip && (0.1..0.25).contains(&t);
        let v = Complex::new(if in_dip { 0.5 } else { 1.0 }, 0.0);
        let free = (dvpp_math::cpolar(command.e, command.theta) - v) / z_f;
        let mag = dvpp_math::cabs(free);
        let i = if mag > i_max {
            free * (i_max / mag)
        } else {
            free
        };
        let s = v * i.conj();
        if in_dip && t >= 0.12 {
            i_sum += dvpp_math::cabs(i) / to_base;
            q_share += s.im / dvpp_math::cabs(s);
            n += 1.0;
        }
        let m = PhasorMeasurement {
            t,
            p: s.re,
            q: s.im,
            v: dvpp_math::cabs(v),
            v_angle: 0.0,
        };
        command = unit.step(&m, &gains(), STEP).expect("the unit steps");
        commands.push(command.clone());
    }
    (commands, i_sum / n.max(1.0), q_share / n.max(1.0f64))
}

/// In a dip a grid-forming unit at its current limit gives mostly active current when it keeps
/// the request's direction (`limit.priority` = 0: the voltage behind the virtual resistance asks
/// for current in phase with the bus) and mostly reactive current with `limit.priority` = 1
/// (the virtual impedance's direction, X/R = 5); both hold I_max. Where the limit does not act
/// the two are the same bits.
#[test]
fn a_grid_forming_unit_gives_reactive_current_in_a_dip_with_reactive_priority() {
    let (_, i_active, q_active) = dip(Priority::Active, true);
    let (_, i_reactive, q_reactive) = dip(Priority::Reactive, true);
    println!(
        "in a 0.5 pu dip: |i| {i_active:.4} / {i_reactive:.4} pu, reactive share {q_active:.3} / {q_reactive:.3} (priority active / reactive)"
    );
    assert!((i_active - 1.2).abs() < 1e-9 && (i_reactive - 1.2).abs() < 1e-9);
    assert!(q_active < 0.6, "{q_active}");
    assert!(q_reactive > 0.9, "{q_reactive}");
    let (plain, _, _) = dip(Priority::Active, false);
    let (reactive, _, _) = dip(Priority::Reactive, false);
    for (a, b) in plain.iter().zip(&reactive) {
        assert!(a.e.to_bits() == b.e.to_bits() && a.theta.to_bits() == b.theta.to_bits());
    }
}
