//! Every entry of the energy table g (the paper's J = 147 hemicube lobes at σ = π/40, N_l = 192) against
//! brute-force quadrature directly over wi (no half-vector change of variables): a midpoint rule on a
//! fine (θi, φi) grid of the hemisphere, all lobes per grid point. Also the isotropic (ring) lobes, whose
//! brute force evaluates the ring lobe through the Bessel closed form, and the hard cases λ = 1, 5000.

use glam::DVec3;
use glint::brdf::energy::{EnergyQuadrature, EnergyTable, default_outgoing};
use glint::brdf::static_term;
use glint::sphere::srbf::{PAPER_SIGMA, lambda_from_sigma, support_cosine};
use glint::sphere::{LobeLayout, LobeSet};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Brute-force row g_j(wo) for all j: Σ over a (θi, φi) midpoint grid of G_j(h) s(wi, wo) cos θi dω.
fn midpoint_row(lobes: &LobeSet, wo: DVec3, f0: f64, n_theta: usize) -> Vec<f64> {
    // For grazing wo, wi near the mirror direction is grazing too and |wi + wo| ≈ 2 k2: h moves ~1/k2
    // times faster than wi, so a lobe is ~1/k2 times narrower in φi. Refine φ accordingly.
    let n_phi = 4 * n_theta * (0.2 / wo.z).ceil().max(1.0) as usize;
    let dp = 2.0 * PI / n_phi as f64;
    // θ panels: [0, π/2 − 0.1] with n points and a horizon panel [π/2 − 0.1, π/2] with n/2 points (a
    // 12× finer step): near the horizon k1/d(k1, k2) rises from 0 over a scale of k2, which is 0.025
    // for the most grazing outgoing direction.
    let split = 0.5 * PI - 0.1;
    let panels = [(0.0, split, n_theta), (split, 0.5 * PI, n_theta / 2)];
    let cut = support_cosine(lobes.lambda(), 40.0);
    let iso = lobes.layout().is_isotropic();
    // A ring lobe is at most exp(2λ(cos(θh − θj) − 1)), so it too can be skipped outside its support.
    let polar: Vec<f64> = lobes.centres().iter().map(|c| c.z.clamp(-1.0, 1.0).acos()).collect();
    let mut row = vec![0.0; lobes.len()];
    for (lo, hi, n) in panels {
        let dt = (hi - lo) / n as f64;
        for i in 0..n {
            let th = lo + (i as f64 + 0.5) * dt;
            let (st, ct) = th.sin_cos();
            for k in 0..n_phi {
                let ph = (k as f64 + 0.5) * dp;
                let wi = DVec3::new(st * ph.cos(), st * ph.sin(), ct);
                let weight = static_term(wi, wo, f0) * ct * st * dt * dp;
                if weight == 0.0 {
                    continue;
                }
                let h = (wi + wo).normalize();
                let theta_h = h.z.clamp(-1.0, 1.0).acos();
                for (j, r) in row.iter_mut().enumerate() {
                    let inside = if iso { (theta_h - polar[j]).cos() > cut } else { h.dot(lobes.centres()[j]) > cut };
                    if inside {
                        *r += lobes.eval_one(j, h) * weight;
                    }
                }
            }
        }
    }
    row
}

/// Richardson extrapolation of the midpoint rule (error c₂h² + c₄h⁴ + …: the integrand is smooth on the
/// (θ, φ) rectangle, periodic in φ): (4 I(2n) − I(n)) / 3.
fn brute_row(lobes: &LobeSet, wo: DVec3, f0: f64, n_theta: usize) -> Vec<f64> {
    let coarse = midpoint_row(lobes, wo, f0, n_theta);
    let fine = midpoint_row(lobes, wo, f0, 2 * n_theta);
    coarse.iter().zip(&fine).map(|(c, f)| (4.0 * f - c) / 3.0).collect()
}

fn check_table(lobes: &LobeSet, outgoing: &[DVec3], f0: f64, n_theta: usize, tolerance: f64) -> f64 {
    let start = std::time::Instant::now();
    let table = EnergyTable::new(lobes, outgoing, &EnergyQuadrature::default());
    let build_secs = start.elapsed().as_secs_f64();
    let brute: Vec<Vec<f64>> = outgoing.par_iter().map(|&wo| brute_row(lobes, wo, f0, n_theta)).collect();
    let max_entry = brute.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
    let mut worst = 0.0f64;
    for (l, row) in brute.iter().enumerate() {
        for (j, &want) in row.iter().enumerate() {
            let got = table.entry(l, j, f0);
            assert!(got.is_finite() && got >= 0.0);
            // Relative error; entries below 1e-6 of the largest are compared in absolute terms.
            let err = (got - want).abs() / want.max(1e-6 * max_entry);
            worst = worst.max(err);
            assert!(err < tolerance, "{} l={l} j={j} wo={:?} got={got} want={want}", lobes.layout().name(), outgoing[l]);
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
    assert_eq!(outgoing.len(), 192 + 64, "the paper's 192 and two rings near the horizon");
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
    // λ = 1: lobes span the whole hemisphere. λ = 5000: a few hundredths of a radian wide (the grid is
    // refined to resolve them; fewer outgoing directions keep the test short).
    let broad = LobeSet::new(LobeLayout::Fibonacci { count: 40 }, 1.0).unwrap();
    check_table(&broad, &default_outgoing(&broad)[..48], 0.04, 64, 1e-3);
    let sharp = LobeSet::new(LobeLayout::Fibonacci { count: 40 }, 5000.0).unwrap();
    let outgoing: Vec<DVec3> = default_outgoing(&sharp).into_iter().step_by(24).collect();
    check_table(&sharp, &outgoing, 0.04, 600, 1e-3);
}
