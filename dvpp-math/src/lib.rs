//! Transcendental functions from one implementation built into every binary, so that a scenario gives the same bits on every CPU and platform.
//!
//! `f64::sin`, `f64::exp`, `f64::hypot`, … call the platform's C library, which picks its code
//! path by CPU (with FMA or without) and differs between glibc (linux64) and the MinGW/msvcrt
//! runtime (win64): the last bits of a result moved from one machine to the next, and a
//! closed loop carries them into every figure. Everything here is the `libm` crate (a port of
//! musl's libm in plain Rust, compiled into the binary, no run-time CPU dispatch) and the complex
//! functions built on it. The workspace's `clippy.toml` forbids the platform's versions, and the
//! tests check that no shipped binary imports one (docs/architecture.md, "Determinism").
//!
//! What is exact anyway and stays as it is: `+ - * /`, `sqrt`, `abs`, `floor`, `round`, `%`
//! (IEEE 754 correctly rounded or exact everywhere). `f64::powi` is not: on linux64 LLVM
//! lowers it to compiler-builtins' multiplication loop, on win64 (an MSVCRT target) to a call of
//! the runtime's `pow`, which rounds once where the loop rounds at every product. [`powi`] is
//! the loop, written out.

pub use libm::{
    acos, asin, atan, atan2, cbrt, cos, cosh, exp, exp2, expm1, fma, hypot, log, log10, log1p,
    log2, pow, sin, sincos, sinh, tan, tanh,
};

use nalgebra::Complex;

/// `x^n` by squaring and multiplying (the loop of compiler-builtins' `__powidf2`), the same
/// products in the same order on every platform; replaces `f64::powi`.
pub fn powi(x: f64, n: i32) -> f64 {
    let (mut base, mut e, mut r) = (x, n.unsigned_abs(), 1.0);
    loop {
        if e & 1 == 1 {
            r *= base;
        }
        e >>= 1;
        if e == 0 {
            break;
        }
        base *= base;
    }
    if n < 0 {
        1.0 / r
    } else {
        r
    }
}

/// `|z|` without overflow (`hypot`); replaces `Complex::norm`.
pub fn cabs(z: Complex<f64>) -> f64 {
    hypot(z.re, z.im)
}

/// The argument of `z` in `(-π, π]` (`atan2`); replaces `Complex::arg`.
pub fn carg(z: Complex<f64>) -> f64 {
    atan2(z.im, z.re)
}

/// `r e^{jθ}`; replaces `Complex::from_polar`.
pub fn cpolar(r: f64, theta: f64) -> Complex<f64> {
    let (s, c) = sincos(theta);
    Complex::new(r * c, r * s)
}

/// `e^{jθ}`, the unit phasor at angle `θ`; replaces `Complex::cis`.
pub fn cis(theta: f64) -> Complex<f64> {
    cpolar(1.0, theta)
}

/// `e^z`; replaces `Complex::exp`.
pub fn cexp(z: Complex<f64>) -> Complex<f64> {
    cpolar(exp(z.re), z.im)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bits of a few values of each function, as this crate computed them when they were
    /// written down (glibc gives the same for these, all correctly rounded). They hold on every
    /// CPU and platform, since no platform code is called; a change here means a `libm` update
    /// changed results, which moves the committed result digests too (tests/digests).
    #[test]
    fn the_same_bits_everywhere() {
        let cases: [(&str, f64, u64); 12] = [
            ("sin", sin(0.7), 0x3fe49d6e694619b8),
            ("cos", cos(0.7), 0x3fe87996529f9d93),
            ("tan", tan(1.3), 0x400cd11b1696e97e),
            ("exp", exp(-0.37), 0x3fe61a7ee209faff),
            ("expm1", expm1(-1e-3), 0xbf50603521cac48c),
            ("log", log(3.7), 0x3ff4eeee650ae550),
            ("log10", log10(0.0042), 0xc0030395e043e2f1),
            ("log2", log2(1e-3), 0xc023ee7b471b3a95),
            ("pow", pow(10.0, -2.6), 0x3f6493cec2631f18),
            ("hypot", hypot(0.3, 1.1), 0x3ff23e2896280f23),
            ("atan2", atan2(-0.2, -1.4), 0xc007ff6067fcc98a),
            ("cabs", cabs(Complex::new(3e200, 4e200)), 0x699a20df0dcd3af0),
        ];
        for (name, v, bits) in cases {
            assert_eq!(v.to_bits(), bits, "{name}: {v:e} = {:#018x}", v.to_bits());
        }
    }

    #[test]
    fn powi_is_the_multiplication_loop() {
        assert_eq!(powi(1.7, 0), 1.0);
        assert_eq!(powi(1.7, 1), 1.7);
        assert_eq!(powi(1.7, 2), 1.7 * 1.7);
        assert_eq!(powi(1.7, 3), 1.7 * (1.7 * 1.7));
        assert_eq!(powi(1.7, 5), 1.7 * ((1.7 * 1.7) * (1.7 * 1.7)));
        assert_eq!(powi(2.0, -3), 0.125);
        assert_eq!(powi(10.0, -300), 1.0 / powi(10.0, 300));
    }

    #[test]
    fn complex_functions_agree_with_their_definitions() {
        let z = Complex::new(-0.6, 0.8);
        assert_eq!(cabs(z), 1.0);
        assert!((carg(z) - (std::f64::consts::PI - atan2(0.8, 0.6))).abs() < 1e-15);
        let w = cpolar(2.0, 0.3);
        assert!((cabs(w) - 2.0).abs() < 1e-15 && (carg(w) - 0.3).abs() < 1e-15);
        let e = cexp(Complex::new(0.5, std::f64::consts::FRAC_PI_2));
        assert!(e.re.abs() < 1e-15 && (e.im - exp(0.5)).abs() < 1e-15);
        assert_eq!(cis(0.0), Complex::new(1.0, 0.0));
    }
}
