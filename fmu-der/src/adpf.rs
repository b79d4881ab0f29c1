//! One channel's ADPF parameters (`adpf.p.*`, `adpf.q.*`): their declaration and their values as `dvpp_controllers::AdpfParams`.

use crate::preset::AdpfDefaults;
use crate::{err, AdpfKind, MAX_LPF};
use dvpp_controllers::{AdpfChannel, AdpfParams, ComplementParams};
use fmi_export::{Integer, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};

/// Handles of one channel's ADPF shape parameters (`adpf.p.*` or `adpf.q.*`).
#[derive(Clone, Serialize, Deserialize)]
pub(crate) struct AdpfVars {
    channel: AdpfChannel,
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

impl AdpfVars {
    pub(crate) fn declare(v: &mut Variables, ch: &str, d: &AdpfDefaults, complement: bool) -> Self {
        let channel = if ch == "p" {
            AdpfChannel::P
        } else {
            AdpfChannel::Q
        };
        let prefix = channel.prefix();
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
        AdpfVars {
            channel,
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

    /// The channel's parameters as they are now; an unknown `adpf.*.kind` code is refused by name.
    pub(crate) fn read(&self, s: &Store) -> Result<AdpfParams, ModelError> {
        let complement = match (self.share, self.n_lpf) {
            (Some(share), Some(n_lpf)) => {
                let mut c = ComplementParams {
                    share: s[share],
                    n_lpf: s[n_lpf] as usize,
                    lpf_tau: [0.0; MAX_LPF],
                    lpf_order: [0; MAX_LPF],
                };
                for k in 0..MAX_LPF {
                    c.lpf_tau[k] = s[self.lpf_tau[k]];
                    c.lpf_order[k] = s[self.lpf_order[k]] as u32;
                }
                Some(c)
            }
            _ => None,
        };
        Ok(AdpfParams {
            channel: self.channel,
            kind: self.kind(s)?,
            tau: s[self.tau],
            tau2: s[self.tau2],
            order: s[self.order] as u32,
            order2: s[self.order2] as u32,
            complement,
        })
    }

    /// The ADPF's kind, or an error naming `adpf.*.kind` if its code is none.
    pub(crate) fn kind(&self, s: &Store) -> Result<AdpfKind, ModelError> {
        AdpfKind::from_code(s[self.kind])
            .map_err(|e| err(&format!("{}.kind", self.channel.prefix()), e))
    }
}
