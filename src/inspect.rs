//! `glint inspect`: what was imported, as plain data (the CLI prints it as text or JSON).
//!
//! Inputs: an imported [`Scene`] and optionally an [`EnvMap`]. Output: an [`InspectReport`] whose
//! JSON form has at least the keys `meshes`, `vertices`, `triangles`, `cameras`, and `env` →
//! `width`, `height`, `clamped_texels`. Invariant: no IO here; the report is a pure function of its
//! inputs.

use crate::env::EnvMap;
use crate::scene::{AttributeSource, PartInfo, Scene};
use serde::Serialize;
use std::fmt::Write;

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct InspectReport {
    pub file: String,
    /// Distinct glTF meshes instanced by the default scene.
    pub meshes: usize,
    /// Triangle primitive instances merged into the object.
    pub primitives: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub bounds: BoundsReport,
    /// Camera names; a file without perspective cameras gets one named "default".
    pub cameras: Vec<String>,
    pub default_camera: bool,
    /// For each attribute: "present" (every part had it), "generated" (computed by glint for at
    /// least one part), "absent" (no part had it) or "partial" (some parts had it, so the merged
    /// mesh has none).
    pub normals: String,
    pub tangents: String,
    pub uvs: String,
    pub normal_fallbacks: usize,
    pub skipped_primitives: usize,
    pub warnings: Vec<String>,
    pub parts: Vec<PartInfo>,
    pub env: Option<EnvReport>,
}

/// Axis-aligned bounds of the merged mesh.
#[derive(Debug, Clone, Serialize)]
pub struct BoundsReport {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub size: [f32; 3],
}

/// The environment map's part of the report.
#[derive(Debug, Clone, Serialize)]
pub struct EnvReport {
    pub file: String,
    pub width: usize,
    pub height: usize,
    /// Largest channel value after sanitising.
    pub peak: f32,
    /// Solid-angle-weighted mean radiance, RGB.
    pub mean_radiance: [f64; 3],
    /// Texels with a negative, NaN or infinite channel, set to 0.
    pub clamped_texels: usize,
    /// False when the image is not 2:1 (it is still read as equirectangular).
    pub two_to_one: bool,
}

fn summarise(parts: &[PartInfo], pick: impl Fn(&PartInfo) -> AttributeSource) -> String {
    let all = |s: AttributeSource| parts.iter().all(|p| pick(p) == s);
    let any = |s: AttributeSource| parts.iter().any(|p| pick(p) == s);
    if parts.is_empty() || all(AttributeSource::Absent) {
        "absent"
    } else if all(AttributeSource::Present) {
        "present"
    } else if any(AttributeSource::Generated) {
        "generated"
    } else {
        "partial"
    }
    .to_string()
}

/// Builds the report.
pub fn report(scene: &Scene, env: Option<&EnvMap>) -> InspectReport {
    let b = &scene.bounds;
    InspectReport {
        file: scene.source.display().to_string(),
        meshes: scene.mesh_count,
        primitives: scene.parts.len(),
        vertices: scene.mesh.positions.len(),
        triangles: scene.mesh.triangles.len(),
        bounds: BoundsReport {
            min: b.min.to_array(),
            max: b.max.to_array(),
            size: b.size().to_array(),
        },
        cameras: scene.cameras.iter().map(|c| c.name.clone()).collect(),
        default_camera: scene.cameras.iter().any(|c| c.is_default),
        normals: summarise(&scene.parts, |p| p.normals),
        tangents: summarise(&scene.parts, |p| p.tangents),
        uvs: summarise(&scene.parts, |p| p.uvs),
        normal_fallbacks: scene.normal_fallbacks,
        skipped_primitives: scene.skipped_primitives,
        warnings: scene.warnings.clone(),
        parts: scene.parts.clone(),
        env: env.map(|e| EnvReport {
            file: e.source().to_string(),
            width: e.width(),
            height: e.height(),
            peak: e.stats().peak,
            mean_radiance: e.stats().mean_radiance,
            clamped_texels: e.stats().clamped_texels,
            two_to_one: e.is_two_to_one(),
        }),
    }
}

impl InspectReport {
    /// Human-readable text, one fact per line.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "scene      {}", self.file);
        let _ = writeln!(
            s,
            "meshes     {} ({} triangle primitives)",
            self.meshes, self.primitives
        );
        let _ = writeln!(s, "vertices   {}", self.vertices);
        let _ = writeln!(s, "triangles  {}", self.triangles);
        let (mn, mx, sz) = (self.bounds.min, self.bounds.max, self.bounds.size);
        let _ = writeln!(
            s,
            "bounds     [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]  (size {:.4} x {:.4} x {:.4})",
            mn[0], mn[1], mn[2], mx[0], mx[1], mx[2], sz[0], sz[1], sz[2]
        );
        let cams = if self.default_camera {
            format!(
                "{} (none in the file: framing the bounds, 640x480)",
                self.cameras.join(", ")
            )
        } else {
            self.cameras.join(", ")
        };
        let _ = writeln!(s, "cameras    {cams}");
        let _ = writeln!(
            s,
            "normals    {}{}",
            self.normals,
            fallback_note(self.normal_fallbacks)
        );
        let _ = writeln!(s, "tangents   {}", self.tangents);
        let _ = writeln!(s, "uvs        {}", self.uvs);
        if self.skipped_primitives > 0 {
            let _ = writeln!(
                s,
                "skipped    {} non-triangle primitives",
                self.skipped_primitives
            );
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning    {w}");
        }
        if let Some(e) = &self.env {
            let _ = writeln!(s, "env        {}", e.file);
            let _ = writeln!(
                s,
                "  size     {} x {}{}",
                e.width,
                e.height,
                if e.two_to_one { "" } else { " (not 2:1)" }
            );
            let _ = writeln!(s, "  peak     {:.6}", e.peak);
            let m = e.mean_radiance;
            let _ = writeln!(
                s,
                "  mean     {:.6} {:.6} {:.6} (RGB, solid-angle weighted)",
                m[0], m[1], m[2]
            );
            let _ = writeln!(
                s,
                "  clamped  {} texels (negative, NaN or infinite, set to 0)",
                e.clamped_texels
            );
        }
        s
    }
}

fn fallback_note(n: usize) -> String {
    if n == 0 {
        String::new()
    } else {
        format!(" ({n} vertices needed a fallback normal)")
    }
}
