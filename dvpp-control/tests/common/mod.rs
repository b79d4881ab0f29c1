//! Shared helpers for the integration tests (deterministic PRNG).
#![allow(dead_code)]

/// xorshift64* generator: deterministic, dependency-free.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// Log-uniform in [lo, hi].
    pub fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        dvpp_math::exp(
            dvpp_math::log(lo) + (dvpp_math::log(hi) - dvpp_math::log(lo)) * self.uniform(),
        )
    }
    pub fn int(&mut self, lo: u32, hi_inclusive: u32) -> u32 {
        lo + (self.next_u64() % u64::from(hi_inclusive - lo + 1)) as u32
    }
    /// `n` non-negative numbers summing to `total`.
    pub fn simplex(&mut self, n: usize, total: f64) -> Vec<f64> {
        let w: Vec<f64> = (0..n).map(|_| self.range(0.01, 1.0)).collect();
        let s: f64 = w.iter().sum();
        w.iter().map(|x| total * x / s).collect()
    }
}
