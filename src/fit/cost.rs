//! What a fit in one view costs once the bake is done, as `glint bake` reports it: the light sums,
//! the view's transfer, and a rotated environment (new sums from the prepared light source and a
//! new
//! transfer; no rays).
//!
//! Inputs: a [`LoadedBake`], a camera and a fit size. Output: [`ViewCost`]. Invariants: reads and
//! writes nothing; the transfers use the lobes a default fit would ([`default_layout`], the bake's
//! σ)
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
pub fn view_cost(
    bake: &LoadedBake,
    camera: &Camera,
    fit_size: (u32, u32),
) -> Result<ViewCost, FitError> {
    let f0 = FitSettings::default().f0;
    let (set, tree) = bake.light_tree()?;
    let lambda = srbf::lambda_from_sigma(bake.header.settings.sigma)?;
    let lobes = LobeSet::new(default_layout(bake.header.decisions.anisotropic), lambda)?;
    let ctx = TransferContext::new(
        &bake.scene.mesh,
        &bake.cuts,
        &tree,
        &lobes,
        bake.tangents.as_deref(),
        None,
    );
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

/// What `glint bake` reports: the bake (written or reused), its decisions and statistics, and what
/// a fit in the chosen view costs after it.
pub struct BakeReport<'a> {
    pub path: &'a std::path::Path,
    pub reused: bool,
    pub header: &'a crate::bake::file::BakeHeader,
    /// Whether the bake refined the mesh.
    pub refined: bool,
    pub camera: &'a Camera,
    pub fit_size: (u32, u32),
    pub cost: &'a ViewCost,
}

impl BakeReport<'_> {
    /// One JSON object (`glint bake --json`; its keys are listed in docs/bake.md).
    pub fn json(&self) -> serde_json::Value {
        let (s, c) = (&self.header.stats, self.cost);
        serde_json::json!({
            "bake": self.path, "reused": self.reused, "vertices": s.vertices, "triangles": s.triangles,
            "rays_traced": s.rays_traced, "mean_cut_size": s.mean_cut_size, "max_cut_size": s.max_cut_size,
            "capped_vertices": s.capped_vertices, "seconds": s.seconds, "decision_seconds": s.decision_seconds,
            "rays_per_second": s.rays_traced as f64 / (s.seconds - s.decision_seconds).max(1e-9),
            "bytes_per_vertex": s.bytes_per_vertex, "tracer": s.tracer, "stages": s.stages,
            "decisions": self.header.decisions,
            "view": {
                "camera": self.camera.name, "fit_width": self.fit_size.0, "fit_height": self.fit_size.1,
                "pixels": c.pixels, "lobes": c.lobes,
            },
            "light_seconds": c.light_seconds, "transfer_seconds": c.transfer_seconds,
            "rotation_seconds": c.rotation_seconds, "rotated_transfer_seconds": c.rotated_transfer_seconds,
        })
    }

    /// Lines for people: what was written, each decision with its reason, the statistics, the view.
    pub fn text(&self) -> String {
        let (s, c) = (&self.header.stats, self.cost);
        let mut lines = vec![format!(
            "{} {}",
            if self.reused { "reused" } else { "wrote" },
            self.path.display()
        )];
        for (what, why) in self.header.decisions.summary(self.refined) {
            lines.push(format!("decision: {what} — {why}"));
        }
        lines.push(format!(
            "{} vertices, {} rays{}, mean cut {:.1} nodes (max {}, {} capped), {:.0} bytes/vertex, {:.2} s \
             ({:.2} s deciding)",
            s.vertices, s.rays_traced,
            if s.tracer.is_empty() { String::new() } else { format!(" (traced with {})", s.tracer) },
            s.mean_cut_size, s.max_cut_size, s.capped_vertices, s.bytes_per_vertex, s.seconds,
            s.decision_seconds
        ));
        if !s.stages.is_empty() {
            lines.push(format!(
                "stages: {}",
                crate::bake::BakeStage::summary(&s.stages)
            ));
        }
        lines.push(format!(
            "view '{}' at {}x{}: {} pixels, J = {}; light sums {:.3} s, transfer {:.3} s; a rotated environment: \
             {:.3} s (sums + transfer, no rays)",
            self.camera.name, self.fit_size.0, self.fit_size.1, c.pixels, c.lobes, c.light_seconds, c.transfer_seconds,
            c.rotation_seconds
        ));
        lines.join("\n")
    }
}
