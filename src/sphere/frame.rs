//! Local shading frames.
//!
//! Convention (the project's, stated once here and repeated in the material JSON and the WGSL
//! headers): local z = the shading normal n, local x = the tangent t, local y = the bitangent b = w
//! · (n × t), with w = ±1 the glTF TANGENT handedness. Directions point away from the surface.
//!
//! Two ways to build a frame:
//! - [`Frame::from_normal_tangent`]: from glTF TANGENT (or MikkTSpace) data, Gram–Schmidt
//!   orthogonalised against n; used when the scene has a tangent field, so an anisotropic p(h)
//!   means the same thing everywhere on the surface.
//! - [`Frame::from_normal`]: the documented fallback when there is no tangent field, Duff et al.,
//!   "Building an Orthonormal Basis, Revisited" (JCGT 2017): continuous except across n.z = 0's
//!   sign flip. Its tangent direction is arbitrary, so only isotropic lobes may be used with it.
//!
//! Invariants: the three axes are unit length and mutually orthogonal within 1e-12 for any unit n.

use glam::DVec3;

/// An orthonormal frame (t, b, n).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub tangent: DVec3,
    pub bitangent: DVec3,
    pub normal: DVec3,
}

impl Frame {
    /// Duff et al. 2017 branchless orthonormal basis around a unit normal.
    pub fn from_normal(n: DVec3) -> Self {
        let n = normalize_or_z(n);
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let tangent = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bitangent = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self {
            tangent,
            bitangent,
            normal: n,
        }
    }

    /// Frame from a normal and a glTF tangent (xyz = direction, w = handedness ±1). Falls back to
    /// [`Frame::from_normal`] when the tangent is (nearly) parallel to n or not finite.
    pub fn from_normal_tangent(n: DVec3, tangent_xyz: DVec3, handedness: f64) -> Self {
        let n = normalize_or_z(n);
        let t = tangent_xyz - n * n.dot(tangent_xyz);
        let len = t.length();
        if !(len.is_finite() && len > 1e-8) {
            return Self::from_normal(n);
        }
        let t = t / len;
        let w = if handedness < 0.0 { -1.0 } else { 1.0 };
        Self {
            tangent: t,
            bitangent: n.cross(t) * w,
            normal: n,
        }
    }

    /// (tangent, bitangent).
    pub fn tangents(&self) -> (DVec3, DVec3) {
        (self.tangent, self.bitangent)
    }

    /// World → local (x = t, y = b, z = n).
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            v.dot(self.tangent),
            v.dot(self.bitangent),
            v.dot(self.normal),
        )
    }

    /// Local → world.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        self.tangent * v.x + self.bitangent * v.y + self.normal * v.z
    }
}

fn normalize_or_z(n: DVec3) -> DVec3 {
    let len = n.length();
    if len.is_finite() && len > 0.0 {
        n / len
    } else {
        DVec3::Z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    fn assert_orthonormal(f: &Frame) {
        for v in [f.tangent, f.bitangent, f.normal] {
            assert!((v.length() - 1.0).abs() < 1e-12);
        }
        assert!(f.tangent.dot(f.bitangent).abs() < 1e-12);
        assert!(f.tangent.dot(f.normal).abs() < 1e-12);
        assert!(f.bitangent.dot(f.normal).abs() < 1e-12);
    }

    #[test]
    fn frames_are_orthonormal_and_round_trip() {
        let mut rng = Rng::new(5);
        for _ in 0..10_000 {
            let n = rng.unit_vector();
            let f = Frame::from_normal(n);
            assert_orthonormal(&f);
            // Right-handed: t × b = n.
            assert!((f.tangent.cross(f.bitangent) - n).length() < 1e-12);
            let v = rng.unit_vector();
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-12);
            assert!((f.to_local(n) - DVec3::Z).length() < 1e-12);
        }
        for n in [DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(0.0, 0.0, -1e-300)] {
            assert_orthonormal(&Frame::from_normal(n));
        }
    }

    #[test]
    fn tangent_frame_follows_the_tangent_and_handedness() {
        let n = DVec3::Y;
        let f = Frame::from_normal_tangent(n, DVec3::new(1.0, 0.3, 0.0), 1.0);
        assert_orthonormal(&f);
        assert!((f.tangent - DVec3::X).length() < 1e-12);
        assert!((f.bitangent - n.cross(DVec3::X)).length() < 1e-12);
        let g = Frame::from_normal_tangent(n, DVec3::new(1.0, 0.3, 0.0), -1.0);
        assert!((g.bitangent + f.bitangent).length() < 1e-12);
        // Degenerate tangent → fallback frame.
        let h = Frame::from_normal_tangent(n, n * 2.0, 1.0);
        assert_orthonormal(&h);
    }
}
