//! The hemi-octahedral map of the upper hemisphere onto the unit square: the parameterisation of
//! every p(h) table glint writes (renderers, the EXR export, the WGSL preview).
//!
//! Tables sample it on a corner-aligned grid: texel (x, y) of an R×R table sits at u = x/(R − 1),
//! v = y/(R − 1), so the outer texels lie on the horizon. Decoding: a = 2u − 1,
//! b = 2v − 1, px = (a + b)/2, py = (a − b)/2, z = 1 − |px| − |py| (never negative, since
//! |px| + |py| = max(|a|, |b|)), h = normalize(px, py, z). Encoding: l1 = |hx| + |hy| + |hz|,
//! px = hx/l1, py = hy/l1, u = (px + py + 1)/2, v = (px − py + 1)/2. The map is continuous, covers
//! the hemisphere once, and its texels' solid angles differ by at most a factor of about 2.
//!
//! The definition lives in the exporters crate ([`glint_exporters::hemi_oct_encode`] and
//! [`glint_exporters::hemi_oct_decode`]: the files glint writes are read with it); this module is
//! its glam face. The WGSL copy (shaders/prt_shade.wgsl) is checked against it by the GPU tests.
//!
//! Inputs and outputs: local unit vectors (z = normal) and (u, v) ∈ [0, 1]². Invariants: no IO; a
//! vector below the horizon is folded up (|z|) so callers never index outside the square.

use glam::DVec3;

/// (u, v) ∈ [0, 1]² of a local unit vector (z < 0 is folded to |z|):
/// [`glint_exporters::hemi_oct_encode`], the one definition.
#[inline]
pub fn encode(h: DVec3) -> (f64, f64) {
    glint_exporters::hemi_oct_encode(h.to_array())
}

/// The unit vector at (u, v) ∈ [0, 1]²: [`glint_exporters::hemi_oct_decode`], the one definition.
#[inline]
pub fn decode(u: f64, v: f64) -> DVec3 {
    DVec3::from_array(glint_exporters::hemi_oct_decode(u, v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    #[test]
    fn round_trip_and_corners() {
        let mut rng = Rng::new(3);
        for _ in 0..10_000 {
            let d = rng.unit_vector();
            let d = DVec3::new(d.x, d.y, d.z.abs());
            let (u, v) = encode(d);
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
            assert!((decode(u, v) - d).length() < 1e-12);
        }
        // The square's corners and edge midpoints lie on the horizon; its centre is the pole.
        assert!((decode(0.5, 0.5) - DVec3::Z).length() < 1e-15);
        for (u, v) in [
            (0.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (1.0, 0.0),
            (0.5, 0.0),
            (0.0, 0.5),
        ] {
            assert!(decode(u, v).z.abs() < 1e-15, "({u}, {v})");
        }
    }
}
