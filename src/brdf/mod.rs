//! The reflectance model every stage shares (method.md §2-3, §5).
//!
//! **BRDF convention (stated once; repeated in the WGSL headers and the material JSON):**
//! `f_r(wi, wo) = ρd/π + f_s(wi, wo)` is the BRDF *without* the cosine factor. Directions are unit
//! vectors in the local frame (z = normal, x = tangent, y = bitangent), both pointing away from the
//! surface; either below the horizon (z ≤ 0) gives f_s = 0. Renderers multiply by max(wi·n, 0)
//! themselves.
//!
//! `f_s(wi, wo) = p(h) · s(wi, wo)`, `s = F(wi·h) / (4 (k1 + k2 − k1 k2))`, `k1 = wi·n`, `k2 =
//! wo·n`, `h = normalize(wi + wo)`, F = Schlick. The constant 4 is kept (the paper drops it), so p
//! is an NDF-like density and coefficients compare across tools.
//!
//! - [`fresnel`]: Schlick's approximation and its split F = F0·a(c) + b(c).
//! - [`dbrdf`]: the static term s (with a denominator that cannot cancel or vanish) and f_s.
//! - [`energy`]: the energy rows g_j^l = ∫ G(h·ξ_j) s(wi, wo^l) (wi·n) dwi, integrated in
//!   half-vector space, and the directional albedo of any fitted p.
//! - [`standard`]: not glint's model but the standard ones its fallbacks are exported as (glTF
//!   with `KHR_materials_*`, UsdPreviewSurface), evaluated per their specifications in the same
//!   convention (no cosine inside f; the split A·c + B includes it).
//!
//! Inputs: local unit directions, lobe sets, coefficients. Outputs: f64. Invariants: f_s is
//! reciprocal for any p and ≥ 0 when p ≥ 0; no IO.

pub mod dbrdf;
pub mod energy;
pub mod fresnel;
pub mod standard;

pub use dbrdf::{DistributionBrdf, denominator, half_vector, static_term};
pub use energy::EnergyTable;
pub use fresnel::schlick;
