//! Cameras and bounds: the [`Camera`] and [`Bounds`] types, [`orbit_camera`], and conversion of
//! glTF perspective cameras.
//!
//! Inputs: bounds of the baked mesh, or a glTF camera and its node's world matrix. Outputs:
//! [`Camera`] values.
//!
//! Invariants: `world_from_camera` is rigid (orthonormal rotation, right-handed, plus translation;
//! glTF cameras look down their local −Z with +Y up); `yfov_rad` is in (0, π); `aspect` and `znear`
//! are finite and positive; `zfar` is `None` (infinite) or greater than `znear`; `width` and
//! `height` are at least 1. Projections are right-handed with depth in 0..1 (wgpu's convention).

use glam::{Mat4, Vec3, Vec4};
use gltf::json;
use gltf::json::validation::Checked;
use serde::Serialize;

/// Image width of every imported or default camera, in pixels.
pub const DEFAULT_WIDTH: u32 = 640;
/// Image height of the default camera, in pixels.
pub const DEFAULT_HEIGHT: u32 = 480;
/// Vertical field of view of the default camera, in degrees.
pub const DEFAULT_YFOV_DEG: f32 = 40.0;
/// Elevation of the default camera above the horizon, in degrees: the direction (0, 0.3, 1).
pub const DEFAULT_ELEVATION_DEG: f32 = 16.699_244; // atan(0.3) in degrees
/// Largest image height derived from a glTF camera's aspect ratio.
const MAX_HEIGHT: u32 = 16384;

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    /// Bounds of the finite points among `points`; `None` if there is none.
    pub fn from_points(points: &[Vec3]) -> Option<Bounds> {
        let mut it = points.iter().filter(|p| p.is_finite());
        let first = *it.next()?;
        let (min, max) = it.fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        Some(Bounds { min, max })
    }

    /// Centre of the box.
    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Side lengths of the box.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// Length of the box's diagonal.
    pub fn diagonal(&self) -> f32 {
        self.size().length()
    }

    /// Radius of the bounding sphere about [`Bounds::centre`]: half the diagonal.
    pub fn radius(&self) -> f32 {
        0.5 * self.diagonal()
    }
}

/// A perspective camera.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Camera {
    /// The glTF camera's name, else its node's name, else `camera N` (N = glTF camera index);
    /// `default` for the camera glint adds.
    pub name: String,
    /// Camera-to-world transform (rigid; the camera looks down its −Z, +Y up).
    pub world_from_camera: Mat4,
    /// Vertical field of view in radians.
    pub yfov_rad: f32,
    /// Width / height.
    pub aspect: f32,
    pub znear: f32,
    /// `None`: infinite far plane.
    pub zfar: Option<f32>,
    pub width: u32,
    pub height: u32,
    /// True for the camera glint adds when the file has no perspective camera.
    pub is_default: bool,
}

impl Camera {
    /// World-to-camera (view) transform.
    pub fn view_from_world(&self) -> Mat4 {
        self.world_from_camera.inverse()
    }

    /// Right-handed perspective projection with NDC depth 0..1 and +Y up, as wgpu expects (what
    /// glam before 0.34 called `Mat4::perspective_rh`; now `glam::camera::rh::proj::directx`), or
    /// its infinite-far variant when `zfar` is `None`; uses [`Camera::aspect`].
    pub fn clip_from_view(&self) -> Mat4 {
        use glam::camera::rh::proj::directx;
        match self.zfar {
            Some(far) => directx::perspective(self.yfov_rad, self.aspect, self.znear, far),
            None => directx::perspective_infinite(self.yfov_rad, self.aspect, self.znear),
        }
    }

    /// `clip_from_view() * view_from_world()`.
    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_view() * self.view_from_world()
    }

    /// Eye position in world space.
    pub fn eye(&self) -> Vec3 {
        self.world_from_camera.w_axis.truncate()
    }

    /// Unit viewing direction in world space (the camera's −Z).
    pub fn forward(&self) -> Vec3 {
        -self.world_from_camera.z_axis.truncate()
    }
}

/// Rigid camera-to-world matrix at `eye` looking along `forward` (non-zero) with +Y up where
/// possible (−Z/+Z up when looking straight down/up).
fn look_along(eye: Vec3, forward: Vec3) -> Mat4 {
    let back = (-forward).normalize_or(Vec3::Z);
    let mut right = Vec3::Y.cross(back);
    if right.length_squared() < 1e-12 {
        right = Vec3::X; // looking straight up or down
    }
    let right = right.normalize();
    let up = back.cross(right);
    Mat4::from_cols(
        right.extend(0.0),
        up.extend(0.0),
        back.extend(0.0),
        eye.extend(1.0),
    )
}

/// A camera looking at the centre of `bounds` from azimuth `az_deg` (about +Y, measured from +Z
/// towards +X) and elevation `el_deg` (up from the horizon), at `dist` bounding radii from the
/// centre; `dist <= 0` (or not finite) fits the bounding sphere (radius = half the diagonal) into
/// the smaller field of view with 10 % margin. Vertical field of view [`DEFAULT_YFOV_DEG`];
/// `znear`/`zfar` enclose the sphere with 10 % margin. Named `orbit`, not default.
/// Degenerate bounds (zero or non-finite radius) are treated as radius 1.
pub fn orbit_camera(
    bounds: &Bounds,
    az_deg: f32,
    el_deg: f32,
    dist: f32,
    width: u32,
    height: u32,
) -> Camera {
    let width = width.max(1);
    let height = height.max(1);
    let aspect = width as f32 / height as f32;
    let yfov = DEFAULT_YFOV_DEG.to_radians();
    let centre = if bounds.centre().is_finite() {
        bounds.centre()
    } else {
        Vec3::ZERO
    };
    let r = bounds.radius();
    let r = if r.is_finite() && r > 1e-12 { r } else { 1.0 };
    let half_y = 0.5 * yfov;
    let half_x = ((half_y).tan() * aspect).atan();
    let half = half_y.min(half_x);
    let d = if dist.is_finite() && dist > 0.0 {
        dist * r
    } else {
        1.1 * r / half.sin()
    };
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    let dir = Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
    let eye = centre + dir * d;
    let znear = (d - 1.1 * r).max(1e-3 * (d + r));
    let zfar = (d + 1.1 * r).max(znear * 2.0);
    Camera {
        name: "orbit".into(),
        world_from_camera: look_along(eye, -dir),
        yfov_rad: yfov,
        aspect,
        znear,
        zfar: Some(zfar),
        width,
        height,
        is_default: false,
    }
}

/// The camera glint adds when the file has none: [`orbit_camera`] at azimuth 0, elevation
/// [`DEFAULT_ELEVATION_DEG`], fitted, 640×480, named `default`.
pub fn default_camera(bounds: &Bounds) -> Camera {
    Camera {
        name: "default".into(),
        is_default: true,
        ..orbit_camera(
            bounds,
            0.0,
            DEFAULT_ELEVATION_DEG,
            0.0,
            DEFAULT_WIDTH,
            DEFAULT_HEIGHT,
        )
    }
}

/// Converts glTF camera `index` seen at a node with world matrix `world`. `Err` holds a warning
/// (orthographic or unusable camera) and the camera is skipped.
pub(crate) fn from_gltf(
    root: &json::Root,
    index: usize,
    node_name: Option<&str>,
    world: &Mat4,
) -> Result<Camera, String> {
    let Some(cam) = root.cameras.get(index) else {
        return Err(format!("camera {index} does not exist; skipped"));
    };
    let name = cam
        .name
        .clone()
        .or_else(|| node_name.map(str::to_owned))
        .unwrap_or_else(|| format!("camera {index}"));
    let persp = match (cam.type_, &cam.perspective) {
        (Checked::Valid(json::camera::Type::Perspective), Some(p)) => p,
        (Checked::Valid(json::camera::Type::Orthographic), _) => {
            return Err(format!("camera {name:?} is orthographic; skipped"));
        }
        _ => {
            return Err(format!(
                "camera {name:?} has no usable perspective projection; skipped"
            ));
        }
    };
    let yfov = persp.yfov;
    if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
        return Err(format!(
            "camera {name:?} has yfov {yfov}, not in (0, π); skipped"
        ));
    }
    let znear = persp.znear;
    if !(znear.is_finite() && znear > 0.0) {
        return Err(format!(
            "camera {name:?} has znear {znear}, not positive; skipped"
        ));
    }
    let zfar = persp.zfar.filter(|&f| f.is_finite() && f > znear);
    let aspect = persp
        .aspect_ratio
        .filter(|&a| a.is_finite() && a > 0.0)
        .unwrap_or(DEFAULT_WIDTH as f32 / DEFAULT_HEIGHT as f32);
    let height = (DEFAULT_WIDTH as f32 / aspect)
        .round()
        .clamp(1.0, MAX_HEIGHT as f32) as u32;

    // Remove scale and shear: keep the viewing axis (−Z), then up (+Y) made orthogonal to it.
    let back = world.z_axis.truncate();
    let up = world.y_axis.truncate();
    let Some(back) = back.try_normalize() else {
        return Err(format!(
            "camera {name:?}: its node's transform is singular; skipped"
        ));
    };
    let Some(up) = (up - back * up.dot(back)).try_normalize() else {
        return Err(format!(
            "camera {name:?}: its node's transform is singular; skipped"
        ));
    };
    let right = up.cross(back);
    let world_from_camera = Mat4::from_cols(
        right.extend(0.0),
        up.extend(0.0),
        back.extend(0.0),
        Vec4::new(world.w_axis.x, world.w_axis.y, world.w_axis.z, 1.0),
    );
    Ok(Camera {
        name,
        world_from_camera,
        yfov_rad: yfov,
        aspect,
        znear,
        zfar,
        width: DEFAULT_WIDTH,
        height,
        is_default: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Bounds {
        Bounds {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        }
    }

    #[test]
    fn orbit_fits_sphere_with_margin() {
        let b = unit_box();
        let c = orbit_camera(&b, 0.0, 0.0, 0.0, 640, 480);
        let r = b.radius();
        // Sphere's angular radius seen from the eye = asin(r / d) = asin(sin(20°) / 1.1).
        let d = c.eye().length();
        let expected = (20f32.to_radians().sin() / 1.1).asin();
        assert!(((r / d).asin() - expected).abs() < 1e-5);
        assert!((c.eye().normalize() - Vec3::Z).length() < 1e-6);
        assert!((c.forward() + Vec3::Z).length() < 1e-6);
        // The centre projects to the middle of the image, in front of the near plane.
        let clip = c.clip_from_world() * Vec4::new(0.0, 0.0, 0.0, 1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5 && ndc.z > 0.0 && ndc.z < 1.0);
    }

    #[test]
    fn orbit_azimuth_and_elevation() {
        let c = orbit_camera(&unit_box(), 90.0, 0.0, 2.0, 100, 100);
        assert!((c.eye() - Vec3::X * 2.0 * unit_box().radius()).length() < 1e-5);
        let c = orbit_camera(&unit_box(), 0.0, 90.0, 1.0, 100, 100);
        assert!(c.world_from_camera.is_finite());
        assert!((c.forward() + Vec3::Y).length() < 1e-5);
    }
}
