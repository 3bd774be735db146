//! Lobe centre layouts ξ_j and the specular distribution p(h) = Σ_j c_j G(h·ξ_j; λ) (method.md §3).
//!
//! Inputs: a [`LobeLayout`] and λ. Outputs: J unit centres in the local frame (z = normal, x =
//! tangent) and evaluation of all J lobes at a local half-vector h. Invariants: centres lie on the
//! upper hemisphere (z ≥ 0); every value is in [0, 1]; an isotropic set's values depend on h·n
//! only.
//!
//! Layouts (all documented, all parameters):
//! - `Hemicube { n }` — the paper's: pixel centres of a hemicube over the half-vector hemisphere. J
//!   = 3n². Top face z = 1: n × n pixel centres. Each of the four side faces (x = ±1, y = ±1, z ∈
//!   [0, 1]) has ⌊n/2⌋ full rows of n pixels. For odd n the half-height row at the horizon does not
//!   split into whole pixels; its 4·n half-pixels are merged into 2n centres evenly spaced in
//!   azimuth (φ_k = π(k + ½)/n) at the elevation of the half-row's centre, atan(½/n). n = 7 gives J
//!   = 147 = 49 + 84 + 14, the paper's count; n = 8 gives 192, the paper's N_l layout for outgoing
//!   directions.
//! - `Fibonacci { count }` — a spherical Fibonacci hemisphere: z_k = 1 − (k + ½)/J, φ_k = k·(golden
//!   angle): equal-area spread for any J.
//! - `Isotropic { count }` — rings: lobes averaged over azimuth, centred at polar angles θ_j =
//!   (π/2)·j/J. p depends on h·n only; the honest choice where the scene has no tangent field.

use super::SphereError;
use super::srbf;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Where the J lobes sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LobeLayout {
    /// The paper's hemicube, J = 3n².
    Hemicube { n: usize },
    /// Spherical Fibonacci points on the hemisphere.
    Fibonacci { count: usize },
    /// Azimuthally averaged ring lobes (isotropic p(h)).
    Isotropic { count: usize },
}

impl LobeLayout {
    /// The paper's layout: 7×7 hemicube, J = 147.
    pub const PAPER: LobeLayout = LobeLayout::Hemicube { n: 7 };

    /// Number of lobes J (saturating: a layout read from a file may name any n, and 3n² must not
    /// overflow before [`LobeLayout::centres`] refuses it).
    pub fn count(&self) -> usize {
        match *self {
            LobeLayout::Hemicube { n } => n.saturating_mul(n).saturating_mul(3),
            LobeLayout::Fibonacci { count } | LobeLayout::Isotropic { count } => count,
        }
    }

    /// The layout a [`LobeLayout::name`] names (`hemicube-7`, `fibonacci-64`, `isotropic-24`).
    pub fn from_name(name: &str) -> Option<Self> {
        let (kind, n) = name.rsplit_once('-')?;
        let n: usize = n.parse().ok()?;
        match kind {
            "hemicube" => Some(LobeLayout::Hemicube { n }),
            "fibonacci" => Some(LobeLayout::Fibonacci { count: n }),
            "isotropic" => Some(LobeLayout::Isotropic { count: n }),
            _ => None,
        }
    }

    /// Short name for reports and file metadata.
    pub fn name(&self) -> String {
        match *self {
            LobeLayout::Hemicube { n } => format!("hemicube-{n}"),
            LobeLayout::Fibonacci { count } => format!("fibonacci-{count}"),
            LobeLayout::Isotropic { count } => format!("isotropic-{count}"),
        }
    }

    /// True when p(h) depends on h·n only.
    pub fn is_isotropic(&self) -> bool {
        matches!(self, LobeLayout::Isotropic { .. })
    }

    /// The centres (unit, z ≥ 0). Isotropic centres sit at azimuth 0 (x ≥ 0, y = 0).
    pub fn centres(&self) -> Result<Vec<DVec3>, SphereError> {
        let count = self.count();
        let bad = |reason: &str| SphereError::BadLayout {
            layout: self.name(),
            count,
            reason: reason.into(),
        };
        if count == 0 {
            return Err(bad("at least one lobe is needed"));
        }
        if count > 100_000 {
            return Err(bad("more than 100000 lobes"));
        }
        Ok(match *self {
            LobeLayout::Hemicube { n } => hemicube_directions(n),
            LobeLayout::Fibonacci { count } => fibonacci_hemisphere(count),
            LobeLayout::Isotropic { count } => (0..count)
                .map(|j| {
                    let theta = std::f64::consts::FRAC_PI_2 * j as f64 / count as f64;
                    DVec3::new(theta.sin(), 0.0, theta.cos())
                })
                .collect(),
        })
    }
}

/// Hemicube pixel-centre directions, J = 3n² (see the module doc).
pub fn hemicube_directions(n: usize) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(3 * n * n);
    let pixel = 2.0 / n as f64;
    let centre = |k: usize| -1.0 + (k as f64 + 0.5) * pixel;
    for r in 0..n {
        for c in 0..n {
            out.push(DVec3::new(centre(c), centre(r), 1.0).normalize());
        }
    }
    for face in 0..4 {
        for row in 0..n / 2 {
            let z = 1.0 - (row as f64 + 0.5) * pixel;
            for c in 0..n {
                let u = centre(c);
                let v = match face {
                    0 => DVec3::new(1.0, u, z),
                    1 => DVec3::new(-u, 1.0, z),
                    2 => DVec3::new(-1.0, -u, z),
                    _ => DVec3::new(u, -1.0, z),
                };
                out.push(v.normalize());
            }
        }
    }
    if n % 2 == 1 {
        let elevation = (0.5 / n as f64).atan();
        for k in 0..2 * n {
            let phi = std::f64::consts::PI * (k as f64 + 0.5) / n as f64;
            out.push(DVec3::new(
                phi.cos() * elevation.cos(),
                phi.sin() * elevation.cos(),
                elevation.sin(),
            ));
        }
    }
    out
}

/// Spherical Fibonacci points on the upper hemisphere.
pub fn fibonacci_hemisphere(count: usize) -> Vec<DVec3> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|k| {
            let z = 1.0 - (k as f64 + 0.5) / count as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden_angle * k as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// A lobe layout with its sharpness: the basis of p(h).
#[derive(Debug, Clone)]
pub struct LobeSet {
    layout: LobeLayout,
    lambda: f64,
    centres: Vec<DVec3>,
    /// (cos θ_j, sin θ_j) of each centre, for ring lobes.
    polar: Vec<(f64, f64)>,
    /// Ring lobes only: each lobe tabulated at RING_TABLE + 1 points of t = √(1 − cos θh) ∈ [0, 1]
    /// (the lobe is smooth in t; linear interpolation is within ~2e-6 of the closed form at λ =
    /// 81).
    ring_table: Vec<f64>,
}

/// Intervals of the ring-lobe table.
const RING_TABLE: usize = 4096;

impl LobeSet {
    /// Builds the set; λ must be finite and positive.
    pub fn new(layout: LobeLayout, lambda: f64) -> Result<Self, SphereError> {
        if !(lambda.is_finite() && lambda > 0.0) {
            return Err(SphereError::LambdaOutOfRange { lambda });
        }
        let centres = layout.centres()?;
        let polar: Vec<(f64, f64)> = centres
            .iter()
            .map(|c| (c.z, (c.x * c.x + c.y * c.y).sqrt()))
            .collect();
        let ring_table = if layout.is_isotropic() {
            polar
                .iter()
                .flat_map(|&(cj, sj)| {
                    (0..=RING_TABLE).map(move |k| {
                        let t = k as f64 / RING_TABLE as f64;
                        let ch = 1.0 - t * t;
                        srbf::ring_lobe(ch, (1.0 - ch * ch).max(0.0).sqrt(), cj, sj, lambda)
                    })
                })
                .collect()
        } else {
            Vec::new()
        };
        Ok(Self {
            layout,
            lambda,
            centres,
            polar,
            ring_table,
        })
    }

    /// The layout.
    pub fn layout(&self) -> LobeLayout {
        self.layout
    }

    /// λ.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// J.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// Never true for a built set.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    /// Centres in the local frame.
    pub fn centres(&self) -> &[DVec3] {
        &self.centres
    }

    /// Lobe j at local half-vector h (unit). Ring lobes come from the table for h.z ≥ 0.
    #[inline]
    pub fn eval_one(&self, j: usize, h: DVec3) -> f64 {
        if self.layout.is_isotropic() {
            if h.z >= 0.0 {
                return self.ring_value(j, self.ring_position(h));
            }
            self.eval_exact(j, h)
        } else {
            srbf::gaussian(h.dot(self.centres[j]), self.lambda)
        }
    }

    /// Intervals of the ring table ([`Self::ring_position`]'s first value is below this).
    pub const RING_INTERVALS: usize = RING_TABLE;

    /// For ring lobes: the table position of a local half-vector (h.z ≥ 0), shared by every lobe.
    #[inline]
    pub fn ring_position(&self, h: DVec3) -> (usize, f64) {
        let x = (1.0 - h.z.clamp(0.0, 1.0)).sqrt() * RING_TABLE as f64;
        let k = (x as usize).min(RING_TABLE - 1);
        (k, x - k as f64)
    }

    /// Ring lobe j at a table position from [`Self::ring_position`].
    #[inline]
    pub fn ring_value(&self, j: usize, (k, f): (usize, f64)) -> f64 {
        let base = j * (RING_TABLE + 1) + k;
        let (a, b) = (self.ring_table[base], self.ring_table[base + 1]);
        a + (b - a) * f
    }

    /// Ring lobe j's table: its values at t = k / [`Self::RING_INTERVALS`], k = 0 ..=
    /// RING_INTERVALS (empty for other layouts). [`Self::ring_value`] interpolates it linearly.
    pub fn ring_row(&self, j: usize) -> &[f64] {
        let n = RING_TABLE + 1;
        self.ring_table.get(j * n..(j + 1) * n).unwrap_or(&[])
    }

    /// Lobe j at h by the closed form (no table).
    pub fn eval_exact(&self, j: usize, h: DVec3) -> f64 {
        self.eval_exact_lambda(j, h, self.lambda)
    }

    /// Lobe j's shape at h with another sharpness λ (same centre): the closed form.
    pub fn eval_exact_lambda(&self, j: usize, h: DVec3, lambda: f64) -> f64 {
        if self.layout.is_isotropic() {
            let (cj, sj) = self.polar[j];
            let ch = h.z.clamp(-1.0, 1.0);
            srbf::ring_lobe(ch, (1.0 - ch * ch).max(0.0).sqrt(), cj, sj, lambda)
        } else {
            srbf::gaussian(h.dot(self.centres[j]), lambda)
        }
    }

    /// The lobe's half-angle of support (G ≥ e^−cutoff) at sharpness λ, in radians: for ring lobes
    /// the distance in polar angle, for Gaussians the angle to the centre.
    pub fn support_angle(lambda: f64, cutoff_exponent: f64) -> f64 {
        srbf::support_cosine(lambda, cutoff_exponent).acos()
    }

    /// Angular distance from h to lobe j's centre as the support test sees it (polar-angle
    /// difference for ring lobes).
    pub fn distance(&self, j: usize, h: DVec3) -> f64 {
        if self.layout.is_isotropic() {
            (h.z.clamp(-1.0, 1.0).acos() - self.polar[j].0.clamp(-1.0, 1.0).acos()).abs()
        } else {
            h.dot(self.centres[j]).clamp(-1.0, 1.0).acos()
        }
    }

    /// All J lobes at local half-vector h into `out` (len J).
    pub fn eval_all(&self, h: DVec3, out: &mut [f64]) {
        for (j, o) in out.iter_mut().enumerate().take(self.centres.len()) {
            *o = self.eval_one(j, h);
        }
    }

    /// p(h) = Σ c_j G_j(h).
    pub fn p(&self, coefficients: &[f64], h: DVec3) -> f64 {
        coefficients
            .iter()
            .enumerate()
            .take(self.centres.len())
            .map(|(j, &c)| c * self.eval_one(j, h))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    #[test]
    fn hemicube_counts_and_spread() {
        for n in 1..=12 {
            let d = hemicube_directions(n);
            assert_eq!(d.len(), 3 * n * n, "n={n}");
            assert!(
                d.iter()
                    .all(|v| v.z > 0.0 && (v.length() - 1.0).abs() < 1e-12)
            );
        }
        let paper = LobeLayout::PAPER.centres().unwrap();
        assert_eq!(paper.len(), 147);
        // Well spread: nearest-neighbour angles between 5° and 20° for every centre.
        for (i, a) in paper.iter().enumerate() {
            let nearest = paper
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, b)| a.dot(*b).clamp(-1.0, 1.0).acos().to_degrees())
                .fold(f64::INFINITY, f64::min);
            assert!(
                (5.0..20.0).contains(&nearest),
                "centre {i} nearest {nearest}°"
            );
        }
        assert_eq!(hemicube_directions(8).len(), 192);
    }

    #[test]
    fn fibonacci_is_well_spread() {
        let d = fibonacci_hemisphere(147);
        assert!(
            d.iter()
                .all(|v| v.z > 0.0 && (v.length() - 1.0).abs() < 1e-12)
        );
        let min_angle = d
            .iter()
            .enumerate()
            .flat_map(|(i, a)| {
                d.iter()
                    .skip(i + 1)
                    .map(move |b| a.dot(*b).clamp(-1.0, 1.0).acos())
            })
            .fold(f64::INFINITY, f64::min)
            .to_degrees();
        assert!(min_angle > 6.0, "min angle {min_angle}°");
    }

    #[test]
    fn isotropic_lobes_depend_on_elevation_only() {
        let set = LobeSet::new(LobeLayout::Isotropic { count: 16 }, 81.06).unwrap();
        let mut rng = Rng::new(2);
        let mut a = vec![0.0; 16];
        let mut b = vec![0.0; 16];
        for _ in 0..1000 {
            let h = rng.hemisphere_vector();
            let phi = rng.range(0.0, 6.3);
            let (s, c) = phi.sin_cos();
            let rotated = DVec3::new(c * h.x - s * h.y, s * h.x + c * h.y, h.z);
            set.eval_all(h, &mut a);
            set.eval_all(rotated, &mut b);
            for j in 0..16 {
                assert!((a[j] - b[j]).abs() < 1e-12);
                assert!((0.0..=1.0 + 1e-12).contains(&a[j]));
            }
        }
    }

    #[test]
    fn ring_table_matches_the_closed_form() {
        for lambda in [1.0, 81.06, 5000.0] {
            let set = LobeSet::new(LobeLayout::Isotropic { count: 24 }, lambda).unwrap();
            let mut rng = Rng::new(8);
            let mut worst = 0.0f64;
            for _ in 0..20_000 {
                let h = rng.hemisphere_vector();
                for j in 0..set.len() {
                    let (a, b) = (set.eval_one(j, h), set.eval_exact(j, h));
                    worst = worst.max((a - b).abs());
                }
            }
            // Absolute error relative to the peak value 1 of a lobe.
            let limit = if lambda > 1000.0 { 2e-3 } else { 1e-5 };
            assert!(worst < limit, "λ={lambda}: table off by {worst}");
        }
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(LobeSet::new(LobeLayout::PAPER, 0.0).is_err());
        assert!(LobeSet::new(LobeLayout::PAPER, f64::INFINITY).is_err());
        assert!(LobeSet::new(LobeLayout::Fibonacci { count: 0 }, 10.0).is_err());
    }
}
