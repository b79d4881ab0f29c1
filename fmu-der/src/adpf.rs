//! One channel's ADPF parameters (`adpf.p.*`, `adpf.q.*`): their declaration and the ADPF they build.

use crate::preset::AdpfDefaults;
use crate::{err, positive, AdpfKind, MAX_LPF};
use dvpp_control::{Adpf, LowPassSpec};
use fmi_export::{Integer, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};

/// Handles of one channel's ADPF shape parameters (`adpf.p.*` or `adpf.q.*`).
#[derive(Clone, Serialize, Deserialize)]
pub(crate) struct AdpfParams {
    prefix: String,
    pub(crate) kind: Integer,
    tau: Real,
    tau2: Real,
    order: Integer,
    order2: Integer,
    /// Complement only (p channel): share, number of closed units, their time constants, orders.
    pub(crate) share: Option<Real>,
    pub(crate) n_lpf: Option<Integer>,
    lpf_tau: Vec<Real>,
    lpf_order: Vec<Integer>,
}

impl AdpfParams {
    pub(crate) fn declare(v: &mut Variables, ch: &str, d: &AdpfDefaults, complement: bool) -> Self {
        let prefix = format!("adpf.{ch}");
        let what = if ch == "p" { "p-f" } else { "v-q" };
        let kinds = if complement {
            "0 static, 1 low-pass, 2 high-pass, 3 band-pass, 4 complement of low-pass units"
        } else {
            "0 static, 1 low-pass, 2 high-pass, 3 band-pass"
        };
        let kind = v.integer(
            Spec::parameter(
                &format!("{prefix}.kind"),
                d.kind.code(),
                "",
                &format!("ADPF shape of the {what} channel: {kinds}"),
            )
            .range(0.0, if complement { 4.0 } else { 3.0 }),
        );
        let tau = v.real(
            Spec::parameter(
                &format!("{prefix}.tau"),
                d.tau,
                "s",
                &format!("{what} ADPF time constant (low-pass, high-pass; slow one of band-pass)"),
            )
            .min(0.0),
        );
        let tau2 = v.real(
            Spec::parameter(
                &format!("{prefix}.tau2"),
                d.tau2,
                "s",
                &format!("{what} ADPF fast time constant of a band-pass (< tau)"),
            )
            .min(0.0),
        );
        let order = v.integer(
            Spec::parameter(
                &format!("{prefix}.order"),
                d.order,
                "",
                &format!("{what} ADPF order d (of the tau factor)"),
            )
            .range(1.0, 8.0),
        );
        let order2 = v.integer(
            Spec::parameter(
                &format!("{prefix}.order2"),
                d.order2,
                "",
                &format!("{what} ADPF order of the tau2 factor of a band-pass"),
            )
            .range(1.0, 8.0),
        );
        let (mut share, mut n_lpf, mut lpf_tau, mut lpf_order) = (None, None, vec![], vec![]);
        if complement {
            share = Some(
                v.real(
                    Spec::parameter(
                        &format!("{prefix}.share"),
                        1.0,
                        "1",
                        "complement: total participation c it closes, m = c - sum of the low-pass factors",
                    )
                    .range(0.0, 1.0),
                ),
            );
            n_lpf = Some(
                v.integer(
                    Spec::parameter(
                        &format!("{prefix}.n_lpf"),
                        d.lpf_tau.len() as i32,
                        "",
                        "complement: number of low-pass units it closes (gains from mu_p_lpf[k])",
                    )
                    .range(0.0, MAX_LPF as f64),
                ),
            );
            for k in 1..=MAX_LPF {
                lpf_tau.push(
                    v.real(
                        Spec::parameter(
                            &format!("{prefix}.lpf[{k}].tau"),
                            d.lpf_tau.get(k - 1).copied().unwrap_or(1.0),
                            "s",
                            &format!("complement: time constant of low-pass unit {k}"),
                        )
                        .min(0.0),
                    ),
                );
                lpf_order.push(
                    v.integer(
                        Spec::parameter(
                            &format!("{prefix}.lpf[{k}].order"),
                            1,
                            "",
                            &format!("complement: order of low-pass unit {k}"),
                        )
                        .range(1.0, 8.0),
                    ),
                );
            }
        }
        AdpfParams {
            prefix,
            kind,
            tau,
            tau2,
            order,
            order2,
            share,
            n_lpf,
            lpf_tau,
            lpf_order,
        }
    }

    pub(crate) fn name(&self, field: &str) -> String {
        format!("{}.{field}", self.prefix)
    }

    /// The ADPF these parameters describe, with dc gain `mu` (static, low-pass) or the closed
    /// units' gains `lpf_mu` (complement).
    pub(crate) fn build(&self, s: &Store, mu: f64, lpf_mu: &[f64]) -> Result<Adpf, ModelError> {
        let order = |i: Integer| s[i] as u32;
        let wrap = |field: &str| {
            let name = self.name(field);
            move |e: dvpp_control::DvppError| err(&name, e)
        };
        match self.kind(s)? {
            AdpfKind::Static => Adpf::static_gain(mu).map_err(wrap("kind")),
            AdpfKind::LowPass => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                Adpf::low_pass(mu, tau, order(self.order)).map_err(wrap("tau"))
            }
            AdpfKind::HighPass => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                Adpf::high_pass(tau, order(self.order)).map_err(wrap("tau"))
            }
            AdpfKind::BandPass => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                let tau2 = positive(s, self.tau2, &self.name("tau2"))?;
                if tau2 >= tau {
                    return Err(err(
                        &self.name("tau2"),
                        format!("= {tau2}: a band-pass needs tau2 < tau = {tau}"),
                    ));
                }
                Adpf::band_pass(tau, tau2, order(self.order), order(self.order2))
                    .map_err(wrap("tau2"))
            }
            AdpfKind::Complement => {
                let (Some(share), Some(n_lpf)) = (self.share, self.n_lpf) else {
                    return Err(err(
                        &self.name("kind"),
                        format!("= {}: a complement closes p-f units only", s[self.kind]),
                    ));
                };
                let share = s[share];
                if share <= 0.0 {
                    return Err(err(&self.name("share"), format!("= {share}: must be > 0")));
                }
                let n = s[n_lpf] as usize;
                let mut specs = Vec::with_capacity(n);
                for (k, (&mu, (&tau, &ord))) in lpf_mu
                    .iter()
                    .zip(self.lpf_tau.iter().zip(&self.lpf_order))
                    .take(n)
                    .enumerate()
                {
                    let name = format!("{}.lpf[{}].tau", self.prefix, k + 1);
                    let tau = positive(s, tau, &name)?;
                    specs.push(LowPassSpec {
                        mu,
                        tau,
                        order: order(ord),
                    });
                }
                let sum: f64 = lpf_mu[..n].iter().sum();
                if sum > share + 1e-9 {
                    return Err(err(
                        "mu_p_lpf",
                        format!("the closed units' dc gains sum to {sum} > share {share}"),
                    ));
                }
                Adpf::complement_of_specs(share, specs).map_err(wrap("n_lpf"))
            }
        }
    }

    /// The ADPF's kind, or an error naming `adpf.*.kind` if its code is none.
    pub(crate) fn kind(&self, s: &Store) -> Result<AdpfKind, ModelError> {
        AdpfKind::from_code(s[self.kind]).map_err(|e| err(&self.name("kind"), e))
    }
}
