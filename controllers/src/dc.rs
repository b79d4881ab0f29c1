//! The dc-voltage control's damping term, which the phasor DER's dc model and the EMT controller share.

/// The gain `k_d` of the capacitor-power term that gives the loop of the dc-voltage control
/// (`k_dc` through the source lag `tau` on the link `c`, `g`) the damping ratio `zeta` (0 when it
/// has that much without it); the phasor DER's dc model and the EMT controller use it alike.
pub fn damping_gain(tau: f64, c: f64, g: f64, k_dc: f64, zeta: f64) -> f64 {
    let k_e = k_dc / c;
    let g = 2.0 * g / c;
    (2.0 * zeta * (k_e * tau).sqrt() - 1.0 - tau * g).max(0.0)
}
