//! MERL isotropic BRDF tables (`<name>.binary`), as the MERL database and its `BRDFRead.cpp` define
//! them.
//!
//! Layout: three little-endian int32 dims (90, 90, 180), then three float64 blocks R, G, B of
//! 90·90·180 values, each stored divided by its channel scale (R 1/1500, G 1.15/1500, B 1.66/1500),
//! index \[θh\]\[θd\]\[φd\] = (i_θh·90 + i_θd)·180 + i_φd with i_θh = ⌊√(θh/(π/2))·90⌋, i_θd =
//! ⌊θd/(π/2)·90⌋, i_φd = ⌊φd/π·180⌋ after folding φd into [0, π) by reciprocity, each clamped.
//!
//! Inputs: a closure f(wi, wo) → RGB f_r (no cosine, local frame z = normal) for
//! [`MerlTable::sample`], or file bytes. Outputs: the table, its bytes ([`MerlTable::to_bytes`]),
//! the exporter ([`MerlExporter`]) and MERL's reference lookup ([`merl_lookup`], a line-by-line
//! port of `lookup_brdf_val` with `std_coords_to_half_diff_coords`: nearest cell, no
//! interpolation).
//!
//! Invariants: [`MerlTable::sample`] evaluates each cell at its centre (i+½ in index space; θh =
//! ((i+½)/90)²·π/2) with φh = 0; cells whose wi or wo is at or below the horizon are stored as 0
//! and the closure is not called for them; values are the true BRDF (the scales are applied only in
//! the file); reading checks dims and length and never panics.

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::material::{MaterialDesc, SceneMesh};
use std::f64::consts::PI;
use std::path::Path;

pub const THETA_H_RES: usize = 90;
pub const THETA_D_RES: usize = 90;
pub const PHI_D_RES: usize = 180;
/// Cells per channel.
pub const MERL_CELLS: usize = THETA_H_RES * THETA_D_RES * PHI_D_RES;
/// Stored = value / scale, per channel.
pub const MERL_SCALES: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// File size in bytes.
pub const MERL_FILE_BYTES: usize = 12 + 3 * 8 * MERL_CELLS;

/// A MERL table of true BRDF values (RGB per cell), index = (i_θh·90 + i_θd)·180 + i_φd.
#[derive(Clone, PartialEq)]
pub struct MerlTable {
    values: Vec<[f64; 3]>,
}

impl std::fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MerlTable {{ cells: {} }}", self.values.len())
    }
}

/// The cell index of (θh, θd, φd) with MERL's index functions (φd is folded by reciprocity).
pub fn merl_index(theta_h: f64, theta_d: f64, phi_d: f64) -> usize {
    // theta_half_index: a square-root mapping that puts more cells near the specular peak.
    let ih = if theta_h <= 0.0 || theta_h.is_nan() {
        0
    } else {
        let t = (theta_h / (PI / 2.0) * THETA_H_RES as f64 * THETA_H_RES as f64).sqrt();
        (t as i64).clamp(0, THETA_H_RES as i64 - 1) as usize
    };
    let id = ((theta_d / (PI * 0.5) * THETA_D_RES as f64) as i64).clamp(0, THETA_D_RES as i64 - 1)
        as usize;
    let phi = if phi_d < 0.0 { phi_d + PI } else { phi_d };
    let ip = ((phi / PI * PHI_D_RES as f64) as i64).clamp(0, PHI_D_RES as i64 - 1) as usize;
    (ih * THETA_D_RES + id) * PHI_D_RES + ip
}

/// Rodrigues rotation of `v` about the unit `axis` by `angle` (MERL's `rotate_vector`).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let d = (axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2]) * (1.0 - c);
    let cross = [
        axis[1] * v[2] - axis[2] * v[1],
        axis[2] * v[0] - axis[0] * v[2],
        axis[0] * v[1] - axis[1] * v[0],
    ];
    [
        v[0] * c + axis[0] * d + cross[0] * s,
        v[1] * c + axis[1] * d + cross[1] * s,
        v[2] * c + axis[2] * d + cross[2] * s,
    ]
}

fn normalized(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 {
        [v[0] / n, v[1] / n, v[2] / n]
    } else {
        v
    }
}

/// MERL's `std_coords_to_half_diff_coords` on direction vectors: (θh, φh, θd, φd).
pub fn half_diff_coords(wi: [f64; 3], wo: [f64; 3]) -> (f64, f64, f64, f64) {
    let angles = |w: [f64; 3]| {
        let w = normalized(w);
        (w[2].clamp(-1.0, 1.0).acos(), w[1].atan2(w[0]))
    };
    let (ti, fi) = angles(wi);
    let (to, fo) = angles(wo);
    let vec = |t: f64, f: f64| [t.sin() * f.cos(), t.sin() * f.sin(), t.cos()];
    let inv = normalized(vec(ti, fi));
    let outv = normalized(vec(to, fo));
    let half = normalized([
        (inv[0] + outv[0]) / 2.0,
        (inv[1] + outv[1]) / 2.0,
        (inv[2] + outv[2]) / 2.0,
    ]);
    let theta_half = half[2].clamp(-1.0, 1.0).acos();
    let fi_half = half[1].atan2(half[0]);
    let temp = rotate(inv, [0.0, 0.0, 1.0], -fi_half);
    let diff = rotate(temp, [0.0, 1.0, 0.0], -theta_half);
    (
        theta_half,
        fi_half,
        diff[2].clamp(-1.0, 1.0).acos(),
        diff[1].atan2(diff[0]),
    )
}

/// (wi, wo) for half/difference angles with φh = 0 (the inverse of [`half_diff_coords`]).
pub fn half_diff_to_dirs(theta_h: f64, theta_d: f64, phi_d: f64) -> ([f64; 3], [f64; 3]) {
    let d = [
        theta_d.sin() * phi_d.cos(),
        theta_d.sin() * phi_d.sin(),
        theta_d.cos(),
    ];
    let wi = rotate(d, [0.0, 1.0, 0.0], theta_h);
    let h = [theta_h.sin(), 0.0, theta_h.cos()];
    let k = 2.0 * (wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2]);
    let wo = [k * h[0] - wi[0], k * h[1] - wi[1], k * h[2] - wi[2]];
    (wi, wo)
}

/// The centre of cell (i_θh, i_θd, i_φd) in angles.
pub fn cell_centre(ih: usize, id: usize, ip: usize) -> (f64, f64, f64) {
    let t = (ih as f64 + 0.5) / THETA_H_RES as f64;
    (
        t * t * PI / 2.0,
        (id as f64 + 0.5) / THETA_D_RES as f64 * PI / 2.0,
        (ip as f64 + 0.5) / PHI_D_RES as f64 * PI,
    )
}

impl MerlTable {
    /// Fills every cell by calling `f(wi, wo)` at its centre (φh = 0); below-horizon cells are 0.
    pub fn sample(mut f: impl FnMut([f64; 3], [f64; 3]) -> [f64; 3]) -> Self {
        let mut values = vec![[0.0; 3]; MERL_CELLS];
        for ih in 0..THETA_H_RES {
            for id in 0..THETA_D_RES {
                for ip in 0..PHI_D_RES {
                    let (th, td, pd) = cell_centre(ih, id, ip);
                    let (wi, wo) = half_diff_to_dirs(th, td, pd);
                    if wi[2] > 0.0 && wo[2] > 0.0 {
                        values[(ih * THETA_D_RES + id) * PHI_D_RES + ip] = f(wi, wo);
                    }
                }
            }
        }
        Self { values }
    }

    /// A table from true values (length [`MERL_CELLS`]).
    pub fn from_values(values: Vec<[f64; 3]>) -> Result<Self, ExportError> {
        if values.len() != MERL_CELLS {
            return Err(ExportError::Merl {
                reason: format!("{} cells, expected {MERL_CELLS}", values.len()),
            });
        }
        Ok(Self { values })
    }

    /// The true values, index = (i_θh·90 + i_θd)·180 + i_φd.
    pub fn values(&self) -> &[[f64; 3]] {
        &self.values
    }

    /// The `.binary` bytes; every value must be finite.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ExportError> {
        if let Some(i) = self
            .values
            .iter()
            .position(|v| v.iter().any(|x| !x.is_finite()))
        {
            return Err(ExportError::Merl {
                reason: format!("cell {i} is not finite"),
            });
        }
        let mut out = Vec::with_capacity(MERL_FILE_BYTES);
        for d in [THETA_H_RES, THETA_D_RES, PHI_D_RES] {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for (k, scale) in MERL_SCALES.iter().enumerate() {
            for v in &self.values {
                out.extend_from_slice(&(v[k] / scale).to_le_bytes());
            }
        }
        Ok(out)
    }

    /// Parses `.binary` bytes (dims must be 90·90·180 in total, as `BRDFRead.cpp` checks).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ExportError> {
        let bad = |reason: String| Err(ExportError::Merl { reason });
        if bytes.len() < 12 {
            return bad(format!(
                "{} bytes is shorter than the 12-byte header",
                bytes.len()
            ));
        }
        let dim = |i: usize| {
            i32::from_le_bytes([
                bytes[4 * i],
                bytes[4 * i + 1],
                bytes[4 * i + 2],
                bytes[4 * i + 3],
            ]) as i64
        };
        let n = dim(0) * dim(1) * dim(2);
        if n != MERL_CELLS as i64 {
            return bad(format!(
                "dimensions {}x{}x{} do not hold {MERL_CELLS} cells",
                dim(0),
                dim(1),
                dim(2)
            ));
        }
        if bytes.len() != MERL_FILE_BYTES {
            return bad(format!("{} bytes, expected {MERL_FILE_BYTES}", bytes.len()));
        }
        let mut values = vec![[0.0; 3]; MERL_CELLS];
        for (k, scale) in MERL_SCALES.iter().enumerate() {
            let block = &bytes[12 + k * 8 * MERL_CELLS..12 + (k + 1) * 8 * MERL_CELLS];
            for (v, chunk) in values.iter_mut().zip(block.chunks_exact(8)) {
                let mut b = [0u8; 8];
                b.copy_from_slice(chunk);
                v[k] = f64::from_le_bytes(b) * scale;
            }
        }
        Ok(Self { values })
    }

    /// MERL's reference lookup: the nearest cell of (wi, wo) (no interpolation).
    pub fn lookup(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let (th, _, td, pd) = half_diff_coords(wi, wo);
        self.values
            .get(merl_index(th, td, pd))
            .copied()
            .unwrap_or([0.0; 3])
    }
}

/// MERL's `lookup_brdf_val` on a table or on `.binary` bytes.
pub fn merl_lookup(table: &MerlTable, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
    table.lookup(wi, wo)
}

/// Reads a `.binary` file.
pub fn read_merl(path: &Path) -> Result<MerlTable, ExportError> {
    let bytes = std::fs::read(path).map_err(|source| ExportError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    MerlTable::from_bytes(&bytes)
}

/// Writes `<name>.binary` from the description's MERL table (refuses when there is none).
#[derive(Debug, Clone, Copy, Default)]
pub struct MerlExporter;

impl Exporter for MerlExporter {
    fn name(&self) -> &'static str {
        "merl"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["binary"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        _scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        desc.validate()?;
        let table = desc.merl.as_ref().ok_or_else(|| ExportError::NoMerlTable {
            material: desc.name.clone(),
        })?;
        Ok(vec![OutputFile {
            path: dir.join(format!("{}.binary", desc.name)),
            bytes: table.to_bytes()?,
        }])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_diff_round_trips_and_cells_map_to_themselves() {
        for &(th, td, pd) in &[(0.3, 0.2, 0.5), (0.01, 0.7, 2.0), (0.6, 0.1, 3.0)] {
            let (wi, wo) = half_diff_to_dirs(th, td, pd);
            let (th2, fh2, td2, pd2) = half_diff_coords(wi, wo);
            assert!(
                (th - th2).abs() < 1e-9
                    && fh2.abs() < 1e-9
                    && (td - td2).abs() < 1e-9
                    && (pd - pd2).abs() < 1e-9,
                "{th2} {td2} {pd2}"
            );
        }
        for &(ih, id, ip) in &[(0, 0, 0), (45, 30, 90), (89, 89, 179), (10, 3, 7)] {
            let (th, td, pd) = cell_centre(ih, id, ip);
            assert_eq!(merl_index(th, td, pd), (ih * 90 + id) * 180 + ip);
        }
        // Reciprocity: φd and φd − π land in the same cell.
        assert_eq!(merl_index(0.2, 0.3, 0.4 - PI), merl_index(0.2, 0.3, 0.4));
    }

    #[test]
    fn bad_bytes_are_errors() {
        assert!(MerlTable::from_bytes(&[1, 2, 3]).is_err());
        let mut b = vec![0u8; MERL_FILE_BYTES];
        b[..4].copy_from_slice(&90i32.to_le_bytes());
        b[4..8].copy_from_slice(&90i32.to_le_bytes());
        b[8..12].copy_from_slice(&180i32.to_le_bytes());
        assert!(MerlTable::from_bytes(&b).is_ok());
        assert!(MerlTable::from_bytes(&b[..b.len() - 8]).is_err());
        b[8..12].copy_from_slice(&(-180i32).to_le_bytes());
        assert!(MerlTable::from_bytes(&b).is_err());
    }
}
