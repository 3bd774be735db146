//! Reference evaluators of the exported BRDF, for readers' tests and the table-accuracy study.
//!
//! f_r(wi, wo) = ρd/π + p(h)·s(wi, wo), without the cosine, in the local frame (z = normal, x =
//! tangent); h = normalize(wi + wo); s = F(wi·h) / (4 (k1 + k2 − k1·k2)), k1 = wi·n, k2 = wo·n, F =
//! f0 + (1 − f0)(1 − wi·h)^5. [`eval_from_table`] reads p(h) from the description's table (what a
//! renderer does with the EXR); [`eval_lobes`] sums the lobes exactly: point lobes p(h) = Σ_j c_j
//! exp(2λ(h·ξ_j − 1)) for anisotropic layouts, ring lobes p(h) = Σ_j c_j exp(2λ(cos(θh − θj) − 1))
//! I0e(2λ sin θh sin θj) for isotropic ones (docs/conventions.md §1).
//!
//! Inputs: a [`MaterialDesc`] and two local unit directions. Outputs: RGB f_r. Invariants: 0 when
//! either direction is at or below the horizon (or degenerate); no IO, no panics.

use crate::bessel::bessel_i0e;
use crate::material::MaterialDesc;
use std::f64::consts::PI;

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The half-vector and the static term s(wi, wo); `None` below the horizon.
pub fn half_and_static(f0: f64, wi: [f64; 3], wo: [f64; 3]) -> Option<([f64; 3], f64)> {
    let (k1, k2) = (wi[2], wo[2]);
    if !(k1 > 0.0 && k2 > 0.0) {
        return None;
    }
    let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let n = dot(s, s).sqrt();
    if !(n > 0.0 && n.is_finite()) {
        return None;
    }
    let h = [s[0] / n, s[1] / n, s[2] / n];
    let c = dot(wi, h).clamp(0.0, 1.0);
    let fresnel = f0 + (1.0 - f0) * (1.0 - c).powi(5);
    Some((h, fresnel / (4.0 * (k1 + k2 * (1.0 - k1)))))
}

fn combine(desc: &MaterialDesc, p: [f64; 3], s: f64) -> [f64; 3] {
    let mut out = [0.0; 3];
    for k in 0..3 {
        out[k] = desc.rho_d[k] / PI + p[k] * s;
    }
    out
}

/// Lobe j at the local half-vector h: a point lobe, or for an isotropic layout its ring lobe (the
/// point lobe averaged over the azimuth of its centre), whose value depends on h.z only.
pub fn lobe(isotropic: bool, lambda: f64, xi: [f64; 3], h: [f64; 3]) -> f64 {
    if isotropic {
        let ch = (h[2] / dot(h, h).sqrt()).clamp(-1.0, 1.0);
        let sh = (1.0 - ch * ch).max(0.0).sqrt();
        let cj = xi[2].clamp(-1.0, 1.0);
        let sj = (1.0 - cj * cj).max(0.0).sqrt();
        let cos_diff = (ch * cj + sh * sj).clamp(-1.0, 1.0);
        (2.0 * lambda * (cos_diff - 1.0)).exp() * bessel_i0e(2.0 * lambda * sh * sj)
    } else {
        (2.0 * lambda * (dot(h, xi) - 1.0)).exp()
    }
}

/// p(h) by the exact lobe sum: ring lobes for an isotropic layout, point lobes otherwise.
pub fn lobes_p(desc: &MaterialDesc, h: [f64; 3]) -> [f64; 3] {
    let mut p = [0.0; 3];
    for (j, xi) in desc.centres.iter().enumerate() {
        let g = lobe(desc.isotropic, desc.lambda, *xi, h);
        for (k, pk) in p.iter_mut().enumerate() {
            *pk += desc.coefficients[k].get(j).copied().unwrap_or(0.0) * g;
        }
    }
    p
}

/// f_r with p(h) read from the table (bilinear on the corner-aligned grid).
pub fn eval_from_table(desc: &MaterialDesc, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
    match half_and_static(desc.f0, wi, wo) {
        Some((h, s)) => combine(desc, desc.table.lookup(h), s),
        None => [0.0; 3],
    }
}

/// f_r with p(h) summed exactly over the lobes.
pub fn eval_lobes(desc: &MaterialDesc, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
    match half_and_static(desc.f0, wi, wo) {
        Some((h, s)) => combine(desc, lobes_p(desc, h), s),
        None => [0.0; 3],
    }
}
