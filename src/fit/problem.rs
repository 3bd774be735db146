//! The fit problem per colour channel (method.md §5) and its solution.
//!
//!   minimise Σ_i w_i (B_i − ρd/π·E_i − Σ_j c_j T_ij)²  subject to  c ≥ 0,  Σ_j g_lj c_j ≤ 1 − ρd
//!
//! As a QP in c: H = TᵀWT, q = −TᵀW(B − ρd/π·E), constant ½ Σ w (B − ρd/π E)² so the objective is half
//! the weighted squared residual. Pixels of every view go into one H and q (multi-view fitting). H
//! does not change while the user paints (T and W do not), so a [`ChannelSystem`] keeps the solver with
//! H factored and only q changes per stroke.
//!
//! Inputs: transfers (T, E per pixel), targets and weights per pixel, the energy rows for the chosen
//! F0, ρd per channel, whether the energy rows apply. Outputs: coefficients per channel with residuals
//! and solver statistics. Invariants: no IO; f64 sums; the energy rows are dropped only when the user
//! asks (`energy_limit = false`); c ≥ 0 always.

use super::qp::{Constraint, QpError, QpSolver};
use crate::brdf::EnergyTable;
use crate::transfer::Transfer;
use rayon::prelude::*;

/// One view's contribution: its transfer and, per pixel, target radiance and least-squares weight.
pub struct ViewData<'a> {
    pub transfer: &'a Transfer,
    pub target: &'a [[f64; 3]],
    pub weight: &'a [f64],
}

/// Weighted normal equations of one channel: H (J×J, row-major), the right side r = TᵀW(B − ρd/π E),
/// and the constant Σ w (B − ρd/π E)².
#[derive(Debug, Clone)]
pub struct NormalEquations {
    pub j: usize,
    pub h: Vec<f64>,
    pub r: Vec<f64>,
    pub constant: f64,
    pub weight_sum: f64,
    pub pixels: usize,
}

/// Forms H = TᵀWT and TᵀW·(B − ρd/π E) for `channel` over all views (f64 accumulation; rows of H in
/// parallel).
pub fn normal_equations(views: &[ViewData], channel: usize, rho_d: f64) -> NormalEquations {
    let j = views.first().map_or(0, |v| v.transfer.lobes);
    // Gather √w·T columns (J × N, column-major by lobe) and √w·residual targets.
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); j];
    let mut y = Vec::new();
    let mut weight_sum = 0.0;
    for v in views {
        for (p, &w) in v.weight.iter().enumerate().take(v.transfer.pixels.len()) {
            let sw = w.max(0.0).sqrt();
            let row = v.transfer.t_row(p, channel);
            for (k, col) in cols.iter_mut().enumerate() {
                col.push(sw * row.get(k).copied().unwrap_or(0.0) as f64);
            }
            let diffuse = rho_d / std::f64::consts::PI * v.transfer.irradiance[p][channel];
            let b = v.target.get(p).map_or(0.0, |t| t[channel]);
            y.push(sw * (b - diffuse));
            weight_sum += w.max(0.0);
        }
    }
    let h_rows: Vec<Vec<f64>> = (0..j)
        .into_par_iter()
        .map(|a| (0..j).map(|b| if b < a { 0.0 } else { dot(&cols[a], &cols[b]) }).collect())
        .collect();
    let mut h = vec![0.0; j * j];
    for a in 0..j {
        for b in a..j {
            h[a * j + b] = h_rows[a][b];
            h[b * j + a] = h_rows[a][b];
        }
    }
    let r = cols.par_iter().map(|c| dot(c, &y)).collect();
    NormalEquations { j, h, r, constant: dot(&y, &y), weight_sum, pixels: y.len() }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    // Four partial sums: vectorises and is deterministic (fixed order).
    let mut s = [0.0f64; 4];
    let chunks = a.len() / 4;
    for i in 0..chunks {
        for k in 0..4 {
            s[k] += a[4 * i + k] * b[4 * i + k];
        }
    }
    let mut tail = 0.0;
    for i in 4 * chunks..a.len().min(b.len()) {
        tail += a[i] * b[i];
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// The per-channel system with its solver, kept across strokes (H fixed, q changing).
pub struct ChannelSystem {
    pub equations: NormalEquations,
    solver: QpSolver,
    /// Energy bound 1 − ρd (if the rows apply).
    pub bound: Option<f64>,
}

/// The result of one channel's solve.
#[derive(Debug, Clone)]
pub struct ChannelFit {
    pub coefficients: Vec<f64>,
    /// Weighted RMS residual √(Σ w r² / Σ w).
    pub residual_rms: f64,
    /// Energy rows that are active (at their bound).
    pub active_energy_rows: usize,
    pub active: Vec<Constraint>,
    pub iterations: usize,
    pub seconds: f64,
}

impl ChannelSystem {
    /// Factors H and sets up the constraints: c ≥ 0 and, with `energy`, G c ≤ 1 − ρd.
    pub fn new(equations: NormalEquations, energy: Option<(&EnergyTable, f64)>, rho_d: f64) -> Result<Self, QpError> {
        let j = equations.j;
        let (g, u, m, bound) = match energy {
            Some((table, f0)) => {
                let u = (1.0 - rho_d).max(0.0);
                (table.matrix(f0), vec![u; table.rows()], table.rows(), Some(u))
            }
            None => (Vec::new(), Vec::new(), 0, None),
        };
        let solver = QpSolver::new(&equations.h, j, &g, &u, m)?;
        Ok(Self { equations, solver, bound })
    }

    /// Solves with the current right side (warm-started from `warm` when given).
    pub fn solve(&self, warm: Option<&[Constraint]>) -> Result<ChannelFit, QpError> {
        let start = std::time::Instant::now();
        let q: Vec<f64> = self.equations.r.iter().map(|x| -x).collect();
        let sol = self.solver.solve(&q, warm)?;
        let seconds = start.elapsed().as_secs_f64();
        // ½‖√W(y − Tc)‖² = ½cᵀHc − rᵀc + ½ yᵀy; the objective the solver reports omits the constant.
        let sq = (2.0 * sol.objective + self.equations.constant).max(0.0);
        let residual_rms = (sq / self.equations.weight_sum.max(f64::MIN_POSITIVE)).sqrt();
        Ok(ChannelFit {
            residual_rms,
            active_energy_rows: sol.active.iter().filter(|c| matches!(c, Constraint::Row(_))).count(),
            active: sol.active,
            iterations: sol.iterations,
            seconds,
            coefficients: sol.c,
        })
    }
}
