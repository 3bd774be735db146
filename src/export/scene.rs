//! The scene an export carries (glTF, USD, Mitsuba): the mesh with its tangent frames, the view as
//! a camera and the environment, taken from a bake (what `glint render` renders) or from an
//! imported scene.
//!
//! Inputs: a [`SceneChoice`] (the command line's --bake or --scene, --env and view options).
//! Output: a [`glint_exporters::SceneMesh`], and the files it came from in the [`Provenance`].
//! Invariants: the camera is the one `glint render` would use for the same options
//! ([`crate::scene::view::render_view`]); the environment carries its rotation.

use super::Provenance;
use crate::bake::{LoadBakeError, LoadedBake};
use crate::env::EnvError;
use crate::scene::ImportError;
use crate::scene::view::{ViewError, render_view};
use std::path::Path;

/// Where an export's scene comes from and how it is seen.
#[derive(Debug, Clone, Copy, Default)]
pub struct SceneChoice<'a> {
    /// A bake: its scene (refined mesh), frames and environment.
    pub bake: Option<&'a Path>,
    /// Else an imported scene, optionally with an environment map.
    pub scene: Option<&'a Path>,
    pub env: Option<&'a Path>,
    pub camera: Option<&'a str>,
    pub orbit: Option<&'a [f32]>,
    pub size: Option<&'a str>,
    /// The environment's rotation about +Y.
    pub rotate_deg: f64,
}

/// Why the scene of an export cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum ExportSceneError {
    #[error(transparent)]
    Bake(#[from] LoadBakeError),
    #[error(transparent)]
    Scene(#[from] ImportError),
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error(transparent)]
    View(#[from] ViewError),
    #[error("--env, --camera, --orbit and --size describe a scene: give --scene or --bake too")]
    NoScene,
}

/// The scene an export carries; `None` without a bake or a scene.
pub fn export_scene(
    choice: &SceneChoice,
    provenance: &mut Provenance,
) -> Result<Option<glint_exporters::SceneMesh>, ExportSceneError> {
    let (scene, tangents, env) = match (choice.bake, choice.scene) {
        (Some(b), _) => {
            let loaded = LoadedBake::open(b)?;
            provenance
                .bake(b)
                .scene_file(&loaded.header.scene_file)
                .env_file(&loaded.header.env_file);
            (loaded.scene, loaded.tangents, Some(loaded.env))
        }
        (None, Some(p)) => {
            let scene = crate::scene::import(p)?;
            let (_, tangents, _) = crate::bake::decisions::decide_frames(&scene.mesh);
            provenance.scene_file(p);
            if let Some(e) = choice.env {
                provenance.env_file(e);
            }
            (
                scene,
                tangents,
                choice.env.map(crate::env::load).transpose()?,
            )
        }
        (None, None)
            if choice.env.is_some()
                || choice.camera.is_some()
                || choice.orbit.is_some()
                || choice.size.is_some() =>
        {
            return Err(ExportSceneError::NoScene);
        }
        (None, None) => return Ok(None),
    };
    let (camera, w, h) = render_view(&scene, choice.camera, choice.orbit, choice.size)?;
    let mut mesh = scene_mesh(&scene.mesh, tangents.as_deref());
    mesh.camera = Some(scene_camera(&camera, w, h));
    mesh.environment = env.map(|e| scene_environment(&e, choice.rotate_deg.to_radians()));
    provenance.env_rotation_deg(choice.rotate_deg);
    Ok(Some(mesh))
}

/// The scene's mesh for the glTF and USD exporters.
pub fn scene_mesh(
    mesh: &crate::scene::Mesh,
    tangents: Option<&[glam::Vec4]>,
) -> glint_exporters::SceneMesh {
    glint_exporters::SceneMesh {
        positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
        normals: mesh.normals.iter().map(|n| n.to_array()).collect(),
        tangents: tangents.map(|t| t.iter().map(|v| v.to_array()).collect()),
        uvs: mesh
            .uvs
            .as_ref()
            .map(|u| u.iter().map(|v| v.to_array()).collect()),
        indices: mesh.triangles.iter().flatten().copied().collect(),
        camera: None,
        environment: None,
    }
}

/// The exporters' camera for a glint camera rendering a `width` × `height` image (its aspect
/// follows the image, as `glint render` sets it).
pub fn scene_camera(
    camera: &crate::scene::Camera,
    width: u32,
    height: u32,
) -> glint_exporters::SceneCamera {
    let m = camera.world_from_camera;
    let unit = |v: glam::Vec3| v.as_dvec3().normalize_or_zero().to_array();
    glint_exporters::SceneCamera {
        name: camera.name.clone(),
        eye: camera.eye().as_dvec3().to_array(),
        forward: unit(-m.z_axis.truncate()),
        up: unit(m.y_axis.truncate()),
        yfov_rad: camera.yfov_rad as f64,
        width,
        height,
        znear: camera.znear as f64,
        zfar: camera.zfar.map(|f| f as f64),
    }
}

/// The exporters' environment: the map's texels in glint's orientation, rotated by `rotation_rad`.
pub fn scene_environment(
    env: &crate::env::EnvMap,
    rotation_rad: f64,
) -> glint_exporters::SceneEnvironment {
    let source = std::path::Path::new(env.source())
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    glint_exporters::SceneEnvironment {
        source,
        width: env.width(),
        height: env.height(),
        texels: env.texels().to_vec(),
        rotation_rad,
    }
}
