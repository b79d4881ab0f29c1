//! One channel's ADPF parameters (`adpf.p.*`, `adpf.q.*`) as plain values, and the ADPF they build, checked.

use crate::{positive, AdpfKind, Error, MAX_LPF};
use dvpp_control::{Adpf, LowPassSpec};
use serde::{Deserialize, Serialize};

/// Which channel an ADPF shapes: its parameters are named `adpf.p.*` or `adpf.q.*`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AdpfChannel {
    /// The p-f channel, `adpf.p.*`.
    P,
    /// The v-q channel, `adpf.q.*`.
    Q,
}

impl AdpfChannel {
    /// The parameters' prefix, `adpf.p` or `adpf.q`.
    pub const fn prefix(self) -> &'static str {
        match self {
            AdpfChannel::P => "adpf.p",
            AdpfChannel::Q => "adpf.q",
        }
    }
}

/// A complement unit's parameters (p channel only): the participation it closes and the
/// low-pass units it closes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ComplementParams {
    /// `adpf.p.share`: the total participation `c`, `m = c - Σ_j μ_j/(τ_j s + 1)^d_j`.
    pub share: f64,
    /// `adpf.p.n_lpf`: how many of the units below it closes.
    pub n_lpf: usize,
    /// `adpf.p.lpf[k].tau`, `adpf.p.lpf[k].order`.
    pub lpf_tau: [f64; MAX_LPF],
    pub lpf_order: [u32; MAX_LPF],
}

/// One channel's ADPF shape (`adpf.p.*` or `adpf.q.*`); its dc gains come from the operator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AdpfParams {
    pub channel: AdpfChannel,
    /// `adpf.*.kind`.
    pub kind: AdpfKind,
    /// `adpf.*.tau`: low-pass, high-pass; the slow one of a band-pass.
    pub tau: f64,
    /// `adpf.*.tau2`: a band-pass's fast time constant (< `tau`).
    pub tau2: f64,
    /// `adpf.*.order`, `adpf.*.order2`.
    pub order: u32,
    pub order2: u32,
    /// The complement's parameters: declared by a p channel only.
    pub complement: Option<ComplementParams>,
}

impl AdpfParams {
    /// The name of the parameter `field` of this channel, e.g. `adpf.p.tau`.
    pub fn name(&self, field: &str) -> String {
        format!("{}.{field}", self.channel.prefix())
    }

    /// The number of low-pass units a complement closes (0 for any other shape's channel).
    pub fn n_lpf(&self) -> usize {
        self.complement.map_or(0, |c| c.n_lpf)
    }

    /// The complement's share (1 where there is none).
    pub fn share(&self) -> f64 {
        self.complement.map_or(1.0, |c| c.share)
    }

    /// The ADPF these parameters describe, with dc gain `mu` (static, low-pass) or the closed
    /// units' gains `lpf_mu` (complement); an error names the parameter at fault.
    pub fn build(&self, mu: f64, lpf_mu: &[f64]) -> Result<Adpf, Error> {
        let wrap = |field: &str| {
            let name = self.name(field);
            move |e: dvpp_control::DvppError| Error::field(&name, e)
        };
        match self.kind {
            AdpfKind::Static => Adpf::static_gain(mu).map_err(wrap("kind")),
            AdpfKind::LowPass => {
                let tau = positive(self.tau, &self.name("tau"))?;
                Adpf::low_pass(mu, tau, self.order).map_err(wrap("tau"))
            }
            AdpfKind::HighPass => {
                let tau = positive(self.tau, &self.name("tau"))?;
                Adpf::high_pass(tau, self.order).map_err(wrap("tau"))
            }
            AdpfKind::BandPass => {
                let tau = positive(self.tau, &self.name("tau"))?;
                let tau2 = positive(self.tau2, &self.name("tau2"))?;
                if tau2 >= tau {
                    return Err(Error::field(
                        &self.name("tau2"),
                        format!("= {tau2}: a band-pass needs tau2 < tau = {tau}"),
                    ));
                }
                Adpf::band_pass(tau, tau2, self.order, self.order2).map_err(wrap("tau2"))
            }
            AdpfKind::Complement => {
                let Some(c) = self.complement else {
                    return Err(Error::field(
                        &self.name("kind"),
                        format!("= {}: a complement closes p-f units only", self.kind.code()),
                    ));
                };
                let share = c.share;
                if share <= 0.0 {
                    return Err(Error::field(
                        &self.name("share"),
                        format!("= {share}: must be > 0"),
                    ));
                }
                let n = c.n_lpf;
                let mut specs = Vec::with_capacity(n);
                for (k, (&mu, (&tau, &order))) in lpf_mu
                    .iter()
                    .zip(c.lpf_tau.iter().zip(&c.lpf_order))
                    .take(n)
                    .enumerate()
                {
                    let name = format!("{}.lpf[{}].tau", self.channel.prefix(), k + 1);
                    let tau = positive(tau, &name)?;
                    specs.push(LowPassSpec { mu, tau, order });
                }
                let sum: f64 = lpf_mu[..n].iter().sum();
                if sum > share + 1e-9 {
                    return Err(Error::field(
                        "mu_p_lpf",
                        format!("the closed units' dc gains sum to {sum} > share {share}"),
                    ));
                }
                Adpf::complement_of_specs(share, specs).map_err(wrap("n_lpf"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn low_pass(tau: f64) -> AdpfParams {
        AdpfParams {
            channel: AdpfChannel::P,
            kind: AdpfKind::LowPass,
            tau,
            tau2: 0.1,
            order: 1,
            order2: 1,
            complement: None,
        }
    }

    #[test]
    fn an_error_names_the_parameter_at_fault() {
        let e = low_pass(-1.0).build(0.5, &[]).unwrap_err();
        assert_eq!(e.to_string(), "'adpf.p.tau' = -1: must be > 0");
        let band = AdpfParams {
            kind: AdpfKind::BandPass,
            channel: AdpfChannel::Q,
            ..low_pass(0.05)
        };
        let e = band.build(0.5, &[]).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("adpf.q.tau2"));
        let complement = AdpfParams {
            kind: AdpfKind::Complement,
            channel: AdpfChannel::Q,
            ..low_pass(1.0)
        };
        let e = complement.build(0.5, &[]).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("adpf.q.kind"));
        assert!(low_pass(1.0).build(0.5, &[]).is_ok());
    }

    #[test]
    fn a_complement_refuses_gains_above_its_share() {
        let mut c = ComplementParams {
            share: 0.5,
            n_lpf: 2,
            lpf_tau: [1.0; MAX_LPF],
            lpf_order: [1; MAX_LPF],
        };
        let p = |c| AdpfParams {
            kind: AdpfKind::Complement,
            complement: Some(c),
            ..low_pass(1.0)
        };
        assert!(p(c).build(0.0, &[0.2, 0.2]).is_ok());
        let e = p(c).build(0.0, &[0.3, 0.3]).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("mu_p_lpf"));
        c.lpf_tau[1] = 0.0;
        let e = p(c).build(0.0, &[0.2, 0.2]).unwrap_err();
        assert_eq!(e.to_string(), "'adpf.p.lpf[2].tau' = 0: must be > 0");
    }
}
