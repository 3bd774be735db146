//! A small deterministic PRNG (xoshiro256++ seeded through splitmix64) for tests, sampling and
//! Monte Carlo rendering. Inputs: a u64 seed. Outputs: uniform u64, f64 in [0, 1), uniform unit
//! vectors. Invariant: the same seed gives the same sequence on every platform and thread count.

use glam::DVec3;

/// xoshiro256++.
#[derive(Debug, Clone)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// Seeds the four words with splitmix64 so that any seed (0 too) gives a good state.
    pub fn new(seed: u64) -> Self {
        let mut z = seed;
        let mut next = || {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            x ^ (x >> 31)
        };
        Self {
            s: [next(), next(), next(), next()],
        }
    }

    /// Next uniform u64.
    pub fn next_u64(&mut self) -> u64 {
        let result = (self.s[0].wrapping_add(self.s[3]))
            .rotate_left(23)
            .wrapping_add(self.s[0]);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }

    /// A uniformly distributed unit vector on the sphere.
    pub fn unit_vector(&mut self) -> DVec3 {
        let z = 1.0 - 2.0 * self.next_f64();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * self.next_f64();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Two independent standard normal numbers (Box–Muller).
    pub fn gaussian_pair(&mut self) -> (f64, f64) {
        let u1 = 1.0 - self.next_f64(); // (0, 1]
        let r = (-2.0 * u1.ln()).sqrt();
        let phi = 2.0 * std::f64::consts::PI * self.next_f64();
        (r * phi.cos(), r * phi.sin())
    }

    /// A uniformly distributed unit vector on the hemisphere z > 0.
    pub fn hemisphere_vector(&mut self) -> DVec3 {
        let v = self.unit_vector();
        DVec3::new(v.x, v.y, v.z.abs().max(f64::MIN_POSITIVE))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_roughly_uniform() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        for _ in 0..100 {
            assert_eq!(a.next_u64(), b.next_u64());
        }
        let mut r = Rng::new(1);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| r.next_f64()).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.01);
        let mean_z: f64 = (0..n).map(|_| r.unit_vector().z).sum::<f64>() / n as f64;
        assert!(mean_z.abs() < 0.01);
    }
}
