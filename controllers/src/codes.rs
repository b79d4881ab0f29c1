//! The integer codes of the DVPP units' parameters (`mode`, `adpf.*.kind`) as enums, converted once from the parameters.

/// How the unit connects: the `mode` parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Mode {
    /// `mode` = 1: imposes its internal voltage, `Δf = -T_pf/m Δp`.
    GridForming,
    /// `mode` = 2: a PLL measures `Δf`, the converter injects `Δp = -m T_pf^-1 Δf`.
    GridFollowing,
}

impl Mode {
    /// All modes, in code order.
    pub const ALL: [Mode; 2] = [Mode::GridForming, Mode::GridFollowing];

    /// The `mode` parameter's value.
    pub const fn code(self) -> i32 {
        match self {
            Mode::GridForming => 1,
            Mode::GridFollowing => 2,
        }
    }

    /// The mode of a `mode` value, or why there is none.
    pub fn from_code(code: i32) -> Result<Mode, String> {
        Mode::ALL
            .into_iter()
            .find(|m| m.code() == code)
            .ok_or_else(|| format!("= {code}: 1 grid-forming, 2 grid-following"))
    }
}

/// The shape of an ADPF: the `adpf.p.kind` and `adpf.q.kind` parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AdpfKind {
    /// 0: `m = μ`.
    Static,
    /// 1: `m = μ/(τ s + 1)^d`.
    LowPass,
    /// 2: `m = τ s/(τ s + 1)^d`.
    HighPass,
    /// 3: `m = (τ₁ - τ₂) s/((τ₁ s + 1)^d₁ (τ₂ s + 1)^d₂)`.
    BandPass,
    /// 4 (p channel only): `m = c - Σ_j μ_j/(τ_j s + 1)^d_j`.
    Complement,
}

impl AdpfKind {
    /// All kinds, in code order.
    pub const ALL: [AdpfKind; 5] = [
        AdpfKind::Static,
        AdpfKind::LowPass,
        AdpfKind::HighPass,
        AdpfKind::BandPass,
        AdpfKind::Complement,
    ];

    /// The `adpf.*.kind` parameter's value.
    pub const fn code(self) -> i32 {
        match self {
            AdpfKind::Static => 0,
            AdpfKind::LowPass => 1,
            AdpfKind::HighPass => 2,
            AdpfKind::BandPass => 3,
            AdpfKind::Complement => 4,
        }
    }

    /// The kind of an `adpf.*.kind` value, or why there is none.
    pub fn from_code(code: i32) -> Result<AdpfKind, String> {
        AdpfKind::ALL
            .into_iter()
            .find(|k| k.code() == code)
            .ok_or_else(|| {
                format!("= {code}: 0 static, 1 low-pass, 2 high-pass, 3 band-pass, 4 complement")
            })
    }

    /// Whether the shape has a dc gain `μ` the operator sets (`mu_p`, `mu_q`): static and
    /// low-pass; a complement's gains are those of the units it closes (`mu_p_lpf`).
    pub const fn has_dc_gain(self) -> bool {
        match self {
            AdpfKind::Static | AdpfKind::LowPass => true,
            AdpfKind::HighPass | AdpfKind::BandPass | AdpfKind::Complement => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_unknown_codes_are_refused() {
        for m in Mode::ALL {
            assert_eq!(Mode::from_code(m.code()), Ok(m));
        }
        for k in AdpfKind::ALL {
            assert_eq!(AdpfKind::from_code(k.code()), Ok(k));
        }
        assert!(Mode::from_code(0).unwrap_err().contains("1 grid-forming"));
        assert!(AdpfKind::from_code(5).unwrap_err().contains("4 complement"));
        assert!(AdpfKind::from_code(-1).is_err());
    }
}
