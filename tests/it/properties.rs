//! Property tests (proptest) of the BRDF's physical guarantees over random inputs:
//!
//! - f_s is finite, ≥ 0 and reciprocal for random lobe layouts, λ, non-negative coefficients, F0
//!   and directions (grazing ones included);
//! - after a constrained fit (random non-negative-target problems solved by the library's QP with
//!   the energy rows on) the directional albedo ∫ f_r cos θi dωi stays ≤ 1.01 on 10⁴ random
//!   outgoing directions, although the energy rows constrain only N_l of them. The albedo is
//!   integrated here independently of the energy table: in *incident*-direction space (the table
//!   integrates in half-vector space), per lobe over a polar cap about the lobe's mirror direction.

use glam::DVec3;
use glint::brdf::{DistributionBrdf, EnergyTable};
use glint::fit::problem::{ChannelSystem, NormalEquations};
use glint::math::GaussLegendre;
use glint::sphere::{LobeLayout, LobeSet};
use proptest::prelude::*;
use rayon::prelude::*;
use std::f64::consts::PI;

/// A unit direction on the upper hemisphere from (u, v) ∈ [0, 1]²; `grazing` pushes z towards 0.
fn hemisphere(u: f64, v: f64, grazing: bool) -> DVec3 {
    let z = if grazing {
        (1e-9f64).max(u.powi(8) * 1e-3)
    } else {
        u.max(1e-12)
    };
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * v;
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// `default` cases, or PROPTEST_CASES when set (for longer runs than CI's: see the README).
fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn layout_strategy() -> impl Strategy<Value = LobeLayout> {
    prop_oneof![
        (1usize..=5).prop_map(|n| LobeLayout::Hemicube { n }),
        (1usize..=80).prop_map(|count| LobeLayout::Fibonacci { count }),
        (1usize..=40).prop_map(|count| LobeLayout::Isotropic { count }),
    ]
}

/// λ log-uniform over [0.5, 10⁴] (σ from ~60° down to ~0.4°).
fn lambda_strategy() -> impl Strategy<Value = f64> {
    (0.0f64..1.0).prop_map(|t| 0.5 * (2e4f64).powf(t))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(48), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn specular_is_finite_non_negative_and_reciprocal(
        layout in layout_strategy(),
        lambda in lambda_strategy(),
        seeds in prop::collection::vec(0.0f64..3.0, 80),
        zeros in prop::collection::vec(any::<bool>(), 80),
        f0 in 0.0f64..=1.0,
        pairs in prop::collection::vec((0.0f64..1.0, 0.0f64..1.0, any::<bool>(), 0.0f64..1.0, 0.0f64..1.0, any::<bool>()), 64),
    ) {
        let lobes = LobeSet::new(layout, lambda).unwrap();
        // Sparse, non-negative coefficients (many exactly 0, as fits produce).
        let coefficients: Vec<f64> = (0..lobes.len()).map(|j| if zeros[j % 80] { 0.0 } else { seeds[j % 80] }).collect();
        let brdf = DistributionBrdf { lobes, coefficients, f0, rho_d: 0.0 };
        for &(u1, v1, g1, u2, v2, g2) in &pairs {
            let (wi, wo) = (hemisphere(u1, v1, g1), hemisphere(u2, v2, g2));
            let a = brdf.specular(wi, wo);
            let b = brdf.specular(wo, wi);
            prop_assert!(a.is_finite() && a >= 0.0, "f_s({wi}, {wo}) = {a}");
            prop_assert!((a - b).abs() <= 1e-12 * a.max(b) + 1e-300, "f_s({wi}, {wo}) = {a} but f_s({wo}, {wi}) = {b}");
            // Below the horizon, f_s is 0 in either slot.
            let below = DVec3::new(wi.x, wi.y, -wi.z);
            prop_assert_eq!(brdf.specular(below, wo), 0.0);
            prop_assert_eq!(brdf.specular(wo, below), 0.0);
        }
    }
}

/// Gauss–Legendre points per radial panel of the cap; trapezoid points on a ring well clear of the
/// horizon.
const RADIAL: usize = 16;
const AZIMUTH: usize = 32;
/// Gauss–Legendre order and largest width (radians) of the graded azimuth panels.
const PANEL_ORDER: usize = 8;
const PANEL_WIDTH: f64 = PI / 6.0;
/// A ring whose features are all at least this wide (radians of azimuth) uses the trapezoid rule.
const SMOOTH: f64 = 0.3;

/// Breakpoints of [lo, hi] for composite Gauss–Legendre, graded geometrically towards each feature
/// (φ, scale): a panel is no wider than the larger of the scale and its distance to the feature
/// behind it, or half its distance to the feature ahead, and never wider than `PANEL_WIDTH`.
fn graded_breaks(lo: f64, hi: f64, features: &[(f64, f64)]) -> Vec<f64> {
    let mut b = vec![lo];
    let mut x = lo;
    while x < hi {
        let mut w = PANEL_WIDTH.min(hi - x);
        for &(p, scale) in features {
            let limit = if p >= x { 0.5 * (p - x) } else { x - p };
            w = w.min(limit.max(scale));
        }
        x = if hi - (x + w) < 1e-12 { hi } else { x + w };
        b.push(x);
    }
    b
}
/// ∫_{H²} f_s(wi, wo) cos θi dωi for one lobe (coefficient 1), by Gauss–Legendre in the radius of a
/// polar cap in wi-space about the mirror direction of wo in the lobe centre, and in the azimuth of
/// each ring of it. The map h → wi is 2-Lipschitz, so the cap of radius 2α, α the angle where G
/// falls below e⁻³⁶, holds the whole lobe.
///
/// For grazing wo the integrand has two sharp features. Where wi crosses the horizon, cos θi · s ∝
/// k1 / (k1 + k2 − k1k2) ramps up from 0 over k1 ~ k2 = wo.z. And −wo lies just below the horizon,
/// where h = normalize(wi + wo) depends on the *direction* from −wo to wi only: near −wo, h sweeps
/// the whole circle ⟂ wo (where the Fresnel factor is ~1) within any small disc. A ring at angular
/// distance δ from −wo sees that as a bright feature ~δ wide. A 32-point trapezoid rule on such
/// rings made the albedo of a λ = 8 lobe 4 % high at wo.z = 5e-4 (a case CI found). So
/// the radius is split at the ring through −wo, and a ring passing within a few tenths of −wo, or
/// crossing the horizon, is integrated on Gauss–Legendre panels graded towards the point nearest
/// −wo and towards its horizon crossings.
fn lobe_albedo_wi(brdf: &DistributionBrdf, j: usize, wo: DVec3, rule: &GaussLegendre) -> f64 {
    let lambda = brdf.lobes.lambda();
    let mut xi = brdf.lobes.centres()[j];
    if brdf.lobes.layout().is_isotropic() {
        unreachable!("ring lobes are not caps");
    }
    // The relevant half-vectors satisfy wo·h ≥ 0: project ξ onto that hemisphere.
    if xi.dot(wo) < 0.0 {
        xi = (xi - xi.dot(wo) * wo).try_normalize().unwrap_or(DVec3::Z);
    }
    let centre = (2.0 * wo.dot(xi) * xi - wo).normalize();
    // G = exp(2λ(cos α − 1)) < e⁻³⁶ beyond 1 − cos α = 18/λ.
    let cos_alpha = 1.0 - 18.0 / lambda;
    let alpha = if cos_alpha <= -1.0 {
        PI
    } else {
        cos_alpha.acos()
    };
    let radius = (2.0 * alpha).min(PI);
    let (u, v) = centre.any_orthonormal_pair();
    // A ring of the cap at angle t from the centre (elevation e above the horizon) lies wholly
    // above the horizon while t < e, partly for e ≤ t < π − e. The radial rule is split there, and
    // a partial ring is integrated over its visible arc only: the integrand is smooth on each piece
    // (integrating the cut-off circle with the trapezoid rule gave errors of ±5 % for broad lobes
    // at grazing wo). (With the centre below the horizon, e < 0: wholly below while t < −e, partly
    // up to π + e, wholly above beyond.)
    let elevation = centre.z.clamp(-1.0, 1.0).asin().abs();
    let minus_wo = -wo;
    let t_star = centre.dot(minus_wo).clamp(-1.0, 1.0).acos();
    let phi_star = minus_wo.dot(v).atan2(minus_wo.dot(u));
    let mut breaks = [
        0.0,
        elevation.min(radius),
        (PI - elevation).min(radius),
        t_star.min(radius),
        radius,
    ];
    breaks.sort_by(f64::total_cmp);
    let panel_rule = GaussLegendre::new(PANEL_ORDER);
    let mut sum = 0.0;
    for panel in breaks.windows(2).filter(|p| p[1] > p[0]) {
        for (t, wt) in rule.on_interval(panel[0], panel[1]) {
            let (st, ct) = t.sin_cos();
            let f = |phi: f64| {
                let wi = ct * centre + st * (phi.cos() * u + phi.sin() * v);
                if wi.z <= 0.0 {
                    return 0.0;
                }
                let Some(h) = (wi + wo).try_normalize() else {
                    return 0.0;
                };
                brdf.lobes.eval_exact(j, h) * glint::brdf::static_term(wi, wo, brdf.f0) * wi.z
            };
            // wi.z(φ) = ct·c.z + st·(u.z cos φ + v.z sin φ) = a + r cos(φ − φ0): highest at φ0.
            let (a, r, phi0) = (ct * centre.z, st * u.z.hypot(v.z), v.z.atan2(u.z));
            // Features along the ring: the point nearest −wo, ~(|t − t*| + k2) from it.
            let star_scale = 0.25 * ((t - t_star).abs() + wo.z) / st.max(1e-300);
            let ring = if a + r <= 0.0 {
                0.0
            } else if a - r >= 0.0 {
                // Wholly above: the lowest point φ0 + π, (a − r + k2) above the ramp.
                let low_scale = 0.25 * (a - r + wo.z) / r.max(1e-300);
                if star_scale.min(low_scale) >= SMOOTH {
                    (0..AZIMUTH)
                        .map(|k| f(2.0 * PI * (k as f64 + 0.5) / AZIMUTH as f64))
                        .sum::<f64>()
                        * 2.0
                        * PI
                        / AZIMUTH as f64
                } else {
                    // One period centred on φ*, the lowest point with its images a period away.
                    let low = phi0 + PI - 2.0 * PI * ((phi0 + PI - phi_star) / (2.0 * PI)).round();
                    let features = [
                        (phi_star, star_scale),
                        (low, low_scale),
                        (low - 2.0 * PI, low_scale),
                        (low + 2.0 * PI, low_scale),
                    ];
                    graded_breaks(phi_star - PI, phi_star + PI, &features)
                        .windows(2)
                        .map(|w| panel_rule.integrate(w[0], w[1], f))
                        .sum()
                }
            } else {
                // The visible arc φ0 ± half, graded towards its two ends (the ramp) and towards φ*.
                let half = (-a / r).clamp(-1.0, 1.0).acos();
                let end_scale = 0.25 * wo.z / r;
                let star = phi_star - 2.0 * PI * ((phi_star - phi0) / (2.0 * PI)).round();
                let features = [
                    (phi0 - half, end_scale),
                    (phi0 + half, end_scale),
                    (star, star_scale),
                ];
                graded_breaks(phi0 - half, phi0 + half, &features)
                    .windows(2)
                    .map(|w| panel_rule.integrate(w[0], w[1], f))
                    .sum()
            };
            sum += wt * st * ring;
        }
    }
    sum
}

/// Gauss–Legendre integration of the same lobe over the whole hemisphere in (cos θi, φi) on a very
/// fine grid: the reference that checks the cap quadrature itself (broad lobes only).
fn lobe_albedo_hemisphere(brdf: &DistributionBrdf, j: usize, wo: DVec3, points: usize) -> f64 {
    let rule = GaussLegendre::new(points);
    let mut sum = 0.0;
    for (z, wz) in rule.on_interval(0.0, 1.0) {
        let r = (1.0 - z * z).sqrt();
        for (phi, wp) in rule.on_interval(0.0, 2.0 * PI) {
            let wi = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            let Some(h) = (wi + wo).try_normalize() else {
                continue;
            };
            sum += wz
                * wp
                * brdf.lobes.eval_exact(j, h)
                * glint::brdf::static_term(wi, wo, brdf.f0)
                * z;
        }
    }
    sum
}

#[test]
fn cap_quadrature_matches_a_full_hemisphere_grid() {
    let rule = GaussLegendre::new(RADIAL);
    for (lambda, j) in [(1.0, 0), (3.5, 5), (10.0, 3), (40.0, 7), (300.0, 1)] {
        let lobes = LobeSet::new(LobeLayout::Hemicube { n: 2 }, lambda).unwrap();
        let brdf = DistributionBrdf {
            coefficients: vec![1.0; lobes.len()],
            lobes,
            f0: 0.3,
            rho_d: 0.0,
        };
        for wo in [
            DVec3::Z,
            DVec3::new(0.6, 0.2, 0.5).normalize(),
            DVec3::new(-0.9, 0.3, 0.05).normalize(),
            DVec3::new(0.9123, 0.4095, 3e-3).normalize(),
            DVec3::new(0.9123, 0.4095, 1e-6).normalize(),
        ] {
            let cap = lobe_albedo_wi(&brdf, j, wo, &rule);
            let full = lobe_albedo_hemisphere(&brdf, j, wo, 200);
            // Grazing wo (z ≤ 3e-3): s varies on the scale wo.z near the horizon, which both rules
            // resolve only to a few 1e-3 (λ = 10 at z = 3e-3: 2.8e-3 apart; the cap rule moves by
            // 2e-5 from 32 to 128 arc points). At λ = 40 they are 7.6e-3 apart and it is not
            // settled which is closer, so grazing directions are checked for λ ≤ 10 only. The
            // albedo property below has 1e-2 of margin.
            if wo.z < 0.01 && lambda > 10.0 {
                continue;
            }
            let tolerance = if wo.z < 0.01 { 5e-3 } else { 2e-3 };
            assert!(
                (cap - full).abs() <= tolerance * full.max(1e-3),
                "λ={lambda} j={j} wo={wo}: cap {cap} vs grid {full}"
            );
        }
    }
}

/// A case CI found: a broad lobe (λ = 8.35) near the normal, seen from wo.z = 5e-4,
/// where the ring through the patch at −wo had made the cap rule 4 % high (albedo 1.0215 reported
/// for a fit whose true albedo is 0.999). The grid at 800² points is converged here to 1e-4 (400²:
/// 0.07 % off, 200²: 0.7 %).
#[test]
fn cap_quadrature_resolves_the_patch_at_minus_wo() {
    let lobes = LobeSet::new(LobeLayout::Fibonacci { count: 7 }, 8.352166783431883).unwrap();
    let brdf = DistributionBrdf {
        coefficients: vec![1.0; lobes.len()],
        lobes,
        f0: 0.05673871523560193,
        rho_d: 0.0,
    };
    let rule = GaussLegendre::new(RADIAL);
    for z in [5e-4, 1e-6] {
        let r = (1.0f64 - z * z).sqrt();
        let wo = DVec3::new(
            0.934177385569804 * r / 0.9999,
            -0.35680856542400635 * r / 0.9999,
            z,
        )
        .normalize();
        for j in [0, 2, 3, 5] {
            let cap = lobe_albedo_wi(&brdf, j, wo, &rule);
            let full = lobe_albedo_hemisphere(&brdf, j, wo, 800);
            assert!(
                (cap - full).abs() <= 1e-3 * full,
                "j={j} wo={wo}: cap {cap} vs grid {full}"
            );
        }
    }
}

/// A random fit problem: T (N × J) ≥ 0, targets ≥ 0 made from an energy-infeasible p (so the energy
/// rows bind) plus noise; normal equations formed here, solved by the library's constrained QP.
fn fit_random(
    lobes: &LobeSet,
    energy: &EnergyTable,
    f0: f64,
    rho_d: f64,
    seed: u64,
    brightness: f64,
) -> Vec<f64> {
    let mut rng = glint::math::Rng::new(seed);
    let j = lobes.len();
    let n = 3 * j + 10;
    let t: Vec<f64> = (0..n * j).map(|_| rng.next_f64().powi(3)).collect();
    let truth: Vec<f64> = (0..j)
        .map(|_| {
            if rng.next_f64() < 0.3 {
                brightness * rng.next_f64()
            } else {
                0.0
            }
        })
        .collect();
    let target: Vec<f64> = (0..n)
        .map(|i| {
            ((0..j).map(|k| t[i * j + k] * truth[k]).sum::<f64>() + 0.1 * rng.next_f64()).max(0.0)
        })
        .collect();
    let mut h = vec![0.0; j * j];
    let mut r = vec![0.0; j];
    for i in 0..n {
        let row = &t[i * j..(i + 1) * j];
        for a in 0..j {
            r[a] += row[a] * target[i];
            for b in 0..j {
                h[a * j + b] += row[a] * row[b];
            }
        }
    }
    let constant = target.iter().map(|b| b * b).sum();
    let equations = NormalEquations {
        j,
        h,
        r,
        constant,
        weight_sum: n as f64,
        pixels: n,
    };
    let system = ChannelSystem::new(equations, Some((energy, f0)), rho_d).unwrap();
    let fit = system.solve(None).unwrap();
    assert!(fit.coefficients.iter().all(|c| c.is_finite() && *c >= 0.0));
    fit.coefficients
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(5), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn fitted_albedo_stays_below_one_on_ten_thousand_directions(
        layout in prop_oneof![(2usize..=4).prop_map(|n| LobeLayout::Hemicube { n }), (6usize..=40).prop_map(|count| LobeLayout::Fibonacci { count })],
        lambda in (0.0f64..1.0).prop_map(|t| 1.0 * (300.0f64).powf(t)),
        f0 in 0.0f64..=1.0,
        rho_d in 0.0f64..0.9,
        seed in any::<u64>(),
        brightness in 1.0f64..100.0,
    ) {
        let lobes = LobeSet::new(layout, lambda).unwrap();
        let energy = EnergyTable::with_defaults(&lobes);
        let coefficients = fit_random(&lobes, &energy, f0, rho_d, seed, brightness);
        let brdf = DistributionBrdf { lobes, coefficients, f0, rho_d };
        let active: Vec<usize> = (0..brdf.coefficients.len()).filter(|&j| brdf.coefficients[j] > 0.0).collect();
        let rule = GaussLegendre::new(RADIAL);
        let mut rng = glint::math::Rng::new(seed ^ 0x9e37_79b9_7f4a_7c15);
        // Uniform in solid angle, plus every 10th direction within 3° of the horizon.
        let directions: Vec<DVec3> = (0..10_000)
            .map(|k| if k % 10 == 0 { hemisphere(rng.next_f64() * 0.05, rng.next_f64(), false) } else { rng.hemisphere_vector() })
            .collect();
        // The diffuse part integrates to ρd exactly.
        let albedos: Vec<f64> = directions
            .par_iter()
            .map(|&wo| rho_d + active.iter().map(|&j| brdf.coefficients[j] * lobe_albedo_wi(&brdf, j, wo, &rule)).sum::<f64>())
            .collect();
        prop_assert!(albedos.iter().all(|a| a.is_finite()));
        let (k, &a) = albedos.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap();
        let worst = (a, directions[k]);
        // The energy rows themselves hold at their own directions (the solver's guarantee).
        let rows = energy.albedo(&brdf.coefficients, f0);
        prop_assert!(rows.iter().all(|&a| a <= 1.0 - rho_d + 1e-9));
        prop_assert!(worst.0 <= 1.01, "{layout:?} λ={lambda:.2} F0={f0:.3} ρd={rho_d:.3}: albedo {:.4} at wo={} ({} active lobes)", worst.0, worst.1, active.len());
    }
}
