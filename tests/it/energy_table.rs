//! Every entry of the energy table g (the paper's J = 147 hemicube lobes at σ = π/40, N_l = 192 +
//! 1 + 64) against brute-force quadrature directly over wi (no half-vector change of variables): a
//! midpoint rule on a fine (θi, φi) grid of the hemisphere, all lobes per grid point. Also the
//! isotropic (ring) lobes, whose brute force evaluates the ring lobe through the Bessel closed
//! form, and the hard cases λ = 1, 5000. Rows near the horizon (glint's 64 extra ones, wo.z = 0.03
//! and 1e-6) use graded Gauss–Legendre panels.

use glam::DVec3;
use glint::brdf::energy::{EnergyQuadrature, EnergyTable, default_outgoing};
use glint::brdf::static_term;
use glint::sphere::srbf::{PAPER_SIGMA, lambda_from_sigma, support_cosine};
use glint::sphere::{LobeLayout, LobeSet};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Which lobes can be non-negligible (G > e^-40) at a half-vector.
struct Support<'a> {
    lobes: &'a LobeSet,
    cut: f64,
    /// Polar angles of the centres: a ring lobe is at most exp(2λ(cos(θh − θj) − 1)), so it too can
    /// be skipped outside its support.
    polar: Vec<f64>,
}

impl<'a> Support<'a> {
    fn new(lobes: &'a LobeSet) -> Self {
        let polar = lobes
            .centres()
            .iter()
            .map(|c| c.z.clamp(-1.0, 1.0).acos())
            .collect();
        Self {
            lobes,
            cut: support_cosine(lobes.lambda(), 40.0),
            polar,
        }
    }
}

/// Adds one quadrature point wi (weight `measure` = dω·cos θi) to every lobe's entry: G_j(h) s(wi,
/// wo).
fn add_point(row: &mut [f64], support: &Support, wi: DVec3, wo: DVec3, f0: f64, measure: f64) {
    let weight = static_term(wi, wo, f0) * measure;
    if weight == 0.0 {
        return;
    }
    let h = (wi + wo).normalize();
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let iso = support.lobes.layout().is_isotropic();
    for (j, r) in row.iter_mut().enumerate() {
        let inside = if iso {
            (theta_h - support.polar[j]).cos() > support.cut
        } else {
            h.dot(support.lobes.centres()[j]) > support.cut
        };
        if inside {
            *r += support.lobes.eval_one(j, h) * weight;
        }
    }
}

/// Brute-force row g_j(wo) for all j: Σ over a (θi, φi) midpoint grid of G_j(h) s(wi, wo) cos θi
/// dω.
fn midpoint_row(lobes: &LobeSet, wo: DVec3, f0: f64, n_theta: usize) -> Vec<f64> {
    // For grazing wo, wi near the mirror direction is grazing too and |wi + wo| ≈ 2 k2: h moves
    // ~1/k2 times faster than wi, so a lobe is ~1/k2 times narrower in φi. Refine φ accordingly.
    let n_phi = 4 * n_theta * (0.2 / wo.z).ceil().max(1.0) as usize;
    let dp = 2.0 * PI / n_phi as f64;
    // θ panels: [0, π/2 − 0.1] with n points and a horizon panel [π/2 − 0.1, π/2] with n/2 points
    // (a 12× finer step): near the horizon k1/d(k1, k2) rises from 0 over a scale of k2, which is
    // 0.025 for the most grazing outgoing direction.
    let split = 0.5 * PI - 0.1;
    let panels = [(0.0, split, n_theta), (split, 0.5 * PI, n_theta / 2)];
    let support = Support::new(lobes);
    let mut row = vec![0.0; lobes.len()];
    for (lo, hi, n) in panels {
        let dt = (hi - lo) / n as f64;
        for i in 0..n {
            let th = lo + (i as f64 + 0.5) * dt;
            let (st, ct) = th.sin_cos();
            for k in 0..n_phi {
                let ph = (k as f64 + 0.5) * dp;
                let wi = DVec3::new(st * ph.cos(), st * ph.sin(), ct);
                add_point(&mut row, &support, wi, wo, f0, ct * st * dt * dp);
            }
        }
    }
    row
}

/// Breakpoints 0 = b₀ < b₁ < … = `length`, steps growing geometrically from `scale` and never wider
/// than `max_width`: fine where the integrand varies on the scale `scale` (at 0), coarse far from
/// it.
fn graded(scale: f64, max_width: f64, length: f64) -> Vec<f64> {
    let mut b = vec![0.0];
    while *b.last().unwrap() < length {
        let last = *b.last().unwrap();
        b.push((last + last.max(scale).min(max_width)).min(length));
    }
    b
}

/// The row for a grazing outgoing direction (k2 = wo.z < 0.05), where the midpoint grid would need
/// ~1/k2 times more φ points: around the mirror direction (θi → π/2, φi → φo + π) h turns on the
/// scale of k2, so composite Gauss–Legendre panels graded geometrically from k2 in both t = π/2 −
/// θi and ψ = φi − φo − π (and no wider than `width_factor`/√λ, nor 0.1, elsewhere). Independent of
/// the table's half-vector quadrature: the integral is taken over wi directly.
fn graded_row(lobes: &LobeSet, wo: DVec3, f0: f64, order: usize, width_factor: f64) -> Vec<f64> {
    let rule = glint::math::quadrature::GaussLegendre::new(order);
    let k2 = wo.z;
    let max_width = (width_factor / lobes.lambda().sqrt()).min(0.1);
    let t_breaks = graded(0.25 * k2, max_width, 0.5 * PI);
    let half = graded(0.25 * k2, max_width, PI);
    let psi_breaks: Vec<f64> = half
        .iter()
        .rev()
        .map(|b| -b)
        .chain(half[1..].iter().copied())
        .collect();
    let phi_o = wo.y.atan2(wo.x);
    let support = Support::new(lobes);
    let mut row = vec![0.0; lobes.len()];
    for tw in t_breaks.windows(2) {
        for (t, wt) in rule.on_interval(tw[0], tw[1]) {
            let th = 0.5 * PI - t;
            let (st, ct) = th.sin_cos();
            for pw in psi_breaks.windows(2) {
                for (psi, wp) in rule.on_interval(pw[0], pw[1]) {
                    let ph = phi_o + PI + psi;
                    let wi = DVec3::new(st * ph.cos(), st * ph.sin(), ct);
                    add_point(&mut row, &support, wi, wo, f0, ct * st * wt * wp);
                }
            }
        }
    }
    row
}

/// Richardson extrapolation of the midpoint rule (error c₂h² + c₄h⁴ + …: the integrand is smooth on
/// the (θ, φ) rectangle, periodic in φ): (4 I(2n) − I(n)) / 3. Grazing rows use [`graded_row`].
fn brute_row(lobes: &LobeSet, wo: DVec3, f0: f64, n_theta: usize) -> Vec<f64> {
    if wo.z < 0.05 {
        // Sharp lobes need narrower panels and a higher order: for λ = 5000 at wo.z = 1e-6 one
        // entry came out 1.54e-5 / 1.36e-5 / 1.35e-5 at orders 8 / 12 / 16 with panels 1.5/√λ wide,
        // and 1.334e-5 / 1.332e-5 (the table: 1.3306e-5) at orders 12 / 16 with panels 0.75/√λ
        // wide.
        let (order, width_factor) = if lobes.lambda() > 1000.0 {
            (12, 0.75)
        } else {
            (8, 1.5)
        };
        return graded_row(lobes, wo, f0, order, width_factor);
    }
    let coarse = midpoint_row(lobes, wo, f0, n_theta);
    let fine = midpoint_row(lobes, wo, f0, 2 * n_theta);
    coarse
        .iter()
        .zip(&fine)
        .map(|(c, f)| (4.0 * f - c) / 3.0)
        .collect()
}

fn check_table(
    lobes: &LobeSet,
    outgoing: &[DVec3],
    f0: f64,
    n_theta: usize,
    tolerance: f64,
) -> f64 {
    let start = std::time::Instant::now();
    let table = EnergyTable::new(lobes, outgoing, &EnergyQuadrature::default());
    let build_secs = start.elapsed().as_secs_f64();
    let brute: Vec<Vec<f64>> = outgoing
        .par_iter()
        .map(|&wo| brute_row(lobes, wo, f0, n_theta))
        .collect();
    let max_entry = brute.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
    let mut worst = 0.0f64;
    for (l, row) in brute.iter().enumerate() {
        // Relative error; entries below 1e-6 of the largest are compared in absolute terms. The
        // grazing rows (wo.z < 0.05, glint's extra horizon rows) are compared relative to the row's
        // largest entry, with a tolerance of at least 1e-2: what an energy row bounds is Σ_j g_lj
        // c_j, and at wo.z = 1e-6 the table's azimuthal rule converges only algebraically across
        // the k1 = 0 cut (measured: 1.0e-3 of the row for isotropic-24, 9.6e-3 for λ = 5000; 2.6e-4
        // for the paper's lobes).
        let row_max = row.iter().fold(0.0f64, |m, &v| m.max(v));
        let grazing = outgoing[l].z < 0.05;
        let (floor, tolerance) = if grazing {
            (row_max, tolerance.max(1e-2))
        } else {
            (1e-6 * max_entry, tolerance)
        };
        for (j, &want) in row.iter().enumerate() {
            let got = table.entry(l, j, f0);
            assert!(got.is_finite() && got >= 0.0);
            let err = (got - want).abs() / want.max(floor);
            worst = worst.max(err);
            assert!(
                err < tolerance,
                "{} l={l} j={j} wo={:?} got={got} want={want} (row max {row_max})",
                lobes.layout().name(),
                outgoing[l]
            );
        }
    }
    println!(
        "{}: λ={:.2}, {}×{} entries, worst relative error {worst:.2e}, table built in {build_secs:.3} s",
        lobes.layout().name(),
        lobes.lambda(),
        table.rows(),
        table.cols()
    );
    worst
}

#[test]
fn every_entry_of_the_paper_table_matches_brute_force() {
    let lambda = lambda_from_sigma(PAPER_SIGMA).unwrap();
    let lobes = LobeSet::new(LobeLayout::PAPER, lambda).unwrap();
    let outgoing = default_outgoing(&lobes);
    assert_eq!(
        outgoing.len(),
        192 + 1 + 64,
        "the paper's 192, the normal and two rings near the horizon"
    );
    check_table(&lobes, &outgoing, 0.04, 96, 1e-3);
}

#[test]
fn isotropic_ring_lobes_match_brute_force() {
    let lambda = lambda_from_sigma(PAPER_SIGMA).unwrap();
    let lobes = LobeSet::new(LobeLayout::Isotropic { count: 24 }, lambda).unwrap();
    let outgoing = default_outgoing(&lobes);
    check_table(&lobes, &outgoing, 0.5, 96, 1e-3);
}

#[test]
fn broad_and_sharp_lobes_match_brute_force() {
    // λ = 1: lobes span the whole hemisphere. λ = 5000: a few hundredths of a radian wide (the grid
    // is refined to resolve them; fewer outgoing directions keep the test short).
    let broad = LobeSet::new(LobeLayout::Fibonacci { count: 40 }, 1.0).unwrap();
    check_table(&broad, &default_outgoing(&broad)[..48], 0.04, 64, 1e-3);
    let sharp = LobeSet::new(LobeLayout::Fibonacci { count: 40 }, 5000.0).unwrap();
    let outgoing: Vec<DVec3> = default_outgoing(&sharp).into_iter().step_by(24).collect();
    check_table(&sharp, &outgoing, 0.04, 600, 1e-3);
}

#[test]
fn graded_reference_agrees_with_the_midpoint_grid_and_with_itself() {
    // The reference for grazing rows checked two ways at wo.z = 0.15, where the midpoint grid is
    // still affordable: against Richardson-extrapolated midpoint sums, and against a higher
    // Gauss–Legendre order.
    let lambda = lambda_from_sigma(PAPER_SIGMA).unwrap();
    let lobes = LobeSet::new(LobeLayout::PAPER, lambda).unwrap();
    for wo in [
        DVec3::new((1.0f64 - 0.15 * 0.15).sqrt(), 0.0, 0.15),
        DVec3::new(0.0, (1.0f64 - 1e-6 * 1e-6).sqrt(), 1e-6),
    ] {
        let g8 = graded_row(&lobes, wo, 0.04, 8, 1.5);
        let g12 = graded_row(&lobes, wo, 0.04, 12, 1.5);
        let max = g12.iter().fold(0.0f64, |m, &v| m.max(v));
        let worst = g8
            .iter()
            .zip(&g12)
            .map(|(a, b)| (a - b).abs() / b.max(1e-6 * max))
            .fold(0.0f64, f64::max);
        assert!(worst < 1e-5, "orders 8 and 12 differ by {worst} at {wo:?}");
        if wo.z > 0.1 {
            let coarse = midpoint_row(&lobes, wo, 0.04, 96);
            let fine = midpoint_row(&lobes, wo, 0.04, 192);
            let mid: Vec<f64> = coarse
                .iter()
                .zip(&fine)
                .map(|(c, f)| (4.0 * f - c) / 3.0)
                .collect();
            let worst = g12
                .iter()
                .zip(&mid)
                .map(|(a, b)| (a - b).abs() / b.max(1e-6 * max))
                .fold(0.0f64, f64::max);
            assert!(worst < 1e-3, "graded and midpoint differ by {worst}");
        }
    }
    // Sharp lobes (λ = 5000, the settings `brute_row` uses for them): orders 12 and 16 agree.
    let sharp = LobeSet::new(LobeLayout::Fibonacci { count: 40 }, 5000.0).unwrap();
    let wo = DVec3::new(-0.9951847266716992, 0.09801714032951181, 1e-6);
    let g12 = graded_row(&sharp, wo, 0.04, 12, 0.75);
    let g16 = graded_row(&sharp, wo, 0.04, 16, 0.75);
    let max = g16.iter().fold(0.0f64, |m, &v| m.max(v));
    let worst = g12
        .iter()
        .zip(&g16)
        .map(|(a, b)| (a - b).abs() / max)
        .fold(0.0f64, f64::max);
    assert!(
        worst < 1e-3,
        "λ = 5000: orders 12 and 16 differ by {worst} of the row at {wo:?}"
    );
}
