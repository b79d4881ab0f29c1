//! DVPP operator model (the `dvpp_operator` FMU; its binary is `fmu/`): the FMI variables of
//! [`dvpp_controllers::operator::Operator`] (online ADPF dc gains for every DER and the desired
//! aggregate response; what it computes is documented there).
//!
//! This crate is the adapter: it declares the variables (grouped: the parameters, each DER's
//! inputs and gains, the PCC and the desired response, the points of coupling), turns the
//! parameters and inputs into the library's typed [`Params`] and [`Measurement`], and writes its
//! [`Command`] back; the command's notices are logged as warnings and events.

pub mod ports;

use dvpp_controllers::operator::{self as library, Command, Measurement, Params, Pcc};
pub use dvpp_controllers::operator::{Form, Role, Unit, Unit as DerEntry, MAX_POCS};
use dvpp_controllers::operator::{PocMeasurement, UnitMeasurement};
use dvpp_controllers::Notice;
use fmi_export::{Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};

/// The DVPP the operator serves (`[model]` in config.toml).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorConfig {
    pub ders: Vec<DerEntry>,
    /// Points of coupling of a DVPP area (inputs `poc[k].p`, `.q`, `.f`, `.v`): `ref.df` is then
    /// matched at them (`-T_pf Σ_k Δp'_poc,k`); 0 (default): at the PCC.
    #[serde(default)]
    pub pocs: usize,
    /// Start value of the parameter `rot.rx` (declared with `pocs` > 0): the R/X ratio the
    /// rotation `p' = (p - rx q)/sqrt(1 + rx²)` of the POC powers compensates, as the DERs'
    /// `rot.rx` (0: classical, plain `Δp`).
    #[serde(default)]
    pub rot_rx: f64,
}

impl Default for OperatorConfig {
    /// Case study I: wind and PV low-pass, BESS the complement, all grid-forming.
    fn default() -> Self {
        let p = Params::default();
        OperatorConfig {
            ders: p.units,
            pocs: p.pocs,
            rot_rx: p.rot_rx,
        }
    }
}

impl OperatorConfig {
    /// The library's parameters with this structure and the parameters' start values.
    fn params(&self) -> Params {
        Params {
            units: self.ders.clone(),
            pocs: self.pocs,
            rot_rx: self.rot_rx,
            ..Params::default()
        }
    }
}

/// Handles of the parameters.
struct ParamVars {
    s_base: Real,
    s_dvpp: Real,
    h: Real,
    d: Real,
    dq: Real,
    mu_min: Real,
    rate_limit: Real,
    delay: Real,
}

/// Handles of one DER's variables.
struct DerVars {
    s_rated: Real,
    p_avail: Real,
    p: Real,
    p_set: Real,
    /// Low-pass units only.
    mu_p: Option<Real>,
    mu_q: Real,
    /// Complement units only: the gains of the low-pass units it complements.
    mu_p_lpf: Vec<Real>,
}

/// Handles of the PCC's inputs and the desired response's outputs.
struct PccVars {
    p: Real,
    q: Real,
    f: Real,
    v: Real,
    ref_df: Real,
    ref_dv: Real,
    err_df: Real,
    err_dv: Real,
    sum_mu_p: Real,
    sum_mu_q: Real,
}

/// Handles of one point of coupling's variables.
struct PocVars {
    p: Real,
    q: Real,
    f: Real,
    err_df: Real,
}

/// Handles of the POCs of a DVPP area (`[model] pocs` > 0).
struct PocsVars {
    /// Parameter `rot.rx`.
    rot_rx: Real,
    vars: Vec<PocVars>,
    /// Inputs `area.p_load`, `area.q_load`.
    load: (Real, Real),
    /// Output `poc.dp`.
    dp: Real,
}

/// The operator FMU: its variables' handles (its running state is the library's operator).
pub struct Operator {
    config: OperatorConfig,
    params: ParamVars,
    ders: Vec<DerVars>,
    pcc: PccVars,
    /// Points of coupling (`[model] pocs` > 0).
    pocs: Option<PocsVars>,
}

impl Operator {
    /// The parameters' values.
    fn params(&self, s: &Store) -> Params {
        let v = &self.params;
        let mut p = self.config.params();
        for (unit, der) in p.units.iter_mut().zip(&self.ders) {
            unit.s_rated = s[der.s_rated];
        }
        if let Some(pocs) = &self.pocs {
            p.rot_rx = s[pocs.rot_rx];
        }
        Params {
            s_base: s[v.s_base],
            s_dvpp: s[v.s_dvpp],
            h: s[v.h],
            d: s[v.d],
            dq: s[v.dq],
            mu_min: s[v.mu_min],
            rate_limit: s[v.rate_limit],
            delay: s[v.delay],
            ..p
        }
    }

    /// The inputs' values.
    fn measurement(&self, s: &Store) -> Measurement {
        let pcc = &self.pcc;
        let (pocs, area_load) = match &self.pocs {
            None => (Vec::new(), (0.0, 0.0)),
            Some(pocs) => (
                pocs.vars
                    .iter()
                    .map(|v| PocMeasurement {
                        p: s[v.p],
                        q: s[v.q],
                        f: s[v.f],
                    })
                    .collect(),
                (s[pocs.load.0], s[pocs.load.1]),
            ),
        };
        Measurement {
            units: self
                .ders
                .iter()
                .map(|d| UnitMeasurement {
                    p_avail: s[d.p_avail],
                    p: s[d.p],
                    p_set: s[d.p_set],
                })
                .collect(),
            pcc: Pcc {
                p: s[pcc.p],
                q: s[pcc.q],
                f: s[pcc.f],
                v: s[pcc.v],
            },
            pocs,
            area_load,
        }
    }

    /// Write the command to the outputs and log its notices.
    fn write(&self, s: &mut Store, c: &Command, ctx: &mut Context) {
        for notice in &c.notices {
            match notice {
                Notice::Warning(m) => ctx.warn(m),
                Notice::Event(m) => ctx.event(m),
            }
        }
        // Only the low-pass units have `mu_p`, in the order of `c.mu_p`.
        for (r, &mu) in self.ders.iter().filter_map(|d| d.mu_p).zip(&c.mu_p) {
            s[r] = mu;
        }
        for (k, der) in self.ders.iter().enumerate() {
            s[der.mu_q] = c.mu_q[k];
            for (j, &r) in der.mu_p_lpf.iter().enumerate() {
                s[r] = c.mu_p[j];
            }
        }
        let pcc = &self.pcc;
        s[pcc.sum_mu_p] = c.sum_mu_p;
        s[pcc.sum_mu_q] = c.sum_mu_q;
        s[pcc.ref_df] = c.ref_df;
        s[pcc.ref_dv] = c.ref_dv;
        s[pcc.err_df] = c.err_df;
        s[pcc.err_dv] = c.err_dv;
        if let Some(pocs) = &self.pocs {
            s[pocs.dp] = c.dp;
            for (v, &e) in pocs.vars.iter().zip(&c.poc_err_df) {
                s[v.err_df] = e;
            }
        }
    }
}

impl Model for Operator {
    type Config = OperatorConfig;
    type State = library::Operator;
    const IDENTIFIER: &'static str = "dvpp_operator";
    const NAME: &'static str = "DVPP operator";
    const DESCRIPTION: &'static str =
        "DVPP operator: online ADPF dc gains (sums exactly 1) and the desired aggregate response T_des";
    /// Phasor steps are 1e-4 to 1e-2 s; 1 s (100 times the longest) keeps one call short.
    const MAX_STEP: f64 = 1.0;

    fn declare(
        config: &OperatorConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let start = config.params();
        start
            .check_structure()
            .map_err(|e| format!("[model] {e}"))?;
        let params = ParamVars::declare(v, &start);
        let mut ders = DerVars::declare_inputs(v, config);
        DerVars::declare_gains(v, config, &mut ders);
        let pcc = PccVars::declare(v);
        let pocs = (config.pocs > 0).then(|| PocsVars::declare(v, config.pocs, config.rot_rx));
        Ok(Operator {
            config: config.clone(),
            params,
            ders,
            pcc,
            pocs,
        })
    }

    fn initialize(
        &self,
        previous: Option<&library::Operator>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<library::Operator, ModelError> {
        let (params, m) = (self.params(s), self.measurement(s));
        let (op, command) = match previous {
            None => library::Operator::initialize(params, &m),
            Some(previous) => library::Operator::initialize_after(previous, params, &m),
        }
        .map_err(|e| ModelError(e.to_string()))?;
        self.write(s, &command, ctx);
        Ok(op)
    }

    fn do_step(
        &self,
        op: &mut library::Operator,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let command = op
            .step(&self.measurement(s), t, h)
            .map_err(|e| ModelError(e.to_string()))?;
        self.write(s, &command, ctx);
        Ok(())
    }
}

/// `who` of DER `k` (0-based) in descriptions: `DER 1 (wind)`.
fn who(k: usize, entry: &DerEntry) -> String {
    format!("DER {} ({})", k + 1, entry.name)
}

impl ParamVars {
    /// The operator's own parameters (before the DERs'), with the start values of `start`.
    fn declare(v: &mut Variables, start: &Params) -> ParamVars {
        ParamVars {
            s_base: v.real(
                Spec::parameter("S_base", start.s_base, "MVA", "system base power").min(1e-3),
            ),
            s_dvpp: v.real(
                Spec::parameter(
                    ports::S_DVPP,
                    start.s_dvpp,
                    "MVA",
                    "DVPP base power T_des is specified on",
                )
                .min(1e-3),
            ),
            h: v.real(
                Spec::parameter(
                    ports::TDES_H,
                    start.h,
                    "s",
                    "virtual inertia of T_pf = 1/(H s + D)",
                )
                .min(1e-6),
            ),
            d: v.real(
                Spec::parameter(
                    ports::TDES_D,
                    start.d,
                    "pu",
                    "damping of T_pf = 1/(H s + D)",
                )
                .min(1e-6),
            ),
            dq: v.real(
                Spec::parameter(ports::TDES_DQ, start.dq, "pu", "q-v droop: T_qv = Dq").min(1e-9),
            ),
            mu_min: v.real(
                Spec::parameter(
                    "mu_min",
                    start.mu_min,
                    "1",
                    "lower bound of a grid-forming low-pass unit's active dc gain (a unit of rating S_i below 0.2 S_dvpp: mu_min S_i/(0.2 S_dvpp))",
                )
                .range(0.0, 0.3),
            ),
            rate_limit: v.real(Spec::parameter(
                "rate_limit",
                start.rate_limit,
                "1/s",
                "largest change of a dc gain per second (0: none)",
            )),
            delay: v.real(Spec::parameter(
                "delay",
                start.delay,
                "s",
                "communication delay of the dc gains (0: none)",
            )),
        }
    }
}

impl DerVars {
    /// Every DER's rating and inputs, DER by DER (the gains follow all of them).
    fn declare_inputs(v: &mut Variables, config: &OperatorConfig) -> Vec<DerVars> {
        let mut ders = Vec::with_capacity(config.ders.len());
        for (k, entry) in config.ders.iter().enumerate() {
            let who = who(k, entry);
            let input = |v: &mut Variables, name: String, start: f64, what: String| {
                v.real(Spec::input(&name, start, "pu", &what))
            };
            let s_rated = v.real(
                Spec::parameter(
                    &ports::der_s_rated(k + 1),
                    entry.s_rated,
                    "MVA",
                    &format!("converter rating of {who}"),
                )
                .min(1e-3),
            );
            let p_avail = input(
                v,
                ports::der_p_avail(k + 1),
                entry.s_rated / 200.0,
                format!("available active power of {who}, on S_base"),
            );
            let p = input(
                v,
                ports::der_p(k + 1),
                0.0,
                format!("active power of {who}, on S_base (for its PQ capability)"),
            );
            let p_set = input(
                v,
                ports::der_p_set(k + 1),
                0.0,
                format!(
                    "active set point of {who}, on S_base: a change of the DVPP's summed set point is not a disturbance of ref.df"
                ),
            );
            input(
                v,
                ports::der_q(k + 1),
                0.0,
                format!("reactive power of {who}, on S_base (monitoring)"),
            );
            ders.push(DerVars {
                s_rated,
                p_avail,
                p,
                p_set,
                mu_p: None,
                mu_q: Real(0),
                mu_p_lpf: Vec::new(),
            });
        }
        ders
    }

    /// Every DER's dc gains, DER by DER: `mu_p` (low-pass), `mu_q`, `mu_p_lpf[j]` (complement);
    /// at initialization they depend on every unit's availability and power.
    fn declare_gains(v: &mut Variables, config: &OperatorConfig, ders: &mut [DerVars]) {
        let deps: Vec<String> = (1..=config.ders.len())
            .flat_map(|k| [ports::der_p_avail(k), ports::der_p(k)])
            .collect();
        let deps: Vec<&str> = deps.iter().map(String::as_str).collect();
        let lpf: Vec<usize> = config.params().low_pass().collect();
        let gain = |v: &mut Variables, name: &str, what: &str| {
            v.real(Spec::output(name, "1", what).initial_dependencies(&deps))
        };
        for (k, entry) in config.ders.iter().enumerate() {
            let who = who(k, entry);
            if entry.role == Role::LowPass {
                ders[k].mu_p = Some(gain(
                    v,
                    &ports::der_mu_p(k + 1),
                    &format!("active ADPF dc gain of {who}"),
                ));
            }
            ders[k].mu_q = gain(
                v,
                &ports::der_mu_q(k + 1),
                &format!("reactive ADPF dc gain of {who}"),
            );
            if entry.role == Role::Complement {
                ders[k].mu_p_lpf = lpf
                    .iter()
                    .enumerate()
                    .map(|(j, &l)| {
                        let what = format!(
                            "active dc gain of low-pass DER {} ({}) that {who} complements",
                            l + 1,
                            config.ders[l].name
                        );
                        gain(v, &ports::der_mu_p_lpf(k + 1, j + 1), &what)
                    })
                    .collect();
            }
        }
    }
}

impl PccVars {
    /// The PCC's inputs, the desired response and the participation checks.
    fn declare(v: &mut Variables) -> PccVars {
        let input = |v: &mut Variables, name: &str, start: f64, what: &str| {
            v.real(Spec::input(name, start, "pu", what))
        };
        let out = |v: &mut Variables, name: &str, unit: &str, what: &str| {
            v.real(Spec::output(name, unit, what))
        };
        PccVars {
            p: input(
                v,
                ports::PCC_P,
                0.0,
                "DVPP active power at the PCC, on S_base",
            ),
            q: input(
                v,
                ports::PCC_Q,
                0.0,
                "DVPP reactive power at the PCC, on S_base",
            ),
            f: input(v, ports::PCC_F, 1.0, "PCC frequency, pu of f_nom"),
            v: input(v, ports::PCC_V, 1.0, "PCC voltage magnitude"),
            ref_df: out(
                v,
                ports::REF_DF,
                "pu",
                "desired frequency deviation -T_pf Δp_pcc, pu of f_nom",
            ),
            ref_dv: out(
                v,
                ports::REF_DV,
                "pu",
                "desired voltage deviation -T_qv Δq_pcc",
            ),
            err_df: out(
                v,
                ports::ERR_DF,
                "pu",
                "measured minus desired frequency deviation",
            ),
            err_dv: out(
                v,
                ports::ERR_DV,
                "pu",
                "measured minus desired voltage deviation",
            ),
            sum_mu_p: out(
                v,
                "check.sum_mu_p",
                "1",
                "Σ μ_p over the low-pass units as sent (participation: 1)",
            ),
            sum_mu_q: out(
                v,
                "check.sum_mu_q",
                "1",
                "Σ μ_q over all units as sent (participation: 1)",
            ),
        }
    }
}

impl PocsVars {
    /// Declare the variables of `n` POCs and the rotation (start `rx`).
    fn declare(v: &mut Variables, n: usize, rx: f64) -> PocsVars {
        let rot_rx = v.real(
            Spec::parameter(
                ports::ROT_RX,
                rx,
                "1",
                "R/X of the DVPP area's lines the POC powers are rotated for: p' = (p - rx q)/sqrt(1 + rx^2) (0 = plain p, classical p-f)",
            )
            .range(0.0, 20.0),
        );
        let mut vars = Vec::with_capacity(n);
        for k in 1..=n {
            let input = |v: &mut Variables, name: String, start: f64, what: &str| {
                v.real(Spec::input(&name, start, "pu", &format!("POC {k}: {what}")))
            };
            let p = input(
                v,
                ports::poc_p(k),
                0.0,
                "active power the DVPP area sends through the POC, on S_base",
            );
            let q = input(
                v,
                ports::poc_q(k),
                0.0,
                "reactive power the DVPP area sends through the POC, on S_base",
            );
            let f = input(v, ports::poc_f(k), 1.0, "frequency, pu of f_nom");
            input(v, ports::poc_v(k), 1.0, "voltage magnitude (monitoring)");
            let err_df = v.real(Spec::output(
                &ports::poc_err_df(k),
                "pu",
                &format!(
                    "POC {k}: measured minus desired frequency deviation (poc[{k}].f - 1) - ref.df"
                ),
            ));
            vars.push(PocVars { p, q, f, err_df });
        }
        let load = (
            v.real(Spec::input(
                ports::AREA_P_LOAD,
                0.0,
                "pu",
                "active power the loads inside the DVPP area draw, on S_base (its change is added to the POC powers: a load step inside the area is not the DVPP's response)",
            )),
            v.real(Spec::input(
                ports::AREA_Q_LOAD,
                0.0,
                "pu",
                "reactive power the loads inside the DVPP area draw, on S_base",
            )),
        );
        let dp = v.real(Spec::output(
            ports::POC_DP,
            "pu",
            "input of T_pf: rotated POC power deviation sum_k dp'_poc,k plus the rotated change of the area's load, less the rotated set-point change, on S_dvpp",
        ));
        PocsVars {
            rot_rx,
            vars,
            load,
            dp,
        }
    }
}

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Operator>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
