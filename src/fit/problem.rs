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

/// Forms H = TᵀWT and TᵀW·(B − ρd/π E) for `channel` over all views, f64 accumulation.
///
/// T is stored row-major per pixel, so H is accumulated as Σ_p w_p a_p a_pᵀ (upper triangle, the inner
/// loop over contiguous lobes), over fixed chunks of 512 pixels summed in order: parallel, cache
/// friendly, and deterministic whatever the thread count.
pub fn normal_equations(views: &[ViewData], channel: usize, rho_d: f64) -> NormalEquations {
    let j = views.first().map_or(0, |v| v.transfer.lobes);
    // (view, pixel) list in order.
    let items: Vec<(usize, usize)> =
        views.iter().enumerate().flat_map(|(vi, v)| (0..v.weight.len().min(v.transfer.pixels.len())).map(move |p| (vi, p))).collect();
    const CHUNK: usize = 512;
    let partial: Vec<(Vec<f64>, Vec<f64>, f64, f64)> = items
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut h = vec![0.0f64; j * j];
            let mut r = vec![0.0f64; j];
            let (mut constant, mut weight_sum) = (0.0, 0.0);
            let mut a = vec![0.0f64; j];
            for &(vi, p) in chunk {
                let v = &views[vi];
                let w = v.weight[p].max(0.0);
                if w == 0.0 {
                    continue;
                }
                for (x, t) in a.iter_mut().zip(v.transfer.t_row(p, channel)) {
                    *x = *t as f64;
                }
                let diffuse = rho_d / std::f64::consts::PI * v.transfer.irradiance[p][channel];
                let y = v.target.get(p).map_or(0.0, |t| t[channel]) - diffuse;
                for k in 0..j {
                    let wk = w * a[k];
                    if wk == 0.0 {
                        continue;
                    }
                    let row = &mut h[k * j + k..(k + 1) * j];
                    for (hh, x) in row.iter_mut().zip(&a[k..]) {
                        *hh += wk * x;
                    }
                    r[k] += wk * y;
                }
                constant += w * y * y;
                weight_sum += w;
            }
            (h, r, constant, weight_sum)
        })
        .collect();
    let mut h = vec![0.0f64; j * j];
    let mut r = vec![0.0f64; j];
    let (mut constant, mut weight_sum) = (0.0, 0.0);
    for (ph, pr, pc, pw) in partial {
        for (a, b) in h.iter_mut().zip(&ph) {
            *a += b;
        }
        for (a, b) in r.iter_mut().zip(&pr) {
            *a += b;
        }
        constant += pc;
        weight_sum += pw;
    }
    for a in 0..j {
        for b in 0..a {
            h[a * j + b] = h[b * j + a];
        }
    }
    NormalEquations { j, h, r, constant, weight_sum, pixels: items.len() }
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
