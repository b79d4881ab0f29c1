//! DER kinds as independent presets and a fleet of named units as a value: case study I's fleet, defined once.
//!
//! A [`DerKind`] is what one unit is on its own (rating, dc side, dispatch, p-f ADPF shape);
//! nothing in it depends on other units. What does depend on the other units (the low-pass
//! units' nominal dc gains, the reactive shares, which low-pass units a complement closes)
//! follows from a [`Fleet`], so adding a unit to a fleet changes that fleet's values and
//! nothing else: every kind keeps its values, and so does every other fleet.

use crate::adaptation::{active_gains, renormalize_with_floor};
use crate::local::MU_MIN_GFM;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The p-f ADPF shape of a unit in a fleet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// A low-pass with `τ` = the unit's `τ_dc` and dc gain its share of the fleet's low-pass
    /// ratings (floored, renormalized to sum 1).
    LowPass,
    /// The complement of the fleet's low-pass units (their time constants and dc gains).
    Complement,
}

/// A kind of DER on its own: rating, dc side, dispatch and p-f ADPF shape. Written and read
/// by its name (one of [`KINDS`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DerKind {
    /// What `[model] preset` names it.
    pub name: &'static str,
    /// Rating, MVA.
    pub s_rated: f64,
    /// Time constant of the dc source, s (a low-pass unit's ADPF `τ` too).
    pub tau_dc: f64,
    /// Dispatch, pu on S_base.
    pub p: f64,
    /// Available power, pu on S_base.
    pub p_avail0: f64,
    /// The primary source can absorb power (a battery): dc source within ±P_avail.
    pub storage: bool,
    /// The p-f ADPF.
    pub shape: Shape,
}

/// Case study I's wind unit (`docs/control.md` §9).
pub const WIND: DerKind = DerKind {
    name: "wind",
    s_rated: 46.0,
    tau_dc: 1.5,
    p: 0.2,
    p_avail0: 0.4,
    storage: false,
    shape: Shape::LowPass,
};

/// Case study I's PV unit.
pub const PV: DerKind = DerKind {
    name: "pv",
    s_rated: 73.0,
    tau_dc: 0.6,
    p: 0.3,
    p_avail0: 0.6,
    storage: false,
    shape: Shape::LowPass,
};

/// Case study I's battery: the complement of the low-pass units.
pub const BESS: DerKind = DerKind {
    name: "bess",
    s_rated: 60.0,
    tau_dc: 0.2,
    p: 0.1,
    p_avail0: 0.6,
    storage: true,
    shape: Shape::Complement,
};

/// Every DER kind (`[model] preset` of the DER FMU). A new kind is one more entry: it changes
/// no other kind's values.
pub const KINDS: &[DerKind] = &[WIND, PV, BESS];

impl DerKind {
    /// The kind called `name`, or why there is none.
    pub fn named(name: &str) -> Result<&'static DerKind, String> {
        KINDS.iter().find(|k| k.name == name).ok_or_else(|| {
            let names: Vec<_> = KINDS.iter().map(|k| format!("\"{}\"", k.name)).collect();
            format!("unknown preset \"{name}\": {}", names.join(", "))
        })
    }
}

impl Serialize for DerKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name)
    }
}

impl<'de> Deserialize<'de> for &'static DerKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        DerKind::named(&name).map_err(serde::de::Error::custom)
    }
}

impl<'de> Deserialize<'de> for DerKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        <&'static DerKind>::deserialize(d).copied()
    }
}

/// A unit of a fleet: its name and its kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FleetUnit {
    /// The unit's name in its DVPP (a component name: `wind`, `pv_gfl`, ...).
    pub name: String,
    /// What the unit is.
    pub kind: DerKind,
}

/// The units of a DVPP, named, in order. The values that depend on the other units follow
/// from it: [`Fleet::nominal_active_gains`], [`Fleet::reactive_share`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fleet {
    /// The units, in the DVPP's order.
    pub units: Vec<FleetUnit>,
}

impl Fleet {
    /// Units of the given kinds, each named as its kind.
    pub fn of(kinds: &[DerKind]) -> Fleet {
        Fleet {
            units: kinds
                .iter()
                .map(|k| FleetUnit {
                    name: k.name.into(),
                    kind: *k,
                })
                .collect(),
        }
    }

    /// Case study I: wind and PV low-pass, the BESS their complement (the one definition the
    /// operator's, the EMT plant's and the DER presets' defaults and the tests read).
    pub fn case_study_i() -> Fleet {
        Fleet::of(&[WIND, PV, BESS])
    }

    /// This fleet with one more unit.
    pub fn with(mut self, name: &str, kind: DerKind) -> Fleet {
        self.units.push(FleetUnit {
            name: name.into(),
            kind,
        });
        self
    }

    /// The unit named `name`, by index.
    pub fn position(&self, name: &str) -> Option<usize> {
        self.units.iter().position(|u| u.name == name)
    }

    /// The first unit of kind `kind` (by its name), by index.
    pub fn position_of_kind(&self, kind: &DerKind) -> Option<usize> {
        self.units.iter().position(|u| u.kind.name == kind.name)
    }

    /// Sum of the ratings, MVA.
    pub fn total_rating(&self) -> f64 {
        self.units.iter().map(|u| u.kind.s_rated).sum()
    }

    /// The indices of the low-pass units, in order.
    pub fn low_pass(&self) -> Vec<usize> {
        (0..self.units.len())
            .filter(|&k| self.units[k].kind.shape == Shape::LowPass)
            .collect()
    }

    /// The low-pass units' nominal dc gains, in the order of [`Fleet::low_pass`]: proportional
    /// to their ratings, floored at [`MU_MIN_GFM`] (grid-forming units) and renormalized to
    /// sum 1.
    pub fn nominal_active_gains(&self) -> Vec<f64> {
        let ratings: Vec<f64> = self
            .low_pass()
            .iter()
            .map(|&k| self.units[k].kind.s_rated)
            .collect();
        let raw = active_gains(&ratings).unwrap_or_else(|_| vec![0.0; ratings.len()]);
        renormalize_with_floor(&raw, &vec![true; ratings.len()], MU_MIN_GFM)
            .expect("nominal gains are feasible")
    }

    /// Unit `k`'s static reactive dc gain: its share of the fleet's ratings (its reactive
    /// capacity at zero active power).
    pub fn reactive_share(&self, k: usize) -> f64 {
        self.units[k].kind.s_rated / self.total_rating()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_study_one_is_wind_pv_low_pass_and_the_bess_complement() {
        let f = Fleet::case_study_i();
        assert_eq!(f.low_pass(), vec![0, 1]);
        assert_eq!(f.total_rating(), 179.0);
        let mu = f.nominal_active_gains();
        assert_eq!(mu[..], crate::CaseStudyI::new().nominal_active_gains()[..]);
        assert_eq!(f.reactive_share(2), 60.0 / 179.0);
    }

    /// A fourth unit is a fleet's business: its gains and shares change, the kinds do not.
    #[test]
    fn a_fourth_unit_changes_its_fleet_s_shares_and_no_kind() {
        let hydro = DerKind {
            name: "hydro",
            s_rated: 40.0,
            tau_dc: 5.0,
            p: 0.1,
            p_avail0: 0.3,
            storage: false,
            shape: Shape::LowPass,
        };
        let before = (WIND, PV, BESS);
        let four = Fleet::case_study_i().with("hydro", hydro);
        assert_eq!(four.low_pass(), vec![0, 1, 3]);
        assert_eq!(four.nominal_active_gains().len(), 3);
        assert_ne!(
            four.nominal_active_gains()[..2],
            Fleet::case_study_i().nominal_active_gains()[..]
        );
        assert_eq!(four.reactive_share(2), 60.0 / 219.0);
        assert_eq!((WIND, PV, BESS), before);
    }

    #[test]
    fn unknown_kinds_are_named() {
        let e = DerKind::named("no_such_kind").unwrap_err();
        assert!(e.contains("no_such_kind") && e.contains("\"wind\""), "{e}");
    }
}
