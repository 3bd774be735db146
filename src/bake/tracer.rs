//! Ray and cone queries against the object's triangles (obvhs; the rays through Intel Embree 3
//! where the build found it, [`Backend`]).
//!
//! Inputs: a world-space [`Mesh`]. Outputs: four queries, all conservative in the same direction:
//! - [`Tracer::occluded`]: does the ray from `origin` along `dir` hit any triangle (any-hit:
//!   Embree's `rtcOccluded1`, or obvhs's CWBVH)?
//! - [`Tracer::cone_free`]: is *every* ray from `apex` inside a cone, and above the plane through
//!   `apex` with normal `n`, certainly unoccluded? Traverses a BVH2 with bounding spheres; answers
//!   `true` only when no triangle's bounding sphere meets the cone above the plane, so a `true` is
//!   exact (no ray through the cone can hit), while a `false` may be pessimistic. The plane
//!   restriction is what makes the test useful: only directions above the vertex's horizon matter
//!   (Ṽ = V·max(cos, 0)), and the vertex's own neighbourhood lies below its tangent plane wherever
//!   the surface is locally convex.
//! - [`Tracer::occluded_from`]: the same any-hit answer for many rays from one origin (a vertex's
//!   visibility cells), traced together: through Embree as one stream (`rtcOccluded1M`, in a
//!   scene of at least `embree::STREAM_TRIANGLES` triangles and a call of at least
//!   `embree::STREAM_MIN` rays) or in packets (`rtcOccluded16`, the last one of 8 where
//!   at most 8 rays are left), or through obvhs's BVH2 in packets of [`PACKET`], where a
//!   node's bounds relative to the shared origin are computed once per packet and a node is
//!   visited once for all the packet's rays that reach it. Rays of
//!   neighbouring cells are nearly coherent, so a packet visits few more nodes than one of its
//!   rays alone.
//! - [`Tracer::occluded_each`]: the same for rays from many origins (the rays of a group of
//!   neighbouring vertices, [`super::cuts::GroupRays`]), through Embree as one stream;
//!   [`Tracer::occluded_grouped`], how the bake traces a group: that stream where Embree traces,
//!   else each vertex's rays (a run of one origin) in packets.
//!
//! Invariants: degenerate (zero-area) triangles are kept out of the BVHs (they cannot occlude);
//! with obvhs both ray queries use the same triangle test (`RtTriangle::intersect`, lane by
//! lane), so a ray gets the same answer alone or in a packet except where the two BVHs' node
//! bounds round differently (a ray grazing a node's face); Embree's answers differ from obvhs's
//! only for rays within rounding of a triangle's edge (tested); no IO.

use crate::scene::Mesh;
use glam::{Vec3, Vec3A};
pub use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;
use std::time::Duration;

/// Bounding sphere of a triangle, in BVH primitive order (16 bytes: a million-triangle mesh keeps
/// 1.6 M of them).
#[derive(Debug, Clone, Copy)]
struct Sphere {
    centre: Vec3,
    radius: f32,
}

/// Rays per packet in [`Tracer::occluded_from`] through obvhs's BVH2 (Embree's are 16).
pub const PACKET: usize = 8;

/// Which code traces [`Tracer::occluded`] and [`Tracer::occluded_from`] (the cone queries are
/// always obvhs's BVH2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// obvhs: single rays through a CWBVH, a vertex's rays in packets through the BVH2.
    Obvhs,
    /// Intel Embree 3 (`rtcOccluded1`, and `rtcOccluded16` for a vertex's rays): 2–4× the rays
    /// per second of obvhs on this project's meshes. Only where `build.rs` found the library.
    Embree,
}

impl Backend {
    /// Embree where this build has it, else obvhs.
    pub fn best() -> Self {
        if cfg!(embree) {
            Self::Embree
        } else {
            Self::Obvhs
        }
    }

    /// The backends this build can use (obvhs always).
    pub fn available() -> &'static [Backend] {
        if cfg!(embree) {
            &[Self::Obvhs, Self::Embree]
        } else {
            &[Self::Obvhs]
        }
    }

    /// The name `glint bake --json` reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Obvhs => "obvhs",
            Self::Embree => "embree",
        }
    }
}

/// What traces the rays.
enum Rays {
    /// The triangles in CWBVH primitive order, in obvhs's intersection form, and the CWBVH.
    Obvhs {
        rt_triangles: Vec<RtTriangle>,
        cwbvh: CwBvh,
    },
    #[cfg(embree)]
    Embree(super::embree::EmbreeTracer),
}

/// obvhs's CWBVH over the triangles, and the triangles in its primitive order ready to intersect:
/// single rays read them without an indirection (computing them per test, or reading them through
/// an index into the BVH2's order, made single rays 7–11 % slower).
fn obvhs_rays(triangles: &[Triangle], params: BvhBuildParams, build_time: &mut Duration) -> Rays {
    let cwbvh = if triangles.is_empty() {
        CwBvh::default()
    } else {
        obvhs::cwbvh::builder::build_cwbvh_from_tris(triangles, params, build_time)
    };
    let rt_triangles = cwbvh
        .primitive_indices
        .iter()
        .map(|&i| {
            let t = &triangles[i as usize];
            RtTriangle::new(t.v0, t.v1, t.v2)
        })
        .collect();
    Rays::Obvhs {
        rt_triangles,
        cwbvh,
    }
}

/// Acceleration structures over the mesh.
pub struct Tracer {
    /// In BVH2 primitive order (a BVH2 leaf's primitives are a range of it), with their bounding
    /// spheres.
    triangles: Vec<Triangle>,
    spheres: Vec<Sphere>,
    bvh2: Bvh2,
    rays: Rays,
    /// Whether [`Tracer::occluded_from`] traces packets (else one ray at a time, as
    /// [`Tracer::occluded`]): on by default; off to measure what packets buy.
    packets: bool,
}

impl Tracer {
    /// Builds the BVHs, the rays' through [`Backend::best`]. Zero-area and non-finite triangles
    /// are skipped.
    pub fn new(mesh: &Mesh) -> Self {
        Self::with_backend(mesh, Backend::best())
    }

    /// [`Tracer::new`] with the rays traced by `backend` (obvhs if this build has no Embree, or
    /// Embree cannot build its scene).
    pub fn with_backend(mesh: &Mesh, backend: Backend) -> Self {
        Self::build(mesh, backend, BvhBuildParams::fast_build())
    }

    /// An obvhs tracer with obvhs's build parameters for the CWBVH the rays traverse (the cone
    /// queries' BVH2 is built fast, or fastest where Embree traces the rays).
    pub fn with_params(mesh: &Mesh, params: BvhBuildParams) -> Self {
        Self::build(mesh, Backend::Obvhs, params)
    }

    /// Which backend traces the rays.
    pub fn backend(&self) -> Backend {
        match self.rays {
            Rays::Obvhs { .. } => Backend::Obvhs,
            #[cfg(embree)]
            Rays::Embree(_) => Backend::Embree,
        }
    }

    fn build(mesh: &Mesh, backend: Backend, params: BvhBuildParams) -> Self {
        let kept: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .copied()
            .filter(|t| {
                let [a, b, c] =
                    t.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
                let area2 = (b - a).cross(c - a).length();
                area2.is_finite() && area2 > 0.0
            })
            .collect();
        let triangles: Vec<Triangle> = kept
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                Triangle {
                    v0: a.into(),
                    v1: b.into(),
                    v2: c.into(),
                }
            })
            .collect();
        let spheres: Vec<Sphere> = triangles
            .iter()
            .map(|t| {
                let centre = (t.v0 + t.v1 + t.v2) / 3.0;
                let radius = (t.v0 - centre)
                    .length()
                    .max((t.v1 - centre).length())
                    .max((t.v2 - centre).length());
                Sphere {
                    centre: centre.into(),
                    radius: radius * (1.0 + 1e-5) + 1e-7,
                }
            })
            .collect();
        let mut build_time = Duration::default();
        let bvh2 = if triangles.is_empty() {
            Bvh2::default()
        } else {
            // Where Embree traces the rays, the BVH2 serves the cone tests alone, which are
            // answered alike on any tree (up to the conservative triangle test's false alarms,
            // which a looser box lets through more often): built with obvhs's fastest settings
            // (docs/benchmarks.md). obvhs's packets traverse it otherwise. (Built before Embree's
            // scene, so that the two builds' peaks do not add up.)
            let params = if cfg!(embree) && backend == Backend::Embree {
                BvhBuildParams::very_fast_build()
            } else {
                BvhBuildParams::fast_build()
            };
            obvhs::bvh2::builder::build_bvh2_from_tris(&triangles, params, &mut build_time)
        };
        #[cfg(embree)]
        let embree = (backend == Backend::Embree)
            .then(|| super::embree::EmbreeTracer::new(&mesh.positions, &kept).ok())
            .flatten()
            .map(Rays::Embree);
        #[cfg(not(embree))]
        let embree: Option<Rays> = {
            let _ = backend;
            None
        };
        let rays = embree.unwrap_or_else(|| obvhs_rays(&triangles, params, &mut build_time));
        // BVH2 order from here on: the cone test and the packets read a leaf's range directly.
        let (triangles, spheres): (Vec<Triangle>, Vec<Sphere>) = bvh2
            .primitive_indices
            .iter()
            .map(|&i| (triangles[i as usize], spheres[i as usize]))
            .unzip();
        Self {
            triangles,
            spheres,
            bvh2,
            rays,
            packets: true,
        }
    }

    /// Turns packets on or off for [`Tracer::occluded_from`] (the answers are the same; only the
    /// time differs).
    pub fn set_packets(&mut self, on: bool) {
        self.packets = on;
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
        match &self.rays {
            Rays::Obvhs {
                rt_triangles,
                cwbvh,
            } => {
                let ray = Ray::new(origin, dir, 0.0, f32::INFINITY);
                !cwbvh.ray_traverse_miss(ray, |ray, id| rt_triangles[id].intersect(ray))
            }
            #[cfg(embree)]
            Rays::Embree(e) => e.occluded(origin, dir),
        }
    }

    /// `out[i]` = whether the ray from `origin` along `dirs[i]` hits a triangle (t ≥ 0), as
    /// [`Tracer::occluded`] answers it, traced together (Embree's streams or packets, obvhs's
    /// packets of [`PACKET`] consecutive rays; module docs): order `dirs` so that neighbours point
    /// alike. `out` must be as long as `dirs`.
    pub fn occluded_from(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        debug_assert_eq!(dirs.len(), out.len());
        if self.bvh2.nodes.is_empty() {
            out.fill(false);
            return;
        }
        if !self.packets {
            for (d, o) in dirs.iter().zip(out.iter_mut()) {
                *o = self.occluded(origin, *d);
            }
            return;
        }
        #[cfg(embree)]
        if let Rays::Embree(e) = &self.rays {
            e.occluded_from(origin, dirs, out);
            return;
        }
        for (d, o) in dirs.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
            let hit = self.packet_occluded(origin, d);
            for (i, o) in o.iter_mut().enumerate() {
                *o = hit >> i & 1 == 1;
            }
        }
    }

    /// [`Tracer::occluded_from`] with Embree's packets of 16 at any size of call (what every call
    /// used before Embree's streams, `embree::STREAM_MIN`) where Embree traces, for the
    /// benches' side by side; the same answers.
    pub fn occluded_from_packets(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_from_packets(origin, dirs, out);
            return;
        }
        self.occluded_from(origin, dirs, out);
    }

    /// Embree's tracer, where it traces this mesh's rays and packets are on: the benches'
    /// variants of [`Tracer::occluded_from`] call it directly.
    #[cfg(embree)]
    fn embree_packets(&self) -> Option<&super::embree::EmbreeTracer> {
        match (&self.rays, self.packets, self.bvh2.nodes.is_empty()) {
            (Rays::Embree(e), true, false) => Some(e),
            _ => None,
        }
    }

    /// [`Tracer::occluded_from`] as one Embree stream at any size of call where Embree traces
    /// ([`super::embree::EmbreeTracer::occluded_stream`]), for the benches' side by side; the same
    /// answers.
    pub fn occluded_stream(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_stream(origin, dirs, out);
            return;
        }
        self.occluded_from(origin, dirs, out);
    }

    /// [`Tracer::occluded_from`] with Embree's packets of 8 (`rtcOccluded8`) where Embree traces,
    /// for the benches' side by side; the same answers.
    pub fn occluded_from_8(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_from_8(origin, dirs, out);
            return;
        }
        self.occluded_from(origin, dirs, out);
    }

    /// The rays of a group of points ([`super::cuts::GroupRays`]), each point's consecutive: where
    /// Embree traces, one stream ([`Tracer::occluded_each`]), else each run of rays from one origin
    /// as [`Tracer::occluded_from`] (packets); the same answers. A vertex of the million-triangle
    /// bake that takes most cells from its neighbours traces ~9 rays a call, which Embree's
    /// packets trace at a third of the speed of a stream of many vertices' rays; on dragon.glb
    /// (30 K triangles) and the bunny the group's stream baked as fast as each point's packets or
    /// faster (docs/benchmarks.md, "Planned first passes left unbuilt").
    pub fn occluded_grouped(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        debug_assert!(origins.len() == dirs.len() && dirs.len() == out.len());
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_each(origins, dirs, out);
            return;
        }
        let mut start = 0;
        while start < origins.len() {
            let origin = origins[start];
            let end = start
                + origins[start..]
                    .iter()
                    .take_while(|&&o| o == origin)
                    .count();
            self.occluded_from(origin, &dirs[start..end], &mut out[start..end]);
            start = end;
        }
    }

    /// `out[i]` = [`Tracer::occluded`] of the ray from `origins[i]` along `dirs[i]`: one Embree
    /// stream (`rtcOccluded1M`, which sorts the rays by octant) where Embree traces, else one
    /// ray at a time; the same answers.
    pub fn occluded_each(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        debug_assert!(origins.len() == dirs.len() && dirs.len() == out.len());
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_each(origins, dirs, out);
            return;
        }
        self.occluded_one_by_one(origins, dirs, out);
    }

    /// `out[i]` = [`Tracer::occluded`] of the ray from `origins[i]` along `dirs[i]`: Embree's
    /// packets of 16 with an origin per ray where Embree traces, else one ray at a time. For the
    /// rays bench's grouping of one direction across neighbouring vertices.
    pub fn occluded_rays(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        debug_assert!(origins.len() == dirs.len() && dirs.len() == out.len());
        #[cfg(embree)]
        if let Some(e) = self.embree_packets() {
            e.occluded_rays(origins, dirs, out);
            return;
        }
        self.occluded_one_by_one(origins, dirs, out);
    }

    /// [`Tracer::occluded_each`] one ray at a time: where Embree does not trace.
    fn occluded_one_by_one(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        for ((p, d), o) in origins.iter().zip(dirs).zip(out.iter_mut()) {
            *o = self.occluded(*p, *d);
        }
    }

    /// Bit i: ray i of the packet (at most [`PACKET`] rays) is occluded.
    fn packet_occluded(&self, origin: Vec3A, dirs: &[Vec3A]) -> u32 {
        const N: usize = PACKET;
        let n = dirs.len().min(N);
        // Directions and inverse directions by lane (unused lanes repeat the first ray and are
        // never active). An inverse of ±∞ is clamped so that 0·inv stays 0, not NaN.
        let mut d = [[0.0f32; N]; 3];
        let mut inv = [[0.0f32; N]; 3];
        for lane in 0..N {
            let dir = dirs[if lane < n { lane } else { 0 }];
            for (axis, c) in dir.to_array().into_iter().enumerate() {
                d[axis][lane] = c;
                inv[axis][lane] = (1.0 / c).clamp(-1e30, 1e30);
            }
        }
        let all: u32 = (1u32 << n) - 1;
        let mut active = all;
        let nodes = &self.bvh2.nodes;
        // (node, rays that reach it); the root is tested like a child.
        let mut stack: [(u32, u32); 64] = [(0, 0); 64];
        let root = slab_mask(&nodes[0].aabb, origin, &inv, active).0;
        if root == 0 {
            return 0;
        }
        stack[0] = (0, root);
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (k, reach) = stack[top];
            let mask = reach & active;
            if mask == 0 {
                continue;
            }
            let node = &nodes[k as usize];
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                for t in &self.triangles[first..first + node.prim_count as usize] {
                    active &= !triangle_mask(t, origin, &d, active & mask);
                    if active & mask == 0 {
                        break;
                    }
                }
                if active == 0 {
                    return all;
                }
                continue;
            }
            let (l, r) = (node.first_index, node.first_index + 1);
            let (ml, nl) = slab_mask(&nodes[l as usize].aabb, origin, &inv, mask);
            let (mr, nr) = slab_mask(&nodes[r as usize].aabb, origin, &inv, mask);
            if top + 2 > stack.len() {
                // Deeper than the stack: finish these rays one at a time.
                for lane in 0..n {
                    if mask >> lane & 1 == 1 && self.occluded(origin, dirs[lane]) {
                        active &= !(1 << lane);
                    }
                }
                continue;
            }
            // The nearer child last, so that it is visited first (an occluder near the vertex
            // ends the packet's rays early).
            let (first, second) = if nl <= nr {
                ((r, mr), (l, ml))
            } else {
                ((l, ml), (r, mr))
            };
            for (child, m) in [first, second] {
                if m != 0 {
                    stack[top] = (child, m);
                    top += 1;
                }
            }
        }
        all & !active
    }

    /// True when no ray from `apex` with direction d, d·axis ≥ cos_half_angle and d·n > 0, can hit
    /// a triangle (see the module doc). `axis` and `n` are unit vectors.
    pub fn cone_free(&self, apex: Vec3A, n: Vec3A, axis: Vec3A, cos_half_angle: f32) -> bool {
        if self.bvh2.nodes.is_empty() {
            return true;
        }
        let cos_a = cos_half_angle.clamp(-1.0, 1.0);
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        // How far a node's box reaches above the plane through the apex: at most 0, it lies
        // entirely on or below it, and no above-horizon ray reaches it.
        let reach = |k: u32| {
            let b = &self.bvh2.nodes[k as usize].aabb;
            ((b.min + b.max) * 0.5 - apex).dot(n) + ((b.max - b.min) * 0.5).dot(n.abs())
        };
        // (node, its reach), the next to visit on top.
        let mut stack: [(u32, f32); 96] = [(0, 0.0); 96];
        stack[0] = (0, reach(0));
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (k, above) = stack[top];
            if above <= 0.0 {
                continue;
            }
            let node = &self.bvh2.nodes[k as usize];
            let centre = (node.aabb.min + node.aabb.max) * 0.5;
            let half = (node.aabb.max - node.aabb.min) * 0.5;
            if !sphere_meets_cone(centre, half.length(), apex, axis, cos_a, sin_a) {
                continue;
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                for k in first..first + node.prim_count as usize {
                    let t = &self.triangles[k];
                    let s = self.spheres[k];
                    if !sphere_meets_cone(s.centre.into(), s.radius, apex, axis, cos_a, sin_a) {
                        continue;
                    }
                    if triangle_meets_cone(t, apex, n, axis, cos_a, sin_a) {
                        return false;
                    }
                }
            } else if top + 2 <= stack.len() {
                // The child that reaches higher above the plane first: it is the likelier to hold
                // a triangle above it, which ends the search.
                let (a, b) = (node.first_index, node.first_index + 1);
                let (a, b) = ((a, reach(a)), (b, reach(b)));
                let (later, sooner) = if a.1 >= b.1 { (b, a) } else { (a, b) };
                stack[top] = later;
                stack[top + 1] = sooner;
                top += 2;
            } else {
                // A BVH deeper than the stack: answer conservatively.
                return false;
            }
        }
        true
    }
}

/// The rays of `mask` whose slab interval through `aabb` meets t ≥ 0, and the smallest entry distance
/// among them. The bounds are padded by a relative 1e-6 of the distance to them, so that rounding
/// never drops a ray that grazes a face (a false "reaches" only costs a visit).
#[inline(always)]
fn slab_mask(
    aabb: &obvhs::aabb::Aabb,
    origin: Vec3A,
    inv: &[[f32; PACKET]; 3],
    mask: u32,
) -> (u32, f32) {
    let lo = (aabb.min - origin).to_array();
    let hi = (aabb.max - origin).to_array();
    let mut near = [0.0f32; PACKET];
    let mut far = [f32::INFINITY; PACKET];
    for axis in 0..3 {
        for lane in 0..PACKET {
            let t0 = lo[axis] * inv[axis][lane];
            let t1 = hi[axis] * inv[axis][lane];
            near[lane] = near[lane].max(t0.min(t1));
            far[lane] = far[lane].min(t0.max(t1));
        }
    }
    let mut out = 0u32;
    let mut nearest = f32::INFINITY;
    for lane in 0..PACKET {
        if mask >> lane & 1 == 1 && near[lane] <= far[lane] * (1.0 + 1e-6) + 1e-30 {
            out |= 1 << lane;
            nearest = nearest.min(near[lane]);
        }
    }
    (out, nearest)
}

/// The rays of `mask` that hit triangle `t` at t ≥ 0: obvhs's `RtTriangle::intersect` (Möller–
/// Trumbore in its layout: e1 = v0 − v1, e2 = v2 − v0, ng = e1 × e2), across the lanes at once,
/// with what the rays share (the edges, c = v0 − origin, ng·c) computed once.
#[inline]
fn triangle_mask(t: &Triangle, origin: Vec3A, d: &[[f32; PACKET]; 3], mask: u32) -> u32 {
    let (e1, e2) = (t.v0 - t.v1, t.v2 - t.v0);
    let ng = e1.cross(e2).to_array();
    let c = (t.v0 - origin).to_array();
    let (e1, e2) = (e1.to_array(), e2.to_array());
    let t_num = (ng[0] * c[0] + ng[1] * c[1]) + ng[2] * c[2];
    let mut valid = [false; PACKET];
    for lane in 0..PACKET {
        let (dx, dy, dz) = (d[0][lane], d[1][lane], d[2][lane]);
        // r = d × c
        let (rx, ry, rz) = (
            dy * c[2] - dz * c[1],
            dz * c[0] - dx * c[2],
            dx * c[1] - dy * c[0],
        );
        let inv_det = 1.0 / ((ng[0] * dx + ng[1] * dy) + ng[2] * dz);
        let u = ((rx * e2[0] + ry * e2[1]) + rz * e2[2]) * inv_det;
        let v = ((rx * e1[0] + ry * e1[1]) + rz * e1[2]) * inv_det;
        let w = 1.0 - u - v;
        let signs = u.to_bits() | v.to_bits() | w.to_bits();
        let dist = t_num * inv_det;
        valid[lane] = inv_det != 0.0 && signs & 0x8000_0000 == 0 && dist >= 0.0;
    }
    let mut hit = 0u32;
    for (lane, &v) in valid.iter().enumerate() {
        hit |= (v as u32) << lane;
    }
    hit & mask
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    /// A point of the unit cube.
    fn unit(rng: &mut Rng) -> Vec3 {
        Vec3::new(
            rng.next_f64() as f32,
            rng.next_f64() as f32,
            rng.next_f64() as f32,
        )
    }

    /// A soup of 400 random triangles in [-2.3, 2.3]³.
    fn soup(rng: &mut Rng) -> Mesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for t in 0..400u32 {
            let centre = unit(rng) * 4.0 - 2.0;
            for _ in 0..3 {
                let jitter = unit(rng) - 0.5;
                positions.push(centre + jitter * 0.6);
            }
            triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
        }
        Mesh {
            normals: vec![Vec3::Z; positions.len()],
            positions,
            tangents: None,
            uvs: None,
            triangles,
        }
    }

    /// Random rays from random points in [-2.5, 2.5]³: (origin, directions) in groups of 1–40.
    fn rays(rng: &mut Rng) -> Vec<(Vec3A, Vec<Vec3A>)> {
        (0..500)
            .map(|_| {
                let origin = Vec3A::from(unit(rng)) * 5.0 - 2.5;
                let count = 1 + (rng.next_f64() as f32 * 40.0) as usize;
                let dirs = (0..count)
                    .map(|_| {
                        let z = 2.0 * rng.next_f64() as f32 - 1.0;
                        let phi = std::f32::consts::TAU * rng.next_f64() as f32;
                        let r = (1.0 - z * z).max(0.0).sqrt();
                        Vec3A::new(r * phi.cos(), r * phi.sin(), z)
                    })
                    .collect();
                (origin, dirs)
            })
            .collect()
    }

    /// With each backend, packets answer as single rays do, on a soup of random triangles seen from random points
    /// (rays in random, not coherent, directions: the hardest case for a packet's bookkeeping).
    /// Exact agreement is not promised — the two BVHs' node bounds round differently — but a
    /// disagreement needs a ray within rounding of a triangle's edge or a node's face.
    #[test]
    fn packets_answer_as_single_rays() {
        let mut rng = Rng::new(7);
        let mesh = soup(&mut rng);
        let groups = rays(&mut rng);
        for &backend in Backend::available() {
            let tracer = Tracer::with_backend(&mesh, backend);
            assert_eq!(tracer.backend(), backend);
            let (mut n, mut hits, mut differ) = (0usize, 0usize, 0usize);
            for (origin, dirs) in &groups {
                // The bake's calls, Embree's streams, packets of 16 (with a tail of 8) and of 8
                // alike.
                let mut out = [(); 4].map(|_| vec![false; dirs.len()]);
                tracer.occluded_from(*origin, dirs, &mut out[0]);
                tracer.occluded_stream(*origin, dirs, &mut out[1]);
                tracer.occluded_from_packets(*origin, dirs, &mut out[2]);
                tracer.occluded_from_8(*origin, dirs, &mut out[3]);
                for (i, d) in dirs.iter().enumerate() {
                    let single = tracer.occluded(*origin, *d);
                    n += 1;
                    hits += single as usize;
                    differ += out.iter().filter(|o| o[i] != single).count();
                }
            }
            assert!(
                hits > n / 10 && hits < n * 9 / 10,
                "{backend:?}: {hits} of {n} occluded"
            );
            assert!(
                differ * 20_000 <= n,
                "{backend:?}: {differ} of {n} rays differ"
            );
            // Every group's rays in one list, each from its own origin, packed across groups.
            let (origins, dirs): (Vec<Vec3A>, Vec<Vec3A>) = groups
                .iter()
                .flat_map(|(o, ds)| ds.iter().map(move |d| (*o, *d)))
                .unzip();
            // Packets of 16 (the rays bench's), one stream, and the bake's groups of vertices (a
            // stream through Embree, each run of one origin in packets through obvhs).
            for each in [
                Tracer::occluded_rays,
                Tracer::occluded_each,
                Tracer::occluded_grouped,
            ] {
                let mut out = vec![false; dirs.len()];
                each(&tracer, &origins, &dirs, &mut out);
                let differ = origins
                    .iter()
                    .zip(&dirs)
                    .zip(&out)
                    .filter(|((o, d), hit)| tracer.occluded(**o, **d) != **hit)
                    .count();
                assert!(
                    differ * 20_000 <= dirs.len(),
                    "{backend:?}: {differ} of {} rays from their own origins differ",
                    dirs.len()
                );
            }
        }
    }

    /// Embree (a second implementation: its own BVH and its robust triangle test) answers as
    /// obvhs does, but for rays within rounding of a triangle's edge.
    #[cfg(embree)]
    #[test]
    fn embree_answers_as_obvhs() {
        let mut rng = Rng::new(11);
        let mesh = soup(&mut rng);
        let obvhs = Tracer::with_backend(&mesh, Backend::Obvhs);
        let embree = Tracer::with_backend(&mesh, Backend::Embree);
        assert_eq!(embree.backend(), Backend::Embree);
        let (mut n, mut hits, mut differ) = (0usize, 0usize, 0usize);
        for (origin, dirs) in rays(&mut rng) {
            for d in dirs {
                let a = obvhs.occluded(origin, d);
                n += 1;
                hits += a as usize;
                differ += (a != embree.occluded(origin, d)) as usize;
            }
        }
        assert!(hits > n / 10 && hits < n * 9 / 10, "{hits} of {n} occluded");
        assert!(differ * 20_000 <= n, "{differ} of {n} rays differ");
    }

    /// The cone test against rays, on hemispheres and narrower cones from random apexes: a cone
    /// that any of 256 rays inside it (and above the plane) finds blocked is never called free,
    /// whatever order the search visits the BVH in; and the test, which may call a cone blocked
    /// when unsure, seldom does so where no ray is blocked.
    #[test]
    fn cone_free_never_frees_a_cone_a_ray_finds_blocked() {
        let mut rng = Rng::new(5);
        let mesh = soup(&mut rng);
        let tracer = Tracer::with_backend(&mesh, Backend::Obvhs);
        let (mut free, mut cautious, mut cones) = (0usize, 0usize, 0usize);
        for i in 0..2000 {
            let apex = Vec3A::from(unit(&mut rng)) * 7.0 - 3.5;
            let n = (Vec3A::from(unit(&mut rng)) - 0.5).normalize();
            let cos_a = [0.0f32, 0.5, 0.9, 0.99][i % 4];
            let tilt = (Vec3A::from(unit(&mut rng)) - 0.5) * 0.8;
            let axis = if cos_a == 0.0 {
                n
            } else {
                (n + tilt).normalize()
            };
            let (t1, t2) = {
                let helper = if axis.x.abs() < 0.9 {
                    Vec3A::X
                } else {
                    Vec3A::Y
                };
                let t1 = axis.cross(helper).normalize();
                (t1, axis.cross(t1))
            };
            let blocked = (0..256).any(|_| {
                let z = 1.0 - rng.next_f64() as f32 * (1.0 - cos_a);
                let phi = std::f32::consts::TAU * rng.next_f64() as f32;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = (axis * z + t1 * (r * phi.cos()) + t2 * (r * phi.sin())).normalize();
                d.dot(n) > 1e-3 && tracer.occluded(apex, d)
            });
            let said_free = tracer.cone_free(apex, n, axis, cos_a);
            assert!(
                !(blocked && said_free),
                "a ray is blocked in a cone called free: apex {apex:?}, n {n:?}, axis {axis:?}, cos {cos_a}"
            );
            free += said_free as usize;
            cautious += (!said_free && !blocked) as usize;
            cones += 1;
        }
        assert!(free > cones / 10, "{free} of {cones} free");
        assert!(
            cautious * 10 < cones,
            "{cautious} of {cones} blocked where no ray is"
        );
    }
}
