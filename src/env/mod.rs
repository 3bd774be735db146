//! Equirectangular HDR environment maps: loading (`.exr`, `.hdr`), sanitising, statistics, the
//! direction ↔ texel mapping, per-texel solid angles and filtered lookup.
//!
//! # Conventions (the project's; every stage relies on them)
//!
//! * **World frame** is glTF's: right-handed, **+Y up**.
//! * **Direction → (u, v)**: for a unit direction `d`, `u = 0.5 + atan2(d.x, -d.z) / (2π)` in `[0,
//!   1)` and `v = acos(clamp(d.y, -1, 1)) / π` in `[0, 1]`. Texel column = `u·W`, row = `v·H`;
//!   **row 0 is the top (+Y)**. The image centre (`u = v = 0.5`) is direction **-Z**; `u = 0.75` is
//!   +X, `u = 0.25` is -X, `u = 0` (the left/right seam) is +Z.
//! * **(u, v) → direction**: `φ = 2π(u − 0.5)`, `θ = πv`, `d = (sinθ sinφ, cosθ, −sinθ cosφ)`.
//!   [`direction_to_uv`] and [`uv_to_direction`] are inverses of each other away from the poles.
//! * **Texel centres** are at `((i + 0.5)/W, (j + 0.5)/H)`. The texel in row `j` spans
//!   `θ ∈ [πj/H, π(j+1)/H]` and subtends `(2π/W)(cos θ0 − cos θ1)` steradians
//!   ([`EnvMap::texel_solid_angle`]); all texels together subtend 4π.
//! * **Rotation** about +Y by `rotation_rad` (right-hand rule about +Y, so +90° carries -Z to -X):
//!   the rotated environment is `L_rot(d) = L(R_y(−rotation_rad) · d)` ([`EnvMap::lookup`]).
//! * **Radiance** is linear RGB (whatever primaries the file uses), stored as `f32`; every sum over
//!   texels is accumulated in `f64`.
//! * **Sanitising**: on construction every negative, NaN or ±Inf channel becomes 0 (lossy codecs
//!   such as DWAB produce small negatives); a texel with any such channel is counted once in
//!   [`EnvStats::clamped_texels`].
//! * **Filtering**: [`EnvMap::lookup`] is bilinear over texel centres, wrapping horizontally and
//!   clamping vertically (no filtering across the poles).
//!
//! Loading refuses, before allocating pixel memory, any image whose declared size exceeds
//! [`MAX_SIDE`] per side or [`MAX_TEXELS`] in total. Images that are not 2:1 are accepted;
//! callers may warn using [`EnvMap::is_two_to_one`].

mod load;

use std::f64::consts::PI;
use std::fmt;
use std::path::PathBuf;

use glam::DVec3;

pub use load::load;

/// Largest accepted number of texels (width · height) of an environment map.
pub const MAX_TEXELS: usize = 64 * 1024 * 1024;

/// Largest accepted width or height of an environment map, in texels.
pub const MAX_SIDE: usize = 32768;

/// Name recorded as [`EnvMap::source`] for maps that were not loaded from a file.
pub const SYNTHETIC: &str = "synthetic";

/// Everything that can go wrong building or loading an environment map. Messages are one line and
/// name the file (or the synthetic source) and the cause.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// The file could not be opened or read.
    #[error("cannot read environment map {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file extension is neither `.exr` nor `.hdr`.
    #[error(
        "environment map {}: unsupported extension {:?} (expected .exr or .hdr)",
        path.display(),
        ext
    )]
    UnsupportedExtension { path: PathBuf, ext: String },
    /// The decoder rejected the file (corrupt, truncated, unsupported feature).
    #[error("cannot decode environment map {}: {message}", path.display())]
    Decode { path: PathBuf, message: String },
    /// An EXR file without a layer holding R, G and B (or Y) channels.
    #[error(
        "environment map {} has no layer with R, G, B (or Y) channels; channels found: [{}]",
        path.display(),
        channels.join(", ")
    )]
    NoRgbChannels {
        path: PathBuf,
        channels: Vec<String>,
    },
    /// The declared image size exceeds [`MAX_SIDE`] or [`MAX_TEXELS`]; refused before allocating.
    #[error(
        "environment map {} is too large: {width}x{height} (limits: {MAX_SIDE} per side, {MAX_TEXELS} texels)",
        path.display()
    )]
    TooLarge {
        path: PathBuf,
        width: u64,
        height: u64,
    },
    /// Width or height is zero.
    #[error("environment map {name} is empty ({width}x{height})")]
    Empty {
        name: String,
        width: usize,
        height: usize,
    },
    /// The texel buffer length does not equal width · height.
    #[error("environment map {name}: {len} texels given for a {width}x{height} image")]
    SizeMismatch {
        name: String,
        width: usize,
        height: usize,
        len: usize,
    },
}

/// Statistics of a sanitised environment map.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EnvStats {
    /// Largest channel value over all texels, after sanitising (0 for an all-black map).
    pub peak: f32,
    /// Solid-angle-weighted mean radiance over the sphere, per channel:
    /// `(1/4π) Σ_texels ω_texel · L_texel`.
    pub mean_radiance: [f64; 3],
    /// Number of texels that had at least one negative, NaN or infinite channel (now zeroed).
    pub clamped_texels: usize,
}

/// An equirectangular environment map (see the module docs for the conventions).
#[derive(Clone)]
pub struct EnvMap {
    width: usize,
    height: usize,
    /// Row-major, top row (+Y) first; every channel finite and ≥ 0.
    texels: Vec<[f32; 3]>,
    stats: EnvStats,
    source: String,
}

impl fmt::Debug for EnvMap {
    // Manual impl: printing every texel would flood logs.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EnvMap")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("source", &self.source)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// Maps a direction to equirectangular coordinates `(u, v)`, `u ∈ [0, 1)`, `v ∈ [0, 1]`.
///
/// `d` need not be unit length (it is normalised); a zero or non-finite `d` yields non-finite or
/// arbitrary-but-finite coordinates, never a panic.
pub fn direction_to_uv(d: DVec3) -> (f64, f64) {
    let len = d.length();
    let y = if len > 0.0 { d.y / len } else { 0.0 };
    let mut u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    // atan2 returns +π on the seam (x = +0, z > 0): fold u = 1 onto u = 0 to keep u in [0, 1).
    if u >= 1.0 {
        u -= 1.0;
    }
    let v = y.clamp(-1.0, 1.0).acos() / PI;
    (u, v)
}

/// Maps equirectangular coordinates to a unit direction:
/// `φ = 2π(u − 0.5)`, `θ = πv`, `d = (sinθ sinφ, cosθ, −sinθ cosφ)`.
pub fn uv_to_direction(u: f64, v: f64) -> DVec3 {
    let (sin_phi, cos_phi) = (2.0 * PI * (u - 0.5)).sin_cos();
    let (sin_theta, cos_theta) = (PI * v).sin_cos();
    DVec3::new(sin_theta * sin_phi, cos_theta, -sin_theta * cos_phi)
}

/// `R_y(angle) · d`: rotation about +Y by `angle` radians, right-hand rule
/// (`x' = cos·x + sin·z`, `z' = −sin·x + cos·z`).
pub fn rotate_y(d: DVec3, angle: f64) -> DVec3 {
    let (s, c) = angle.sin_cos();
    DVec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
}

impl EnvMap {
    /// Builds a map from row-major texels (top row first). Sanitises every negative, NaN or ±Inf
    /// channel to 0 and computes [`EnvStats`].
    pub fn from_rgb(
        width: usize,
        height: usize,
        mut texels: Vec<[f32; 3]>,
        source: impl Into<String>,
    ) -> Result<EnvMap, EnvError> {
        let source = source.into();
        if width == 0 || height == 0 {
            return Err(EnvError::Empty {
                name: source,
                width,
                height,
            });
        }
        if width.checked_mul(height) != Some(texels.len()) {
            return Err(EnvError::SizeMismatch {
                name: source,
                width,
                height,
                len: texels.len(),
            });
        }
        let mut clamped_texels = 0usize;
        let mut peak = 0.0f32;
        for texel in &mut texels {
            let mut bad = false;
            for c in texel.iter_mut() {
                if !c.is_finite() || *c < 0.0 {
                    *c = 0.0;
                    bad = true;
                } else if *c == 0.0 {
                    *c = 0.0; // normalise -0.0 to +0.0
                }
                peak = peak.max(*c);
            }
            clamped_texels += usize::from(bad);
        }
        let mut map = EnvMap {
            width,
            height,
            texels,
            stats: EnvStats {
                peak,
                mean_radiance: [0.0; 3],
                clamped_texels,
            },
            source,
        };
        map.stats.mean_radiance = map.compute_mean_radiance();
        Ok(map)
    }

    /// A constant map of radiance `rgb` (sanitised like [`EnvMap::from_rgb`]), for tests and
    /// furnace checks. Refuses sizes beyond [`MAX_SIDE`] / [`MAX_TEXELS`].
    pub fn uniform(width: usize, height: usize, rgb: [f32; 3]) -> Result<EnvMap, EnvError> {
        check_size(PathBuf::from(SYNTHETIC), width as u64, height as u64)?;
        if width == 0 || height == 0 {
            return Err(EnvError::Empty {
                name: SYNTHETIC.to_string(),
                width,
                height,
            });
        }
        EnvMap::from_rgb(width, height, vec![rgb; width * height], SYNTHETIC)
    }

    /// A map whose texels are `f(texel-centre direction)`, for tests and procedural
    /// environments. Refuses sizes beyond [`MAX_SIDE`] / [`MAX_TEXELS`].
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(DVec3) -> [f32; 3],
    ) -> Result<EnvMap, EnvError> {
        check_size(PathBuf::from(SYNTHETIC), width as u64, height as u64)?;
        let mut texels = Vec::with_capacity(width * height);
        for row in 0..height {
            for col in 0..width {
                texels.push(f(texel_centre_direction(width, height, col, row)));
            }
        }
        EnvMap::from_rgb(width, height, texels, SYNTHETIC)
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row-major texels, top row (+Y) first; index = `row · width + col`. All finite and ≥ 0.
    pub fn texels(&self) -> &[[f32; 3]] {
        &self.texels
    }

    /// The texel at `(col, row)`, or `None` out of range.
    pub fn texel(&self, col: usize, row: usize) -> Option<[f32; 3]> {
        if col < self.width && row < self.height {
            self.texels.get(row * self.width + col).copied()
        } else {
            None
        }
    }

    /// Statistics computed at construction.
    pub fn stats(&self) -> &EnvStats {
        &self.stats
    }

    /// File name the map was loaded from, or `"synthetic"`.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Whether width == 2 · height (the proper equirectangular aspect). Other sizes are accepted
    /// but stretch the texels; callers may warn.
    pub fn is_two_to_one(&self) -> bool {
        self.height.checked_mul(2) == Some(self.width)
    }

    /// Solid angle (sr) of one texel in `row`: `(2π/W)(cos θ0 − cos θ1)` with
    /// `θ0 = π·row/H`, `θ1 = π(row+1)/H`. 0 for a row out of range.
    pub fn texel_solid_angle(&self, row: usize) -> f64 {
        if row >= self.height {
            return 0.0;
        }
        let h = self.height as f64;
        let theta0 = PI * row as f64 / h;
        let theta1 = PI * (row + 1) as f64 / h;
        // cos θ0 − cos θ1 = 2 sin((θ0+θ1)/2) sin((θ1−θ0)/2): no cancellation near the poles.
        let band = 2.0 * (0.5 * (theta0 + theta1)).sin() * (0.5 * (theta1 - theta0)).sin();
        2.0 * PI / self.width as f64 * band
    }

    /// Unit direction of the centre of texel `(col, row)`.
    pub fn texel_direction(&self, col: usize, row: usize) -> DVec3 {
        texel_centre_direction(self.width, self.height, col, row)
    }

    /// Bilinearly filtered radiance arriving from direction `d` in the environment rotated about
    /// +Y by `rotation_rad`: `L(R_y(−rotation_rad) · d)`. Wraps horizontally, clamps vertically.
    /// A zero or non-finite `d` returns black.
    pub fn lookup(&self, d: DVec3, rotation_rad: f64) -> [f64; 3] {
        let d = if rotation_rad == 0.0 {
            d
        } else {
            rotate_y(d, -rotation_rad)
        };
        let (u, v) = direction_to_uv(d);
        self.lookup_uv(u, v)
    }

    /// Radiance of the texel holding direction `d` in the environment rotated by `rotation_rad`
    /// (the map read as constant over each texel: what the Monte Carlo reference integrates).
    /// Non-finite `d` returns black.
    pub fn lookup_nearest(&self, d: DVec3, rotation_rad: f64) -> [f64; 3] {
        let d = if rotation_rad == 0.0 {
            d
        } else {
            rotate_y(d, -rotation_rad)
        };
        let (u, v) = direction_to_uv(d);
        if !u.is_finite() || !v.is_finite() {
            return [0.0; 3];
        }
        let x = ((u * self.width as f64).floor() as i64).rem_euclid(self.width as i64) as usize;
        let y = ((v * self.height as f64).floor() as i64).clamp(0, self.height as i64 - 1) as usize;
        self.texels[y * self.width + x].map(|c| c as f64)
    }

    /// Bilinearly filtered radiance at equirectangular coordinates `(u, v)`; texel centres at
    /// `((i + 0.5)/W, (j + 0.5)/H)`. Wraps `u`, clamps `v`. Non-finite coordinates return black.
    pub fn lookup_uv(&self, u: f64, v: f64) -> [f64; 3] {
        if !u.is_finite() || !v.is_finite() {
            return [0.0; 3];
        }
        let w = self.width as i64;
        let h = self.height as i64;
        let x = u * self.width as f64 - 0.5;
        let y = v * self.height as f64 - 0.5;
        let x0f = x.floor();
        let y0f = y.floor();
        let fx = x - x0f;
        let fy = y - y0f;
        // Finite u, v: the float→int casts saturate, and rem_euclid / clamp bring them in range.
        let x0 = (x0f as i64).rem_euclid(w) as usize;
        let x1 = (x0f as i64).saturating_add(1).rem_euclid(w) as usize;
        let y0 = (y0f as i64).clamp(0, h - 1) as usize;
        let y1 = (y0f as i64).saturating_add(1).clamp(0, h - 1) as usize;
        let t = |col: usize, row: usize| self.texels[row * self.width + col];
        let (a, b, c, e) = (t(x0, y0), t(x1, y0), t(x0, y1), t(x1, y1));
        let mut out = [0.0; 3];
        for (k, o) in out.iter_mut().enumerate() {
            let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
            let bottom = c[k] as f64 * (1.0 - fx) + e[k] as f64 * fx;
            *o = top * (1.0 - fy) + bottom * fy;
        }
        out
    }

    fn compute_mean_radiance(&self) -> [f64; 3] {
        let mut total = [0.0f64; 3];
        for (row, texels) in self.texels.chunks_exact(self.width).enumerate() {
            let mut row_sum = [0.0f64; 3];
            for t in texels {
                for k in 0..3 {
                    row_sum[k] += t[k] as f64;
                }
            }
            let omega = self.texel_solid_angle(row);
            for k in 0..3 {
                total[k] += omega * row_sum[k];
            }
        }
        total.map(|s| s / (4.0 * PI))
    }
}

fn texel_centre_direction(width: usize, height: usize, col: usize, row: usize) -> DVec3 {
    uv_to_direction(
        (col as f64 + 0.5) / width as f64,
        (row as f64 + 0.5) / height as f64,
    )
}

/// Refuses sizes beyond [`MAX_SIDE`] per side or [`MAX_TEXELS`] in total.
fn check_size(path: PathBuf, width: u64, height: u64) -> Result<(), EnvError> {
    let too_large = width > MAX_SIDE as u64
        || height > MAX_SIDE as u64
        || width.saturating_mul(height) > MAX_TEXELS as u64;
    if too_large {
        Err(EnvError::TooLarge {
            path,
            width,
            height,
        })
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seam_and_axes() {
        let (u, v) = direction_to_uv(DVec3::new(0.0, 0.0, 1.0));
        assert!((0.0..1.0).contains(&u), "u = {u}");
        assert!((v - 0.5).abs() < 1e-15);
        let (u, _) = direction_to_uv(DVec3::X);
        assert!((u - 0.75).abs() < 1e-15);
        let (u, _) = direction_to_uv(-DVec3::X);
        assert!((u - 0.25).abs() < 1e-15);
        assert_eq!(direction_to_uv(DVec3::Y).1, 0.0);
        assert_eq!(direction_to_uv(-DVec3::Y).1, 1.0);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let map = EnvMap::uniform(8, 4, [1.0, 2.0, 3.0]).unwrap();
        assert_eq!(map.lookup(DVec3::ZERO, 0.0), [1.0, 2.0, 3.0]);
        assert_eq!(map.lookup(DVec3::splat(f64::NAN), 0.3), [0.0; 3]);
        assert_eq!(map.lookup_uv(1e300, -1e300), [1.0, 2.0, 3.0]);
        assert_eq!(map.texel(8, 0), None);
        assert_eq!(map.texel_solid_angle(4), 0.0);
        assert!(EnvMap::uniform(0, 4, [1.0; 3]).is_err());
        assert!(EnvMap::uniform(MAX_SIDE + 1, 1, [1.0; 3]).is_err());
        assert!(EnvMap::from_rgb(usize::MAX, 2, vec![], "x").is_err());
    }

    #[test]
    fn uniform_stats() {
        let map = EnvMap::uniform(64, 32, [0.5, 1.0, 2.0]).unwrap();
        let s = map.stats();
        assert_eq!(s.peak, 2.0);
        assert_eq!(s.clamped_texels, 0);
        for (m, e) in s.mean_radiance.iter().zip([0.5, 1.0, 2.0]) {
            assert!((m - e).abs() < 1e-12, "{m} vs {e}");
        }
        assert!(map.is_two_to_one());
    }
}
