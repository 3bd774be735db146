//! `glint fit --dump-qp`: a fit's problem and solution as `.npy` files anyone can re-solve.
//!
//! Input: a [`FitOutcome`] and its [`FitSettings`]. Output: `T.npy`, `B.npy`, `w.npy`, `E.npy`,
//! `energy_rows.npy` (with the limit on), `bounds.npy`, `c.npy` and `meta.json` (the problem in
//! words) in a folder. Invariants: every file is written atomically; the arrays are f64, C order.

use super::run::FitSettings;
use super::session::FitOutcome;
use glint_exporters::npy::write_f64;
use std::path::{Path, PathBuf};

/// Why a dump failed.
#[derive(Debug, thiserror::Error)]
pub enum DumpError {
    #[error("cannot create {}: {source}", path.display())]
    Create {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Write(#[from] glint_exporters::AtomicWriteError),
}

/// Writes the problem and solution of `outcome` into `dir` (created if missing).
pub fn write_qp(dir: &Path, outcome: &FitOutcome, settings: &FitSettings) -> Result<(), DumpError> {
    std::fs::create_dir_all(dir).map_err(|source| DumpError::Create {
        path: dir.to_path_buf(),
        source,
    })?;
    let j = outcome.material.centres.len();
    let (mut t, mut b, mut w, mut e) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for v in &outcome.views {
        for p in 0..v.transfer.pixels.len() {
            for c in 0..3 {
                t.extend(v.transfer.t_row(p, c).iter().map(|x| *x as f64));
            }
            b.extend_from_slice(&v.target[p]);
            w.push(v.weight[p]);
            e.extend_from_slice(&v.transfer.irradiance[p]);
        }
    }
    let n = w.len();
    write_f64(&dir.join("T.npy"), &[n, 3, j], &t)?;
    write_f64(&dir.join("B.npy"), &[n, 3], &b)?;
    write_f64(&dir.join("w.npy"), &[n], &w)?;
    write_f64(&dir.join("E.npy"), &[n, 3], &e)?;
    let rows = outcome
        .energy
        .as_ref()
        .map(|table| (table.rows(), table.matrix(settings.f0)));
    if let Some((l, g)) = &rows {
        write_f64(&dir.join("energy_rows.npy"), &[*l, j], g)?;
    }
    write_f64(
        &dir.join("bounds.npy"),
        &[3],
        &settings.rho_d.map(|r| 1.0 - r),
    )?;
    let c: Vec<f64> = outcome
        .material
        .coefficients
        .iter()
        .flatten()
        .copied()
        .collect();
    write_f64(&dir.join("c.npy"), &[3, j], &c)?;
    let meta = serde_json::json!({
        "problem": "per channel k: minimise sum_i w_i (B[i,k] - rho_d[k]/pi E[i,k] - sum_j T[i,k,j] c[k,j])^2 subject to c[k] >= 0 and energy_rows @ c[k] <= bounds[k] (energy rows absent when the limit is off)",
        "rho_d": settings.rho_d,
        "f0": settings.f0,
        "energy_limit": settings.energy_limit,
        "pixels": n,
        "lobes": j,
        "energy_rows": rows.as_ref().map_or(0, |r| r.0),
        "files": ["T.npy", "B.npy", "w.npy", "E.npy", "energy_rows.npy", "bounds.npy", "c.npy"],
    });
    let text = serde_json::to_string_pretty(&meta).unwrap_or_default();
    glint_exporters::write_atomic(&dir.join("meta.json"), text.as_bytes())?;
    Ok(())
}
