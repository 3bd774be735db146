//! From a fitted material to the exporters' plain description: the tabulated p(h), the fitted
//! pbrMetallicRoughness fallback, the MERL isotropic projection and provenance.
//!
//! Inputs: a [`Material`], a table resolution, provenance strings, optionally the scene's mesh.
//! Outputs: a [`glint_exporters::MaterialDesc`] (and a [`glint_exporters::SceneMesh`]) — the exporters
//! crate knows file formats, this module knows the BRDF.
//!
//! The fallback: glTF's pbrMetallicRoughness BRDF (the Khronos reference: GGX D with α = roughness²,
//! height-correlated Smith V, f = (1 − m)·[c/π·(1 − F_d) + D·V·F_d] + m·D·V·[c + (1 − c)(1 − v·h)⁵],
//! F_d = 0.04 + 0.96 (1 − v·h)⁵) fitted to glint's f_r·cos θi in least squares over 4,096 stratified
//! direction pairs. It is linear in the base colour c for fixed (m, α), so c is solved in closed form
//! per channel on a grid of 11 metallic × 64 roughness values and the best is refined by a finer grid.
//! The relative RMS error of the fit is reported. Anisotropic materials get an isotropic fallback (the
//! anisotropy extension is not fitted; the error says how much that costs).
//!
//! Invariants: no IO; deterministic (fixed sample sets).

use crate::brdf::dbrdf::static_term;
use crate::fit::material::Material;
use crate::math::Rng;
use crate::render::table::PhTable;
use crate::sphere::{LobeSet, SphereError};
use glam::DVec3;
use glint_exporters::{MaterialDesc, MerlTable, PbrFallback};
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Default resolution of the exported p(h) table (see exporters/README.md for its accuracy).
pub const EXPORT_TABLE_RESOLUTION: usize = 512;

/// glint's BRDF from the table, in the local frame, without the cosine.
fn eval_table(table: &PhTable, rho_d: [f64; 3], f0: f64, wi: DVec3, wo: DVec3) -> [f64; 3] {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return [0.0; 3];
    }
    let Some(h) = (wi + wo).try_normalize() else { return rho_d.map(|r| r / PI) };
    let p = table.lookup(h);
    let s = static_term(wi, wo, f0);
    std::array::from_fn(|c| rho_d[c] / PI + p[c] * s)
}

/// The Khronos pbrMetallicRoughness BRDF split as f = c·A + B (per channel, same A and B).
fn gltf_parts(metallic: f64, roughness: f64, wi: DVec3, wo: DVec3) -> (f64, f64) {
    let Some(h) = (wi + wo).try_normalize() else { return (0.0, 0.0) };
    let (nl, nv, nh, vh) = (wi.z, wo.z, h.z.max(0.0), wo.dot(h).max(0.0));
    let a2 = (roughness * roughness).powi(2).max(1e-12);
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let v = 0.5 / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
    let s5 = (1.0 - vh).powi(5);
    let fd = 0.04 + 0.96 * s5;
    let a = (1.0 - metallic) * (1.0 - fd) / PI + metallic * d * v * (1.0 - s5);
    let b = (1.0 - metallic) * d * v * fd + metallic * d * v * s5;
    (a, b)
}

/// Fits the pbrMetallicRoughness fallback to the BRDF given by `table`, ρd and F0.
pub fn fit_fallback(table: &PhTable, rho_d: [f64; 3], f0: f64) -> PbrFallback {
    // Stratified direction pairs over the two hemispheres, cosine-weighted: (wi, wo, weight).
    let mut rng = Rng::new(20260501);
    let n = 64;
    let mut pairs = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let mut cos_dir = |k: usize| {
                let (u1, u2) = ((k as f64 + rng.next_f64()) / n as f64, rng.next_f64());
                let r = u1.sqrt();
                let phi = 2.0 * PI * u2;
                DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(1e-4).sqrt())
            };
            let (wi, wo) = (cos_dir(i), cos_dir(j));
            pairs.push((wi, wo));
        }
    }
    // Target: f·cos θi (what a renderer sums), per channel.
    let target: Vec<[f64; 3]> = pairs.iter().map(|&(wi, wo)| eval_table(table, rho_d, f0, wi, wo).map(|f| f * wi.z)).collect();
    let norm: f64 = target.iter().flatten().map(|t| t * t).sum();
    let evaluate = |m: f64, r: f64| -> ([f64; 3], f64) {
        let parts: Vec<(f64, f64)> = pairs.iter().map(|&(wi, wo)| {
            let (a, b) = gltf_parts(m, r, wi, wo);
            (a * wi.z, b * wi.z)
        }).collect();
        let mut colour = [0.0; 3];
        let mut err = 0.0;
        for c in 0..3 {
            let (mut num, mut den) = (0.0, 0.0);
            for (k, &(a, b)) in parts.iter().enumerate() {
                num += a * (target[k][c] - b);
                den += a * a;
            }
            colour[c] = if den > 0.0 { (num / den).clamp(0.0, 1.0) } else { 0.0 };
            err += parts.iter().enumerate().map(|(k, &(a, b))| (colour[c] * a + b - target[k][c]).powi(2)).sum::<f64>();
        }
        (colour, err)
    };
    let mut best = (0.0, 0.5, [0.5; 3], f64::INFINITY);
    for mi in 0..=10 {
        for ri in 0..64 {
            let (m, r) = (mi as f64 / 10.0, 0.02 + 0.98 * ri as f64 / 63.0);
            let (colour, err) = evaluate(m, r);
            if err < best.3 {
                best = (m, r, colour, err);
            }
        }
    }
    // Refine around the best cell.
    let (m0, r0) = (best.0, best.1);
    for mi in -5..=5 {
        for ri in -8..=8 {
            let (m, r) = ((m0 + mi as f64 * 0.02).clamp(0.0, 1.0), (r0 + ri as f64 * 0.002).clamp(0.02, 1.0));
            let (colour, err) = evaluate(m, r);
            if err < best.3 {
                best = (m, r, colour, err);
            }
        }
    }
    PbrFallback { base_color: best.2, metallic: best.0, roughness: best.1, anisotropy: None, relative_error: if norm > 0.0 { (best.3 / norm).sqrt() } else { 0.0 } }
}

/// The MERL table of the material's isotropic projection: for isotropic layouts the exact lobe sum
/// (ring lobes depend on h·n only, so no averaging is needed); for anisotropic ones the BRDF from the
/// table averaged over 8 rotations about the normal.
pub fn merl_table(material: &Material, lobes: &LobeSet, table: &PhTable) -> MerlTable {
    let (rho_d, f0) = (material.rho_d, material.f0);
    if material.layout.is_isotropic() {
        return MerlTable::sample(|wi, wo| {
            let (wi, wo) = (DVec3::from(wi), DVec3::from(wo));
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return [0.0; 3];
            }
            let Some(h) = (wi + wo).try_normalize() else { return rho_d.map(|r| r / PI) };
            let s = static_term(wi, wo, f0);
            std::array::from_fn(|c| rho_d[c] / PI + lobes.p(&material.coefficients[c], h) * s)
        });
    }
    let rotations = 8;
    MerlTable::sample(|wi, wo| {
        let (wi, wo) = (DVec3::from(wi), DVec3::from(wo));
        let mut acc = [0.0; 3];
        for k in 0..rotations {
            let a = 2.0 * PI * k as f64 / rotations as f64;
            let (c, s) = (a.cos(), a.sin());
            let rot = |d: DVec3| DVec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
            let f = eval_table(table, rho_d, f0, rot(wi), rot(wo));
            for ch in 0..3 {
                acc[ch] += f[ch] / rotations as f64;
            }
        }
        acc
    })
}

/// The exporters' description of a material: lobe table, p(h) at `table_resolution`, fallback, MERL.
pub fn material_desc(material: &Material, name: &str, table_resolution: usize, provenance: BTreeMap<String, String>) -> Result<MaterialDesc, SphereError> {
    let lobes: LobeSet = material.lobes()?;
    let coefficients = [material.coefficients[0].as_slice(), material.coefficients[1].as_slice(), material.coefficients[2].as_slice()];
    let table = PhTable::build_unfiltered(&lobes, coefficients, table_resolution);
    let isotropic = material.layout.is_isotropic();
    let fallback = fit_fallback(&table, material.rho_d, material.f0);
    let merl = merl_table(material, &lobes, &table);
    Ok(MaterialDesc {
        name: name.to_string(),
        model: material.model.clone(),
        version: material.version,
        lambda: material.lambda,
        sigma: material.sigma,
        layout: material.layout.name(),
        isotropic,
        centres: material.centres.clone(),
        coefficients: material.coefficients.clone(),
        rho_d: material.rho_d,
        f0: material.f0,
        brdf_convention: material.brdf_convention.clone(),
        frame_convention: material.frame.clone(),
        provenance,
        table: glint_exporters::PhTable { resolution: table.resolution() as u32, texels: table.texels().to_vec() },
        fallback,
        merl: Some(merl),
    })
}

/// The scene's mesh for the glTF and USD exporters.
pub fn scene_mesh(mesh: &crate::scene::Mesh, tangents: Option<&[glam::Vec4]>) -> glint_exporters::SceneMesh {
    glint_exporters::SceneMesh {
        positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
        normals: mesh.normals.iter().map(|n| n.to_array()).collect(),
        tangents: tangents.map(|t| t.iter().map(|v| v.to_array()).collect()),
        uvs: mesh.uvs.as_ref().map(|u| u.iter().map(|v| v.to_array()).collect()),
        indices: mesh.triangles.iter().flatten().copied().collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fallback_fit_recovers_a_gltf_material() {
        // A table made from the glTF BRDF itself (its specular part, as p·s would hold it) is fitted
        // back: tabulate p(h) := (f_gltf − c·(1 − m)(1 − F_d)/π)/s along the mirror configuration is not
        // separable, so instead check the fit on a pure Lambertian: ρd = 0.6, no lobes → metallic 0,
        // base colour ≈ 0.6, error small.
        let lobes = LobeSet::new(crate::sphere::LobeLayout::Isotropic { count: 8 }, 20.0).unwrap();
        let zero = vec![0.0; lobes.len()];
        let table = PhTable::build_unfiltered(&lobes, [&zero, &zero, &zero], 64);
        let fb = fit_fallback(&table, [0.6, 0.3, 0.1], 0.04);
        println!("{fb:?}");
        assert!(fb.metallic <= 0.1, "{fb:?}");
        for (c, want) in [0.6, 0.3, 0.1].iter().enumerate() {
            assert!((fb.base_color[c] - want).abs() < 0.08, "{fb:?}");
        }
        assert!(fb.relative_error < 0.1, "{fb:?}");
    }
}
