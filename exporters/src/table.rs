//! The tabulated p(h) and its hemi-octahedral parameterisation — the one definition that writers,
//! readers and renderers share.
//!
//! Inputs: a resolution R and R² RGB texels (row-major, index = y·R + x), or a function of the
//! local half-vector to tabulate. Outputs: [`hemi_oct_decode`] (texel coordinates → h),
//! [`hemi_oct_encode`] (h → texel coordinates), [`PhTable::lookup`] (bilinear on a corner-aligned
//! grid) and [`PhTable::tabulate`].
//!
//! Parameterisation ("hemi-octahedral", corner-aligned): texel (x, y) sits at u = x/(R−1), v =
//! y/(R−1) (the outer texels lie on the horizon, so bilinear lookup covers the square without
//! clamping); a = 2u−1, b = 2v−1, px = (a+b)/2, py = (a−b)/2, z = 1−|px|−|py| (≥ 0 on the whole
//! square), h = normalize(px, py, z). Inverse: l1 = |hx|+|hy|+|hz|, px = hx/l1, py = hy/l1, u =
//! (px+py+1)/2, v = (px−py+1)/2. The square's border is the horizon; its centre is the normal. Row
//! y = 0 is the first (top) scan line of the EXR.
//!
//! Invariants: decode ∘ encode is the identity on the upper hemisphere (to rounding); lookup at a
//! texel centre returns that texel exactly; no IO.

/// The parameterisation's name, written into every file's metadata.
pub const PARAMETERISATION: &str = "hemi-octahedral";

/// The parameterisation's definition, written beside its name.
pub const PARAMETERISATION_FORMULA: &str = "hemi-octahedral: texel (x, y) of an RxR table sits at u = x/(R-1), v = y/(R-1) (corner-aligned: the outer texels lie on the horizon); a = 2u-1, b = 2v-1, px = (a+b)/2, py = (a-b)/2, z = 1-|px|-|py|, h = normalize(px, py, z) in the local frame (z = normal, x = tangent); inverse l1 = |hx|+|hy|+hz, u = (hx/l1+hy/l1+1)/2, v = (hx/l1-hy/l1+1)/2; bilinear between texels; row y = 0 is the first (top) scan line";

/// The table resolution glint writes unless told otherwise: 512 (3 MiB of RGB f32). Measured
/// against the exact lobe sum at λ = 81 (σ = π/40): specular f_r within 0.7 % where ≥ 1 % of its
/// peak, error ≤ 0.2 % of the peak everywhere; see exporters/README.md for the table per
/// resolution.
pub const DEFAULT_TABLE_RESOLUTION: u32 = 512;

/// Largest resolution accepted (a 16384² RGB f32 table is 3 GiB).
pub const MAX_TABLE_RESOLUTION: u32 = 16384;

/// The local half-vector (unit, z ≥ 0) at table coordinates (u, v) ∈ [0, 1]². The one definition:
/// glint's renderers (the library's `sphere::hemi_oct` re-exports it), the exporters, and the WGSL
/// copy in shaders/prt_shade.wgsl (checked against this on every texel by the GPU tests).
pub fn hemi_oct_decode(u: f64, v: f64) -> [f64; 3] {
    let a = 2.0 * u - 1.0;
    let b = 2.0 * v - 1.0;
    let px = 0.5 * (a + b);
    let py = 0.5 * (a - b);
    let z = (1.0 - px.abs() - py.abs()).max(0.0);
    // z ≥ 0 and |px| + |py| + z ≥ 1 on the whole square, so the length is ≥ 1/√3.
    let inv = 1.0 / (px * px + py * py + z * z).sqrt();
    [px * inv, py * inv, z * inv]
}

/// Table coordinates (u, v) ∈ [0, 1]² of a local direction. A direction below the horizon
/// (h.z < 0) is folded to its mirror image above it (|h.z|), so every direction indexes the square;
/// a zero or non-finite vector maps to the centre (the normal).
pub fn hemi_oct_encode(h: [f64; 3]) -> (f64, f64) {
    let l1 = h[0].abs() + h[1].abs() + h[2].abs();
    if !(l1.is_finite() && l1 > 0.0) {
        return (0.5, 0.5);
    }
    let px = h[0] / l1;
    let py = h[1] / l1;
    (((px + py) + 1.0) * 0.5, ((px - py) + 1.0) * 0.5)
}

/// The tabulated p(h): `resolution²` RGB texels, row-major (index = y·resolution + x).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PhTable {
    pub resolution: u32,
    pub texels: Vec<[f32; 3]>,
}

impl PhTable {
    /// Tabulates `p` at every texel (u, v) = (x/(R−1), y/(R−1)).
    pub fn tabulate(resolution: u32, mut p: impl FnMut([f64; 3]) -> [f64; 3]) -> Self {
        let r = resolution as usize;
        let mut texels = Vec::with_capacity(r * r);
        for y in 0..r {
            for x in 0..r {
                let h = hemi_oct_decode(
                    x as f64 / (r - 1).max(1) as f64,
                    y as f64 / (r - 1).max(1) as f64,
                );
                let v = p(h);
                texels.push([v[0] as f32, v[1] as f32, v[2] as f32]);
            }
        }
        Self { resolution, texels }
    }

    /// Checks the size and that every texel is finite.
    pub fn validate(&self) -> Result<(), String> {
        if self.resolution < 2 || self.resolution > MAX_TABLE_RESOLUTION {
            return Err(format!(
                "resolution {} is outside 2..={MAX_TABLE_RESOLUTION}",
                self.resolution
            ));
        }
        let want = self.resolution as usize * self.resolution as usize;
        if self.texels.len() != want {
            return Err(format!(
                "has {} texels, resolution {} needs {want}",
                self.texels.len(),
                self.resolution
            ));
        }
        if self.texels.iter().flatten().any(|x| !x.is_finite()) {
            return Err("has a non-finite texel".into());
        }
        Ok(())
    }

    /// p(h) for a local direction h (need not be unit): bilinear between the four texels around
    /// (u·(R−1), v·(R−1)). An empty or mis-sized table gives 0.
    pub fn lookup(&self, h: [f64; 3]) -> [f64; 3] {
        let r = self.resolution as usize;
        if r < 2 || self.texels.len() != r * r {
            return [0.0; 3];
        }
        let (u, v) = hemi_oct_encode(h);
        let fx = u * (r - 1) as f64;
        let fy = v * (r - 1) as f64;
        let x0f = fx.floor();
        let y0f = fy.floor();
        let tx = fx - x0f;
        let ty = fy - y0f;
        let clamp = |i: f64| (i.max(0.0) as usize).min(r - 1);
        let (x0, x1) = (clamp(x0f), clamp(x0f + 1.0));
        let (y0, y1) = (clamp(y0f), clamp(y0f + 1.0));
        let t = |x: usize, y: usize| self.texels[y * r + x];
        let (a, b, c, d) = (t(x0, y0), t(x1, y0), t(x0, y1), t(x1, y1));
        let mut out = [0.0; 3];
        for k in 0..3 {
            let top = a[k] as f64 * (1.0 - tx) + b[k] as f64 * tx;
            let bottom = c[k] as f64 * (1.0 - tx) + d[k] as f64 * tx;
            out[k] = top * (1.0 - ty) + bottom * ty;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_inverts_decode() {
        for i in 0..=20 {
            for j in 0..=20 {
                let (u, v) = (i as f64 / 20.0, j as f64 / 20.0);
                let h = hemi_oct_decode(u, v);
                assert!(
                    (h[0] * h[0] + h[1] * h[1] + h[2] * h[2] - 1.0).abs() < 1e-12 && h[2] >= 0.0
                );
                let (u2, v2) = hemi_oct_encode(h);
                assert!(
                    (u - u2).abs() < 1e-12 && (v - v2).abs() < 1e-12,
                    "{u} {v} -> {u2} {v2}"
                );
            }
        }
        assert_eq!(hemi_oct_decode(0.5, 0.5), [0.0, 0.0, 1.0]);
        assert!(PARAMETERISATION_FORMULA.starts_with(&format!("{PARAMETERISATION}:")));
        assert_eq!(hemi_oct_encode([0.0, 0.0, 0.0]), (0.5, 0.5));
        assert_eq!(hemi_oct_encode([f64::NAN, 0.0, 1.0]), (0.5, 0.5));
        // +x (the tangent) is the u = 1, v = 1 corner; +y is u = 1, v = 0.
        assert_eq!(hemi_oct_encode([1.0, 0.0, 0.0]), (1.0, 1.0));
        assert_eq!(hemi_oct_encode([0.0, 1.0, 0.0]), (1.0, 0.0));
    }

    #[test]
    fn lookup_hits_texels_and_interpolates() {
        let t = PhTable::tabulate(8, |h| [h[0], h[1], h[2]]);
        for y in 0..8 {
            for x in 0..8 {
                let h = hemi_oct_decode(x as f64 / 7.0, y as f64 / 7.0);
                let got = t.lookup(h);
                let want = t.texels[y * 8 + x];
                for k in 0..3 {
                    assert!((got[k] - want[k] as f64).abs() < 1e-6, "{x} {y}");
                }
            }
        }
        // Corner-aligned: +x (u = v = 1) is the last texel itself.
        let corner = t.lookup([1.0, 0.0, 0.0]);
        assert!(
            (corner[0] - t.texels[63][0] as f64).abs() < 1e-6 && (corner[0] - 1.0).abs() < 1e-6
        );
        // A constant table is constant everywhere.
        let c = PhTable {
            resolution: 4,
            texels: vec![[0.25, 0.5, 1.0]; 16],
        };
        assert_eq!(c.lookup([0.3, -0.7, 0.2]), [0.25, 0.5, 1.0]);
        assert!(
            PhTable {
                resolution: 3,
                texels: vec![]
            }
            .validate()
            .is_err()
        );
    }
}
