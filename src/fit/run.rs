//! Running a fit from a bake and a stroke file: views → cameras → transfer → targets → per-channel
//! solves → a [`Material`].
//!
//! Inputs: the scene, the environment, the bake's cuts and decisions, parsed strokes, [`FitSettings`].
//! Output: the material and what was fitted (for `--dump-qp`). No IO (the CLI reads and writes).
//! Invariants: the current rendering B' that strokes paint over is the diffuse one (c = 0), as the
//! paper starts; strokes off the object are counted and ignored; no strokes at all return the current
//! (zero-specular) material and say so.

use super::material::{FitStats, Material};
use super::problem::{ChannelFit, ViewData, solve_rgb};
use super::qp::QpError;
use super::strokes::{ViewSpec, ViewStrokes, targets};
use crate::bake::Cuts;
use crate::brdf::EnergyTable;
use crate::env::EnvMap;
use crate::light::LightSums;
use crate::scene::{Camera, Scene, orbit_camera};
use crate::sphere::{DirectionSet, LightTree, LobeLayout, LobeSet, SphereError, srbf};
use crate::transfer::{Transfer, TransferContext};
use glam::Vec4;

/// The user's parameters of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// Diffuse albedo per channel (set by the user, not fitted).
    pub rho_d: [f64; 3],
    pub f0: f64,
    /// Energy rows on (the physical default) or off (a physically impossible BRDF on purpose).
    pub energy_limit: bool,
    /// Lobe layout; `None`: the paper's hemicube where the scene has a tangent field, else 24 rings.
    pub layout: Option<LobeLayout>,
    pub sigma: f64,
    /// Fit resolution; `None`: a quarter of each view's image size.
    pub fit_size: Option<(u32, u32)>,
    /// Environment rotation about +Y (radians).
    pub rotation_rad: f64,
}

impl Default for FitSettings {
    fn default() -> Self {
        Self { rho_d: [0.5; 3], f0: 0.04, energy_limit: true, layout: None, sigma: srbf::PAPER_SIGMA, fit_size: None, rotation_rad: 0.0 }
    }
}

/// Why a fit cannot run.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error("stroke view {view}: no such camera (the scene has: {available})")]
    UnknownView { view: String, available: String },
    #[error("fit settings: {0}")]
    Settings(String),
    #[error("lobes: {0}")]
    Sphere(#[from] SphereError),
    #[error("solver: {0}")]
    Qp(#[from] QpError),
}

/// One fitted view.
pub struct FittedView {
    pub camera: Camera,
    pub fit_size: (u32, u32),
    pub transfer: Transfer,
    pub target: Vec<[f64; 3]>,
    pub weight: Vec<f64>,
}

/// Everything a fit produced.
pub struct FitOutcome {
    pub material: Material,
    pub views: Vec<FittedView>,
    pub energy: Option<EnergyTable>,
    pub channels: Vec<ChannelFit>,
}

/// The camera a stroke view names, sized to the stroke file's image.
pub fn camera_for(scene: &Scene, view: &ViewSpec, image_size: [u32; 2]) -> Result<Camera, FitError> {
    let names = || scene.cameras.iter().map(|c| c.name.clone()).collect::<Vec<_>>().join(", ");
    let mut camera = match view {
        ViewSpec::Name(n) => scene.cameras.iter().find(|c| &c.name == n).cloned().ok_or_else(|| FitError::UnknownView { view: format!("'{n}'"), available: names() })?,
        ViewSpec::Index(i) => scene.cameras.get(*i).cloned().ok_or_else(|| FitError::UnknownView { view: format!("#{i}"), available: names() })?,
        ViewSpec::Orbit { orbit } => orbit_camera(&scene.bounds, orbit[0], orbit[1], orbit[2], image_size[0], image_size[1]),
    };
    camera.width = image_size[0];
    camera.height = image_size[1];
    camera.aspect = image_size[0] as f32 / image_size[1].max(1) as f32;
    Ok(camera)
}

/// The default lobe layout for a scene with or without a tangent field.
pub fn default_layout(anisotropic: bool) -> LobeLayout {
    if anisotropic { LobeLayout::PAPER } else { LobeLayout::Isotropic { count: 24 } }
}

/// Runs the fit.
#[allow(clippy::too_many_arguments)]
pub fn fit(
    scene: &Scene,
    env: &EnvMap,
    cuts: &Cuts,
    resolution: usize,
    tangents: Option<&[Vec4]>,
    anisotropic: bool,
    strokes: &[ViewStrokes],
    settings: &FitSettings,
) -> Result<FitOutcome, FitError> {
    if settings.rho_d.iter().any(|r| !(0.0..=1.0).contains(r)) || !(0.0..=1.0).contains(&settings.f0) {
        return Err(FitError::Settings(format!("rho_d {:?} and f0 {} must lie in [0, 1]", settings.rho_d, settings.f0)));
    }
    let lambda = srbf::lambda_from_sigma(settings.sigma)?;
    let layout = settings.layout.unwrap_or_else(|| default_layout(anisotropic));
    if !layout.is_isotropic() && !anisotropic {
        return Err(FitError::Settings(format!("layout {} is anisotropic but the scene has no tangent field", layout.name())));
    }
    let lobes = LobeSet::new(layout, lambda)?;
    let set = DirectionSet::cube(resolution)?;
    let tree = LightTree::build(&set);
    let light = LightSums::new(env, &set, &tree, settings.rotation_rad);
    let ctx = TransferContext::new(&scene.mesh, cuts, &tree, &lobes, tangents, None);
    let mut views = Vec::new();
    let mut off_object = 0;
    let mut stroke_count = 0;
    for v in strokes {
        let camera = camera_for(scene, &v.view, v.image_size)?;
        let fit_size = settings.fit_size.unwrap_or(((v.image_size[0] / 4).max(1), (v.image_size[1] / 4).max(1)));
        let transfer = ctx.compute(&light, &camera, fit_size.0, fit_size.1, settings.f0);
        // The rendering strokes paint over: diffuse only.
        let zero = vec![0.0; lobes.len()];
        let current = transfer.render(settings.rho_d, [&zero, &zero, &zero]);
        let pixels: Vec<(u32, u32)> = transfer.pixels.iter().map(|p| (p.x, p.y)).collect();
        let t = targets(v, &pixels, fit_size, &current);
        off_object += t.off_object.len();
        stroke_count += v.strokes.len();
        views.push(FittedView { camera, fit_size, target: t.target, weight: t.weight, transfer });
    }
    let mut notes = Vec::new();
    if off_object > 0 {
        notes.push(format!("{off_object} stroke(s) touched no pixel of the object and were ignored"));
    }
    let pixels: usize = views.iter().map(|v| v.transfer.pixels.len()).sum();
    let active_strokes = stroke_count - off_object;
    if active_strokes == 0 || pixels == 0 {
        notes.push("no stroke touched the object: the current material (diffuse, no specular lobes) is returned unchanged".into());
        let stats = FitStats { pixels, views: views.len(), energy_limit: settings.energy_limit, strokes_off_object: off_object, notes, ..FitStats::default() };
        let zero = vec![0.0; lobes.len()];
        let material = Material::new(&lobes, settings.sigma, [zero.clone(), zero.clone(), zero], settings.rho_d, settings.f0, stats);
        return Ok(FitOutcome { material, views, energy: None, channels: Vec::new() });
    }
    let energy = settings.energy_limit.then(|| EnergyTable::clone(&EnergyTable::cached(&lobes)));
    let start = std::time::Instant::now();
    let data: Vec<ViewData> = views.iter().map(|v| ViewData { transfer: &v.transfer, target: &v.target, weight: &v.weight }).collect();
    let channels = solve_rgb(&data, energy.as_ref().map(|e| (e, settings.f0)), settings.rho_d)?;
    let solve_seconds = start.elapsed().as_secs_f64();
    let stats = FitStats {
        residual_rms: std::array::from_fn(|c| channels[c].residual_rms),
        active_energy_rows: std::array::from_fn(|c| channels[c].active_energy_rows),
        active_constraints: std::array::from_fn(|c| channels[c].active.len()),
        iterations: std::array::from_fn(|c| channels[c].iterations),
        solve_seconds,
        pixels,
        views: views.len(),
        energy_limit: settings.energy_limit,
        strokes_off_object: off_object,
        notes,
    };
    let coefficients = std::array::from_fn(|c| channels[c].coefficients.clone());
    let material = Material::new(&lobes, settings.sigma, coefficients, settings.rho_d, settings.f0, stats);
    Ok(FitOutcome { material, views, energy, channels })
}
