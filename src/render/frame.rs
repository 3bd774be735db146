//! A fitted material rendered on a bake, as `glint render` renders it: the PRT frame (tabulated p)
//! or the Monte Carlo reference (exact lobes, rays against the mesh), and the reference of an
//! exported fallback.
//!
//! Inputs: a [`LoadedBake`], a [`Material`], a camera and image size, the environment's rotation.
//! Output: a linear [`Image`] (object pixels only; the caller fills the background) and what
//! rendered it, in words. With `traced`, the PRT frame's visibility is traced per pixel where a
//! triangle's corners disagree ([`super::traced`], `glint render --trace-visibility`), by a
//! [`Baker`] made with the bake's own decisions. Invariants: the reference's shadow rays leave the
//! surface at 1e-4 of the scene's diagonal (docs/conventions.md §6); an anisotropic material on a
//! scene without tangents is an error.

use super::traced::Tracing;
use super::{ExactMaterial, Image, Prt, PrtSettings, Shading, Specular, render_reference, table};
use crate::bake::{BakeError, Baker, LoadedBake, Tracer};
use crate::brdf::standard::StandardMaterial;
use crate::fit::material::Material;
use crate::light::LightSums;
use crate::scene::Camera;
use crate::sphere::{LobeSet, SphereError};

/// Why a frame cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error("the material's layout {0} is anisotropic but the scene has no tangent field")]
    NoTangents(String),
    #[error("--reference needs at least 1 sample per pixel")]
    NoSamples,
    #[error(transparent)]
    Sphere(#[from] SphereError),
    #[error(transparent)]
    Bake(#[from] BakeError),
}

/// The reference's shadow-ray offset for a bake: 1e-4 of the scene's diagonal.
pub fn ray_offset(bake: &LoadedBake) -> f64 {
    1e-4 * bake.scene.bounds.diagonal() as f64
}

/// The material's lobes, checked against the scene's frames.
pub fn material_lobes(bake: &LoadedBake, material: &Material) -> Result<LobeSet, FrameError> {
    if !material.layout.is_isotropic() && bake.tangents.is_none() {
        return Err(FrameError::NoTangents(material.layout.name()));
    }
    Ok(material.lobes()?)
}

/// The CPU PRT frame (default settings, p tabulated at its default resolution); `traced`: with
/// per-pixel traced visibility, its cells refined at shadow edges as it says
/// ([`super::traced::tracing_settings`]).
pub fn prt_frame(
    bake: &LoadedBake,
    material: &Material,
    camera: &Camera,
    (w, h): (u32, u32),
    rotation_rad: f64,
    traced: Option<Tracing>,
) -> Result<(Image, String), FrameError> {
    let lobes = material_lobes(bake, material)?;
    let c = &material.coefficients;
    let t = table::PhPyramid::build(
        &lobes,
        [&c[0], &c[1], &c[2]],
        table::default_resolution(lobes.lambda()),
    );
    let shading = Shading {
        rho_d: material.rho_d,
        f0: material.f0,
        specular: Specular::Table(&t),
    };
    let (img, how) = prt_render(bake, camera, (w, h), rotation_rad, &shading, traced)?;
    Ok((img, format!("PRT{how}, p(h) table {}²", t.resolution())))
}

/// The CPU PRT frame of a standard material (an exported fallback): the same light runs as
/// [`prt_frame`], the material evaluated whole at each run's direction (not pre-filtered).
pub fn prt_frame_standard(
    bake: &LoadedBake,
    material: &StandardMaterial,
    camera: &Camera,
    size: (u32, u32),
    rotation_rad: f64,
    traced: Option<Tracing>,
) -> Result<(Image, String), FrameError> {
    let shading = Shading {
        rho_d: material.back_facing_rho(),
        f0: 0.04,
        specular: Specular::Standard(material),
    };
    let (img, how) = prt_render(bake, camera, size, rotation_rad, &shading, traced)?;
    Ok((img, format!("PRT{how} of the {}", standard_name(material))))
}

fn standard_name(material: &StandardMaterial) -> &'static str {
    match material {
        StandardMaterial::Gltf { .. } => "glTF fallback",
        StandardMaterial::Preview { .. } => "UsdPreviewSurface fallback",
    }
}

/// A PRT frame with default settings, and how its visibility was had, in words (empty: the
/// corners' cuts).
fn prt_render(
    bake: &LoadedBake,
    camera: &Camera,
    (w, h): (u32, u32),
    rotation_rad: f64,
    shading: &Shading,
    traced: Option<Tracing>,
) -> Result<(Image, String), FrameError> {
    if let Some(tracing) = traced {
        let baker = bake_tracer(bake, tracing)?;
        let light = LightSums::new(&bake.env, &baker.set, &baker.tree, rotation_rad);
        let (img, stats) = super::render_traced(
            &baker,
            &bake.scene.mesh,
            &bake.cuts,
            &bake.parents,
            bake.tangents.as_deref(),
            &light,
            camera,
            (w, h),
            shading,
            PrtSettings::default(),
        );
        let how = format!(
            " with visibility traced at {} of {} pixels ({:.2} M rays)",
            stats.traced,
            stats.pixels,
            stats.rays as f64 / 1e6
        );
        return Ok((img, how));
    }
    let (set, tree) = bake.light_tree()?;
    let light = LightSums::new(&bake.env, &set, &tree, rotation_rad);
    let prt = Prt::new(
        &bake.scene.mesh,
        &bake.cuts,
        &tree,
        bake.tangents.as_deref(),
        PrtSettings::default(),
    );
    Ok((prt.render(&light, camera, w, h, shading), String::new()))
}

/// A [`Baker`] over the bake's mesh that traces a frame's pixels as
/// [`super::traced::tracing_settings`] says; no decision is made again.
pub fn bake_tracer(bake: &LoadedBake, tracing: Tracing) -> Result<Baker<'_>, FrameError> {
    let settings =
        super::traced::tracing_settings(bake.header.settings, &bake.header.decisions, tracing);
    Ok(Baker::new(&bake.scene, &bake.env, settings)?)
}

/// The Monte Carlo reference with `spp` samples per pixel.
pub fn reference_frame(
    bake: &LoadedBake,
    material: &Material,
    camera: &Camera,
    (w, h): (u32, u32),
    rotation_rad: f64,
    spp: u32,
) -> Result<(Image, String), FrameError> {
    let lobes = material_lobes(bake, material)?;
    let c = &material.coefficients;
    let m = ExactMaterial {
        lobes: &lobes,
        coefficients: [&c[0], &c[1], &c[2]],
        rho_d: material.rho_d,
        f0: material.f0,
    };
    let img = with_reference_scene(bake, rotation_rad, spp, |s| {
        render_reference(
            s.mesh,
            s.tangents,
            s.tracer,
            s.ray_offset,
            s.env,
            s.rotation_rad,
            m,
            camera,
            w,
            h,
            spp,
            1,
        )
    })?;
    Ok((img, format!("Monte Carlo reference, {spp} spp")))
}

/// The Monte Carlo reference of a standard material (an exported fallback, read by
/// [`crate::material_file::read_fallback`]) with `spp` samples per pixel: the same estimator,
/// visibility, light and seed as [`reference_frame`], so the two images differ by the BRDFs only.
pub fn reference_frame_standard(
    bake: &LoadedBake,
    material: &StandardMaterial,
    camera: &Camera,
    (w, h): (u32, u32),
    rotation_rad: f64,
    spp: u32,
) -> Result<(Image, String), FrameError> {
    let img = with_reference_scene(bake, rotation_rad, spp, |s| {
        super::render_reference_standard(s, material, camera, (w, h), spp, 1)
    })?;
    let what = standard_name(material);
    Ok((
        img,
        format!("Monte Carlo reference of the {what}, {spp} spp"),
    ))
}

/// Renders with the bake's reference scene (mesh, tangents, a tracer, the shadow rays' offset, the
/// environment at `rotation_rad`); at least one sample per pixel.
fn with_reference_scene(
    bake: &LoadedBake,
    rotation_rad: f64,
    spp: u32,
    render: impl FnOnce(&super::ReferenceScene) -> Image,
) -> Result<Image, FrameError> {
    if spp == 0 {
        return Err(FrameError::NoSamples);
    }
    let tracer = Tracer::new(&bake.scene.mesh);
    Ok(render(&super::ReferenceScene {
        mesh: &bake.scene.mesh,
        tangents: bake.tangents.as_deref(),
        tracer: &tracer,
        ray_offset: ray_offset(bake),
        env: &bake.env,
        rotation_rad,
    }))
}
