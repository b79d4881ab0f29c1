//! The split of a scenario's DERs and their grid slots at `[dvpp] eps` into grid-forming and
//! grid-following parts.

use der_model::ports as der;

use super::{real, DerSpec};

/// DER parameters in power units that a split scales with the part (pu on S_base).
pub(super) const SPLIT_POWERS: [&str; 2] = [der::P_AVAIL0, "avail.dP"];

/// The parts of a unit split at `eps`: (name suffix, grid-forming, part); a part of zero is
/// left out.
fn parts(eps: f64) -> Vec<(&'static str, bool, f64)> {
    [("_gfm", true, eps), ("_gfl", false, 1.0 - eps)]
        .into_iter()
        .filter(|&(_, _, x)| x > 0.0)
        .collect()
}

/// The DERs split at `eps`, in the order of [`split_case`]'s slots: each part named after its
/// unit and form, its power-valued start values scaled, and a complement's share set to the part.
pub(super) fn split_ders(ders: &[DerSpec], eps: f64) -> Vec<DerSpec> {
    parts(eps)
        .into_iter()
        .flat_map(|(suffix, _, part)| {
            ders.iter().map(move |d| {
                let mut start = d.start.clone();
                for key in SPLIT_POWERS {
                    if let Some(x) = start.get(key).and_then(|v| v.as_float()) {
                        start.insert(key.into(), real(x * part));
                    }
                }
                start.entry("adpf.p.share").or_insert_with(|| real(part));
                // The preset's dc gains split like the unit (the operator sends the actual ones
                // from the first step; these keep the initialization consistent).
                let preset = d
                    .preset
                    .as_deref()
                    .and_then(|p| der_model::Preset::named(p).ok());
                if let Some(p) = preset {
                    let u = der_model::UnitDefaults::of(Some(p));
                    let gains = [
                        (der::MU_P.to_string(), u.mu_p),
                        (der::MU_Q.to_string(), u.mu_q),
                    ]
                    .into_iter()
                    .chain(
                        u.mu_p_lpf
                            .iter()
                            .enumerate()
                            .map(|(j, &m)| (der::mu_p_lpf(j + 1), m)),
                    );
                    for (key, mu) in gains {
                        start.entry(key).or_insert_with(|| real(mu * part));
                    }
                }
                DerSpec {
                    name: format!("{}{suffix}", d.name),
                    preset: d.preset.clone(),
                    dvpp: d.dvpp.clone(),
                    start,
                }
            })
        })
        .collect()
}

/// The grid case with every DER slot split into its grid-forming and grid-following parts
/// (ratings and dispatch scaled, the PCC's slot list following).
pub(super) fn split_case(case: &grid_model::Case, eps: f64, scale: f64) -> grid_model::Case {
    let mut out = case.clone();
    out.ders.clear();
    let mut new_index = vec![Vec::new(); case.ders.len()];
    for (&(suffix, forming, part), _) in parts(eps).iter().zip(0..) {
        for (k, slot) in case.ders.iter().enumerate() {
            let name = slot.name.clone().unwrap_or_else(|| format!("der{}", k + 1));
            out.ders.push(grid_model::DerSlot {
                name: Some(format!("{name}{suffix}")),
                kind: if forming {
                    grid_model::DerKind::GridForming
                } else {
                    grid_model::DerKind::GridFollowing
                },
                rating_mva: slot.rating_mva * part * scale,
                p_mw: slot.p_mw * part,
                q_mvar: slot.q_mvar * part,
                ..slot.clone()
            });
            new_index[k].push(out.ders.len());
        }
    }
    if let Some(pcc) = &mut out.pcc {
        pcc.slots = pcc
            .slots
            .iter()
            .flat_map(|&s| new_index.get(s - 1).cloned().unwrap_or_default())
            .collect();
    }
    out
}
