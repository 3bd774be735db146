//! `glint::fit::qp` against Clarabel (an interior-point solver, the independent reference) on
//! random fit-like problems: H = TᵀWT, q = −TᵀWB from a random positive T, weights W and targets
//! B, energy rows G ≥ 0 with u = 1 − ρd.
//!
//! Tolerances asserted (the solver is exact up to rounding; Clarabel runs at 1e-10
//! gap/feasibility):
//! - objective: |f − f_clarabel| ≤ 1e-6·|f_clarabel|;
//! - feasibility: c ≥ 0 exactly, G c ≤ u + 1e-9;
//! - KKT: stationarity ≤ 1e-8 relative to the largest term (‖Hc‖, ‖q‖, ‖λ‖, ‖Gᵀμ‖), multipliers ≥ 0
//!   exactly, complementarity |multiplier · slack| ≤ 1e-9·max(1, max multiplier);
//! - c close to Clarabel's where the problem is strictly convex: ≤ 1e-5·max(1, ‖c‖∞);
//! - warm/hot and cold solves agree to 1e-9 in every coefficient.
//!
//! Run with `--nocapture` to see the timings of cold, warm and hot solves at n = 147, m = 192.

use std::time::Instant;

use crate::common;

use glint::fit::qp::{
    Constraint, HotStart, QpError, QpProblem, QpSolution, QpSolver, kkt_residuals, solve,
    solve_warm,
};

/// splitmix64.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = self.0;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^ (x >> 31)
    }

    fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
}

/// An owned problem.
struct Gen {
    n: usize,
    m: usize,
    h: Vec<f64>,
    q: Vec<f64>,
    g: Vec<f64>,
    u: Vec<f64>,
}

impl Gen {
    fn problem(&self) -> QpProblem<'_> {
        QpProblem {
            h: &self.h,
            q: &self.q,
            g: &self.g,
            u: &self.u,
            n: self.n,
            m: self.m,
        }
    }
}

/// H = TᵀWT, q = −TᵀWB for a p×n row-major T.
fn normal_equations(t: &[f64], w: &[f64], b: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut h = vec![0.0; n * n];
    let mut q = vec![0.0; n];
    for (k, row) in t.chunks_exact(n).enumerate() {
        for i in 0..n {
            let wi = w[k] * row[i];
            q[i] -= wi * b[k];
            for j in i..n {
                h[i * n + j] += wi * row[j];
            }
        }
    }
    for i in 0..n {
        for j in 0..i {
            h[i * n + j] = h[j * n + i];
        }
    }
    (h, q)
}

/// Energy rows G ∈ [0, 1) and u = 1 − ρd with ρd ∈ [0.1, 0.5).
fn energy_rows(rng: &mut Rng, n: usize, m: usize) -> (Vec<f64>, Vec<f64>) {
    let g = (0..m * n).map(|_| rng.f64()).collect();
    let u = vec![1.0 - rng.range(0.1, 0.5); m];
    (g, u)
}

/// Random fit: T (p×n) with entries U(0,1)², W ∈ [0.1, 1), B ∈ [0, brightness).
fn random_problem(seed: u64, n: usize, m: usize, p: usize, brightness: f64) -> Gen {
    let mut rng = Rng(seed);
    let t: Vec<f64> = (0..p * n).map(|_| rng.f64().powi(2)).collect();
    let w: Vec<f64> = (0..p).map(|_| rng.range(0.1, 1.0)).collect();
    let b: Vec<f64> = (0..p).map(|_| brightness * rng.f64()).collect();
    let (h, q) = normal_equations(&t, &w, &b, n);
    let (g, u) = energy_rows(&mut rng, n, m);
    Gen { n, m, h, q, g, u }
}

/// Like a constant environment: the first `alike` columns of T are one column plus 1e-9 noise.
fn near_singular_problem(seed: u64, n: usize, alike: usize, m: usize, p: usize) -> Gen {
    let mut rng = Rng(seed);
    let base: Vec<f64> = (0..p).map(|_| rng.f64()).collect();
    let mut t = vec![0.0; p * n];
    for k in 0..p {
        for j in 0..n {
            t[k * n + j] = if j < alike {
                base[k] + 1e-9 * rng.f64()
            } else {
                rng.f64().powi(2)
            };
        }
    }
    let w: Vec<f64> = (0..p).map(|_| rng.range(0.1, 1.0)).collect();
    let b: Vec<f64> = (0..p).map(|_| 3.0 * rng.f64()).collect();
    let (h, q) = normal_equations(&t, &w, &b, n);
    let (g, u) = energy_rows(&mut rng, n, m);
    // Scale the rows so that the energy bound binds.
    let g = g.iter().map(|v| v * 0.5).collect();
    Gen { n, m, h, q, g, u }
}

fn objective(prob: &Gen, c: &[f64]) -> f64 {
    let n = prob.n;
    (0..n)
        .map(|i| {
            let hc: f64 = (0..n).map(|j| prob.h[i * n + j] * c[j]).sum();
            c[i] * (0.5 * hc + prob.q[i])
        })
        .sum()
}

/// Clarabel: min ½xᵀPx + qᵀx s.t. Ax + s = b, s ≥ 0 with A = [−I; G], b = [0; u].
fn clarabel(prob: &Gen) -> (Vec<f64>, f64) {
    let x = common::clarabel_qp(&prob.h, &prob.q, &prob.g, &prob.u, prob.n, prob.m);
    let f = objective(prob, &x);
    (x, f)
}

/// Feasibility, KKT and objective checks; returns max |c − c_clarabel|.
fn check(prob: &Gen, sol: &QpSolution, label: &str) -> f64 {
    let (n, m) = (prob.n, prob.m);
    assert_eq!(sol.c.len(), n);
    assert!(
        sol.c.iter().all(|&v| v >= 0.0),
        "{label}: negative coefficient"
    );
    for i in 0..m {
        let gc: f64 = (0..n).map(|j| prob.g[i * n + j] * sol.c[j]).sum();
        assert!(
            gc <= prob.u[i] + 1e-9,
            "{label}: row {i}: Gc = {gc} > u = {}",
            prob.u[i]
        );
    }
    let k = kkt_residuals(&prob.problem(), sol);
    let max_mult = sol.multipliers.iter().fold(1.0f64, |a, &b| a.max(b));
    assert!(k.primal_infeasibility <= 1e-9, "{label}: {k:?}");
    assert!(k.stationarity_relative <= 1e-8, "{label}: {k:?}");
    assert_eq!(k.dual_infeasibility, 0.0, "{label}: {k:?}");
    assert!(k.complementarity <= 1e-9 * max_mult, "{label}: {k:?}");
    assert!(
        (sol.objective - objective(prob, &sol.c)).abs() <= 1e-12 * sol.objective.abs().max(1.0)
    );

    let (x, f_ref) = clarabel(prob);
    let rel = (sol.objective - f_ref).abs() / f_ref.abs().max(1e-300);
    assert!(
        rel <= 1e-6,
        "{label}: objective {} vs clarabel {f_ref} (rel {rel:e})",
        sol.objective
    );
    let dc = sol
        .c
        .iter()
        .zip(&x)
        .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
    let rows = sol
        .active
        .iter()
        .filter(|a| matches!(a, Constraint::Row(_)))
        .count();
    println!(
        "{label}: n {n} m {m}: {} active ({rows} rows), {} iterations, objective {:.9e}, \
         rel diff {rel:.1e}, max |Δc| {dc:.1e}, {k:?}",
        sol.active.len(),
        sol.iterations,
        sol.objective
    );
    dc
}

#[test]
fn random_problems_match_clarabel() {
    let cases = [
        (1, 20, 0, 200, 1.0),
        (2, 20, 192, 200, 1.0),
        (3, 20, 192, 200, 0.2),
        (4, 60, 0, 600, 0.5),
        (5, 60, 192, 600, 2.0),
        (6, 147, 0, 2700, 1.0),
        (7, 147, 192, 2700, 1.0),
        (8, 147, 192, 2700, 5.0),
    ];
    let mut any_row = false;
    for (seed, n, m, p, brightness) in cases {
        let prob = random_problem(seed, n, m, p, brightness);
        let sol = solve(&prob.problem()).unwrap();
        any_row |= sol.active.iter().any(|a| matches!(a, Constraint::Row(_)));
        let label = format!("seed {seed}");
        let dc = check(&prob, &sol, &label);
        let cmax = sol.c.iter().fold(1.0f64, |a, &b| a.max(b));
        assert!(
            dc <= 1e-5 * cmax,
            "{label}: c differs from clarabel's by {dc}"
        );
        // The plain GI path (no seed, no block start) reaches the same answer.
        let plain = QpSolver::from_problem(&prob.problem())
            .unwrap()
            .solve_unseeded(&prob.q)
            .unwrap();
        check(&prob, &plain, &format!("{label} unseeded"));
        assert!(
            max_diff(&plain.c, &sol.c) <= 1e-8 * cmax,
            "{label}: seeded and plain GI differ"
        );
    }
    assert!(any_row, "no case had an energy row active");
}

#[test]
fn energy_rows_bind_for_impossible_targets() {
    let prob = random_problem(11, 60, 192, 600, 100.0);
    let sol = solve(&prob.problem()).unwrap();
    assert!(
        sol.active.iter().any(|a| matches!(a, Constraint::Row(_))),
        "no energy row active: {:?}",
        sol.active
    );
    check(&prob, &sol, "impossible targets");
}

#[test]
fn near_rank_deficient_hessian() {
    for (seed, m) in [(21, 0), (22, 192)] {
        let prob = near_singular_problem(seed, 130, 100, m, 1000);
        let label = format!("near-singular m = {m}");
        let sol = solve(&prob.problem()).unwrap();
        let max_diag = (0..prob.n)
            .map(|i| prob.h[i * prob.n + i])
            .fold(0.0, f64::max);
        assert!(sol.regularisation > 0.0 && sol.regularisation <= 1e-12 * max_diag * 1.000001);
        check(&prob, &sol, &label);
        // Determinism: a second solver from the same data gives the same bits.
        let again = solve(&prob.problem()).unwrap();
        let bits = |s: &QpSolution| s.c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&sol), bits(&again), "{label}: not deterministic");
        assert_eq!(sol.objective.to_bits(), again.objective.to_bits());
        assert_eq!(sol.active, again.active);
    }
}

/// Minimum wall time of `reps` runs, in ms.
fn time_ms<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let start = Instant::now();
        let v = f();
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
        out = Some(v);
    }
    (best, out.expect("reps > 0"))
}

/// Minimum wall time (ms) of a hot solve from a copy of `hot` (the copy is not timed).
fn time_hot(solver: &QpSolver, hot: &HotStart, q: &[f64], reps: usize) -> (f64, QpSolution) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let mut h = hot.clone();
        let start = Instant::now();
        let s = solver.solve_hot(q, &mut h).unwrap();
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
        out = Some(s);
    }
    (best, out.expect("reps > 0"))
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// A new stroke: q changed by up to ±`change` (relative) in 10 % of its entries.
fn perturb(rng: &mut Rng, q: &[f64], change: f64) -> Vec<f64> {
    let mut q2 = q.to_vec();
    for _ in 0..q.len() / 10 {
        let j = (rng.next_u64() % q.len() as u64) as usize;
        q2[j] *= 1.0 + rng.range(-change, change);
    }
    q2
}

/// How many constraints differ between two active sets.
fn active_changes(a: &[Constraint], b: &[Constraint]) -> usize {
    a.iter().filter(|c| !b.contains(c)).count() + b.iter().filter(|c| !a.contains(c)).count()
}

#[test]
fn warm_start_matches_cold_and_is_faster() {
    let (n, m, p) = (147, 192, 2700);
    let prob = random_problem(31, n, m, p, 1.5);
    let (t_new, solver) = time_ms(3, || {
        QpSolver::new(&prob.h, n, &prob.g, &prob.u, m).unwrap()
    });
    let (t_cold, cold) = time_ms(5, || solver.solve(&prob.q, None).unwrap());

    let mut rng = Rng(32);
    let q2 = perturb(&mut rng, &prob.q, 0.05);
    let (t_cold2, cold2) = time_ms(5, || solver.solve_unseeded(&q2).unwrap());
    let (t_seeded, seeded) = time_ms(5, || solver.solve(&q2, None).unwrap());
    assert!(max_diff(&seeded.c, &cold2.c) <= 1e-9);
    let (t_warm, warm) = time_ms(5, || solver.solve(&q2, Some(&cold.active)).unwrap());
    let mut hot = HotStart::default();
    let hot_first = solver.solve_hot(&prob.q, &mut hot).unwrap();
    let (t_hot, hot2) = time_hot(&solver, &hot, &q2, 20);

    assert!(max_diff(&hot_first.c, &cold.c) <= 1e-9);
    for (name, s) in [("warm", &warm), ("hot", &hot2)] {
        let d = max_diff(&s.c, &cold2.c);
        assert!(d <= 1e-9, "{name} and cold differ by {d}");
        assert!(
            s.iterations < cold2.iterations,
            "{name}: {} iterations, cold {}",
            s.iterations,
            cold2.iterations
        );
        let k = kkt_residuals(
            &QpProblem {
                q: &q2,
                ..prob.problem()
            },
            s,
        );
        assert!(
            k.primal_infeasibility <= 1e-9 && k.stationarity_relative <= 1e-8,
            "{k:?}"
        );
    }
    // The one-shot warm entry point agrees too.
    let one_shot = solve_warm(
        &QpProblem {
            q: &q2,
            ..prob.problem()
        },
        &cold.active,
    )
    .unwrap();
    assert!(max_diff(&one_shot.c, &cold2.c) <= 1e-9);

    let rows = cold2
        .active
        .iter()
        .filter(|a| matches!(a, Constraint::Row(_)))
        .count();
    println!(
        "n = {n}, m = {m}, T {p}×{n}, random G; {} active ({rows} rows)",
        cold2.active.len()
    );
    println!("QpSolver::new (Cholesky + inverse): {t_new:.3} ms");
    println!(
        "cold solve, plain GI: {t_cold2:.3} ms, {} iterations; seeded (active-set guess + block start): \
         {t_seeded:.3} ms, {} GI iterations (first q, seeded: {t_cold:.3} ms)",
        cold2.iterations, seeded.iterations
    );
    println!(
        "after a ±5 % change in 10 % of q ({} active-set changes):",
        active_changes(&cold.active, &cold2.active)
    );
    println!(
        "  warm solve (active list): {t_warm:.3} ms, {} iterations",
        warm.iterations
    );
    println!(
        "  hot solve (cached factor): {t_hot:.3} ms, {} iterations",
        hot2.iterations
    );

    // Smaller and larger strokes, hot from the first answer.
    for change in [0.002, 0.01, 0.05, 0.2] {
        let q3 = perturb(&mut rng, &prob.q, change);
        let (t, s) = time_hot(&solver, &hot, &q3, 10);
        let reference = solver.solve(&q3, None).unwrap();
        assert!(max_diff(&s.c, &reference.c) <= 1e-9);
        println!(
            "  ±{:>4.1} %: hot {t:.3} ms, {} iterations, {} active-set changes",
            change * 100.0,
            s.iterations,
            active_changes(&cold.active, &s.active)
        );
    }

    // A painting session: 30 strokes in a row, each re-solved hot from the previous one.
    let mut hot = HotStart::default();
    let mut q_now = prob.q.clone();
    solver.solve_hot(&q_now, &mut hot).unwrap();
    let mut total = 0.0;
    let mut worst: f64 = 0.0;
    let mut iterations = 0;
    for _ in 0..30 {
        q_now = perturb(&mut rng, &q_now, 0.05);
        let start = Instant::now();
        let s = solver.solve_hot(&q_now, &mut hot).unwrap();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        total += ms;
        worst = worst.max(ms);
        iterations += s.iterations;
        let reference = solver.solve(&q_now, None).unwrap();
        assert!(max_diff(&s.c, &reference.c) <= 1e-9);
    }
    println!(
        "  30 successive ±5 % strokes, hot: mean {:.3} ms, worst {worst:.3} ms, mean {:.1} iterations",
        total / 30.0,
        iterations as f64 / 30.0
    );
}

#[test]
fn hot_starts_survive_refreshes_and_foreign_solvers() {
    // More hot solves than HOT_REFRESH, so the cached factor is rebuilt on the way.
    let prob = random_problem(51, 60, 192, 600, 2.0);
    let solver = QpSolver::from_problem(&prob.problem()).unwrap();
    let mut rng = Rng(52);
    let mut hot = HotStart::default();
    let mut q = prob.q.clone();
    for _ in 0..glint::fit::qp::HOT_REFRESH + 6 {
        q = perturb(&mut rng, &q, 0.05);
        let s = solver.solve_hot(&q, &mut hot).unwrap();
        let reference = solver.solve(&q, None).unwrap();
        assert!(max_diff(&s.c, &reference.c) <= 1e-9);
        assert_eq!(hot.active(), s.active);
    }
    // A HotStart from another solver is ignored, not trusted.
    let other = random_problem(53, 60, 192, 600, 2.0);
    let other_solver = QpSolver::from_problem(&other.problem()).unwrap();
    let s = other_solver.solve_hot(&other.q, &mut hot).unwrap();
    let reference = other_solver.solve(&other.q, None).unwrap();
    assert!(max_diff(&s.c, &reference.c) <= 1e-9);
}

#[test]
fn bad_input_is_rejected_without_panics() {
    let prob = random_problem(41, 5, 3, 20, 1.0);
    let (n, m) = (5, 3);
    let is_bad = |r: Result<QpSolution, QpError>| matches!(r, Err(QpError::BadInput(_)));
    let with = |f: &dyn Fn(&mut Gen)| {
        let mut g = Gen {
            n,
            m,
            h: prob.h.clone(),
            q: prob.q.clone(),
            g: prob.g.clone(),
            u: prob.u.clone(),
        };
        f(&mut g);
        solve(&g.problem())
    };
    assert!(with(&|_| {}).is_ok());
    assert!(is_bad(with(&|g| {
        g.h.pop();
    })));
    assert!(is_bad(with(&|g| g.q.push(0.0))));
    assert!(is_bad(with(&|g| g.g.truncate(7))));
    assert!(is_bad(with(&|g| g.u.push(1.0))));
    assert!(is_bad(with(&|g| g.n = 6)));
    assert!(is_bad(with(&|g| g.m = 2)));
    assert!(is_bad(with(&|g| g.h[3] = f64::NAN)));
    assert!(is_bad(with(&|g| g.q[0] = f64::NAN)));
    assert!(is_bad(with(&|g| g.q[4] = f64::INFINITY)));
    assert!(is_bad(with(&|g| g.g[2] = f64::NAN)));
    assert!(is_bad(with(&|g| g.u[1] = f64::NEG_INFINITY)));
    assert!(is_bad(with(&|g| g.h[1] += 1.0))); // not symmetric
    assert!(is_bad(with(&|g| g.n = usize::MAX))); // n² overflows

    let p = prob.problem();
    assert!(is_bad(solve_warm(&p, &[Constraint::Bound(n)])));
    assert!(is_bad(solve_warm(&p, &[Constraint::Row(m)])));
    assert!(
        solve_warm(
            &p,
            &[
                Constraint::Bound(0),
                Constraint::Bound(0),
                Constraint::Row(2)
            ]
        )
        .is_ok()
    );

    let solver = QpSolver::from_problem(&p).unwrap();
    assert!(is_bad(solver.solve(&[0.0; 4], None)));
    let mut hot = HotStart::default();
    solver.solve_hot(&prob.q, &mut hot).unwrap();
    assert!(is_bad(solver.solve_hot(&[f64::NAN; 5], &mut hot)));
    assert!(
        hot.active().is_empty(),
        "hot start not cleared after an error"
    );

    // Not PSD, infeasible.
    let minus_i: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { -1.0 } else { 0.0 })
        .collect();
    let r = solve(&QpProblem { h: &minus_i, ..p });
    assert_eq!(r.unwrap_err(), QpError::NotPositiveDefinite);
    let negative_u = [-1.0; 3];
    let r = solve(&QpProblem {
        u: &negative_u,
        ..p
    });
    assert_eq!(r.unwrap_err(), QpError::Infeasible);

    // KKT report of mismatched data: infinities, no panic.
    let sol = solve(&p).unwrap();
    let short_q = [0.0; 4];
    let k = kkt_residuals(&QpProblem { q: &short_q, ..p }, &sol);
    assert!(k.stationarity.is_infinite() && k.primal_infeasibility.is_infinite());

    for e in [
        QpError::NotPositiveDefinite,
        QpError::Infeasible,
        QpError::MaxIterations { iterations: 10 },
        QpError::BadInput("x".into()),
    ] {
        assert!(!e.to_string().contains('\n'));
    }
}
