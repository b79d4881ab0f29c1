//! Phasor relations between a converter's internal voltage and its terminal quantities.

/// Power `p + j q` a source `E∠θ` injects through `R + jX` into a bus at `V∠φ` (all per unit).
pub fn injection(e: f64, theta: f64, v: f64, phi: f64, r: f64, x: f64) -> (f64, f64) {
    let (dr, di) = (
        e * dvpp_math::cos(theta) - v * dvpp_math::cos(phi),
        e * dvpp_math::sin(theta) - v * dvpp_math::sin(phi),
    );
    let z2 = r * r + x * x;
    let (ir, ii) = ((dr * r + di * x) / z2, (di * r - dr * x) / z2);
    let (vr, vi) = (v * dvpp_math::cos(phi), v * dvpp_math::sin(phi));
    (vr * ir + vi * ii, vi * ir - vr * ii)
}

/// The internal voltage `(E, θ)` behind `R + jX` that injects `p + j q` into a bus at `V∠φ`.
pub fn internal_voltage(p: f64, q: f64, v: f64, phi: f64, r: f64, x: f64) -> (f64, f64) {
    let (ir, ii) = (
        (p * dvpp_math::cos(phi) + q * dvpp_math::sin(phi)) / v,
        (p * dvpp_math::sin(phi) - q * dvpp_math::cos(phi)) / v,
    );
    let er = v * dvpp_math::cos(phi) + r * ir - x * ii;
    let ei = v * dvpp_math::sin(phi) + r * ii + x * ir;
    (dvpp_math::hypot(er, ei), dvpp_math::atan2(ei, er))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn internal_voltage_inverts_injection() {
        for &(p, q, v, phi) in &[
            (0.3, 0.1, 1.02, 0.16),
            (-0.2, 0.05, 0.98, -0.4),
            (0.0, 0.0, 1.0, 0.0),
        ] {
            let (e, th) = internal_voltage(p, q, v, phi, 0.03, 0.35);
            let (p2, q2) = injection(e, th, v, phi, 0.03, 0.35);
            assert!(
                (p - p2).abs() < 1e-13 && (q - q2).abs() < 1e-13,
                "{p} {q} -> {p2} {q2}"
            );
        }
    }
}
