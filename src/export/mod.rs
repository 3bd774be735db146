//! From a fitted material to the exporters' plain description: the tabulated p(h), the standard
//! fallback ([`pbr_fallback`]), the MERL isotropic projection, the scene (mesh, camera,
//! environment) and one [`Provenance`] for every file.
//!
//! Inputs: a [`Material`], a table resolution, a [`Provenance`], optionally the scene's mesh.
//! Outputs: a [`glint_exporters::MaterialDesc`] (and a [`glint_exporters::SceneMesh`]) — the
//! exporters crate knows file formats, this module knows the BRDF.
//!
//! Invariants: no IO except hashing the material file a provenance names; deterministic.

pub mod layered_fallback;
pub mod pbr_fallback;
mod provenance;
mod scene;

use pbr_fallback::eval_table;
pub use pbr_fallback::{
    FallbackFit, ISOTROPY_TOLERANCE, azimuthal_deviation, fit_fallback, fit_fallback_anisotropic,
    material_fallback,
};
pub use provenance::{Provenance, Tool};
pub use scene::{
    ExportSceneError, SceneChoice, export_scene, scene_camera, scene_environment, scene_mesh,
};

use crate::brdf::dbrdf::static_term;
use crate::fit::material::Material;
use crate::render::table::PhPyramid;
use crate::sphere::{LobeSet, SphereError};
use glam::DVec3;
use glint_exporters::{MaterialDesc, MerlTable};
use std::f64::consts::PI;

/// The name an export gives its files: the material file's stem, with every character but ASCII
/// letters, digits, `_` and `-` replaced by `_`.
pub fn material_name(path: &std::path::Path) -> String {
    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("material");
    stem.replace(
        |c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-'),
        "_",
    )
}

/// Default resolution of the exported p(h) table (see exporters/README.md for its accuracy).
pub const EXPORT_TABLE_RESOLUTION: usize = 512;
/// The MERL table of the material's isotropic projection: for isotropic layouts the exact lobe sum
/// (ring lobes depend on h·n only, so no averaging is needed); for anisotropic ones the BRDF from
/// the table averaged over 8 rotations about the normal.
pub fn merl_table(material: &Material, lobes: &LobeSet, table: &PhPyramid) -> MerlTable {
    let (rho_d, f0) = (material.rho_d, material.f0);
    if material.layout.is_isotropic() {
        return MerlTable::sample(|wi, wo| {
            let (wi, wo) = (DVec3::from(wi), DVec3::from(wo));
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return [0.0; 3];
            }
            let Some(h) = (wi + wo).try_normalize() else {
                return rho_d.map(|r| r / PI);
            };
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

/// The exporters' description of a material: lobe table, p(h) at `table_resolution`, the glTF and
/// UsdPreviewSurface fallbacks (fitted where `scene`'s camera looks under its environment, when it
/// carries both), MERL.
pub fn material_desc(
    material: &Material,
    name: &str,
    table_resolution: usize,
    mut provenance: Provenance,
    scene: Option<&glint_exporters::SceneMesh>,
) -> Result<MaterialDesc, SphereError> {
    let lobes: LobeSet = material.lobes()?;
    let coefficients = [
        material.coefficients[0].as_slice(),
        material.coefficients[1].as_slice(),
        material.coefficients[2].as_slice(),
    ];
    let table = PhPyramid::build_unfiltered(&lobes, coefficients, table_resolution);
    let isotropic = material.layout.is_isotropic();
    let fit = material_fallback(material, &lobes, &table);
    if fit.fallback.anisotropy.is_some() {
        provenance.set(
            "fallback_isotropic_relative_error",
            format!("{:?}", fit.isotropic_relative_error),
        );
    }
    let objective = layered_fallback::Objective::new(&table, material.rho_d, material.f0, scene);
    let fallback = layered_fallback::fit_gltf(&objective, &fit.fallback);
    let preview_surface = layered_fallback::fit_preview(&objective, &fallback);
    provenance.set("fallback_weighting", fallback.weighting.name().to_string());
    provenance.set(
        "fallback_gltf_relative_error",
        format!("{:?}", fallback.relative_error),
    );
    provenance.set(
        "fallback_gltf_one_lobe_relative_error",
        format!("{:?}", fallback.one_lobe_relative_error),
    );
    provenance.set(
        "fallback_usd_relative_error",
        format!("{:?}", preview_surface.relative_error),
    );
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
        brdf_convention: glint_exporters::material::brdf_convention(isotropic).into(),
        frame_convention: glint_exporters::material::FRAME_CONVENTION.into(),
        provenance: provenance.into_map(),
        table: table.to_table(),
        fallback,
        preview_surface,
        merl: Some(merl),
    })
}
