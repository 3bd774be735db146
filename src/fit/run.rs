//! Running a fit from a bake and a stroke file: views → cameras → transfer → targets → per-channel
//! solves → a [`Material`](super::material::Material), in a fresh [`FitSession`].
//!
//! Inputs: a [`Baked`] scene (from a [`LoadedBake`] or built in memory), parsed strokes,
//! [`FitSettings`]. Output: the material and what was fitted (for `--dump-qp`). No IO (the CLI
//! reads and writes). Invariants: those of [`FitSession::fit`].

use super::qp::QpError;
use super::session::{FitInputs, FitSession};
pub use super::session::{FitOutcome, FittedView};
use super::strokes::{ViewSpec, ViewStrokes};
use crate::bake::{Cuts, LoadedBake};
use crate::env::EnvMap;
use crate::light::LightSums;
use crate::scene::{Camera, Scene, orbit_camera};
use crate::sphere::{DirectionSet, LightTree, LobeLayout, SphereError, srbf};
use glam::Vec4;

/// The user's parameters of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// Diffuse albedo per channel (set by the user, not fitted).
    pub rho_d: [f64; 3],
    pub f0: f64,
    /// Energy rows on (the physical default) or off (a physically impossible BRDF on purpose).
    pub energy_limit: bool,
    /// Lobe layout; `None`: the paper's hemicube where the scene has a tangent field, else 24
    /// rings.
    pub layout: Option<LobeLayout>,
    pub sigma: f64,
    /// Fit resolution; `None`: a quarter of each view's image size.
    pub fit_size: Option<(u32, u32)>,
    /// Environment rotation about +Y (radians).
    pub rotation_rad: f64,
}

impl Default for FitSettings {
    fn default() -> Self {
        Self {
            rho_d: [0.5; 3],
            f0: 0.04,
            energy_limit: true,
            layout: None,
            sigma: srbf::PAPER_SIGMA,
            fit_size: None,
            rotation_rad: 0.0,
        }
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

/// The camera a stroke view names, sized to the stroke file's image.
pub fn camera_for(
    scene: &Scene,
    view: &ViewSpec,
    image_size: [u32; 2],
) -> Result<Camera, FitError> {
    let names = || {
        scene
            .cameras
            .iter()
            .map(|c| c.name.clone())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut camera = match view {
        ViewSpec::Name(n) => scene
            .cameras
            .iter()
            .find(|c| &c.name == n)
            .cloned()
            .ok_or_else(|| FitError::UnknownView {
                view: format!("'{n}'"),
                available: names(),
            })?,
        ViewSpec::Index(i) => {
            scene
                .cameras
                .get(*i)
                .cloned()
                .ok_or_else(|| FitError::UnknownView {
                    view: format!("#{i}"),
                    available: names(),
                })?
        }
        ViewSpec::Orbit { orbit } => orbit_camera(
            &scene.bounds,
            orbit[0],
            orbit[1],
            orbit[2],
            image_size[0],
            image_size[1],
        ),
    };
    camera.width = image_size[0];
    camera.height = image_size[1];
    camera.aspect = image_size[0] as f32 / image_size[1].max(1) as f32;
    Ok(camera)
}

/// The default lobe layout for a scene with or without a tangent field.
pub fn default_layout(anisotropic: bool) -> LobeLayout {
    if anisotropic {
        LobeLayout::PAPER
    } else {
        LobeLayout::Isotropic { count: 24 }
    }
}

/// A bake as a one-shot fit reads it: the scene (its mesh is the one the cuts belong to), the
/// environment, the cuts, the direction set's resolution and the frames.
#[derive(Clone, Copy)]
pub struct Baked<'a> {
    pub scene: &'a Scene,
    pub env: &'a EnvMap,
    pub cuts: &'a Cuts,
    /// Directions per cube face of the bake's direction set.
    pub resolution: usize,
    pub tangents: Option<&'a [Vec4]>,
    pub anisotropic: bool,
}

impl<'a> From<&'a LoadedBake> for Baked<'a> {
    fn from(b: &'a LoadedBake) -> Self {
        Self {
            scene: &b.scene,
            env: &b.env,
            cuts: &b.cuts,
            resolution: b.header.decisions.resolution,
            tangents: b.tangents.as_deref(),
            anisotropic: b.header.decisions.anisotropic,
        }
    }
}

/// Runs one fit in a fresh [`FitSession`]: the light sums at the settings' rotation, each view's
/// transfer, one solve per channel.
pub fn fit(
    baked: &Baked,
    strokes: &[ViewStrokes],
    settings: &FitSettings,
) -> Result<FitOutcome, FitError> {
    let set = DirectionSet::cube(baked.resolution)?;
    let tree = LightTree::build(&set);
    let light = LightSums::new(baked.env, &set, &tree, settings.rotation_rad);
    let inputs = FitInputs {
        scene: baked.scene,
        mesh: &baked.scene.mesh,
        tangents: baked.tangents,
        anisotropic: baked.anisotropic,
        cuts: baked.cuts,
        tree: &tree,
        light: &light,
    };
    FitSession::default().fit(&inputs, strokes, settings)
}
