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

/// Above this many multiply-adds (N·J²) H is formed as two halves side by side: 640×480 views at
/// J = 147 (N ≈ 45 K, 1e9), not the fit view (N ≈ 2.7 K, 6e7), where the three channels already
/// run side by side.
const GRAM_SPLIT_FLOPS: usize = 200_000_000;

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

/// Forms H = TᵀWT and TᵀW·(B − ρd/π E) for `channel` over all views, f64.
///
/// A = √W·T (N × J, row-major as T is stored) is gathered once and H = AᵀA is one blocked GEMM (faer),
/// sequential: deterministic, and safe to call from many threads at once (faer's rayon GEMM called from
/// concurrent callers thrashed: the fit tests took 317 s instead of 35 s).
pub fn normal_equations(views: &[ViewData], channel: usize, rho_d: f64) -> NormalEquations {
    let j = views.first().map_or(0, |v| v.transfer.lobes);
    let items: Vec<(usize, usize)> =
        views.iter().enumerate().flat_map(|(vi, v)| (0..v.weight.len().min(v.transfer.pixels.len())).map(move |p| (vi, p))).collect();
    let n = items.len();
    let mut buf = vec![0.0f64; n * j];
    let mut y = vec![0.0f64; n];
    let mut weight_sum = 0.0;
    for (i, &(vi, p)) in items.iter().enumerate() {
        let v = &views[vi];
        let w = v.weight[p].max(0.0);
        let sw = w.sqrt();
        for (x, t) in buf[i * j..(i + 1) * j].iter_mut().zip(v.transfer.t_row(p, channel)) {
            *x = sw * *t as f64;
        }
        let diffuse = rho_d / std::f64::consts::PI * v.transfer.irradiance[p][channel];
        y[i] = sw * (v.target.get(p).map_or(0.0, |t| t[channel]) - diffuse);
        weight_sum += w;
    }
    // AᵀA of a block of rows, sequential.
    let gram = |rows: &[f64]| {
        let m = rows.len() / j.max(1);
        let a = faer::MatRef::from_row_major_slice(rows, m, j);
        let mut out = faer::Mat::<f64>::zeros(j, j);
        faer::linalg::matmul::matmul(out.as_mut(), faer::Accum::Replace, a.transpose(), a, 1.0, faer::Par::Seq);
        out
    };
    // Large problems (a full-resolution view) split the rows into two fixed halves formed side by
    // side (rayon::join of two sequential GEMMs, so no oversubscription) and added: the split does not
    // depend on the thread count, so neither do the bits.
    let hm = if n * j * j >= GRAM_SPLIT_FLOPS && n >= 2 {
        let (top, bottom) = buf.split_at((n / 2) * j);
        let (mut x, y) = rayon::join(|| gram(top), || gram(bottom));
        for c in 0..j {
            for r in 0..j {
                x[(r, c)] += y[(r, c)];
            }
        }
        x
    } else {
        gram(&buf)
    };
    let mut h = vec![0.0f64; j * j];
    for r in 0..j {
        for c in r..j {
            // Symmetrise exactly (the GEMM's halves may differ in the last bit). faer's lower-triangle
            // product was tried (2026-11-22) and measured no faster at J = 147 (12.6 vs 12.1 ms for RGB).
            let v = 0.5 * (hm[(r, c)] + hm[(c, r)]);
            h[r * j + c] = v;
            h[c * j + r] = v;
        }
    }
    let mut r = vec![0.0f64; j];
    for (row, yi) in buf.chunks_exact(j.max(1)).zip(&y) {
        for (rk, x) in r.iter_mut().zip(row) {
            *rk += x * yi;
        }
    }
    let constant = y.iter().map(|v| v * v).sum();
    NormalEquations { j, h, r, constant, weight_sum, pixels: n }
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

/// Solves the three channels cold: red from scratch, green and blue warm-started from red's active set
/// (the channels differ only in the light's colour, so their active sets are alike). See
/// [`solve_rgb_from`].
pub fn solve_rgb(views: &[ViewData], energy: Option<(&EnergyTable, f64)>, rho_d: [f64; 3]) -> Result<Vec<ChannelFit>, QpError> {
    solve_rgb_from(views, energy, rho_d, None).map(Vec::from)
}

/// Solves the three channels, each warm-started from `warm[c]` (the previous fit's active sets) when
/// given; otherwise red cold and green and blue from red's active set. The result is the same as three
/// cold solves (the solver is exact from any start); only the time differs.
///
/// Parallel (rayon) but deterministic: each channel's H is formed and its QP solved sequentially, so
/// the bits do not depend on the schedule. Without `warm`, red's H and cold solve run beside the
/// forming of green's and blue's H; green and blue are then solved side by side.
pub fn solve_rgb_from(
    views: &[ViewData],
    energy: Option<(&EnergyTable, f64)>,
    rho_d: [f64; 3],
    warm: Option<&[Vec<Constraint>; 3]>,
) -> Result<[ChannelFit; 3], QpError> {
    let system = |c: usize| ChannelSystem::new(normal_equations(views, c, rho_d[c]), energy, rho_d[c]);
    match warm {
        Some(warm) => {
            let solve = |c: usize| system(c)?.solve(Some(&warm[c]));
            let (r, (g, b)) = rayon::join(|| solve(0), || rayon::join(|| solve(1), || solve(2)));
            Ok([r?, g?, b?])
        }
        None => {
            let (r, (g, b)) = rayon::join(|| system(0)?.solve(None), || rayon::join(|| system(1), || system(2)));
            let (r, g, b) = (r?, g?, b?);
            let (g, b) = rayon::join(|| g.solve(Some(&r.active)), || b.solve(Some(&r.active)));
            Ok([r, g?, b?])
        }
    }
}
