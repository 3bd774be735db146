//! The Gaussian spherical radial basis function of Tsai & Shih 2006 (method.md §3).
//!
//! G(x; λ) = exp(2λ(x − 1)), x = h·ξ the cosine to the lobe centre: peak 1 at x = 1, and written
//! this way it cannot overflow. Its integral over the sphere is (π/λ)(1 − e^(−4λ)).
//!
//! Bandwidth: the paper prints σ² = 1 − (cosh(2λ) − (2λ)⁻¹); the correct relation uses **coth**:
//! the mean cosine of a von Mises–Fisher lobe with κ = 2λ is L(κ) = coth κ − 1/κ (the Langevin
//! function), and σ² = 1 − L(2λ). For σ = π/40, λ = 81.06. (With cosh there is a spurious root near
//! λ = 0.6.) We evaluate 1 − L(κ) as 1/κ − 2/expm1(2κ), which has no cancellation for large κ, and
//! by its Taylor series for small κ.
//!
//! Inputs: λ > 0 (or σ in (0, 1)). Outputs: finite values for every λ from 1e-6 to 1e8.

use super::SphereError;
use crate::math::bessel_i0e;

/// The paper's lobe width, σ = π/40.
pub const PAPER_SIGMA: f64 = std::f64::consts::PI / 40.0;

/// G(x; λ) = exp(2λ(x − 1)); x is clamped to [-1, 1] so rounding cannot push it past the peak.
#[inline]
pub fn gaussian(x: f64, lambda: f64) -> f64 {
    (2.0 * lambda * (x.clamp(-1.0, 1.0) - 1.0)).exp()
}

/// ∫_{S²} G(ω·ξ; λ) dω = (π/λ)(1 − e^(−4λ)), computed with expm1 for small λ.
pub fn integral(lambda: f64) -> f64 {
    -(-4.0 * lambda).exp_m1() * std::f64::consts::PI / lambda
}

/// 1 − L(κ), L the Langevin function coth κ − 1/κ: the lobe's σ² for κ = 2λ.
pub fn one_minus_mean_cosine(kappa: f64) -> f64 {
    if kappa < 1e-2 {
        // L(κ) = κ/3 − κ³/45 + 2κ⁵/945 − …
        let k2 = kappa * kappa;
        1.0 - kappa * (1.0 / 3.0 - k2 * (1.0 / 45.0 - k2 * 2.0 / 945.0))
    } else {
        1.0 / kappa - 2.0 / (2.0 * kappa).exp_m1()
    }
}

/// σ of a lobe of sharpness λ: σ² = 1 − (coth 2λ − 1/(2λ)).
pub fn sigma_from_lambda(lambda: f64) -> Result<f64, SphereError> {
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(SphereError::LambdaOutOfRange { lambda });
    }
    Ok(one_minus_mean_cosine(2.0 * lambda).sqrt())
}

/// λ of a lobe of width σ, the inverse of [`sigma_from_lambda`] (bisection on log κ: 1 − L is
/// strictly decreasing from 1 at κ → 0 to 0 at κ → ∞, so the root is unique).
pub fn lambda_from_sigma(sigma: f64) -> Result<f64, SphereError> {
    if !(sigma.is_finite() && sigma > 0.0 && sigma < 1.0) {
        return Err(SphereError::SigmaOutOfRange { sigma });
    }
    let target = sigma * sigma;
    let (mut lo, mut hi) = ((1e-12f64).ln(), (1e16f64).ln());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if one_minus_mean_cosine(mid.exp()) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(0.5 * (0.5 * (lo + hi)).exp())
}

/// The cosine below which G(x; λ) < e^(−cutoff_exponent): x_min = 1 − cutoff/(2λ), clamped to [-1,
/// 1]. Quadratures and renderers skip lobes past it (e^(−40) ≈ 4e-18 is below f64's relative
/// precision).
pub fn support_cosine(lambda: f64, cutoff_exponent: f64) -> f64 {
    (1.0 - cutoff_exponent / (2.0 * lambda)).clamp(-1.0, 1.0)
}

/// The ring lobe: G averaged over the azimuth of its centre, for a half-vector at polar angle θh
/// and a centre at polar angle θj (both from the normal), given by their cosines and sines: (1/2π)
/// ∫ G(h·R_φ ξ) dφ = exp(2λ(cos(θh − θj) − 1)) · I0e(2λ sin θh sin θj). Depends on h·n only: the
/// isotropic model's basis.
#[inline]
pub fn ring_lobe(cos_h: f64, sin_h: f64, cos_j: f64, sin_j: f64, lambda: f64) -> f64 {
    let cos_diff = (cos_h * cos_j + sin_h * sin_j).clamp(-1.0, 1.0);
    (2.0 * lambda * (cos_diff - 1.0)).exp() * bessel_i0e(2.0 * lambda * sin_h * sin_j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{GaussLegendre, Rng};
    use std::f64::consts::PI;

    #[test]
    fn paper_sigma_gives_lambda_81_06() {
        let lambda = lambda_from_sigma(PAPER_SIGMA).unwrap();
        assert!((lambda - 81.06).abs() <= 0.01, "lambda = {lambda}");
        // And not the spurious cosh root near 0.6.
        assert!(lambda > 10.0);
    }

    #[test]
    fn sigma_and_lambda_are_inverse() {
        for &lambda in &[1e-4, 0.01, 0.3, 1.0, 81.0, 5000.0, 1e7] {
            let sigma = sigma_from_lambda(lambda).unwrap();
            let back = lambda_from_sigma(sigma).unwrap();
            assert!(
                ((back - lambda) / lambda).abs() < 1e-9,
                "lambda={lambda} back={back}"
            );
        }
        assert!(lambda_from_sigma(0.0).is_err());
        assert!(lambda_from_sigma(1.0).is_err());
        assert!(lambda_from_sigma(f64::NAN).is_err());
        assert!(sigma_from_lambda(-1.0).is_err());
    }

    #[test]
    fn mean_cosine_series_and_closed_form_meet() {
        // Both branches agree at the switch point.
        let k: f64 = 1e-2;
        let series = {
            let k2 = k * k;
            1.0 - k * (1.0 / 3.0 - k2 * (1.0 / 45.0 - k2 * 2.0 / 945.0))
        };
        let closed = 1.0 / k - 2.0 / (2.0 * k).exp_m1();
        assert!((series - closed).abs() < 1e-12);
        // Direct definition of sigma^2 via quadrature of the vMF mean cosine, κ = 2λ = 162.1:
        // <cos> = ∫ x e^{κ x} dx / ∫ e^{κ x} dx over [-1, 1].
        let kappa = 162.11;
        let rule = GaussLegendre::new(200);
        let num = rule.integrate(-1.0, 1.0, |x| x * (kappa * (x - 1.0)).exp());
        let den = rule.integrate(-1.0, 1.0, |x| (kappa * (x - 1.0)).exp());
        assert!(((1.0 - num / den) - one_minus_mean_cosine(kappa)).abs() < 1e-12);
    }

    /// ∫G dω by quadrature in polar coordinates about an arbitrary axis: θ by composite
    /// Gauss–Legendre (panels packed near the peak), φ by the trapezoid rule on a random tilted
    /// frame, evaluating G through the dot product with the centre (not through the polar angle),
    /// so a wrong exponent, factor or axis handling would show.
    fn quadrature_integral(lambda: f64, seed: u64) -> f64 {
        let mut rng = Rng::new(seed);
        let xi = rng.unit_vector();
        let (t, b) = crate::sphere::Frame::from_normal(xi).tangents();
        let rule = GaussLegendre::new(64);
        let width = (1.0 / lambda).sqrt().min(PI);
        let mut edges = vec![0.0];
        let mut e = width / 8.0;
        while e < PI {
            edges.push(e);
            e *= 2.0;
        }
        edges.push(PI);
        let n_phi = 64;
        let mut total = 0.0;
        for w in edges.windows(2) {
            for (theta, wt) in rule.on_interval(w[0], w[1]) {
                let mut ring = 0.0;
                for k in 0..n_phi {
                    let phi = 2.0 * PI * (k as f64 + 0.3) / n_phi as f64;
                    let d = xi * theta.cos() + (t * phi.cos() + b * phi.sin()) * theta.sin();
                    ring += gaussian(d.dot(xi), lambda);
                }
                total += wt * theta.sin() * ring * 2.0 * PI / n_phi as f64;
            }
        }
        total
    }

    #[test]
    fn integral_matches_quadrature() {
        for (i, &lambda) in [1.0, 81.0, 5000.0].iter().enumerate() {
            let closed = integral(lambda);
            let want = (PI / lambda) * (1.0 - (-4.0 * lambda).exp());
            assert!(((closed - want) / want).abs() < 1e-14);
            let quad = quadrature_integral(lambda, i as u64 + 3);
            assert!(
                ((quad - closed) / closed).abs() < 1e-9,
                "lambda={lambda} quad={quad} closed={closed}"
            );
        }
    }

    #[test]
    fn ring_lobe_is_the_azimuthal_average() {
        let mut rng = Rng::new(11);
        for &lambda in &[1.0, 81.06, 5000.0] {
            for _ in 0..20 {
                let th = rng.range(0.0, PI / 2.0);
                let tj = if lambda > 1000.0 {
                    th + rng.range(-0.02, 0.02)
                } else {
                    rng.range(0.0, PI / 2.0)
                };
                let (ch, sh, cj, sj) = (th.cos(), th.sin(), tj.cos(), tj.sin().abs());
                // Brute force: trapezoid over the azimuth (periodic, exponentially convergent).
                let n = 20_000;
                let mut sum = 0.0;
                for k in 0..n {
                    let phi = 2.0 * PI * k as f64 / n as f64;
                    let x = ch * cj + sh * sj * phi.cos();
                    sum += gaussian(x, lambda);
                }
                let brute = sum / n as f64;
                let ring = ring_lobe(ch, sh, cj, sj, lambda);
                let tol = 1e-10 + 1e-9 * brute;
                assert!(
                    (ring - brute).abs() <= tol,
                    "λ={lambda} ring={ring} brute={brute}"
                );
            }
        }
    }

    #[test]
    fn gaussian_never_overflows() {
        for &lambda in &[1e-6, 1.0, 1e4, 1e8] {
            for &x in &[-1.0, 0.0, 0.5, 1.0, 1.0 + 1e-12] {
                let g = gaussian(x, lambda);
                assert!(g.is_finite() && (0.0..=1.0).contains(&g));
            }
        }
    }
}
