//! Ray and cone queries against the object's triangles (obvhs).
//!
//! Inputs: a world-space [`Mesh`]. Outputs: two queries, both conservative in the same direction:
//! - [`Tracer::occluded`]: does the ray from `origin` along `dir` hit any triangle (any-hit,
//!   CWBVH)?
//! - [`Tracer::cone_free`]: is *every* ray from `apex` inside a cone, and above the plane through
//!   `apex` with normal `n`, certainly unoccluded? Traverses a BVH2 with bounding spheres; answers
//!   `true` only when no triangle's bounding sphere meets the cone above the plane, so a `true` is
//!   exact (no ray through the cone can hit), while a `false` may be pessimistic. The plane
//!   restriction is what makes the test useful: only directions above the vertex's horizon matter
//!   (Ṽ = V·max(cos, 0)), and the vertex's own neighbourhood lies below its tangent plane wherever
//!   the surface is locally convex.
//!
//! Invariants: degenerate (zero-area) triangles are kept out of the BVH (they cannot occlude); no
//! IO.

use crate::scene::Mesh;
use glam::{Vec3, Vec3A};
pub use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;
use std::time::Duration;

/// Bounding sphere of a triangle, in BVH primitive order.
#[derive(Debug, Clone, Copy)]
struct Sphere {
    centre: Vec3A,
    radius: f32,
}

/// Acceleration structures over the mesh.
pub struct Tracer {
    triangles: Vec<Triangle>,
    /// The same triangles in CWBVH primitive order, in obvhs's intersection-ready form.
    rt_triangles: Vec<RtTriangle>,
    spheres: Vec<Sphere>,
    bvh2: Bvh2,
    cwbvh: CwBvh,
}

impl Tracer {
    /// Builds both BVHs. Zero-area and non-finite triangles are skipped.
    pub fn new(mesh: &Mesh) -> Self {
        Self::with_params(mesh, BvhBuildParams::fast_build())
    }

    /// [`Tracer::new`] with obvhs's build parameters for the CWBVH the rays traverse (the cone
    /// queries' BVH2 is always built fast).
    pub fn with_params(mesh: &Mesh, params: BvhBuildParams) -> Self {
        let triangles: Vec<Triangle> = mesh
            .triangles
            .iter()
            .filter_map(|t| {
                let [a, b, c] =
                    t.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
                let area2 = (b - a).cross(c - a).length();
                (area2.is_finite() && area2 > 0.0).then(|| Triangle {
                    v0: a.into(),
                    v1: b.into(),
                    v2: c.into(),
                })
            })
            .collect();
        let spheres = triangles
            .iter()
            .map(|t| {
                let centre = (t.v0 + t.v1 + t.v2) / 3.0;
                let radius = (t.v0 - centre)
                    .length()
                    .max((t.v1 - centre).length())
                    .max((t.v2 - centre).length());
                Sphere {
                    centre,
                    radius: radius * (1.0 + 1e-5) + 1e-7,
                }
            })
            .collect();
        let mut build_time = Duration::default();
        let bvh2 = if triangles.is_empty() {
            Bvh2::default()
        } else {
            obvhs::bvh2::builder::build_bvh2_from_tris(
                &triangles,
                BvhBuildParams::fast_build(),
                &mut build_time,
            )
        };
        let cwbvh = if triangles.is_empty() {
            CwBvh::default()
        } else {
            obvhs::cwbvh::builder::build_cwbvh_from_tris(&triangles, params, &mut build_time)
        };
        let rt_triangles = cwbvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = &triangles[i as usize];
                RtTriangle::new(t.v0, t.v1, t.v2)
            })
            .collect();
        Self {
            triangles,
            rt_triangles,
            spheres,
            bvh2,
            cwbvh,
        }
    }

    /// Number of triangles in the BVH (degenerate ones excluded).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Any hit along the ray (origin, dir) for t in (0, ∞).
    ///
    /// `#[inline]`: inlined into its callers, obvhs's traversal stays a function of its own. Out of
    /// line, with the traversal inlined into it, dragon_100k's bake is about 6 % slower (rays/s
    /// 4.5 → 4.2 M; `cargo bench --bench bake`).
    pub fn occluded(&self, origin: Vec3A, dir: Vec3A) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let ray = Ray::new(origin, dir, 0.0, f32::INFINITY);
        !self
            .cwbvh
            .ray_traverse_miss(ray, |ray, id| self.rt_triangles[id].intersect(ray))
    }

    /// True when no ray from `apex` with direction d, d·axis ≥ cos_half_angle and d·n > 0, can hit
    /// a triangle (see the module doc). `axis` and `n` are unit vectors.
    pub fn cone_free(&self, apex: Vec3A, n: Vec3A, axis: Vec3A, cos_half_angle: f32) -> bool {
        if self.bvh2.nodes.is_empty() {
            return true;
        }
        let cos_a = cos_half_angle.clamp(-1.0, 1.0);
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        let mut stack: [u32; 96] = [0; 96];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.bvh2.nodes[stack[top] as usize];
            let centre = (node.aabb.min + node.aabb.max) * 0.5;
            let half = (node.aabb.max - node.aabb.min) * 0.5;
            // Entirely on or below the plane through the apex: no above-horizon ray reaches it.
            if (centre - apex).dot(n) + half.dot(n.abs()) <= 0.0 {
                continue;
            }
            if !sphere_meets_cone(centre, half.length(), apex, axis, cos_a, sin_a) {
                continue;
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                for k in first..first + node.prim_count as usize {
                    let prim = self.bvh2.primitive_indices[k] as usize;
                    let t = &self.triangles[prim];
                    let s = self.spheres[prim];
                    if !sphere_meets_cone(s.centre, s.radius, apex, axis, cos_a, sin_a) {
                        continue;
                    }
                    if triangle_meets_cone(t, apex, n, axis, cos_a, sin_a) {
                        return false;
                    }
                }
            } else if top + 2 <= stack.len() {
                stack[top] = node.first_index;
                stack[top + 1] = node.first_index + 1;
                top += 2;
            } else {
                // A BVH deeper than the stack: answer conservatively.
                return false;
            }
        }
        true
    }
}

/// Does the part of triangle `t` above the plane through `apex` (normal `n`) meet the cone? The
/// triangle is clipped to the half-space (x − apex)·n > 0; every point of the clipped polygon is a
/// convex combination of its corners, so the directions from the apex to it lie in the convex cone
/// spanned by the corner directions, which is inside their bounding cap (centre = normalised sum of
/// the unit corner directions, radius = the largest angle to a corner). Conservative: true when
/// unsure (a corner at the apex, a polygon spanning more than a hemisphere of directions).
fn triangle_meets_cone(
    t: &Triangle,
    apex: Vec3A,
    n: Vec3A,
    axis: Vec3A,
    cos_a: f32,
    sin_a: f32,
) -> bool {
    let verts = [t.v0, t.v1, t.v2];
    let heights = verts.map(|v| (v - apex).dot(n));
    let mut corners: [Vec3A; 4] = [Vec3A::ZERO; 4];
    let mut count = 0;
    for i in 0..3 {
        let j = (i + 1) % 3;
        let (a, b, ha, hb) = (verts[i], verts[j], heights[i], heights[j]);
        if ha > 0.0 {
            corners[count] = a;
            count += 1;
        }
        if (ha > 0.0) != (hb > 0.0) {
            // The edge crosses the plane: its crossing point (on the plane, elevation 0).
            let s = ha / (ha - hb);
            if count < 4 {
                corners[count] = a + (b - a) * s;
                count += 1;
            }
        }
    }
    if count == 0 {
        return false;
    }
    let mut dirs = [Vec3A::ZERO; 4];
    let mut sum = Vec3A::ZERO;
    for k in 0..count {
        let d = corners[k] - apex;
        let len = d.length();
        if len.is_nan() || len <= 1e-12 {
            return true;
        }
        dirs[k] = d / len;
        sum += dirs[k];
    }
    let len = sum.length();
    if len.is_nan() || len <= 1e-6 {
        return true;
    }
    let centre = sum / len;
    let cos_r = dirs[..count]
        .iter()
        .map(|d| d.dot(centre))
        .fold(1.0f32, f32::min);
    if cos_r <= 0.0 {
        return true;
    }
    let sin_r = (1.0 - cos_r * cos_r).max(0.0).sqrt();
    // Caps meet iff angle(centre, axis) ≤ α + r.
    let cos_sum = cos_a * cos_r - sin_a * sin_r;
    let sin_sum = sin_a * cos_r + cos_a * sin_r;
    if sin_sum < 0.0 {
        return true;
    }
    centre.dot(axis) >= cos_sum - 1e-6
}

/// Does the sphere (c, r) meet the infinite cone with apex `apex`, unit axis and half-angle α
/// (given by its cosine and sine)? Conservative: true when unsure.
#[inline]
fn sphere_meets_cone(c: Vec3A, r: f32, apex: Vec3A, axis: Vec3A, cos_a: f32, sin_a: f32) -> bool {
    let q = c - apex;
    let d2 = q.length_squared();
    if d2 <= r * r {
        return true;
    }
    let d = d2.sqrt();
    let cos_phi = q.dot(axis) / d;
    // The sphere subtends half-angle β from the apex: sin β = r/d. Meets iff φ ≤ α + β.
    let sin_b = r / d;
    let cos_b = (1.0 - sin_b * sin_b).max(0.0).sqrt();
    // α + β ≥ π: the cone-plus-margin covers everything.
    let cos_ab = cos_a * cos_b - sin_a * sin_b;
    let sin_ab = sin_a * cos_b + cos_a * sin_b;
    if sin_ab < 0.0 && cos_ab < 0.0 {
        return true;
    }
    cos_phi >= cos_ab - 1e-6
}
