//! The exponentially scaled modified Bessel function of the first kind, order zero:
//! I0e(x) = e^(-|x|) I0(x).
//!
//! It appears in the azimuthal average of a Gaussian lobe (the isotropic "ring" lobe): averaging
//! exp(2λ(h·ξ - 1)) over the azimuth of ξ gives exp(2λ(cos(θh - θξ) - 1)) · I0e(2λ sin θh sin θξ),
//! a form that cannot overflow for any λ. Inputs: any finite x. Output: a value in (0, 1], with
//! relative error below 1e-14 (power series below 30, asymptotic series above: both converge to
//! full precision there).
//!
//! Defined here, in the file-format crate, because its reference evaluator of the exported BRDF
//! ([`crate::brdf`]) needs it and this crate cannot depend on `glint`; glint's `math` module
//! re-exports it and tests it against the integral representation.

/// e^(-|x|) I0(x).
pub fn bessel_i0e(x: f64) -> f64 {
    let x = x.abs();
    if x < 30.0 {
        // I0(x) = Σ (x²/4)^k / (k!)², all terms positive: no cancellation.
        let q = 0.25 * x * x;
        let mut term = 1.0f64;
        let mut sum = 1.0f64;
        let mut k = 1.0f64;
        while term > sum * 1e-17 {
            term *= q / (k * k);
            sum += term;
            k += 1.0;
        }
        sum * (-x).exp()
    } else {
        // I0(x) e^-x ~ 1/sqrt(2πx) Σ ((2k-1)!!)² / (k! 8^k x^k); at x ≥ 30 the smallest term is far
        // below 1e-17 before the series starts to diverge.
        let mut term = 1.0f64;
        let mut sum = 1.0f64;
        let mut k = 1.0f64;
        loop {
            let next = term * (2.0 * k - 1.0) * (2.0 * k - 1.0) / (k * 8.0 * x);
            if next.abs() < 1e-17 * sum || next > term {
                break;
            }
            term = next;
            sum += term;
            k += 1.0;
        }
        sum / (2.0 * std::f64::consts::PI * x).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // I0(1) = 1.2660658777520082 (Abramowitz & Stegun table 9.8).
        assert!((bessel_i0e(1.0) * 1f64.exp() - 1.266_065_877_752_008_2).abs() < 1e-14);
        assert_eq!(bessel_i0e(0.0), 1.0);
    }
}
