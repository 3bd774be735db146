//! The exponentially scaled Bessel function I0e(x) = e^(-|x|) I0(x) of the ring lobes, defined in
//! `glint_exporters::bessel` (the exporters' reference evaluator needs it and that crate cannot
//! depend on glint) and re-exported here; tested here against its integral representation with
//! glint's quadrature.

pub use glint_exporters::bessel::bessel_i0e;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::GaussLegendre;

    /// Independent reference: I0e(x) = (1/π) ∫_0^π exp(x (cos t - 1)) dt by Gauss–Legendre.
    fn reference(x: f64) -> f64 {
        let rule = GaussLegendre::new(200);
        // Split [0, π] so the peak near t = 0 (sharp for large x) is resolved.
        let cut = (8.0 / x.max(1e-3)).sqrt().min(std::f64::consts::PI);
        let f = |t: f64| (x * (t.cos() - 1.0)).exp();
        (rule.integrate(0.0, cut, f) + rule.integrate(cut, std::f64::consts::PI, f))
            / std::f64::consts::PI
    }

    #[test]
    fn matches_the_integral_representation() {
        for &x in &[
            0.0, 1e-8, 0.5, 1.0, 5.0, 29.9, 30.0, 30.1, 100.0, 1000.0, 1e4,
        ] {
            let got = bessel_i0e(x);
            let want = reference(x);
            assert!(
                ((got - want) / want).abs() < 1e-12,
                "x={x} got={got} want={want}"
            );
        }
    }
}
