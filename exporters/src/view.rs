//! The view a scene export carries besides its mesh: the camera glint renders from and the
//! environment that lights it (docs/conventions.md §4–5).
//!
//! Inputs: plain data the caller fills from its own camera and environment map. Outputs: the types,
//! their validation, and [`SceneEnvironment::lookup_bilinear`] (glint's bilinear lookup, which the
//! Mitsuba exporter resamples). Invariants: no IO; validation rejects what would make a file
//! invalid.

use crate::error::ExportError;

/// A perspective camera in the world frame (right-handed, +Y up): it looks along `forward` with
/// `up` towards the top of the image; one ray per pixel through the pixel centre.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneCamera {
    /// The camera's name (`default`, `orbit`, or the glTF camera's).
    pub name: String,
    pub eye: [f64; 3],
    /// Unit viewing direction (the camera's −Z).
    pub forward: [f64; 3],
    /// Unit up direction (the camera's +Y), orthogonal to `forward`.
    pub up: [f64; 3],
    /// Vertical field of view in radians, in (0, π).
    pub yfov_rad: f64,
    pub width: u32,
    pub height: u32,
    pub znear: f64,
    /// `None`: infinite.
    pub zfar: Option<f64>,
}

impl SceneCamera {
    /// Checks finiteness, unit and orthogonal axes, the field of view and the image size.
    pub fn validate(&self) -> Result<(), ExportError> {
        let bad = |reason: String| Err(ExportError::InvalidView { reason });
        let n = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let numbers = self
            .eye
            .iter()
            .chain(&self.forward)
            .chain(&self.up)
            .chain([&self.yfov_rad, &self.znear]);
        if numbers.into_iter().any(|x| !x.is_finite()) || self.zfar.is_some_and(|f| !f.is_finite())
        {
            return bad(format!(
                "camera '{}' has a non-finite number",
                self.name.escape_debug()
            ));
        }
        let dot = self.forward[0] * self.up[0]
            + self.forward[1] * self.up[1]
            + self.forward[2] * self.up[2];
        if (n(self.forward) - 1.0).abs() > 1e-4
            || (n(self.up) - 1.0).abs() > 1e-4
            || dot.abs() > 1e-4
        {
            return bad(format!(
                "camera '{}': forward and up must be orthogonal unit vectors",
                self.name.escape_debug()
            ));
        }
        if !(self.yfov_rad > 0.0 && self.yfov_rad < std::f64::consts::PI) {
            return bad(format!(
                "camera '{}': the field of view {} rad is outside (0, pi)",
                self.name.escape_debug(),
                self.yfov_rad
            ));
        }
        // (finiteness was checked above, so the comparisons are total)
        if self.znear <= 0.0 || self.zfar.is_some_and(|f| f <= self.znear) {
            return bad(format!(
                "camera '{}': near {} and far {:?} planes are not 0 < near < far",
                self.name.escape_debug(),
                self.znear,
                self.zfar
            ));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(format!(
                "camera '{}': image size {}x{} is outside 1..16384",
                self.name.escape_debug(),
                self.width,
                self.height
            ));
        }
        Ok(())
    }

    /// The camera as `glint render --json` prints it (docs/conventions.md §4).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "name": self.name, "eye": self.eye, "forward": self.forward, "up": self.up, "right": self.right(),
            "yfov_deg": self.yfov_rad.to_degrees(), "width": self.width, "height": self.height,
            "znear": self.znear, "zfar": self.zfar, "pixel_centres": true,
        })
    }

    /// The camera's +X (image right): forward × up.
    pub fn right(&self) -> [f64; 3] {
        let (f, u) = (self.forward, self.up);
        [
            f[1] * u[2] - f[2] * u[1],
            f[2] * u[0] - f[0] * u[2],
            f[0] * u[1] - f[1] * u[0],
        ]
    }
}

/// An equirectangular environment map in glint's orientation (docs/conventions.md §5), rotated by
/// `rotation_rad` about +Y.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SceneEnvironment {
    /// A plain file name for reports (`studio_1k.exr`); not a path.
    pub source: String,
    pub width: usize,
    pub height: usize,
    /// Row-major linear RGB, row 0 at the top (+Y); non-negative and finite.
    pub texels: Vec<[f32; 3]>,
    pub rotation_rad: f64,
}

impl SceneEnvironment {
    /// Checks the size, the texels and the rotation.
    pub fn validate(&self) -> Result<(), ExportError> {
        let bad = |reason: String| Err(ExportError::InvalidView { reason });
        if self.width == 0 || self.height == 0 || self.width > 65536 || self.height > 32768 {
            return bad(format!(
                "the environment's size {}x{} is outside 1..65536 x 1..32768",
                self.width, self.height
            ));
        }
        if self.texels.len() != self.width * self.height {
            return bad(format!(
                "the environment has {} texels for {}x{}",
                self.texels.len(),
                self.width,
                self.height
            ));
        }
        if self
            .texels
            .iter()
            .flatten()
            .any(|x| !(x.is_finite() && *x >= 0.0))
        {
            return bad("the environment has a negative or non-finite texel".into());
        }
        if !self.rotation_rad.is_finite() {
            return bad("the environment's rotation is not finite".into());
        }
        Ok(())
    }

    /// glint's bilinear lookup at equirectangular (u, v): texel centres at ((i + 0.5)/W, (j +
    /// 0.5)/H), u wraps, v clamps (the map unrotated).
    pub fn lookup_bilinear(&self, u: f64, v: f64) -> [f64; 3] {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = u * self.width as f64 - 0.5;
        let y = v * self.height as f64 - 0.5;
        let (x0f, y0f) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0f, y - y0f);
        let x0 = (x0f as i64).rem_euclid(w) as usize;
        let x1 = (x0f as i64 + 1).rem_euclid(w) as usize;
        let y0 = (y0f as i64).clamp(0, h - 1) as usize;
        let y1 = (y0f as i64 + 1).clamp(0, h - 1) as usize;
        let t = |x: usize, y: usize| self.texels[y * self.width + x];
        let (a, b, c, d) = (t(x0, y0), t(x1, y0), t(x0, y1), t(x1, y1));
        std::array::from_fn(|k| {
            let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
            let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
            top * (1.0 - fy) + bottom * fy
        })
    }
}
