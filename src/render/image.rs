//! Rendered images: linear RGB radiance per pixel with a coverage mask, the background, comparisons
//! and the two output formats.
//!
//! Inputs: pixels from a renderer. Outputs: linear f32 EXR (exact radiance) or an 8-bit sRGB PNG
//! tone-mapped with the ACES filmic fit (Narkowicz 2015) after an exposure. Relative RMSE over the
//! pixels both images cover: ‖a − b‖₂ / ‖b‖₂ over all channels.
//!
//! Invariants: files are written atomically (temp file, then rename); pixels are row-major from the
//! top-left.

use crate::env::EnvMap;
use crate::scene::Camera;
use glam::{Vec3, Vec4};
use std::path::Path;

/// Why an image cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: unknown image extension (use .png or .exr)")]
    Extension { path: String },
    #[error("{path}: {reason}")]
    Encode { path: String, reason: String },
    #[error(transparent)]
    Write(#[from] glint_exporters::AtomicWriteError),
}

/// A linear RGB image with a coverage mask (pixels the object covers).
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
    pub covered: Vec<bool>,
}

impl Image {
    /// Black, nothing covered.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            pixels: vec![[0.0; 3]; n],
            covered: vec![false; n],
        }
    }

    /// Sets a covered pixel.
    pub fn set(&mut self, x: u32, y: u32, rgb: [f32; 3]) {
        let k = y as usize * self.width as usize + x as usize;
        self.pixels[k] = rgb;
        self.covered[k] = true;
    }

    /// Pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Number of covered pixels.
    pub fn covered_count(&self) -> usize {
        self.covered.iter().filter(|&&c| c).count()
    }

    /// Fills uncovered pixels with the environment seen through them (rotated by `rotation_rad`).
    pub fn fill_background(&mut self, env: &EnvMap, rotation_rad: f64, camera: &Camera) {
        let world_from_clip = camera.clip_from_world().inverse();
        let eye = camera.eye();
        for y in 0..self.height {
            for x in 0..self.width {
                let k = y as usize * self.width as usize + x as usize;
                if self.covered[k] {
                    continue;
                }
                let ndc_x = (x as f32 + 0.5) / self.width as f32 * 2.0 - 1.0;
                let ndc_y = 1.0 - (y as f32 + 0.5) / self.height as f32 * 2.0;
                let p = world_from_clip * Vec4::new(ndc_x, ndc_y, 0.5, 1.0);
                let d: Vec3 = (p.truncate() / p.w - eye).normalize_or_zero();
                self.pixels[k] = env.lookup(d.as_dvec3(), rotation_rad).map(|v| v as f32);
            }
        }
    }

    /// ‖a − b‖₂ / ‖b‖₂ over the pixels both cover (all channels); `None` when none is shared or b
    /// is 0.
    pub fn relative_rmse(&self, reference: &Image) -> Option<f64> {
        if self.width != reference.width || self.height != reference.height {
            return None;
        }
        let (mut num, mut den, mut n) = (0.0f64, 0.0f64, 0usize);
        for k in 0..self.pixels.len() {
            if self.covered[k] && reference.covered[k] {
                n += 1;
                for c in 0..3 {
                    let (a, b) = (self.pixels[k][c] as f64, reference.pixels[k][c] as f64);
                    num += (a - b) * (a - b);
                    den += b * b;
                }
            }
        }
        (n > 0 && den > 0.0).then(|| (num / den).sqrt())
    }

    /// Writes `.exr` (linear f32 RGBA, A the coverage) or `.png` (tone-mapped sRGB at `exposure`),
    /// atomically.
    pub fn write(&self, path: &Path, exposure: f32) -> Result<(), ImageError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let bytes = match ext.as_deref() {
            Some("exr") => self.exr_bytes().map_err(|reason| ImageError::Encode {
                path: path.display().to_string(),
                reason,
            })?,
            Some("png") => self
                .png_bytes(exposure)
                .map_err(|reason| ImageError::Encode {
                    path: path.display().to_string(),
                    reason,
                })?,
            _ => {
                return Err(ImageError::Extension {
                    path: path.display().to_string(),
                });
            }
        };
        glint_exporters::write_atomic(path, &bytes)?;
        Ok(())
    }

    /// The linear image as EXR bytes: f32 RGB radiance and A, the coverage (1 on object pixels, 0
    /// on the background), so a comparison can mask object pixels (docs/conventions.md §4).
    pub fn exr_bytes(&self) -> Result<Vec<u8>, String> {
        use exr::prelude::*;
        let w = self.width as usize;
        let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
            let p = self.pixels[y * w + x];
            (
                p[0],
                p[1],
                p[2],
                if self.covered[y * w + x] { 1.0f32 } else { 0.0 },
            )
        });
        let image = Image::from_channels((w, self.height as usize), channels);
        let mut out = std::io::Cursor::new(Vec::new());
        image
            .write()
            .to_buffered(&mut out)
            .map_err(|e| e.to_string())?;
        Ok(out.into_inner())
    }

    /// Tone-mapped 8-bit sRGB, as PNG bytes.
    pub fn png_bytes(&self, exposure: f32) -> Result<Vec<u8>, String> {
        let rgb: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| p.map(|v| tone_map(v, exposure)))
            .collect();
        let img =
            image::RgbImage::from_raw(self.width, self.height, rgb).ok_or("image size mismatch")?;
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png)
            .map_err(|e| e.to_string())?;
        Ok(out.into_inner())
    }
}

/// A linear value as the PNG writer and the app show it: times `exposure`, the ACES filmic curve
/// (`aces`), then sRGB-encoded to 8 bits.
pub fn tone_map(linear: f32, exposure: f32) -> u8 {
    encode_srgb(aces(linear.max(0.0) * exposure))
}

/// ACES filmic curve fit (Narkowicz 2015), input linear, output in [0, 1].
fn aces(x: f32) -> f32 {
    let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
    ((x * (a * x + b)) / (x * (c * x + d) + e)).clamp(0.0, 1.0)
}

fn encode_srgb(x: f32) -> u8 {
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}
