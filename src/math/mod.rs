//! Small numeric building blocks shared by every stage: Gauss–Legendre quadrature, the
//! exponentially scaled Bessel function I0e (for azimuthally averaged lobes), compensated sums and
//! a deterministic PRNG and a content hash.
//!
//! Inputs: plain numbers. Outputs: plain numbers. Invariants: everything here is pure (no IO, no
//! global state) and f64; every function is finite for every finite input in its documented domain.

pub mod bessel;
pub mod quadrature;
pub mod rng;

pub use bessel::bessel_i0e;
pub use quadrature::GaussLegendre;
pub use rng::Rng;

/// Neumaier-compensated sum: exact to a few ulps for the long sums of small positive terms that the
/// direction set and the light tree add up (tens of thousands of texel solid angles).
pub fn compensated_sum(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut sum = 0.0f64;
    let mut compensation = 0.0f64;
    for v in values {
        let t = sum + v;
        if sum.abs() >= v.abs() {
            compensation += (sum - t) + v;
        } else {
            compensation += (v - t) + sum;
        }
        sum = t;
    }
    sum + compensation
}

/// FNV-1a, 64 bit: the content hash of bake inputs and cached tables (not cryptographic; a cache
/// also checks what it reads back).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compensated_sum_beats_naive_on_many_small_terms() {
        let n = 1_000_000;
        let term = 0.1f64;
        let exact = 100_000.0;
        let naive: f64 = (0..n).map(|_| term).sum();
        let compensated = compensated_sum((0..n).map(|_| term));
        assert!(
            (compensated - exact).abs() <= 1e-9,
            "compensated {compensated}"
        );
        assert!((naive - exact).abs() > (compensated - exact).abs());
    }
}
