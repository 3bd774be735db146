//! Schlick's Fresnel approximation, F(c) = F0 + (1 − F0)(1 − c)^5, c = wi·h.
//!
//! Inputs: F0 ∈ [0, 1] and a cosine (clamped to [0, 1]). Outputs: F ∈ [F0, 1]. Because F is affine
//! in F0, F = F0·a(c) + b(c) with a = 1 − (1 − c)^5 and b = (1 − c)^5: tables that integrate F (the
//! energy rows) are stored as two parts and combined for any F0 without re-integrating.

/// (1 − c)^5 with c clamped to [0, 1].
#[inline]
pub fn schlick_weight(cos: f64) -> f64 {
    let m = 1.0 - cos.clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// F0 + (1 − F0)(1 − c)^5.
#[inline]
pub fn schlick(f0: f64, cos: f64) -> f64 {
    let b = schlick_weight(cos);
    f0 + (1.0 - f0) * b
}

/// (a, b) with F = F0·a + b.
#[inline]
pub fn schlick_parts(cos: f64) -> (f64, f64) {
    let b = schlick_weight(cos);
    (1.0 - b, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_and_split() {
        assert_eq!(schlick(0.04, 1.0), 0.04);
        assert_eq!(schlick(0.04, 0.0), 1.0);
        for &f0 in &[0.0, 0.04, 0.5, 1.0] {
            for k in 0..=100 {
                let c = k as f64 / 100.0;
                let (a, b) = schlick_parts(c);
                assert!((schlick(f0, c) - (f0 * a + b)).abs() < 1e-15);
                assert!(schlick(f0, c) >= f0 - 1e-15 && schlick(f0, c) <= 1.0);
                // Direct power form.
                assert!((schlick(f0, c) - (f0 + (1.0 - f0) * (1.0 - c).powi(5))).abs() < 1e-15);
            }
        }
    }
}
