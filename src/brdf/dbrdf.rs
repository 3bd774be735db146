//! Ashikhmin's distribution-based BRDF with a sum-of-SRBF distribution (method.md §3).
//!
//! Convention: see [`crate::brdf`] — f_r without the cosine, local directions away from the
//! surface.
//!
//! The static term s = F(wi·h) / (4 d), d = k1 + k2 − k1 k2. The spec writes d as 1 − (1 − k1)(1 −
//! k2), which is the same number but cancels catastrophically when both directions graze (k1, k2 →
//! 0: the named hard case). We compute d = k1 + k2·(1 − k1): every term is non-negative on [0, 1]²,
//! so there is no cancellation anywhere, and d ≥ max(k1, k2). d vanishes only when both directions
//! lie exactly on the horizon; there it is floored at [`DENOMINATOR_FLOOR`], which keeps s finite
//! (s ≤ 1/(4·1e-12)). Every use multiplies s by the cosine k1 (or k2) of a direction, and k1·s ≤
//! F/4, so the floor never changes a rendered value by more than the floor itself.
//!
//! Inputs: local unit directions, F0, a lobe set and coefficients. Outputs: finite, non-negative
//! values when the coefficients are non-negative. Invariant: f_s(wi, wo) = f_s(wo, wi) exactly,
//! rounding included (s is computed from symmetric parts: wi·wo and the cosines ordered by size).

use super::fresnel::schlick;
use crate::sphere::LobeSet;
use glam::DVec3;

/// Floor of the static term's denominator d (reached only when both directions graze exactly).
pub const DENOMINATOR_FLOOR: f64 = 1e-12;

/// d = k1 + k2 − k1 k2, computed without cancellation, with k clamped to [0, 1] and floored.
#[inline]
pub fn denominator(k1: f64, k2: f64) -> f64 {
    // The larger cosine first, so that d(k1, k2) and d(k2, k1) round alike (exact reciprocity).
    let (hi, lo) = if k1 >= k2 { (k1, k2) } else { (k2, k1) };
    let (hi, lo) = (hi.clamp(0.0, 1.0), lo.clamp(0.0, 1.0));
    (hi + lo * (1.0 - hi)).max(DENOMINATOR_FLOOR)
}

/// normalize(wi + wo), or None when wi = −wo (no half-vector).
#[inline]
pub fn half_vector(wi: DVec3, wo: DVec3) -> Option<DVec3> {
    (wi + wo).try_normalize()
}

/// The half-vector's cosines without a local frame, from k1 = wi·n, k2 = wo·n and c = wi·wo (unit
/// directions): (wi·h = wo·h, h·n) = ((1 + c), (k1 + k2)) / |wi + wo| with |wi + wo| = √(2 + 2c)
/// (one square root). `None` when wi is at or below the horizon or wi = −wo. What isotropic lobes
/// need.
#[inline]
pub fn half_vector_cosines(k1: f64, k2: f64, c: f64) -> Option<(f64, f64)> {
    let (valid, wo_h, cos_h) = half_vector_cosines_masked(k1, k2, c);
    valid.then_some((wo_h, cos_h))
}

/// [`half_vector_cosines`] without a branch on the data, for loops over many directions at once:
/// (whether there is a half-vector, wi·h, h·n), the cosines finite but meaningless when there is
/// none.
#[inline(always)]
pub fn half_vector_cosines_masked(k1: f64, k2: f64, c: f64) -> (bool, f64, f64) {
    let len2 = 2.0 + 2.0 * c;
    let valid = k1 > 0.0 && len2 > 1e-24;
    let inv = 1.0 / len2.max(1e-24).sqrt();
    (valid, (1.0 + c) * inv, ((k1 + k2) * inv).min(1.0))
}

/// s(wi, wo) = F(wi·h) / (4 d(k1, k2)); 0 when either direction is at or below the horizon.
#[inline]
pub fn static_term(wi: DVec3, wo: DVec3, f0: f64) -> f64 {
    let (k1, k2) = (wi.z, wo.z);
    if !(k1 > 0.0 && k2 > 0.0) {
        return 0.0;
    }
    // wi·h = wo·h = √((1 + wi·wo)/2): symmetric in its rounding too (wi·h and wo·h computed from h
    // differ by an ulp, which (1 − c)^5 amplifies near c = 1).
    let d = wi.dot(wo);
    if !(d > -1.0) {
        return 0.0;
    }
    static_term_parts(k1, k2, ((1.0 + d) * 0.5).sqrt(), f0)
}

/// s from its parts: k1 = wi·n, k2 = wo·n, c = wi·h.
#[inline]
pub fn static_term_parts(k1: f64, k2: f64, cos_ih: f64, f0: f64) -> f64 {
    schlick(f0, cos_ih) / (4.0 * denominator(k1, k2))
}

/// One colour channel of the BRDF: ρd/π + p(h) s(wi, wo), with p(h) = Σ c_j G(h·ξ_j).
#[derive(Debug, Clone)]
pub struct DistributionBrdf {
    pub lobes: LobeSet,
    pub coefficients: Vec<f64>,
    pub f0: f64,
    pub rho_d: f64,
}

impl DistributionBrdf {
    /// f_s(wi, wo) = p(h) s(wi, wo) (no diffuse part, no cosine).
    pub fn specular(&self, wi: DVec3, wo: DVec3) -> f64 {
        let s = static_term(wi, wo, self.f0);
        if s == 0.0 {
            return 0.0;
        }
        let Some(h) = half_vector(wi, wo) else {
            return 0.0;
        };
        self.lobes.p(&self.coefficients, h) * s
    }

    /// f_r(wi, wo) = ρd/π + f_s(wi, wo); 0 below the horizon.
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        if !(wi.z > 0.0 && wo.z > 0.0) {
            return 0.0;
        }
        self.rho_d / std::f64::consts::PI + self.specular(wi, wo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;
    use crate::sphere::{LobeLayout, LobeSet};

    fn random_brdf(rng: &mut Rng, layout: LobeLayout, lambda: f64) -> DistributionBrdf {
        let lobes = LobeSet::new(layout, lambda).unwrap();
        let coefficients = (0..lobes.len()).map(|_| rng.range(0.0, 2.0)).collect();
        DistributionBrdf {
            lobes,
            coefficients,
            f0: rng.range(0.0, 1.0),
            rho_d: 0.3,
        }
    }

    #[test]
    fn reciprocal_on_ten_thousand_random_pairs() {
        let mut rng = Rng::new(42);
        for layout in [LobeLayout::PAPER, LobeLayout::Isotropic { count: 24 }] {
            let brdf = random_brdf(&mut rng, layout, 81.06);
            for _ in 0..10_000 {
                let wi = rng.hemisphere_vector();
                let wo = rng.hemisphere_vector();
                let a = brdf.specular(wi, wo);
                let b = brdf.specular(wo, wi);
                assert!(a.is_finite() && a >= 0.0);
                assert!(
                    (a - b).abs() <= 1e-12 * a.abs().max(1e-300),
                    "f({wi},{wo})={a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn static_term_is_finite_and_non_negative_down_to_grazing() {
        let f0 = 0.04;
        for &k1 in &[0.0, 1e-300, 1e-12, 1e-8, 1e-4, 0.5, 1.0] {
            for &k2 in &[0.0, 1e-300, 1e-12, 1e-8, 1e-4, 0.5, 1.0] {
                let d = denominator(k1, k2);
                assert!(d.is_finite() && d > 0.0);
                let s = static_term_parts(k1, k2, 0.0, f0);
                assert!(s.is_finite() && s >= 0.0, "k1={k1} k2={k2} s={s}");
                // k1·s is bounded by F/4 ≤ 1/4: the quantity renderers use.
                assert!(k1 * s <= 0.25 + 1e-12 && k2 * s <= 0.25 + 1e-12);
            }
        }
        // Relative accuracy at grazing: d(1e-8, 1e-8) = 2e-8 − 1e-16 exactly.
        let d = denominator(1e-8, 1e-8);
        assert!(((d - (2e-8 - 1e-16)) / 2e-8).abs() < 1e-15, "d={d}");
        // The spec's algebraic form loses ~8 digits there; ours does not.
        let spec_form = 1.0 - (1.0f64 - 1e-8) * (1.0f64 - 1e-8);
        assert!(((spec_form - (2e-8 - 1e-16)) / 2e-8).abs() > 1e-12);
        // Grazing directions built as vectors.
        let wi = DVec3::new(1.0, 0.0, 1e-8).normalize();
        let wo = DVec3::new(-1.0, 0.0, 1e-8).normalize();
        let s = static_term(wi, wo, f0);
        assert!(s.is_finite() && s >= 0.0);
        assert_eq!(static_term(DVec3::X, -DVec3::X, f0), 0.0);
        assert_eq!(static_term(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, f0), 0.0);
    }

    #[test]
    fn matches_the_papers_form_away_from_grazing() {
        let mut rng = Rng::new(3);
        for _ in 0..1000 {
            let wi = rng.hemisphere_vector();
            let wo = rng.hemisphere_vector();
            let h = (wi + wo).normalize();
            let (k1, k2) = (wi.z, wo.z);
            let want = schlick(0.5, wi.dot(h)) / (4.0 * (k1 + k2 - k1 * k2));
            let got = static_term(wi, wo, 0.5);
            if k1 > 1e-6 || k2 > 1e-6 {
                assert!(((got - want) / want).abs() < 1e-10);
            }
        }
    }
}
