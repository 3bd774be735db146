//! The fit problem per colour channel (method.md §5) and its solution.
//!
//!   minimise Σ_i w_i (B_i − ρd/π·E_i − Σ_j c_j T_ij)²  subject to  c ≥ 0,  Σ_j g_lj c_j ≤ 1 − ρd
//!
//! As a QP in c: H = TᵀWT, q = −TᵀW(B − ρd/π·E), constant ½ Σ w (B − ρd/π E)² so the objective is
//! half the weighted squared residual. Pixels of every view go into one H and q (multi-view
//! fitting). H does not change while the user paints (T and W do not), so a [`ChannelSystem`] keeps
//! the solver with H factored and only q changes per stroke.
//!
//! Inputs: transfers (T, E per pixel), targets and weights per pixel, the energy rows for the
//! chosen F0, ρd per channel, whether the energy rows apply. Outputs: coefficients per channel with
//! residuals and solver statistics. Invariants: no IO; f64 sums; the energy rows are dropped only
//! when the user asks (`energy_limit = false`); c ≥ 0 always.

use super::qp::{Constraint, QpError, QpSolver};
use crate::brdf::EnergyTable;
use crate::transfer::Transfer;
use faer::linalg::matmul::triangular::BlockStructure;

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

/// Weighted normal equations of one channel: H (J×J, row-major), the right side r = TᵀW(B − ρd/π
/// E), and the constant Σ w (B − ρd/π E)².
#[derive(Debug, Clone)]
pub struct NormalEquations {
    pub j: usize,
    pub h: Vec<f64>,
    pub r: Vec<f64>,
    pub constant: f64,
    pub weight_sum: f64,
    pub pixels: usize,
}

/// Rows gathered per GEMM call: a block of √W·[T | y] (≈ 1.2 MB at J = 147) stays in cache, where
/// gathering all N rows first cost as much as the product itself (20 ms of 55 ms per channel at
/// 640×480, J = 147).
const GATHER_ROWS: usize = 512;

/// Forms H = TᵀWT and TᵀW·(B − ρd/π E) for `channel` over all views, f64.
///
/// A = √W·[T | y] with y = B − ρd/π E (N × (J+1)) is gathered a block of rows at a time and its
/// Gram matrix AᵀA accumulated by faer's lower-triangular GEMM, sequential: one product gives H
/// (the leading J×J), r (the last row) and Σ w y² (the corner), and the triangle halves the work.
/// Sequential so that it is deterministic and safe to call from many threads at once (faer's rayon
/// GEMM called from concurrent callers thrashed: the fit tests took 317 s instead of 35 s).
pub fn normal_equations(views: &[ViewData], channel: usize, rho_d: f64) -> NormalEquations {
    let j = views.first().map_or(0, |v| v.transfer.lobes);
    let items: Vec<(usize, usize)> = views
        .iter()
        .enumerate()
        .flat_map(|(vi, v)| (0..v.weight.len().min(v.transfer.pixels.len())).map(move |p| (vi, p)))
        .collect();
    let n = items.len();
    let jj = j + 1;
    // Lower triangle of AᵀA over a run of pixels, in fixed blocks of rows.
    let gram = |items: &[(usize, usize)]| {
        let mut out = faer::Mat::<f64>::zeros(jj, jj);
        let mut buf = vec![0.0f64; GATHER_ROWS.min(items.len()) * jj];
        for block in items.chunks(GATHER_ROWS) {
            for (row, &(vi, p)) in buf.chunks_exact_mut(jj).zip(block) {
                let v = &views[vi];
                let sw = v.weight[p].max(0.0).sqrt();
                for (x, t) in row[..j].iter_mut().zip(v.transfer.t_row(p, channel)) {
                    *x = sw * *t as f64;
                }
                let diffuse = rho_d / std::f64::consts::PI * v.transfer.irradiance[p][channel];
                row[j] = sw * (v.target.get(p).map_or(0.0, |t| t[channel]) - diffuse);
            }
            let a = faer::MatRef::from_row_major_slice(&buf[..block.len() * jj], block.len(), jj);
            faer::linalg::matmul::triangular::matmul(
                out.as_mut(),
                BlockStructure::TriangularLower,
                faer::Accum::Add,
                a.transpose(),
                BlockStructure::Rectangular,
                a,
                BlockStructure::Rectangular,
                1.0,
                faer::Par::Seq,
            );
        }
        out
    };
    // Large problems (a full-resolution view) split the pixels into two fixed halves formed side by
    // side (rayon::join of two sequential products, so no oversubscription) and added: the split
    // does not depend on the thread count, so neither do the bits.
    let g = if n * j * j >= GRAM_SPLIT_FLOPS && n >= 2 {
        let (top, bottom) = items.split_at(n / 2);
        let (mut x, y) = rayon::join(|| gram(top), || gram(bottom));
        for c in 0..jj {
            for r in c..jj {
                x[(r, c)] += y[(r, c)];
            }
        }
        x
    } else {
        gram(&items)
    };
    let mut h = vec![0.0f64; j * j];
    for c in 0..j {
        for r in c..j {
            h[r * j + c] = g[(r, c)];
            h[c * j + r] = g[(r, c)];
        }
    }
    let r = (0..j).map(|k| g[(j, k)]).collect();
    let weight_sum = items
        .iter()
        .map(|&(vi, p)| views[vi].weight[p].max(0.0))
        .sum();
    NormalEquations {
        j,
        h,
        r,
        constant: g[(j, j)],
        weight_sum,
        pixels: n,
    }
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
    pub fn new(
        equations: NormalEquations,
        energy: Option<(&EnergyTable, f64)>,
        rho_d: f64,
    ) -> Result<Self, QpError> {
        let j = equations.j;
        let (g, u, m, bound) = match energy {
            Some((table, f0)) => {
                let u = (1.0 - rho_d).max(0.0);
                (
                    table.matrix(f0),
                    vec![u; table.rows()],
                    table.rows(),
                    Some(u),
                )
            }
            None => (Vec::new(), Vec::new(), 0, None),
        };
        let solver = QpSolver::new(&equations.h, j, &g, &u, m)?;
        Ok(Self {
            equations,
            solver,
            bound,
        })
    }

    /// Solves with the current right side (warm-started from `warm` when given).
    pub fn solve(&self, warm: Option<&[Constraint]>) -> Result<ChannelFit, QpError> {
        let start = std::time::Instant::now();
        let q: Vec<f64> = self.equations.r.iter().map(|x| -x).collect();
        let sol = self.solver.solve(&q, warm)?;
        let seconds = start.elapsed().as_secs_f64();
        // ½‖√W(y − Tc)‖² = ½cᵀHc − rᵀc + ½ yᵀy; the objective the solver reports omits the
        // constant.
        let sq = (2.0 * sol.objective + self.equations.constant).max(0.0);
        let residual_rms = (sq / self.equations.weight_sum.max(f64::MIN_POSITIVE)).sqrt();
        Ok(ChannelFit {
            residual_rms,
            active_energy_rows: sol
                .active
                .iter()
                .filter(|c| matches!(c, Constraint::Row(_)))
                .count(),
            active: sol.active,
            iterations: sol.iterations,
            seconds,
            coefficients: sol.c,
        })
    }
}

/// Solves the three channels cold: red from scratch, green and blue warm-started from red's active
/// set (the channels differ only in the light's colour, so their active sets are alike). See
/// [`solve_rgb_from`].
pub fn solve_rgb(
    views: &[ViewData],
    energy: Option<(&EnergyTable, f64)>,
    rho_d: [f64; 3],
) -> Result<Vec<ChannelFit>, QpError> {
    solve_rgb_from(views, energy, rho_d, None).map(Vec::from)
}

/// Solves the three channels, each warm-started from `warm[c]` (the previous fit's active sets)
/// when given; otherwise red cold and green and blue from red's active set. The result is the same
/// as three cold solves (the solver is exact from any start); only the time differs.
///
/// Parallel (rayon) but deterministic: each channel's H is formed and its QP solved sequentially,
/// so the bits do not depend on the schedule. Without `warm`, red's H and cold solve run beside the
/// forming of green's and blue's H; green and blue are then solved side by side.
pub fn solve_rgb_from(
    views: &[ViewData],
    energy: Option<(&EnergyTable, f64)>,
    rho_d: [f64; 3],
    warm: Option<&[Vec<Constraint>; 3]>,
) -> Result<[ChannelFit; 3], QpError> {
    let system =
        |c: usize| ChannelSystem::new(normal_equations(views, c, rho_d[c]), energy, rho_d[c]);
    match warm {
        Some(warm) => {
            let solve = |c: usize| system(c)?.solve(Some(&warm[c]));
            let (r, (g, b)) = rayon::join(|| solve(0), || rayon::join(|| solve(1), || solve(2)));
            Ok([r?, g?, b?])
        }
        None => {
            let (r, (g, b)) = rayon::join(
                || system(0)?.solve(None),
                || rayon::join(|| system(1), || system(2)),
            );
            let (r, g, b) = (r?, g?, b?);
            let (g, b) = rayon::join(|| g.solve(Some(&r.active)), || b.solve(Some(&r.active)));
            Ok([r, g?, b?])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::PixelSample;

    fn transfer(n: usize, j: usize, seed: u64) -> Transfer {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 1_000_003) as f64 / 1_000_003.0
        };
        let pixel = PixelSample {
            x: 0,
            y: 0,
            triangle: 0,
            bary: [1.0, 0.0, 0.0],
            position: glam::Vec3::ZERO,
            normal: glam::Vec3::Z,
        };
        Transfer {
            width: 1,
            height: 1,
            pixels: vec![pixel; n],
            lobes: j,
            t: (0..n * 3 * j).map(|_| rnd() as f32).collect(),
            irradiance: (0..n).map(|_| [rnd(), rnd(), rnd()]).collect(),
            seconds: 0.0,
        }
    }

    /// H, r and the constant against the plain f64 sums over pixels, for two views whose pixel
    /// count is no multiple of the gather block and large enough (N·J² ≥ GRAM_SPLIT_FLOPS) that the
    /// product is formed as two halves; negative weights count as 0.
    #[test]
    fn normal_equations_equal_the_direct_sums() {
        let j = 147;
        let sizes = [5000, GRAM_SPLIT_FLOPS / (j * j) - 5000 + 777];
        let transfers: Vec<Transfer> = sizes
            .iter()
            .zip([3u64, 17])
            .map(|(&n, s)| transfer(n, j, s))
            .collect();
        let targets: Vec<Vec<[f64; 3]>> = sizes
            .iter()
            .map(|&n| {
                (0..n)
                    .map(|i| [0.3 + (i % 7) as f64 * 0.1, 0.2, -0.1])
                    .collect()
            })
            .collect();
        let weights: Vec<Vec<f64>> = sizes
            .iter()
            .map(|&n| (0..n).map(|i| [1.0, 0.1, -0.5, 0.0][i % 4]).collect())
            .collect();
        let views: Vec<ViewData> = (0..2)
            .map(|v| ViewData {
                transfer: &transfers[v],
                target: &targets[v],
                weight: &weights[v],
            })
            .collect();
        assert!(sizes.iter().sum::<usize>() * j * j >= GRAM_SPLIT_FLOPS);
        for channel in 0..3 {
            let rho_d = 0.4;
            let eq = normal_equations(&views, channel, rho_d);
            let mut h = vec![0.0f64; j * j];
            let mut r = vec![0.0f64; j];
            let (mut constant, mut weight_sum) = (0.0, 0.0);
            for v in &views {
                for p in 0..v.weight.len() {
                    let w = v.weight[p].max(0.0);
                    let t = v.transfer.t_row(p, channel);
                    let y = v.target[p][channel]
                        - rho_d / std::f64::consts::PI * v.transfer.irradiance[p][channel];
                    for a in 0..j {
                        r[a] += w * t[a] as f64 * y;
                        for b in 0..j {
                            h[a * j + b] += w * t[a] as f64 * t[b] as f64;
                        }
                    }
                    constant += w * y * y;
                    weight_sum += w;
                }
            }
            assert_eq!(eq.pixels, sizes.iter().sum::<usize>());
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-11 * b.abs().max(1.0);
            for k in 0..j * j {
                assert!(close(eq.h[k], h[k]), "H[{k}]: {} vs {}", eq.h[k], h[k]);
                assert_eq!(eq.h[k], eq.h[(k % j) * j + k / j], "H symmetric");
            }
            for k in 0..j {
                assert!(close(eq.r[k], r[k]), "r[{k}]: {} vs {}", eq.r[k], r[k]);
            }
            assert!(
                close(eq.constant, constant),
                "{} vs {constant}",
                eq.constant
            );
            assert!(close(eq.weight_sum, weight_sum));
        }
    }
}
