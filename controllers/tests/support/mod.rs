//! What the EMT unit's closed-loop tests share: the generic unit, the operator's unity gains, and unit 1's measurements from and commands into the EMT plant run in process.

use dvpp_control::converter::{Abc, InnerDesign};
use dvpp_controllers::emt::{
    EmtCommand, EmtMeasurement, EmtParams, FilterParams, InnerKind, QPiParams,
};
use dvpp_controllers::layer::TDesParams;
use dvpp_controllers::{
    AdpfChannel, AdpfKind, AdpfParams, ComplementParams, DcLinkParams, Mode, OperatorGains,
    PllParams, Rating, SourceParams, MAX_LPF,
};
use emt_plant_model::Plant;
use fmi_export::harness::Harness;
use fmi_export::Status;

/// The generic unit of the FMU's start values (a 60 MVA grid-forming unit with static ADPFs,
/// the paper's filter and transformer), in `mode` with `kind`; grid-following with `vq.tau` =
/// 2 s (the v-q droop's lag; 0.5 s is not stable on weak grids, docs/emt.md).
pub fn unit_params(mode: Mode, kind: InnerKind) -> EmtParams {
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
        mode,
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
        vq_tau: match mode {
            Mode::GridForming => 0.5,
            Mode::GridFollowing => 2.0,
        },
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
        inner_kind: kind,
        t_s: 50e-6,
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

/// The operator's gains of a unit alone: `μ_p = μ_q = 1`.
pub const GAINS: OperatorGains = OperatorGains {
    mu_p: 1.0,
    mu_q: 1.0,
    mu_p_lpf: [0.0; MAX_LPF],
};

/// The plant's measurements of unit 1 at `t`.
pub fn measure(plant: &mut Harness<Plant>, t: f64) -> EmtMeasurement {
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

/// The command into the plant's inputs.
pub fn command(plant: &mut Harness<Plant>, c: &EmtCommand) {
    for (ph, m) in ["a", "b", "c"].iter().zip(c.m_abc) {
        plant.set(&format!("der[1].m_{ph}"), m);
    }
    plant.set("der[1].i_dc_ref", c.i_dc_ref);
    plant.set("der[1].p_src_min", c.p_src_min);
    plant.set("der[1].p_src_max", c.p_src_max);
}

/// The plant's configuration of one 60 MVA unit exporting 0.3 pu of `S_base` into a Thevenin
/// source, no load (the conformance cases have their own).
#[allow(dead_code)]
pub const THEVENIN_UNIT: &str = "[model]\ncase = \"island\"\nthevenin = true\nunits = [{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = 0.3 }]\nloads = []\n";

/// The EMT plant of configuration `toml`, its experiment set up, with unit 1's filter,
/// transformer and dc link those the unit `params` is designed for.
pub fn plant_for(toml: &str, params: &EmtParams) -> Harness<Plant> {
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
    plant
}
