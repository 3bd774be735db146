//! The view a command names: a camera of the scene by name, an orbit around its bounds, or the
//! scene's first camera (else the default camera), at an image size given as "WxH".
//!
//! Inputs: the scene and the command line's choices. Output: a [`Camera`] whose aspect follows the
//! image. Invariants: an unknown camera, a malformed orbit or a size outside 1..=8192 is a one-line
//! [`ViewError`], never a panic.

use super::{Camera, Scene, default_camera, orbit_camera};

/// Why a view cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error("--orbit takes three numbers: azimuth°,elevation°,distance")]
    Orbit,
    #[error("the scene has no camera named '{name}' (it has: {available})")]
    UnknownCamera { name: String, available: String },
    #[error("the scene has no camera")]
    NoCamera,
    #[error("size '{0}' is not WxH")]
    SizeFormat(String),
    #[error("size '{0}': {1}")]
    SizeNumber(String, std::num::ParseIntError),
    #[error("size {0}x{1} is outside 1..8192")]
    SizeRange(u32, u32),
}

/// The camera named, an orbit (azimuth°, elevation°, distance in bounding radii), or the scene's
/// first camera; the image size is the scene's first camera's (640×480 without one).
pub fn pick_view(
    scene: &Scene,
    name: Option<&str>,
    orbit: Option<&[f32]>,
) -> Result<Camera, ViewError> {
    if let Some(o) = orbit {
        let &[az, el, dist] = o else {
            return Err(ViewError::Orbit);
        };
        let (w, h) = scene
            .cameras
            .first()
            .map_or((640, 480), |c| (c.width, c.height));
        return Ok(orbit_camera(&scene.bounds, az, el, dist, w, h));
    }
    match name {
        Some(n) => scene
            .cameras
            .iter()
            .find(|c| c.name == n)
            .cloned()
            .ok_or_else(|| ViewError::UnknownCamera {
                name: n.to_string(),
                available: scene
                    .cameras
                    .iter()
                    .map(|c| c.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            }),
        None => scene.cameras.first().cloned().ok_or(ViewError::NoCamera),
    }
}

/// "WxH" → (W, H), both in 1..=8192.
pub fn parse_size(s: &str) -> Result<(u32, u32), ViewError> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| ViewError::SizeFormat(s.to_string()))?;
    let number = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|e| ViewError::SizeNumber(s.to_string(), e))
    };
    let (w, h) = (number(w)?, number(h)?);
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        return Err(ViewError::SizeRange(w, h));
    }
    Ok((w, h))
}

/// The camera `glint render` and `glint export` use, with its image size: [`pick_view`], else (no
/// camera and no orbit asked for) the default camera; `size` overrides the camera's own; the aspect
/// follows the image.
pub fn render_view(
    scene: &Scene,
    camera: Option<&str>,
    orbit: Option<&[f32]>,
    size: Option<&str>,
) -> Result<(Camera, u32, u32), ViewError> {
    let mut cam = match pick_view(scene, camera, orbit) {
        Ok(c) => c,
        Err(_) if camera.is_none() && orbit.is_none() => default_camera(&scene.bounds),
        Err(e) => return Err(e),
    };
    let (w, h) = match size {
        Some(s) => parse_size(s)?,
        None => (cam.width.max(1), cam.height.max(1)),
    };
    cam.aspect = w as f32 / h as f32;
    Ok((cam, w, h))
}
