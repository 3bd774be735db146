//! The wgpu preview (method.md §7): the same per-vertex sum as the CPU PRT renderer
//! ([`crate::render::prt`]), as a compute pass (`shaders/prt_shade.wgsl`), then a raster pass
//! (`shaders/prt_raster.wgsl`) that interpolates the vertices' radiance into an Rgba32Float target.
//!
//! - [`context`]: a headless device (Vulkan or GL; Mesa's lavapipe in CI) and its description.
//! - [`preview`]: [`GpuPreview`] — buffers for the bake (static), the light (per rotation) and the
//!   material (per fit); shading, rasterising and reading back.
//! - [`uniforms`]: `#[repr(C)]` Pod mirrors of the WGSL structs ("must match" on both sides,
//!   checked against naga's layouts in tests).
//!
//! Inputs: mesh, cuts, light tree, tangents, [`crate::light::LightSums`], a material (ρd, F0, a
//! [`crate::render::PhPyramid`]), a camera. Outputs: per-vertex radiance and
//! [`crate::render::Image`]s. Invariants: the GPU evaluates the CPU reference's equations in f32
//! over the same runs (tests compare them: tests/it/gpu.rs); light sums are formed in f64 on the
//! CPU per light-tree node, so the GPU never subtracts prefix sums; no IO besides the device;
//! errors are [`GpuError`] values, never panics (a missing adapter is an error the CLI reports).

pub mod context;
pub mod preview;
pub mod uniforms;

pub use context::GpuContext;
pub use preview::{GpuPreview, SOFTWARE_LOOP_BUDGET};

/// What can go wrong on the GPU path.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (backends tried: {backends}); on Linux install Mesa's Vulkan drivers (Debian: mesa-vulkan-drivers)"
    )]
    NoAdapter { backends: String },
    #[error("the GPU adapter {adapter} refused a device: {reason}")]
    Device { adapter: String, reason: String },
    #[error("{what} needs {needed} but the GPU adapter allows {allowed}")]
    Limit {
        what: &'static str,
        needed: u64,
        allowed: u64,
    },
    #[error("reading the frame back from the GPU failed: {reason}")]
    Readback { reason: String },
    #[error("the GPU preview has no {what} yet (call {call} first)")]
    NotReady {
        what: &'static str,
        call: &'static str,
    },
    #[error("wgpu reported an error: {reason}")]
    Wgpu { reason: String },
}

/// Why `glint render --gpu` cannot render.
#[derive(Debug, thiserror::Error)]
pub enum GpuFrameError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Frame(#[from] crate::render::frame::FrameError),
}

/// `glint render --gpu`: the PRT frame from the wgpu preview (vertex shading, on the first
/// adapter), as [`crate::render::frame::prt_frame`] draws it on the CPU.
pub fn preview_frame(
    bake: &crate::bake::LoadedBake,
    material: &crate::fit::material::Material,
    camera: &crate::scene::Camera,
    (w, h): (u32, u32),
    rotation_rad: f64,
) -> Result<(crate::render::Image, String), GpuFrameError> {
    use crate::render::{PrtSettings, table};
    let lobes = crate::render::frame::material_lobes(bake, material)?;
    let (set, tree) = bake
        .light_tree()
        .map_err(crate::render::frame::FrameError::from)?;
    let ctx = GpuContext::headless()?;
    let settings = PrtSettings {
        max_edge_px: 0.0,
        per_pixel: false,
        ..PrtSettings::default()
    };
    let mut preview = GpuPreview::new(
        &ctx,
        &bake.scene.mesh,
        &bake.cuts,
        &tree,
        bake.tangents.as_deref(),
        settings,
    )?;
    let c = &material.coefficients;
    let t = table::PhPyramid::build(
        &lobes,
        [&c[0], &c[1], &c[2]],
        table::default_resolution(lobes.lambda()),
    );
    preview.set_light(
        &crate::light::LightSums::new(&bake.env, &set, &tree, rotation_rad),
        &tree,
    )?;
    preview.set_material(material.rho_d, material.f0, Some(&t))?;
    let img = preview.render(camera, w, h)?;
    Ok((
        img,
        format!(
            "wgpu PRT preview on {}, p(h) table {}²",
            ctx.describe(),
            t.resolution()
        ),
    ))
}
