//! What a fit in one view costs once the bake is done, as `glint bake` reports it: the light sums,
//! the view's transfer, and a rotated environment (new sums from the prepared light source and a new
//! transfer; no rays).
//!
//! Inputs: a [`LoadedBake`], a camera and a fit size. Output: [`ViewCost`]. Invariants: reads and
//! writes nothing; the transfers use the lobes a default fit would ([`default_layout`], the bake's σ)
//! and the default F0.

use super::run::{FitError, FitSettings, default_layout};
use crate::bake::LoadedBake;
use crate::light::{LightSource, LightSums};
use crate::scene::Camera;
use crate::sphere::{LobeSet, srbf};
use crate::transfer::TransferContext;
use std::time::Instant;

/// The rotation the rotated-environment timing uses: any angle but 0 (which would reuse the sums).
pub const PROBE_ROTATION_RAD: f64 = 0.5;

/// Seconds of each step of a fit's preparation in one view.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ViewCost {
    /// Pixels of the object in the fit image.
    pub pixels: usize,
    /// J of the default layout.
    pub lobes: usize,
    pub light_seconds: f64,
    pub transfer_seconds: f64,
    /// Light sums for a rotated environment and the view's transfer under it.
    pub rotation_seconds: f64,
    pub rotated_transfer_seconds: f64,
}

/// Measures [`ViewCost`] for `camera` at `fit_size`.
pub fn view_cost(bake: &LoadedBake, camera: &Camera, fit_size: (u32, u32)) -> Result<ViewCost, FitError> {
    let f0 = FitSettings::default().f0;
    let (set, tree) = bake.light_tree()?;
    let lambda = srbf::lambda_from_sigma(bake.header.settings.sigma)?;
    let lobes = LobeSet::new(default_layout(bake.header.decisions.anisotropic), lambda)?;
    let ctx = TransferContext::new(&bake.scene.mesh, &bake.cuts, &tree, &lobes, bake.tangents.as_deref(), None);
    let start = Instant::now();
    let light = LightSums::new(&bake.env, &set, &tree, 0.0);
    let light_seconds = start.elapsed().as_secs_f64();
    let transfer = ctx.compute(&light, camera, fit_size.0, fit_size.1, f0);
    let source = LightSource::new(&bake.env);
    let start = Instant::now();
    let rotated = LightSums::from_source(&source, &set, &tree, PROBE_ROTATION_RAD);
    let rotated_transfer = ctx.compute(&rotated, camera, fit_size.0, fit_size.1, f0);
    let rotation_seconds = start.elapsed().as_secs_f64();
    Ok(ViewCost {
        pixels: transfer.pixels.len(),
        lobes: lobes.len(),
        light_seconds,
        transfer_seconds: transfer.seconds,
        rotation_seconds,
        rotated_transfer_seconds: rotated_transfer.seconds,
    })
}
