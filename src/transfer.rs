//! Transfer: T_j and the irradiance E for the pixels of a view (method.md §4, eq. 5-7).
//!
//! T_j(x) = ∫ L(wi) Ṽ(x, wi) G(h·ξ_j) s(wi, wo(x)) dwi,  E(x) = ∫ L Ṽ dwi,  Ṽ = V·max(wi·n, 0),
//! so that the rendered radiance is B(x) = ρd/π·E(x) + Σ_j c_j T_j(x) (per colour channel).
//!
//! Inputs: the bake's cuts, the light tree and [`LightSums`] (for the environment's rotation), a
//! [`LobeSet`], the mesh (positions, normals, tangents or none), a camera and a fit resolution, and F0.
//! Output: a [`Transfer`] — per covered pixel its sample (triangle, barycentrics, position, normal), T
//! (3 × J per pixel, f32) and E (RGB, f64).
//!
//! How a pixel is summed: its triangle's three vertex cuts and the *shading partition* (tree nodes no
//! wider than about a quarter of the lobe's width in wi-space, so that evaluating the BRDF at one
//! direction per node is accurate) are merged into elementary runs of consecutive leaves (cut nodes are
//! leaf ranges in tree order). For each run the prefix sums give its power Σ Ω L, solid angle and moment
//! Σ Ω d in O(1); V is the barycentric blend of the three vertices' V_k; Ṽ uses the pixel's
//! interpolated normal, with the run's mean cosine exact (moment·n / Ω) when it lies above the horizon,
//! and where it straddles it split by a walk down the tree into sub-ranges above (exact) and the nodes
//! of ≤ 16 leaves the horizon cuts (clipped whole by a disc model, [`LightTree::split_by_horizon`]). The BRDF is evaluated
//! at the run's mean direction; only lobes whose support (G > e^-14) can reach the half-vector are
//! evaluated ([`LobeGrid`]). Ring lobes (isotropic sets) depend on the half-vector's polar angle alone
//! and are read from one table in t = √(1 − cos θh) with linear interpolation, so a run's weight is
//! split between the two table points it falls between (a histogram per pixel and channel) and each
//! lobe is the dot product of the histogram with its table row once per pixel: the same sums as
//! evaluating every lobe per run, regrouped (dragon_100k at 160×120: 12.8 lobes per run).
//!
//! Invariants: no ray tracing (visibility comes from the bake; a new view or rotation only re-sums);
//! pixels are independent, so the result does not depend on the thread count; no IO.

use crate::bake::{Cuts, Span, for_each_run};
use crate::brdf::dbrdf::{static_term, static_term_parts};
use crate::light::LightSums;
use crate::raster::{Fragment, rasterize};
use crate::scene::{Camera, Mesh};
use crate::sphere::light_tree::{Partition, PartitionCone};
use crate::sphere::{Frame, LightTree, LobeSet, hemi_oct, srbf};
use glam::{DVec3, Vec3, Vec4};
use rayon::prelude::*;

/// Relative threshold under which a lobe is not evaluated: G < e^-14 ≈ 8e-7.
pub const LOBE_CUTOFF_EXPONENT: f64 = 14.0;

/// Which lobes can be non-negligible at a half-vector: an octahedral grid over the upper hemisphere
/// of local half-vectors, each cell listing the lobes whose support cone meets the cell's bounding cap.
/// (Ring lobes need no grid: the transfer sums them through the ring table.)
#[derive(Debug, Clone)]
pub struct LobeGrid {
    size: usize,
    offsets: Vec<u32>,
    lobes: Vec<u32>,
}

impl LobeGrid {
    /// Builds the grid for a lobe set (isotropic sets get one list per elevation band in effect).
    pub fn new(lobes: &LobeSet) -> Self {
        let size = 32usize;
        let support = srbf::support_cosine(lobes.lambda(), LOBE_CUTOFF_EXPONENT).acos();
        let mut offsets = vec![0u32];
        let mut list = Vec::new();
        for cy in 0..size {
            for cx in 0..size {
                // Bounding cap of the cell: centre and the largest angle to its corners and edge midpoints.
                let centre = hemi_oct::decode((cx as f64 + 0.5) / size as f64, (cy as f64 + 0.5) / size as f64);
                let mut radius = 0.0f64;
                for (a, b) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.0), (0.0, 0.5), (1.0, 0.5), (0.5, 1.0)] {
                    let p = hemi_oct::decode((cx as f64 + a) / size as f64, (cy as f64 + b) / size as f64);
                    radius = radius.max(p.dot(centre).clamp(-1.0, 1.0).acos());
                }
                radius *= 1.05;
                for (j, xi) in lobes.centres().iter().enumerate() {
                    let angle = if lobes.layout().is_isotropic() {
                        // A ring lobe depends on the elevation only: distance in polar angle.
                        (centre.z.clamp(-1.0, 1.0).acos() - xi.z.clamp(-1.0, 1.0).acos()).abs()
                    } else {
                        centre.dot(*xi).clamp(-1.0, 1.0).acos()
                    };
                    if angle <= support + radius {
                        list.push(j as u32);
                    }
                }
                offsets.push(list.len() as u32);
            }
        }
        Self { size, offsets, lobes: list }
    }

    /// Candidate lobes for a local unit half-vector (z ≥ 0 expected; z < 0 is folded up).
    #[inline]
    pub fn candidates(&self, h: DVec3) -> &[u32] {
        let (u, v) = hemi_oct::encode(h);
        let cx = ((u * self.size as f64) as usize).min(self.size - 1);
        let cy = ((v * self.size as f64) as usize).min(self.size - 1);
        let c = cy * self.size + cx;
        &self.lobes[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }
}

/// One pixel of the fit view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelSample {
    pub x: u32,
    pub y: u32,
    pub triangle: u32,
    pub bary: [f32; 3],
    pub position: Vec3,
    pub normal: Vec3,
}

/// T and E for the pixels of one view.
#[derive(Debug, Clone)]
pub struct Transfer {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<PixelSample>,
    /// J.
    pub lobes: usize,
    /// T, (pixel · 3 + channel) · J + j.
    pub t: Vec<f32>,
    /// Irradiance E per pixel, RGB.
    pub irradiance: Vec<[f64; 3]>,
    pub seconds: f64,
}

impl Transfer {
    /// T_j for one pixel and channel.
    pub fn t_row(&self, pixel: usize, channel: usize) -> &[f32] {
        let start = (pixel * 3 + channel) * self.lobes;
        &self.t[start..start + self.lobes]
    }

    /// B = ρd/π·E + Σ_j c_j T_j per pixel (coefficients per channel).
    pub fn render(&self, rho_d: [f64; 3], coefficients: [&[f64]; 3]) -> Vec<[f64; 3]> {
        (0..self.pixels.len())
            .map(|p| {
                std::array::from_fn(|c| {
                    let spec: f64 = self.t_row(p, c).iter().zip(coefficients[c]).map(|(t, k)| *t as f64 * k).sum();
                    rho_d[c] / std::f64::consts::PI * self.irradiance[p][c] + spec
                })
            })
            .collect()
    }
}

/// A shading node's solid angle, moment and radiant power under the current light.
#[derive(Debug, Clone, Copy)]
struct NodeLight {
    omega: f64,
    moment: DVec3,
    power: [f64; 3],
}

/// What stays fixed across views and rotations: built once per bake and lobe set.
pub struct TransferContext<'a> {
    pub mesh: &'a Mesh,
    pub cuts: &'a Cuts,
    pub tree: &'a LightTree,
    pub lobes: &'a LobeSet,
    pub tangents: Option<&'a [Vec4]>,
    grid: LobeGrid,
    /// Leaf ranges [first, end) of the shading partition, in order.
    shading: Vec<(u32, u32)>,
    /// Per shading node, its light-tree node (where the walk that splits a run at the horizon starts).
    shading_nodes: Vec<u32>,
    /// Per shading node, its corner cone (copied from the tree so that runs read them in order).
    shading_cones: Vec<PartitionCone>,
    /// Ring lobes only: per lobe, the table points [first, last] where it exceeds the cutoff.
    ring_support: Vec<(usize, usize)>,
}

impl<'a> TransferContext<'a> {
    /// `shading_angle`: the largest cone half-angle (radians) of a shading node; `None` uses an eighth of
    /// the lobe width in wi-space (σ_wi = 2σ), i.e. σ/4 (nodes about σ/2 across). Measured on the bunny
    /// (tests/transfer.rs): σ/2 leaves T 1.75 % off direct integration, σ/4 1.0 %, σ/8 0.99 % (the rest is
    /// per-vertex visibility).
    pub fn new(mesh: &'a Mesh, cuts: &'a Cuts, tree: &'a LightTree, lobes: &'a LobeSet, tangents: Option<&'a [Vec4]>, shading_angle: Option<f64>) -> Self {
        let sigma = srbf::sigma_from_lambda(lobes.lambda()).unwrap_or(0.08);
        let target = shading_angle.unwrap_or(0.25 * sigma).max(1e-6);
        let Partition { ranges: shading, nodes: shading_nodes, .. } = tree.partition(target);
        let shading_cones = shading_nodes.iter().map(|&k| *tree.corner_cone(k as usize)).collect();
        let cutoff = (-LOBE_CUTOFF_EXPONENT).exp();
        let ring_support = if lobes.layout().is_isotropic() {
            (0..lobes.len())
                .map(|j| {
                    let row = lobes.ring_row(j);
                    let first = row.iter().position(|&g| g > cutoff).unwrap_or(row.len());
                    let last = row.iter().rposition(|&g| g > cutoff).unwrap_or(0);
                    (first, last)
                })
                .collect()
        } else {
            Vec::new()
        };
        Self { mesh, cuts, tree, lobes, tangents, grid: LobeGrid::new(lobes), shading, shading_nodes, shading_cones, ring_support }
    }

    /// Number of nodes in the shading partition (over the whole sphere).
    pub fn shading_nodes(&self) -> usize {
        self.shading.len()
    }

    fn spans(&self, v: usize) -> Vec<Span> {
        self.cuts.spans(v, self.tree).collect()
    }

    /// T and E for the pixels of `camera` at `width`×`height`, environment sums `light`, Fresnel F0.
    pub fn compute(&self, light: &LightSums, camera: &Camera, width: u32, height: u32, f0: f64) -> Transfer {
        let start = std::time::Instant::now();
        let fragments = rasterize(self.mesh, camera, width, height);
        let eye = camera.eye().as_dvec3();
        // Spans of the vertices the view sees.
        let mut used = vec![false; self.mesh.positions.len()];
        for f in &fragments {
            for &i in &self.mesh.triangles[f.triangle as usize] {
                used[i as usize] = true;
            }
        }
        let spans: Vec<Option<Vec<Span>>> =
            used.par_iter().enumerate().map(|(v, &u)| u.then(|| self.spans(v))).collect();
        let j_count = self.lobes.len();
        // Each shading node's light, read once per run instead of two prefix-sum entries per array
        // (nearly every run is a whole shading node: cut nodes are much wider).
        let node_light: Vec<NodeLight> = self
            .shading
            .iter()
            .map(|&(a, z)| {
                let (a, z) = (a as usize, z as usize);
                NodeLight { omega: light.omega(a, z), moment: light.moment(a, z), power: light.power(a, z) }
            })
            .collect();
        let bins = if self.lobes.layout().is_isotropic() { LobeSet::RING_INTERVALS + 1 } else { 0 };
        let results: Vec<(PixelSample, Vec<f32>, [f64; 3])> = fragments
            .par_iter()
            // Per thread, the ring histogram (table points × 3 channels, interleaved), all zero between
            // pixels.
            .map_init(|| vec![0.0f64; 3 * bins], |hist, f| self.pixel(f, &spans, light, &node_light, eye, f0, j_count, hist))
            .collect();
        let mut pixels = Vec::with_capacity(results.len());
        let mut t = Vec::with_capacity(results.len() * 3 * j_count);
        let mut irradiance = Vec::with_capacity(results.len());
        for (p, row, e) in results {
            pixels.push(p);
            t.extend_from_slice(&row);
            irradiance.push(e);
        }
        Transfer { width, height, pixels, lobes: j_count, t, irradiance, seconds: start.elapsed().as_secs_f64() }
    }

    #[allow(clippy::too_many_arguments)]
    fn pixel(&self, f: &Fragment, spans: &[Option<Vec<Span>>], light: &LightSums, node_light: &[NodeLight], eye: DVec3, f0: f64, j_count: usize, hist: &mut [f64]) -> (PixelSample, Vec<f32>, [f64; 3]) {
        let tri = self.mesh.triangles[f.triangle as usize];
        let b = f.bary.map(|x| x as f64);
        let position: DVec3 = (0..3).map(|i| self.mesh.positions[tri[i] as usize].as_dvec3() * b[i]).sum();
        let normal = (0..3)
            .map(|i| self.mesh.normals[tri[i] as usize].as_dvec3() * b[i])
            .sum::<DVec3>()
            .try_normalize()
            .unwrap_or(DVec3::Y);
        let frame = match self.tangents {
            Some(t) => {
                let tw: Vec4 = (0..3).map(|i| t[tri[i] as usize] * f.bary[i]).sum();
                Frame::from_normal_tangent(normal, tw.truncate().as_dvec3(), if tw.w < 0.0 { -1.0 } else { 1.0 })
            }
            None => Frame::from_normal(normal),
        };
        let wo_world = (eye - position).try_normalize().unwrap_or(normal);
        let wo = frame.to_local(wo_world);
        let sample = PixelSample { x: f.x, y: f.y, triangle: f.triangle, bary: f.bary, position: position.as_vec3(), normal: normal.as_vec3() };
        let mut acc = vec![0.0f64; 3 * j_count];
        let mut e = [0.0f64; 3];
        // Where the interpolated shading normal faces away from the eye (silhouettes), the specular term
        // is 0 and the diffuse term is kept: the convention every renderer shares.
        let specular = wo.z > 0.0;
        let vertex_spans: [&[Span]; 3] = std::array::from_fn(|i| spans[tri[i] as usize].as_deref().unwrap_or(&[]));
        let leaves = self.tree.leaf_count() as u32;
        let isotropic = self.lobes.layout().is_isotropic();
        let (mut k_lo, mut k_hi) = (usize::MAX, 0usize);
        for_each_run(&vertex_spans, &b, &self.shading, leaves, |a, z, vis, si| {
            let whole = self.shading[si] == (a as u32, z as u32);
            let (omega, moment) = if whole { (node_light[si].omega, node_light[si].moment) } else { (light.omega(a, z), light.moment(a, z)) };
            let Some(dir) = moment.try_normalize() else { return };
            // ∫ max(ω·n, 0) dω over the run: its moment · n (exact) when it lies wholly above the
            // horizon (the shading node's corner cone settles most runs at once), else split by a walk
            // down the tree into sub-ranges above (their moments) and leaves astride (linear clip).
            // A whole shading node wholly above or below the horizon is settled by its cone here, as the
            // walk's first test would settle it, without touching the tree.
            let cone = &self.shading_cones[si];
            let cb = cone.axis.dot(normal);
            let mut cos_mass = 0.0;
            if whole && cone.cos > 0.0 && cb > cone.sin {
                cos_mass = moment.dot(normal);
            } else if !(whole && cone.cos > 0.0 && cb < -cone.sin) {
                self.tree.split_by_horizon(self.shading_nodes[si] as usize, a, z, normal, crate::sphere::light_tree::COARSE_HORIZON_LEAVES, &mut |lo, hi, clipped| {
                    cos_mass += match clipped {
                        None if (lo, hi) == (a, z) => moment.dot(normal),
                        None => light.moment(lo, hi).dot(normal),
                        Some(c) => c,
                    }
                });
            }
            if cos_mass <= 0.0 || omega <= 0.0 {
                return;
            }
            let power = if whole { node_light[si].power } else { light.power(a, z) };
            let weight = vis * cos_mass / omega;
            for c in 0..3 {
                e[c] += weight * power[c];
            }
            if !specular {
                return;
            }
            if isotropic {
                // Ring lobes need only h·n: from wi·n, wo·n and wi·wo, with |wi + wo| = √(2 + 2 wi·wo)
                // (no local frame, one square root).
                let k1 = dir.dot(normal);
                let c = dir.dot(wo_world);
                let len2 = 2.0 + 2.0 * c;
                if k1 <= 0.0 || len2.is_nan() || len2 <= 1e-24 {
                    return;
                }
                let inv = 1.0 / len2.sqrt();
                let s = static_term_parts(k1, wo.z, (1.0 + c) * inv, f0);
                if s <= 0.0 {
                    return;
                }
                let ws = weight * s;
                // Σ_j g_j(t) w = Σ_j (a_jk (1 − f) + a_j,k+1 f) w: the weight goes to the two points.
                let (k, frac) = self.lobes.ring_position(DVec3::new(0.0, 0.0, (k1 + wo.z) * inv));
                let (below, above) = (ws * (1.0 - frac), ws * frac);
                let b = 3 * k;
                for c in 0..3 {
                    hist[b + c] += below * power[c];
                    hist[b + 3 + c] += above * power[c];
                }
                k_lo = k_lo.min(k);
                k_hi = k_hi.max(k + 1);
                return;
            }
            let wi = frame.to_local(dir);
            if wi.z <= 0.0 {
                return;
            }
            let s = static_term(wi, wo, f0);
            let Some(h) = (wi + wo).try_normalize() else { return };
            if s <= 0.0 {
                return;
            }
            let ws = weight * s;
            let wp = [ws * power[0], ws * power[1], ws * power[2]];
            for &j in self.grid.candidates(h) {
                let j = j as usize;
                let g = self.lobes.eval_one(j, h);
                acc[j] += wp[0] * g;
                acc[j_count + j] += wp[1] * g;
                acc[2 * j_count + j] += wp[2] * g;
            }
        });
        if isotropic && k_lo <= k_hi {
            for (j, &(first, last)) in self.ring_support.iter().enumerate() {
                let (a, z) = (first.max(k_lo), last.min(k_hi));
                if a > z {
                    continue;
                }
                let row = &self.lobes.ring_row(j)[a..=z];
                let (mut s0, mut s1, mut s2) = (0.0f64, 0.0f64, 0.0f64);
                for (t, r) in hist[3 * a..3 * z + 3].chunks_exact(3).zip(row) {
                    s0 += t[0] * r;
                    s1 += t[1] * r;
                    s2 += t[2] * r;
                }
                acc[j] += s0;
                acc[j_count + j] += s1;
                acc[2 * j_count + j] += s2;
            }
            hist[3 * k_lo..3 * k_hi + 3].fill(0.0);
        }
        (sample, acc.iter().map(|&x| x as f32).collect(), e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::LobeLayout;

    #[test]
    fn grid_candidates_hold_every_lobe_that_is_not_negligible() {
        // At random half-vectors, every lobe above the cutoff (relative to its peak of 1) is among the
        // grid cell's candidates, for ring and for hemicube lobes.
        let lambda = srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap();
        let cutoff = (-LOBE_CUTOFF_EXPONENT).exp();
        for layout in [LobeLayout::Isotropic { count: 24 }, LobeLayout::PAPER] {
            let lobes = LobeSet::new(layout, lambda).unwrap();
            let grid = LobeGrid::new(&lobes);
            let mut rng = crate::math::Rng::new(17);
            let mut seen = 0;
            for _ in 0..20_000 {
                let h = rng.hemisphere_vector();
                let candidates = grid.candidates(h);
                assert!(candidates.len() <= lobes.len());
                for j in 0..lobes.len() {
                    if lobes.eval_exact(j, h) > cutoff {
                        seen += 1;
                        assert!(candidates.contains(&(j as u32)), "{layout:?}: lobe {j} at h = {h} missing from the grid");
                    }
                }
            }
            assert!(seen > 20_000, "{seen}");
        }
    }
}
