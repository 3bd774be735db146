//! An exact, warm-startable dual active-set QP solver (Goldfarb–Idnani 1983, the algorithm of
//! QuadProg) for the per-channel fit of method.md §5:
//!
//! ```text
//! minimise ½ cᵀ H c + qᵀ c   subject to   c_j ≥ 0 (j < n)   and   G c ≤ u   (m rows, m may be 0)
//! ```
//!
//! Inputs: `H` (n×n, row-major, symmetric positive semidefinite; in glint H = TᵀWT), `q` (n),
//! `G` (m×n, row-major; the energy rows, non-negative in glint) and `u` (m; u = 1 − ρd ≥ 0, so
//! c = 0 is feasible). Outputs: a [`QpSolution`] with the minimiser `c`, the objective (evaluated
//! with the *given* H), the active set with its multipliers, the iteration count and the
//! regularisation used. [`QpSolver`] owns the factorisation of H (computed once: H does not change
//! while the user paints) and solves for many `q`, cold or warm; [`solve`] and [`solve_warm`] are
//! one-shot conveniences.
//!
//! Method. Every constraint is written aᵀc ≥ b (a bound: a = e_j, b = 0; an energy row:
//! a = −G_i, b = −u_i). With H = LLᵀ, the solver keeps J = L⁻ᵀQ and the upper-triangular R of
//! L⁻¹N = Q[R; 0] for the matrix N of active normals, starts from the unconstrained minimiser,
//! repeatedly adds the most violated constraint (violation divided by ‖a‖) by primal/dual steps,
//! drops a constraint whose multiplier would turn negative, and updates J and R by Givens
//! rotations. Every step keeps the dual feasible and raises the dual objective.
//!
//! Regularisation. GI needs H ≻ 0, but a constant environment makes columns of T alike and H
//! nearly singular. The solver always factors H + δI with δ = 1e-12 · max diag(H) (1e-12 when
//! H = 0), accepted when every Cholesky pivot stays above δ/2: the exact pivots of a PSD H + δI
//! are ≥ δ, and f64 rounding moves them by about n·ε·max diag, below δ/2 for n up to ~2000. If a
//! pivot falls below δ/2 the ladder tries 1e-10, 1e-8, 1e-6 (× max diag) and then reports
//! [`QpError::NotPositiveDefinite`]. δ is relative, so scaling H and q together leaves c
//! unchanged; it is reported in [`QpSolution::regularisation`] and [`QpSolver::regularisation`],
//! changes c by a relative ~1e-12 where H is well conditioned and fixes the split along H's
//! (near-)null directions, where the objective does not care. The reported objective uses the
//! unregularised H.
//!
//! Warm starts. [`QpSolver::solve`] with `Some(previous_active)` imposes the previous active set
//! as equalities (skipping any normal that is dependent on those already imposed), releases the
//! constraints whose multipliers come out negative one at a time (most negative first, after
//! scaling by ‖a‖), and so starts GI from a dual-feasible point near the answer. The bounds of the
//! set are imposed in one block: one Cholesky of H + δI with the variables reordered (bounds
//! first, read as an upper-triangular factor) gives J and R directly, O(n³/3) in all instead of
//! O(n²) Givens rotations per bound; energy rows follow by rotations.
//!
//! Cold starts. [`QpSolver::solve`] with `None` first guesses the active bounds by a few
//! primal–dual active-set steps on the bound constraints alone (one Cholesky of the free block
//! each; `QpSolver::seed_bounds`) and warm-starts GI from that guess as above. The plain GI from
//! the unconstrained minimiser adds the ~100 active bounds of a typical fit one at a time, often
//! dropping and re-adding them (~300 steps at n = 147); [`QpSolver::solve_unseeded`] keeps that
//! path. Both end at the same minimiser: GI is exact from any dual-feasible start.
//!
//! Hot starts. Warm starts still rebuild J; [`QpSolver::solve_hot`] goes further and
//! keeps J and R of the last solve in a [`HotStart`], so re-solving after a small change of q costs
//! O(n²) per active-set change. The cached factor is rebuilt from the active list every
//! [`HOT_REFRESH`] hot solves so rounding in J cannot accumulate.
//!
//! Degeneracy. Ties (equal violations, equal step ratios) go to the lowest index, so the path is
//! deterministic. A normal whose component outside the active span is below
//! 1e-12·‖Jᵀa‖ + 64ε·‖J‖·‖a‖ counts as dependent and takes a pure dual step. Zero-length steps
//! (a multiplier already 0) only drop a constraint, so they cannot repeat more often than the
//! active set is large; every full step strictly raises the dual objective, so no active set
//! repeats (GI's finiteness). A constraint counts as violated only beyond 1e-12·(1 + |b| + Σ|a_j
//! c_j|) (rounding level), and an iteration cap of 20·(n + m) + 100 turns any residual cycling
//! into [`QpError::MaxIterations`]. At the end c is recomputed from the active set directly
//! (x = J₁R⁻ᵀb_A − J₂J₂ᵀq, no cancellation against a huge unconstrained minimiser), checked again,
//! active bounds are set to exactly 0 and rounding-level negatives clamped to 0.
//!
//! Invariants: deterministic (same inputs, same bits; no threads, no global state); f64
//! throughout; no IO; no panics on any input (bad sizes and NaN/∞ give [`QpError::BadInput`]);
//! on success c ≥ 0 exactly and G c ≤ u to 1e-12 relative to the row's scale, which is 1e-9
//! absolute whenever Σ_j |G_ij c_j| ≤ 1e3 (always, for non-negative energy rows with u ≤ 1).

use thiserror::Error;

/// Regularisation ladder, relative to max diag(H): the first rung at which Cholesky succeeds wins.
const REG_LADDER: [f64; 4] = [1e-12, 1e-10, 1e-8, 1e-6];
/// A constraint is violated when its slack is below −FEAS_REL·(1 + |b| + Σ|a_j c_j|).
const FEAS_REL: f64 = 1e-12;
/// Dependence test: ‖d₂‖ ≤ DEP_REL·‖d‖ + DEP_ABS·‖J‖·‖a‖.
const DEP_REL: f64 = 1e-12;
const DEP_ABS: f64 = 64.0 * f64::EPSILON;
/// Most primal–dual active-set steps of the cold start's guess ([`QpSolver::seed_bounds`]).
const SEED_ITERATIONS: usize = 12;
/// A [`HotStart`] factor is rebuilt from its active list after this many hot solves.
pub const HOT_REFRESH: usize = 64;

/// One inequality of the problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Constraint {
    /// c_j ≥ 0.
    Bound(usize),
    /// (G c)_i ≤ u_i.
    Row(usize),
}

/// The problem data, borrowed. `h` is n×n and `g` is m×n, both row-major.
#[derive(Debug, Clone, Copy)]
pub struct QpProblem<'a> {
    pub h: &'a [f64],
    pub q: &'a [f64],
    pub g: &'a [f64],
    pub u: &'a [f64],
    pub n: usize,
    pub m: usize,
}

/// The minimiser and its certificate.
#[derive(Debug, Clone, PartialEq)]
pub struct QpSolution {
    /// The minimiser (n).
    pub c: Vec<f64>,
    /// ½cᵀHc + qᵀc with the given (unregularised) H.
    pub objective: f64,
    /// The active constraints, in the order the solver added them (a good warm start as is).
    pub active: Vec<Constraint>,
    /// The multiplier of each active constraint, ≥ 0, for the constraint as written in
    /// [`Constraint`]: Hc + q = Σ_bounds λ_j e_j − Σ_rows μ_i G_iᵀ (up to δc and rounding).
    pub multipliers: Vec<f64>,
    /// GI steps (additions, drops and releases of the warm set); re-imposing the warm set is
    /// not counted.
    pub iterations: usize,
    /// δ of the factored H + δI (see the module doc).
    pub regularisation: f64,
}

/// Why a solve failed. One line each.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum QpError {
    #[error("the QP Hessian is not positive semidefinite (Cholesky failed with δ = 1e-6·max diag)")]
    NotPositiveDefinite,
    #[error("the QP constraints are infeasible")]
    Infeasible,
    #[error("the QP solver did not converge in {iterations} iterations")]
    MaxIterations { iterations: usize },
    #[error("bad QP input: {0}")]
    BadInput(String),
}

/// KKT residuals of a solution (absolute, ∞-norms), for tests and fit statistics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KktReport {
    /// ‖Hc + q − Σλ_j e_j + Σμ_i G_iᵀ‖∞.
    pub stationarity: f64,
    /// `stationarity` divided by the largest of ‖Hc‖∞, ‖q‖∞, ‖Σλ_j e_j‖∞, ‖Σμ_i G_iᵀ‖∞ (or 1 if
    /// all are 0).
    pub stationarity_relative: f64,
    /// max(0, max_j −c_j, max_i (Gc − u)_i).
    pub primal_infeasibility: f64,
    /// max(0, −min multiplier).
    pub dual_infeasibility: f64,
    /// max over active constraints of |multiplier · slack|.
    pub complementarity: f64,
}

/// The factorisation of H (and copies of G, u) for solving many q. Plain data: `Send + Sync`.
#[derive(Debug, Clone)]
pub struct QpSolver {
    n: usize,
    m: usize,
    /// Symmetrised, unregularised H (row-major), for the objective.
    h: Vec<f64>,
    g: Vec<f64>,
    u: Vec<f64>,
    /// Gᵀ (n×m row-major), for Gx as a sum of columns.
    gt: Vec<f64>,
    g_norm: Vec<f64>,
    /// ‖G_i‖₁ per row.
    g_l1: Vec<f64>,
    /// J₀ = L⁻ᵀ, column-major (upper triangular); equals L⁻¹ row-major.
    j0: Vec<f64>,
    /// Largest column norm of J₀ (≈ ‖H⁻¹‖^½), the scale of rounding in Jᵀa.
    j_scale: f64,
    delta: f64,
    key: u64,
}

/// The factor (J, R) and active set of a previous solve, for [`QpSolver::solve_hot`]. Start with
/// `HotStart::default()`; a `HotStart` from another solver (other H, G or u) is ignored.
#[derive(Debug, Clone, Default)]
pub struct HotStart {
    key: u64,
    n: usize,
    active: Vec<usize>,
    j: Vec<f64>,
    r: Vec<f64>,
    solves: usize,
}

impl HotStart {
    /// The active set it holds (empty when cold).
    pub fn active(&self) -> Vec<Constraint> {
        self.active
            .iter()
            .map(|&k| to_constraint(k, self.n))
            .collect()
    }

    /// Forget everything (the next hot solve starts cold).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

/// One-shot cold solve.
pub fn solve(problem: &QpProblem) -> Result<QpSolution, QpError> {
    QpSolver::from_problem(problem)?.solve(problem.q, None)
}

/// One-shot solve warm-started from a previous active set (see the module doc).
pub fn solve_warm(
    problem: &QpProblem,
    previous_active: &[Constraint],
) -> Result<QpSolution, QpError> {
    QpSolver::from_problem(problem)?.solve(problem.q, Some(previous_active))
}

impl QpSolver {
    /// Validates H, G, u, factors H + δI (see the module doc) and inverts the factor.
    /// Errors: [`QpError::BadInput`] for wrong sizes, NaN/∞ or a non-symmetric H;
    /// [`QpError::NotPositiveDefinite`] when even δ = 1e-6·max diag fails.
    pub fn new(h: &[f64], n: usize, g: &[f64], u: &[f64], m: usize) -> Result<Self, QpError> {
        let nn = n
            .checked_mul(n)
            .ok_or_else(|| bad(format!("n = {n} is too large")))?;
        let mn = m
            .checked_mul(n)
            .ok_or_else(|| bad(format!("m·n = {m}·{n} is too large")))?;
        if h.len() != nn {
            return Err(bad(format!(
                "h has {} entries, expected n² = {nn}",
                h.len()
            )));
        }
        if g.len() != mn {
            return Err(bad(format!(
                "g has {} entries, expected m·n = {mn}",
                g.len()
            )));
        }
        if u.len() != m {
            return Err(bad(format!("u has {} entries, expected m = {m}", u.len())));
        }
        check_finite("h", h)?;
        check_finite("g", g)?;
        check_finite("u", u)?;

        // Symmetrise, rejecting more than rounding-level asymmetry.
        let max_diag_abs = (0..n).map(|i| h[i * n + i].abs()).fold(0.0, f64::max);
        let mut hs = vec![0.0; nn];
        for i in 0..n {
            for j in 0..=i {
                let (a, b) = (h[i * n + j], h[j * n + i]);
                if (a - b).abs() > 1e-8 * (a.abs() + b.abs()) + 1e-14 * max_diag_abs {
                    return Err(bad(format!("h is not symmetric at ({i}, {j}): {a} vs {b}")));
                }
                let s = 0.5 * (a + b);
                hs[i * n + j] = s;
                hs[j * n + i] = s;
            }
        }

        let max_diag = (0..n).map(|i| hs[i * n + i]).fold(0.0, f64::max);
        let scale = if max_diag > 0.0 { max_diag } else { 1.0 };
        let mut factor = None;
        for rel in REG_LADDER {
            let delta = rel * scale;
            if let Some(l) = cholesky(&hs, n, delta) {
                factor = Some((l, delta));
                break;
            }
        }
        let (l, delta) = factor.ok_or(QpError::NotPositiveDefinite)?;
        let j0 = lower_inverse(&l, n);
        let j_scale = (0..n)
            .map(|k| dot(&j0[k * n..(k + 1) * n], &j0[k * n..(k + 1) * n]).sqrt())
            .fold(0.0, f64::max);
        if !j_scale.is_finite() {
            return Err(QpError::NotPositiveDefinite);
        }
        let g_norm = (0..m)
            .map(|i| dot(&g[i * n..(i + 1) * n], &g[i * n..(i + 1) * n]).sqrt())
            .collect();
        let g_l1 = (0..m)
            .map(|i| g[i * n..(i + 1) * n].iter().map(|v| v.abs()).sum())
            .collect();
        let mut gt = vec![0.0; mn];
        for i in 0..m {
            for j in 0..n {
                gt[j * m + i] = g[i * n + j];
            }
        }

        let mut key = 0xcbf2_9ce4_8422_2325u64;
        for w in [n as u64, m as u64]
            .into_iter()
            .chain(hs.iter().chain(g).chain(u).map(|v| v.to_bits()))
        {
            key = (key ^ w).wrapping_mul(0x0100_0000_01b3);
        }
        Ok(Self {
            n,
            m,
            h: hs,
            g: g.to_vec(),
            u: u.to_vec(),
            gt,
            g_norm,
            g_l1,
            j0,
            j_scale,
            delta,
            key: key | 1,
        })
    }

    /// [`QpSolver::new`] from a problem's H, G, u (its q is not used).
    pub fn from_problem(problem: &QpProblem) -> Result<Self, QpError> {
        Self::new(problem.h, problem.n, problem.g, problem.u, problem.m)
    }

    /// Number of variables.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of energy rows.
    pub fn m(&self) -> usize {
        self.m
    }

    /// δ of the factored H + δI.
    pub fn regularisation(&self) -> f64 {
        self.delta
    }

    /// Solves for `q`, cold (`None`) or warm-started from a previous active set (see the module
    /// doc). The answer does not depend on the warm set beyond rounding.
    pub fn solve(&self, q: &[f64], warm: Option<&[Constraint]>) -> Result<QpSolution, QpError> {
        self.check_q(q)?;
        let ids = match warm {
            Some(list) => self.constraint_ids(list)?,
            None => self.seed_bounds(q),
        };
        let mut w = self.block_start(q, &ids);
        w.settle()?;
        w.run()?;
        Ok(w.finish())
    }

    /// Solves for `q` by plain Goldfarb–Idnani from the unconstrained minimiser, adding constraints
    /// one at a time (no seed, no block start): the textbook path, kept as a second route to the
    /// same answer for tests and to measure what the seeded start saves.
    pub fn solve_unseeded(&self, q: &[f64]) -> Result<QpSolution, QpError> {
        self.check_q(q)?;
        let mut w = Work::new(
            self,
            q,
            self.j0.clone(),
            vec![0.0; self.n * self.n],
            Vec::new(),
        );
        w.settle()?;
        w.run()?;
        Ok(w.finish())
    }

    /// A working state with the constraints `ids` imposed as equalities: the bounds among them in
    /// one block ([`QpSolver::bound_factor`]: one Cholesky of the reordered H + δI, O(n³/3),
    /// instead of O(n²) Givens rotations per bound), then the energy rows one by one. Falls back to
    /// rotations for everything if the reordered factorisation fails (rounding at the edge of δ).
    fn block_start<'s>(&'s self, q: &'s [f64], ids: &[usize]) -> Work<'s> {
        let n = self.n;
        let mut seen = vec![false; n];
        let bounds: Vec<usize> = ids
            .iter()
            .copied()
            .filter(|&k| k < n && !std::mem::replace(&mut seen[k], true))
            .collect();
        let rows: Vec<usize> = ids.iter().copied().filter(|&k| k >= n).collect();
        let factor = if bounds.is_empty() {
            None
        } else {
            self.bound_factor(&bounds)
        };
        let mut w = match factor {
            Some((j, r)) => Work::new(self, q, j, r, bounds),
            None => {
                let mut w = Work::new(self, q, self.j0.clone(), vec![0.0; n * n], Vec::new());
                w.impose(&bounds);
                w
            }
        };
        w.impose(&rows);
        w
    }

    /// J and R of the GI invariants (JJᵀ = (H + δI)⁻¹, JᵀN = [R; 0]) for the active bounds
    /// `bounds` (distinct, in order) in one factorisation. Order the variables π = (bounds, the
    /// rest) and write P H Pᵀ = K Kᵀ with K *upper* triangular (the Cholesky factor of the matrix
    /// with the order reversed, σ = reverse π, read backwards). With M = PᵀK: MMᵀ = H, so
    /// J = M⁻ᵀ = PᵀK⁻ᵀ, and Jᵀe_{π(k)} = K⁻¹e_k is column k of the upper-triangular K⁻¹: the first
    /// |bounds| columns of K⁻¹ are R, with nothing below it. In terms of `B = H[σ][σ] = LLᵀ`:
    /// `J[row, c] = L⁻¹[n−1−c][pos_σ(row)]` and `R[i, c] = L⁻¹[n−1−i][n−1−c]`. None when a pivot of
    /// B + δI falls below δ/2 (the same acceptance rule as [`QpSolver::new`]).
    fn bound_factor(&self, bounds: &[usize]) -> Option<(Vec<f64>, Vec<f64>)> {
        let n = self.n;
        let qa = bounds.len();
        let mut in_bounds = vec![false; n];
        for &k in bounds {
            in_bounds[k] = true;
        }
        // σ = reverse(bounds ++ free): the free variables (descending), then the bounds reversed.
        let sigma: Vec<usize> = (0..n)
            .rev()
            .filter(|&k| !in_bounds[k])
            .chain(bounds.iter().rev().copied())
            .collect();
        let mut pos = vec![0usize; n];
        for (i, &k) in sigma.iter().enumerate() {
            pos[k] = i;
        }
        let mut b = vec![0.0; n * n];
        for (i, &si) in sigma.iter().enumerate() {
            let hrow = &self.h[si * n..(si + 1) * n];
            for (j, &sj) in sigma.iter().enumerate().take(i + 1) {
                b[i * n + j] = hrow[sj];
            }
        }
        let l = cholesky(&b, n, self.delta)?;
        let linv = lower_inverse(&l, n);
        let mut j = vec![0.0; n * n];
        for c in 0..n {
            let lrow = &linv[(n - 1 - c) * n..(n - c) * n];
            let col = &mut j[c * n..(c + 1) * n];
            for (row, x) in col.iter_mut().enumerate() {
                *x = lrow[pos[row]];
            }
        }
        let mut r = vec![0.0; n * n];
        for c in 0..qa {
            for i in 0..=c {
                r[c * n + i] = linv[(n - 1 - i) * n + (n - 1 - c)];
            }
        }
        if j.iter().chain(&r[..qa * n]).all(|v| v.is_finite()) {
            Some((j, r))
        } else {
            None
        }
    }

    /// A guess of the bounds active at the minimiser, for a cold start: the primal–dual active-set
    /// iteration (Hintermüller, Ito & Kunisch 2002) on the bound constraints alone (the energy rows
    /// are left to GI). From the unconstrained minimiser, A = {j : x_j < 0}; then repeatedly solve
    /// (H + δI)_FF x_F = −q_F with x_A = 0, take the multipliers λ_A = (Hx + q)_A, and move to A' =
    /// {j ∈ F : x_j < 0} ∪ {j ∈ A : λ_j > 0}, until A repeats or [`SEED_ITERATIONS`] pass. Each
    /// step is one Cholesky of the free block. Only a guess: GI from it is exact whatever it is.
    fn seed_bounds(&self, q: &[f64]) -> Vec<usize> {
        let n = self.n;
        // x = −(H + δI)⁻¹q = −J₀J₀ᵀq.
        let y: Vec<f64> = (0..n)
            .map(|c| dot(&self.j0[c * n..(c + 1) * n], q))
            .collect();
        let mut x = vec![0.0; n];
        for (c, &yc) in y.iter().enumerate() {
            axpy(-yc, &self.j0[c * n..(c + 1) * n], &mut x);
        }
        let mut active: Vec<bool> = x.iter().map(|&v| v < 0.0).collect();
        for _ in 0..SEED_ITERATIONS {
            let free: Vec<usize> = (0..n).filter(|&k| !active[k]).collect();
            let nf = free.len();
            let mut hff = vec![0.0; nf * nf];
            for (a, &fa) in free.iter().enumerate() {
                for (b, &fb) in free.iter().enumerate().take(a + 1) {
                    hff[a * nf + b] = self.h[fa * n + fb];
                }
            }
            let Some(l) = cholesky(&hff, nf, self.delta) else {
                break;
            };
            // Forward and back substitution: L Lᵀ x_F = −q_F.
            let mut v: Vec<f64> = free.iter().map(|&k| -q[k]).collect();
            for i in 0..nf {
                v[i] = (v[i] - dot(&l[i * nf..i * nf + i], &v[..i])) / l[i * nf + i];
            }
            // Lᵀ is upper triangular, and row-major L read column-major is Lᵀ.
            back_substitute(&l, nf, nf, &mut v);
            x.fill(0.0);
            for (&k, &vk) in free.iter().zip(&v) {
                x[k] = vk;
            }
            let next: Vec<bool> = (0..n)
                .map(|k| {
                    if active[k] {
                        dot(&self.h[k * n..(k + 1) * n], &x) + q[k] > 0.0
                    } else {
                        x[k] < 0.0
                    }
                })
                .collect();
            if next == active {
                break;
            }
            active = next;
        }
        (0..n).filter(|&k| active[k]).collect()
    }

    /// Solves for `q` starting from the factor and active set left in `hot` by the previous hot
    /// solve with this solver (cold when `hot` is empty or from another solver), and leaves the
    /// new factor there. The fastest way to re-solve after a small change of q. On error `hot`
    /// is cleared.
    pub fn solve_hot(&self, q: &[f64], hot: &mut HotStart) -> Result<QpSolution, QpError> {
        if let Err(e) = self.check_q(q) {
            hot.clear();
            return Err(e);
        }
        let nn = self.n * self.n;
        let same = hot.key == self.key;
        let reuse = same && hot.solves < HOT_REFRESH && hot.j.len() == nn && hot.r.len() == nn;
        let result = if reuse {
            let mut w = Work::new(
                self,
                q,
                std::mem::take(&mut hot.j),
                std::mem::take(&mut hot.r),
                std::mem::take(&mut hot.active),
            );
            hot.solves += 1;
            w.settle().and_then(|()| w.run()).map(|()| w)
        } else {
            let ids = if same {
                std::mem::take(&mut hot.active)
            } else {
                self.seed_bounds(q)
            };
            let mut w = self.block_start(q, &ids);
            hot.solves = 1;
            w.settle().and_then(|()| w.run()).map(|()| w)
        };
        match result {
            Ok(mut w) => {
                let solution = w.finish();
                hot.key = self.key;
                hot.n = self.n;
                hot.active = std::mem::take(&mut w.active);
                hot.j = std::mem::take(&mut w.j);
                hot.r = std::mem::take(&mut w.r);
                Ok(solution)
            }
            Err(e) => {
                hot.clear();
                Err(e)
            }
        }
    }

    fn check_q(&self, q: &[f64]) -> Result<(), QpError> {
        if q.len() != self.n {
            return Err(bad(format!(
                "q has {} entries, expected n = {}",
                q.len(),
                self.n
            )));
        }
        check_finite("q", q)
    }

    fn constraint_ids(&self, list: &[Constraint]) -> Result<Vec<usize>, QpError> {
        list.iter()
            .map(|&c| match c {
                Constraint::Bound(j) if j < self.n => Ok(j),
                Constraint::Row(i) if i < self.m => Ok(self.n + i),
                other => Err(bad(format!(
                    "warm constraint {other:?} out of range (n = {}, m = {})",
                    self.n, self.m
                ))),
            })
            .collect()
    }

    fn row(&self, i: usize) -> &[f64] {
        &self.g[i * self.n..(i + 1) * self.n]
    }

    /// ‖a_k‖.
    fn normal_norm(&self, k: usize) -> f64 {
        if k < self.n {
            1.0
        } else {
            self.g_norm[k - self.n]
        }
    }

    /// b_k.
    fn rhs(&self, k: usize) -> f64 {
        if k < self.n { 0.0 } else { -self.u[k - self.n] }
    }
}

/// The working state of one solve. Constraint ids: 0..n bounds, n..n+m rows.
struct Work<'s> {
    s: &'s QpSolver,
    q: &'s [f64],
    /// J, column-major n×n.
    j: Vec<f64>,
    /// R, column-major n×n, upper triangular in its leading qa×qa block.
    r: Vec<f64>,
    active: Vec<usize>,
    mult: Vec<f64>,
    is_active: Vec<bool>,
    x: Vec<f64>,
    /// Jᵀa_p (also scratch).
    d: Vec<f64>,
    /// Primal direction J₂d₂.
    z: Vec<f64>,
    /// Dual direction R⁻¹d₁ (also scratch).
    rv: Vec<f64>,
    /// J'ᵀa_l of the last removed constraint (see [`Work::remove_active`]).
    w: Vec<f64>,
    /// Gx (scratch of [`Work::most_violated`]).
    gx: Vec<f64>,
    iterations: usize,
    max_iterations: usize,
}

impl<'s> Work<'s> {
    fn new(s: &'s QpSolver, q: &'s [f64], j: Vec<f64>, r: Vec<f64>, active: Vec<usize>) -> Self {
        let n = s.n;
        let mut is_active = vec![false; n + s.m];
        for &k in &active {
            is_active[k] = true;
        }
        let qa = active.len();
        Self {
            s,
            q,
            j,
            r,
            active,
            mult: vec![0.0; qa],
            is_active,
            x: vec![0.0; n],
            d: vec![0.0; n],
            z: vec![0.0; n],
            rv: vec![0.0; n],
            w: vec![0.0; n],
            gx: vec![0.0; s.m],
            iterations: 0,
            max_iterations: 20 * (n + s.m) + 100,
        }
    }

    fn col(&self, c: usize) -> &[f64] {
        let n = self.s.n;
        &self.j[c * n..(c + 1) * n]
    }

    fn tick(&mut self) -> Result<(), QpError> {
        self.iterations += 1;
        if self.iterations > self.max_iterations {
            return Err(QpError::MaxIterations {
                iterations: self.max_iterations,
            });
        }
        Ok(())
    }

    /// d = Jᵀa_k.
    fn jt_normal(&mut self, k: usize) {
        let n = self.s.n;
        if k < n {
            for c in 0..n {
                self.d[c] = self.j[c * n + k];
            }
        } else {
            let row = self.s.row(k - n);
            for c in 0..n {
                self.d[c] = -dot(&self.j[c * n..(c + 1) * n], row);
            }
        }
    }

    /// Whether a_k (with d = Jᵀa_k) is dependent on the active normals, and ‖d₂‖².
    fn dependent(&self, k: usize) -> (bool, f64) {
        let qa = self.active.len();
        let d2 = dot(&self.d[qa..], &self.d[qa..]);
        let d1 = dot(&self.d[..qa], &self.d[..qa]);
        let tol = DEP_REL * (d1 + d2).sqrt() + DEP_ABS * self.s.j_scale * self.s.normal_norm(k);
        (d2.sqrt() <= tol, d2)
    }

    /// a_kᵀx − b_k.
    fn slack(&self, k: usize) -> f64 {
        let n = self.s.n;
        if k < n {
            self.x[k]
        } else {
            self.s.u[k - n] - dot(self.s.row(k - n), &self.x)
        }
    }

    /// The most violated inactive constraint (violation / ‖a‖; ties to the lowest id). The row
    /// products Gx are accumulated from the columns of G (vectorised axpys; zeros of x skipped).
    fn most_violated(&mut self) -> Option<usize> {
        let (n, m) = (self.s.n, self.s.m);
        let mut best = None;
        let mut best_v = 0.0;
        let mut x_max: f64 = 0.0;
        for k in 0..n {
            let s = self.x[k];
            x_max = x_max.max(s.abs());
            if !self.is_active[k] && s < -FEAS_REL * (1.0 + s.abs()) && -s > best_v {
                best_v = -s;
                best = Some(k);
            }
        }
        if m == 0 {
            return best;
        }
        self.gx.fill(0.0);
        for (j, &xj) in self.x.iter().enumerate() {
            if xj != 0.0 {
                axpy(xj, &self.s.gt[j * m..(j + 1) * m], &mut self.gx);
            }
        }
        for i in 0..m {
            let ui = self.s.u[i];
            let s = ui - self.gx[i];
            if self.is_active[n + i] || s >= 0.0 {
                continue;
            }
            // Violated beyond rounding: FEAS_REL·(1 + |u| + Σ|G_ij x_j|), with the cheap bound
            // ‖G_i‖₁‖x‖∞ ≥ Σ|G_ij x_j| tried first.
            let loose = FEAS_REL * (1.0 + ui.abs() + self.s.g_l1[i] * x_max);
            let violated = s < -loose || {
                let mag: f64 = self
                    .s
                    .row(i)
                    .iter()
                    .zip(&self.x)
                    .map(|(a, b)| (a * b).abs())
                    .sum();
                s < -FEAS_REL * (1.0 + ui.abs() + mag)
            };
            let v = -s / self.s.g_norm[i];
            if violated && v > best_v {
                best_v = v;
                best = Some(n + i);
            }
        }
        best
    }

    /// z = J₂d₂.
    fn primal_direction(&mut self) {
        let n = self.s.n;
        let qa = self.active.len();
        self.z.fill(0.0);
        for c in qa..n {
            let dc = self.d[c];
            if dc != 0.0 {
                axpy(dc, &self.j[c * n..(c + 1) * n], &mut self.z);
            }
        }
    }

    /// rv = R⁻¹d₁.
    fn dual_direction(&mut self) {
        let n = self.s.n;
        let qa = self.active.len();
        self.rv[..qa].copy_from_slice(&self.d[..qa]);
        back_substitute(&self.r, n, qa, &mut self.rv);
    }

    /// Appends constraint k (with d = Jᵀa_k, independent) to the active set: Givens rotations
    /// zero d below position qa, and d₁ becomes the new column of R.
    fn push_active(&mut self, k: usize, multiplier: f64) {
        let n = self.s.n;
        let qa = self.active.len();
        for i in (qa + 1..n).rev() {
            let b = self.d[i];
            if b == 0.0 {
                continue;
            }
            let a = self.d[i - 1];
            let h = norm2(a, b);
            let (ca, cb) = two_cols(&mut self.j, n, i - 1);
            rotate(ca, cb, a / h, b / h);
            self.d[i - 1] = h;
            self.d[i] = 0.0;
        }
        self.r[qa * n..qa * n + qa + 1].copy_from_slice(&self.d[..=qa]);
        self.active.push(k);
        self.mult.push(multiplier);
        self.is_active[k] = true;
    }

    /// Removes the active constraint at position l: R loses column l (upper Hessenberg after),
    /// Givens rotations on rows restore the triangle, and the same rotations act on J. Leaves
    /// w[..qa_old] = J'ᵀa_l (the removed normal in the new basis; its last entry belongs to the
    /// column J'[:, qa_new] that moved from J₁ to J₂).
    fn remove_active(&mut self, l: usize) {
        let n = self.s.n;
        let qa = self.active.len();
        let k = self.active.remove(l);
        self.mult.remove(l);
        self.is_active[k] = false;
        self.w[..=l].copy_from_slice(&self.r[l * n..l * n + l + 1]);
        self.w[l + 1..qa].fill(0.0);
        for c in l..qa - 1 {
            self.r.copy_within((c + 1) * n..(c + 1) * n + c + 2, c * n);
        }
        self.r[(qa - 1) * n..qa * n].fill(0.0);
        for c in l..qa - 1 {
            let a = self.r[c * n + c];
            let b = self.r[c * n + c + 1];
            if b == 0.0 {
                continue;
            }
            let h = norm2(a, b);
            let (cs, sn) = (a / h, b / h);
            for col in c + 1..qa - 1 {
                let (x, y) = (self.r[col * n + c], self.r[col * n + c + 1]);
                self.r[col * n + c] = cs * x + sn * y;
                self.r[col * n + c + 1] = cs * y - sn * x;
            }
            self.r[c * n + c] = h;
            self.r[c * n + c + 1] = 0.0;
            let (x, y) = (self.w[c], self.w[c + 1]);
            self.w[c] = cs * x + sn * y;
            self.w[c + 1] = cs * y - sn * x;
            let (ca, cb) = two_cols(&mut self.j, n, c);
            rotate(ca, cb, cs, sn);
        }
    }

    /// Releases the active constraint at position l and moves x and the multipliers to the
    /// minimiser on the smaller active set in O(n + qa²): with J', R' after the removal and
    /// w = J'ᵀa_l, x' = x − u_l·w_qa'·J'[:, qa'] and u' = u₋ₗ + u_l·R'⁻¹w[..qa'].
    fn release(&mut self, l: usize) {
        let n = self.s.n;
        let ul = self.mult[l];
        self.remove_active(l);
        let qa = self.active.len();
        let coef = -ul * self.w[qa];
        if coef != 0.0 {
            axpy(coef, &self.j[qa * n..(qa + 1) * n], &mut self.x);
        }
        back_substitute(&self.r, n, qa, &mut self.w);
        for k in 0..qa {
            self.mult[k] += ul * self.w[k];
        }
    }

    /// Imposes the listed constraints as equalities (duplicates and dependent ones skipped).
    fn impose(&mut self, ids: &[usize]) {
        for &k in ids {
            if self.is_active[k] {
                continue;
            }
            self.jt_normal(k);
            if !self.dependent(k).0 {
                self.push_active(k, 0.0);
            }
        }
    }

    /// x and the multipliers from the active set directly: x = J₁R⁻ᵀb_A − J₂J₂ᵀq and
    /// u = R⁻¹(R⁻ᵀb_A + J₁ᵀq).
    fn recompute(&mut self) {
        let n = self.s.n;
        let qa = self.active.len();
        for c in 0..n {
            self.d[c] = dot(self.col(c), self.q);
        }
        for k in 0..qa {
            let t = self.s.rhs(self.active[k]) - dot(&self.r[k * n..k * n + k], &self.rv[..k]);
            self.rv[k] = t / self.r[k * n + k];
        }
        self.x.fill(0.0);
        for c in 0..n {
            let coef = if c < qa { self.rv[c] } else { -self.d[c] };
            if coef != 0.0 {
                axpy(coef, &self.j[c * n..(c + 1) * n], &mut self.x);
            }
        }
        for k in 0..qa {
            self.rv[k] += self.d[k];
        }
        back_substitute(&self.r, n, qa, &mut self.rv);
        self.mult.clear();
        self.mult.extend_from_slice(&self.rv[..qa]);
    }

    /// Recomputes x and the multipliers, then releases negative multipliers one at a time (most
    /// negative after scaling by ‖a‖ first; see [`Work::release`]): afterwards the state is
    /// dual feasible.
    fn settle(&mut self) -> Result<(), QpError> {
        self.recompute();
        loop {
            let mut worst = None;
            let mut worst_v = 0.0;
            for (pos, (&k, &u)) in self.active.iter().zip(&self.mult).enumerate() {
                let v = u * self.s.normal_norm(k);
                if v < worst_v {
                    worst_v = v;
                    worst = Some(pos);
                }
            }
            match worst {
                Some(l) => {
                    self.tick()?;
                    self.release(l);
                }
                None => return Ok(()),
            }
        }
    }

    /// The GI main loop from a dual-feasible state; ends with a direct recomputation.
    fn run(&mut self) -> Result<(), QpError> {
        let mut refined = false;
        loop {
            match self.most_violated() {
                Some(p) => {
                    refined = false;
                    self.add_violated(p)?;
                }
                None if refined => return Ok(()),
                None => {
                    self.settle()?;
                    refined = true;
                }
            }
        }
    }

    /// Steps until the violated constraint p joins the active set.
    fn add_violated(&mut self, p: usize) -> Result<(), QpError> {
        let mut up = 0.0;
        loop {
            self.tick()?;
            let sp = self.slack(p);
            self.jt_normal(p);
            let (dep, dd2) = self.dependent(p);
            if !dep {
                self.primal_direction();
            }
            self.dual_direction();
            let qa = self.active.len();
            let mut t1 = f64::INFINITY;
            let mut l = 0;
            for k in 0..qa {
                let rk = self.rv[k];
                if rk > 0.0 {
                    let ratio = self.mult[k] / rk;
                    if ratio < t1 {
                        t1 = ratio;
                        l = k;
                    }
                }
            }
            let t2 = if dep {
                f64::INFINITY
            } else {
                (-sp / dd2).max(0.0)
            };
            let t = t1.min(t2);
            if !t.is_finite() {
                return Err(QpError::Infeasible);
            }
            for k in 0..qa {
                self.mult[k] = (self.mult[k] - t * self.rv[k]).max(0.0);
            }
            up += t;
            if !dep {
                axpy(t, &self.z, &mut self.x);
            }
            if t2 <= t1 {
                self.push_active(p, up);
                return Ok(());
            }
            self.remove_active(l);
        }
    }

    fn finish(&mut self) -> QpSolution {
        let n = self.s.n;
        let mut c = self.x.clone();
        for &k in &self.active {
            if k < n {
                c[k] = 0.0;
            }
        }
        for v in &mut c {
            if *v < 0.0 {
                *v = 0.0;
            }
        }
        let objective = (0..n)
            .map(|i| c[i] * (0.5 * dot(&self.s.h[i * n..(i + 1) * n], &c) + self.q[i]))
            .sum();
        QpSolution {
            c,
            objective,
            active: self.active.iter().map(|&k| to_constraint(k, n)).collect(),
            multipliers: self.mult.iter().map(|&u| u.max(0.0)).collect(),
            iterations: self.iterations,
            regularisation: self.s.delta,
        }
    }
}

/// KKT residuals of `solution` for `problem` (see [`KktReport`]). Mismatched sizes or
/// out-of-range constraints give a report of infinities.
pub fn kkt_residuals(problem: &QpProblem, solution: &QpSolution) -> KktReport {
    let (n, m) = (problem.n, problem.m);
    let inf = KktReport {
        stationarity: f64::INFINITY,
        stationarity_relative: f64::INFINITY,
        primal_infeasibility: f64::INFINITY,
        dual_infeasibility: f64::INFINITY,
        complementarity: f64::INFINITY,
    };
    let sizes_ok = n.checked_mul(n) == Some(problem.h.len())
        && m.checked_mul(n) == Some(problem.g.len())
        && problem.q.len() == n
        && problem.u.len() == m
        && solution.c.len() == n
        && solution.multipliers.len() == solution.active.len()
        && solution.active.iter().all(|&a| match a {
            Constraint::Bound(j) => j < n,
            Constraint::Row(i) => i < m,
        });
    if !sizes_ok {
        return inf;
    }
    let c = &solution.c;
    let row = |i: usize| &problem.g[i * n..(i + 1) * n];
    let hc: Vec<f64> = (0..n)
        .map(|i| dot(&problem.h[i * n..(i + 1) * n], c))
        .collect();
    let mut bounds = vec![0.0; n];
    let mut rows = vec![0.0; n];
    let mut complementarity: f64 = 0.0;
    for (&a, &mu) in solution.active.iter().zip(&solution.multipliers) {
        match a {
            Constraint::Bound(j) => {
                bounds[j] += mu;
                complementarity = complementarity.max((mu * c[j]).abs());
            }
            Constraint::Row(i) => {
                axpy(mu, row(i), &mut rows);
                let slack = problem.u[i] - dot(row(i), c);
                complementarity = complementarity.max((mu * slack).abs());
            }
        }
    }
    let norm = |v: &[f64]| v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let stationarity = norm(
        &(0..n)
            .map(|i| hc[i] + problem.q[i] - bounds[i] + rows[i])
            .collect::<Vec<_>>(),
    );
    let scale = norm(&hc)
        .max(norm(problem.q))
        .max(norm(&bounds))
        .max(norm(&rows));
    let scale = if scale > 0.0 { scale } else { 1.0 };
    let mut primal: f64 = 0.0;
    for &v in c {
        primal = primal.max(-v);
    }
    for i in 0..m {
        primal = primal.max(dot(row(i), c) - problem.u[i]);
    }
    let dual = solution
        .multipliers
        .iter()
        .fold(0.0f64, |a, &mu| a.max(-mu));
    let report = KktReport {
        stationarity,
        stationarity_relative: stationarity / scale,
        primal_infeasibility: primal,
        dual_infeasibility: dual,
        complementarity,
    };
    if [stationarity, primal, dual, complementarity]
        .iter()
        .all(|v| !v.is_nan())
    {
        report
    } else {
        inf
    }
}

fn to_constraint(k: usize, n: usize) -> Constraint {
    if k < n {
        Constraint::Bound(k)
    } else {
        Constraint::Row(k - n)
    }
}

fn bad(message: String) -> QpError {
    QpError::BadInput(message)
}

fn check_finite(name: &str, v: &[f64]) -> Result<(), QpError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(bad(format!("{name}[{i}] = {} is not finite", v[i]))),
        None => Ok(()),
    }
}

/// Cholesky of H + δI (row-major lower L), or None when a pivot falls below δ/2.
fn cholesky(h: &[f64], n: usize, delta: f64) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s = h[i * n + j] - dot(&l[i * n..i * n + j], &l[j * n..j * n + j]);
            if i == j {
                let pivot = s + delta;
                if !(pivot >= 0.5 * delta && pivot.is_finite()) {
                    return None;
                }
                l[i * n + i] = pivot.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// L⁻¹ of a row-major lower-triangular L, row-major (= L⁻ᵀ column-major).
fn lower_inverse(l: &[f64], n: usize) -> Vec<f64> {
    let mut x = vec![0.0; n * n];
    for i in 0..n {
        let (done, rest) = x.split_at_mut(i * n);
        let xi = &mut rest[..n];
        xi[i] = 1.0;
        for k in 0..i {
            let lik = l[i * n + k];
            if lik != 0.0 {
                axpy(-lik, &done[k * n..k * n + k + 1], &mut xi[..k + 1]);
            }
        }
        let inv = 1.0 / l[i * n + i];
        for v in &mut xi[..=i] {
            *v *= inv;
        }
    }
    x
}

/// v[..qa] ← R⁻¹v[..qa] for the column-major upper-triangular R (leading dimension n).
fn back_substitute(r: &[f64], n: usize, qa: usize, v: &mut [f64]) {
    for i in (0..qa).rev() {
        let vi = v[i] / r[i * n + i];
        v[i] = vi;
        axpy(-vi, &r[i * n..i * n + i], &mut v[..i]);
    }
}

/// Columns c and c + 1 of a column-major matrix with n rows.
fn two_cols(j: &mut [f64], n: usize, c: usize) -> (&mut [f64], &mut [f64]) {
    let (a, b) = j.split_at_mut((c + 1) * n);
    (&mut a[c * n..], &mut b[..n])
}

/// (a, b) ← (c·a + s·b, c·b − s·a).
fn rotate(a: &mut [f64], b: &mut [f64], c: f64, s: f64) {
    for (x, y) in a.iter_mut().zip(b.iter_mut()) {
        let (u, v) = (*x, *y);
        *x = c * u + s * v;
        *y = c * v - s * u;
    }
}

/// y += αx.
fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

/// √(a² + b²), without the cost of `hypot` unless the squares could over- or underflow.
fn norm2(a: f64, b: f64) -> f64 {
    let s = a * a + b * b;
    if s.is_finite() && s > 1e-290 {
        s.sqrt()
    } else {
        a.hypot(b)
    }
}

/// Dot product with eight independent partial sums (vectorises; fixed order: deterministic).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let len = a.len().min(b.len());
    let (ca, ra) = a[..len].as_chunks::<8>();
    let (cb, rb) = b[..len].as_chunks::<8>();
    let mut s = [0.0f64; 8];
    for (x, y) in ca.iter().zip(cb) {
        for ((sk, xk), yk) in s.iter_mut().zip(x).zip(y) {
            *sk += xk * yk;
        }
    }
    let mut t = ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]));
    for (x, y) in ra.iter().zip(rb) {
        t += x * y;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problem<'a>(
        h: &'a [f64],
        q: &'a [f64],
        g: &'a [f64],
        u: &'a [f64],
        n: usize,
    ) -> QpProblem<'a> {
        QpProblem {
            h,
            q,
            g,
            u,
            n,
            m: u.len(),
        }
    }

    #[test]
    fn unconstrained_minimiser_when_feasible() {
        let h = [2.0, 0.0, 0.0, 4.0];
        let q = [-2.0, -4.0];
        let s = solve(&problem(&h, &q, &[], &[], 2)).unwrap();
        assert!((s.c[0] - 1.0).abs() < 1e-9 && (s.c[1] - 1.0).abs() < 1e-9);
        assert!(s.active.is_empty());
        assert!((s.objective + 3.0).abs() < 1e-9);
    }

    #[test]
    fn bound_becomes_active() {
        // min ½(c0² + c1²) − c0 + c1: unconstrained (1, −1); with c ≥ 0: (1, 0), λ1 = 1.
        let h = [1.0, 0.0, 0.0, 1.0];
        let q = [-1.0, 1.0];
        let s = solve(&problem(&h, &q, &[], &[], 2)).unwrap();
        // c0 = 1/(1 + δ) with δ = 1e-12; the active bound is exactly 0.
        assert!((s.c[0] - 1.0).abs() < 1e-11 && s.c[1] == 0.0, "{:?}", s.c);
        assert_eq!(s.active, vec![Constraint::Bound(1)]);
        assert!((s.multipliers[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn energy_row_becomes_active() {
        // min ½‖c − (1, 2)‖² s.t. c0 + c1 ≤ 1, c ≥ 0: (0, 1), row multiplier 1, bound 0 with λ = 0.
        let h = [1.0, 0.0, 0.0, 1.0];
        let q = [-1.0, -2.0];
        let g = [1.0, 1.0];
        let u = [1.0];
        let p = problem(&h, &q, &g, &u, 2);
        let s = solve(&p).unwrap();
        assert!(
            (s.c[0]).abs() < 1e-12 && (s.c[1] - 1.0).abs() < 1e-12,
            "{:?}",
            s.c
        );
        assert!(s.active.contains(&Constraint::Row(0)));
        let k = kkt_residuals(&p, &s);
        assert!(
            k.stationarity < 1e-9 && k.primal_infeasibility < 1e-12,
            "{k:?}"
        );
    }

    /// H = Hilbert matrix + diag·I (n×n) and two positive energy rows.
    fn hilbert_problem(n: usize, diag: f64) -> (Vec<f64>, Vec<f64>) {
        let h = (0..n * n)
            .map(|k| 1.0 / (1 + k / n + k % n) as f64 + if k / n == k % n { diag } else { 0.0 })
            .collect();
        let g = (0..2 * n)
            .map(|k| ((k * 7) % 5) as f64 * 0.3 + 0.1)
            .collect();
        (h, g)
    }

    /// JᵀHJ = I for the working factor (H well conditioned, δ negligible).
    fn assert_jthj_is_identity(h: &[f64], n: usize, w: &Work) {
        for a in 0..n {
            for b in 0..n {
                let hj: Vec<f64> = (0..n)
                    .map(|i| dot(&h[i * n..(i + 1) * n], w.col(b)))
                    .collect();
                let v = dot(w.col(a), &hj);
                assert!(
                    (v - f64::from(u8::from(a == b))).abs() < 1e-10,
                    "JᵀHJ[{a},{b}] = {v}"
                );
            }
        }
    }

    #[test]
    fn factor_updates_keep_the_invariants() {
        // After adds and drops, JᵀHJ = I and JᵀN = [R; 0].
        let n = 5;
        let (h, g) = hilbert_problem(n, 1.0);
        let u = [1.0, 2.0];
        let solver = QpSolver::new(&h, n, &g, &u, 2).unwrap();
        let q = vec![0.0; n];
        let mut w = Work::new(&solver, &q, solver.j0.clone(), vec![0.0; n * n], Vec::new());
        w.impose(&[2, n, 0, n + 1, 4]);
        w.remove_active(1);
        w.remove_active(0);
        w.impose(&[1]);
        let qa = w.active.len();
        assert_jthj_is_identity(&h, n, &w);
        // Releasing a constraint updates x and the multipliers exactly as a recomputation would.
        let mut v = Work::new(&solver, &q, w.j.clone(), w.r.clone(), w.active.clone());
        let q2: Vec<f64> = (0..n).map(|i| (i as f64 - 2.0) * 0.7).collect();
        v.q = &q2;
        v.recompute();
        v.release(1);
        let (x, mult) = (v.x.clone(), v.mult.clone());
        v.recompute();
        assert!(
            x.iter().zip(&v.x).all(|(a, b)| (a - b).abs() < 1e-10),
            "{x:?} {:?}",
            v.x
        );
        assert!(mult.iter().zip(&v.mult).all(|(a, b)| (a - b).abs() < 1e-10));
        for (pos, &k) in w.active.clone().iter().enumerate() {
            w.jt_normal(k);
            for c in 0..n {
                let expect = if c < qa { w.r[pos * n + c] } else { 0.0 };
                assert!(
                    (w.d[c] - expect).abs() < 1e-10,
                    "JᵀN[{c},{pos}] = {}",
                    w.d[c]
                );
            }
        }
    }

    #[test]
    fn block_start_keeps_the_invariants_and_equals_rotations() {
        // The bounds imposed in one reordered Cholesky: JᵀHJ = I (H + δI, δ tiny here), JᵀN = [R;
        // 0] with R upper triangular, rows added after by rotations; and x, the multipliers from it
        // equal those of the rotation path.
        let n = 7;
        let (h, g) = hilbert_problem(n, 0.5);
        let u = [1.0, 2.0];
        let solver = QpSolver::new(&h, n, &g, &u, 2).unwrap();
        let q: Vec<f64> = (0..n).map(|i| (i as f64 - 3.0) * 0.9).collect();
        let ids = [5, 1, 1, n + 1, 3, 0];
        let mut w = solver.block_start(&q, &ids);
        assert_eq!(w.active, vec![5, 1, 3, 0, n + 1]);
        assert_jthj_is_identity(&h, n, &w);
        for (pos, &k) in w.active.clone().iter().enumerate() {
            w.jt_normal(k);
            for c in 0..n {
                let expect = if c <= pos { w.r[pos * n + c] } else { 0.0 };
                assert!(
                    (w.d[c] - expect).abs() < 1e-10,
                    "JᵀN[{c},{pos}] = {} vs {expect}",
                    w.d[c]
                );
            }
            assert!(w.r[pos * n + pos] > 0.0);
        }
        w.recompute();
        let mut v = Work::new(&solver, &q, solver.j0.clone(), vec![0.0; n * n], Vec::new());
        v.impose(&[5, 1, 3, 0, n + 1]);
        v.recompute();
        assert_eq!(v.active, w.active);
        for (a, b) in w.x.iter().zip(&v.x).chain(w.mult.iter().zip(&v.mult)) {
            assert!((a - b).abs() < 1e-10 * (1.0 + b.abs()), "{a} vs {b}");
        }
    }

    #[test]
    fn seeded_and_unseeded_cold_starts_agree() {
        // 40 random bound- and row-constrained problems: the seeded cold start, the plain GI and a
        // warm start from a wrong active set reach the same minimiser.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..40 {
            let n = 3 + case % 17;
            let m = case % 4;
            let p = n + 5;
            let t: Vec<f64> = (0..p * n).map(|_| next()).collect();
            let mut h = vec![0.0; n * n];
            for a in 0..n {
                for b in 0..n {
                    h[a * n + b] = (0..p).map(|i| t[i * n + a] * t[i * n + b]).sum();
                }
            }
            let q: Vec<f64> = (0..n).map(|_| next() * 4.0 - 2.5).collect();
            let g: Vec<f64> = (0..m * n).map(|_| next()).collect();
            let u: Vec<f64> = (0..m).map(|_| 0.2 + next()).collect();
            let solver = QpSolver::new(&h, n, &g, &u, m).unwrap();
            let seeded = solver.solve(&q, None).unwrap();
            let plain = solver.solve_unseeded(&q).unwrap();
            let wrong: Vec<Constraint> = (0..n).step_by(2).map(Constraint::Bound).collect();
            let warm = solver.solve(&q, Some(&wrong)).unwrap();
            let scale = 1.0 + plain.c.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for other in [&seeded, &warm] {
                let d = other
                    .c
                    .iter()
                    .zip(&plain.c)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
                assert!(d <= 1e-8 * scale, "case {case}: differ by {d}");
                let k = kkt_residuals(&problem(&h, &q, &g, &u, n), other);
                assert!(
                    k.primal_infeasibility <= 1e-9 && k.dual_infeasibility == 0.0,
                    "case {case}: {k:?}"
                );
            }
        }
    }

    #[test]
    fn singular_hessian_is_regularised() {
        let h = [1.0, 1.0, 1.0, 1.0];
        let q = [-1.0, -1.0];
        let s = solve(&problem(&h, &q, &[], &[], 2)).unwrap();
        assert_eq!(s.regularisation, 1e-12);
        // Along H's null direction (1, −1) the solution is fixed only by δ, so rounding of order
        // ε/δ shows there; along (1, 1) and in the objective it is exact.
        assert!((s.c[0] + s.c[1] - 1.0).abs() < 1e-9, "{:?}", s.c);
        assert!((s.c[0] - s.c[1]).abs() < 1e-3, "{:?}", s.c);
        assert!((s.objective + 0.5).abs() < 1e-9);
    }

    #[test]
    fn errors_are_one_line() {
        let h = [-1.0];
        let e = solve(&problem(&h, &[0.0], &[], &[], 1)).unwrap_err();
        assert_eq!(e, QpError::NotPositiveDefinite);
        let e = solve(&problem(&[1.0], &[0.0], &[1.0], &[-1.0], 1)).unwrap_err();
        assert_eq!(e, QpError::Infeasible);
        let e = solve(&problem(&[1.0], &[f64::NAN], &[], &[], 1)).unwrap_err();
        assert!(matches!(e, QpError::BadInput(_)));
        for e in [
            e,
            QpError::Infeasible,
            QpError::MaxIterations { iterations: 3 },
        ] {
            assert!(!e.to_string().contains('\n'));
        }
    }
}
