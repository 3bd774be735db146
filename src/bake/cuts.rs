//! Per-vertex visibility cuts through the light tree (method.md §4; Åkerlund et al. 2007).
//!
//! Inputs: a vertex (position, unit normal), the [`LightTree`], a [`Tracer`] and [`CutSettings`].
//! Output: the vertex's cut — tree nodes that partition the leaves above its horizon — with, per node,
//! the cosine-weighted visible fraction
//!   V_k = Σ_{i∈k} Ω_i c_i V_i / Σ_{i∈k} Ω_i c_i,   c_i = max(d_i·n, 0),  V_i ∈ {0, 1}
//! (V_i = visibility of leaf direction d_i by a ray from the vertex offset along n; with visibility cells
//! of C > 1 leaves, V_i is the visibility along the mean direction of the cell that holds leaf i). The mean of
//! Ṽ = V·max(cos, 0) over a node follows exactly: ⟨Ṽ⟩_k = V_k · Σ Ω_i c_i / Ω_k; and within the node Ṽ is
//! reconstructed as V_k·c_i, which is exact when V is constant over the node.
//!
//! Algorithm (top-down, then merged bottom-up):
//! 1. A node wholly below the horizon is dropped (Ṽ = 0, no rays).
//! 2. A node whose cone of directions is free ([`Tracer::cone_free`]) is visible, V = 1, exactly, with
//!    no rays: this settles open sky wholesale.
//! 3. A node so near the horizon that ½·Σ Ω_i c_i ≤ ε·Ω_k is accepted with V = ½ and no rays: whatever
//!    its true visibility, the mean |Ṽ| error over it is within ε.
//! 4. Otherwise a node with at most `trace_leaves` leaves has every above-horizon leaf traced; larger
//!    nodes are split.
//! 5. Sibling results merge into their parent while the error bound
//!    Σ_i Ω_i c_i |V_i − V_parent| ≤ ε·Ω_parent holds, i.e. the mean absolute error of Ṽ over the node is
//!    at most ε (the bound is exact for traced leaves and conservative above them).
//! 6. If the cut has more than `max_cut` nodes, ε is doubled and the merge redone (traced leaves are
//!    cached, so no ray is cast twice) until it fits; such vertices are counted.
//!
//! Invariants: the cut's nodes are disjoint and in pre-order (= leaf order); every above-horizon leaf
//! lies in exactly one; values are in [0, 1]; the result does not depend on the thread that made it.

use super::tracer::Tracer;
use crate::sphere::LightTree;
use glam::{DVec3, Vec3A};
use serde::{Deserialize, Serialize};

/// Knobs of the cut.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CutSettings {
    /// Error bound ε on the mean |Ṽ error| over any cut node.
    pub epsilon: f64,
    /// Cap on the number of nodes in one vertex's cut.
    pub max_cut: usize,
    /// Nodes with at most this many leaves are ray traced cell by cell when their cone is not free.
    pub trace_leaves: usize,
    /// Visibility resolution: nodes with at most this many leaves are visibility cells, traced with one
    /// ray along their mean direction (1 = every leaf direction is traced). Light and BRDF still use
    /// every leaf; within a cell Ṽ = V_cell·max(cos, 0).
    pub cell_leaves: usize,
    /// Ray origin offset along the normal, as a fraction of the bounding-box diagonal.
    pub ray_offset: f64,
}

impl Default for CutSettings {
    fn default() -> Self {
        Self { epsilon: 0.02, max_cut: 1024, trace_leaves: 4096, cell_leaves: 4, ray_offset: 1e-4 }
    }
}

/// One vertex's cut.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VertexCut {
    /// (node index, V_k), in pre-order.
    pub entries: Vec<(u32, f32)>,
    /// Rays cast for this vertex.
    pub rays: u64,
    /// ε actually used (> settings.epsilon when the cap forced coarsening).
    pub epsilon_used: f64,
}

/// Per-thread scratch: the traced leaf visibilities of the current vertex (generation-stamped so that
/// nothing is cleared between vertices).
pub struct CutScratch {
    stamp: Vec<u32>,
    visible: Vec<bool>,
    generation: u32,
}

impl CutScratch {
    /// Scratch for a tree with `leaves` leaves.
    pub fn new(leaves: usize) -> Self {
        Self { stamp: vec![0; leaves], visible: vec![false; leaves], generation: 0 }
    }

    fn next_vertex(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
    }
}

struct Ctx<'a> {
    tree: &'a LightTree,
    tracer: &'a Tracer,
    apex: Vec3A,
    n: DVec3,
    nf: Vec3A,
    trace_leaves: usize,
    cell_leaves: usize,
    epsilon: f64,
    scratch: &'a mut CutScratch,
    rays: u64,
    /// Whether cone tests may be used (false on redo passes: their answers are cached in `free`).
    free: Vec<u32>,
    redo: bool,
}

/// (Σ Ω c, Σ Ω c V, error bound Σ Ω c |V_i − V_node|) of a subtree.
type Sums = (f64, f64, f64);

/// The cut of one vertex at `position` with unit `normal`.
pub fn vertex_cut(
    position: DVec3,
    normal: DVec3,
    offset: f64,
    tree: &LightTree,
    tracer: &Tracer,
    settings: &CutSettings,
    scratch: &mut CutScratch,
) -> VertexCut {
    scratch.next_vertex();
    let apex = position + normal * offset;
    let mut ctx = Ctx {
        tree,
        tracer,
        apex: apex.as_vec3().into(),
        n: normal,
        nf: normal.as_vec3().into(),
        trace_leaves: settings.trace_leaves.max(settings.cell_leaves).max(1),
        cell_leaves: settings.cell_leaves.max(1),
        epsilon: settings.epsilon.max(0.0),
        scratch,
        rays: 0,
        free: Vec::new(),
        redo: false,
    };
    let mut entries = Vec::new();
    loop {
        entries.clear();
        build(&mut ctx, 0, false, &mut entries);
        if entries.len() <= settings.max_cut.max(1) || ctx.epsilon >= 1.0 {
            break;
        }
        ctx.epsilon = if ctx.epsilon > 0.0 { ctx.epsilon * 2.0 } else { 1e-3 };
        ctx.redo = true;
    }
    VertexCut { entries, rays: ctx.rays, epsilon_used: ctx.epsilon }
}

/// Σ_i Ω_i c_i over the node's leaves, with Ω_i c_i = max(moment_i·n, 0) (exact for a leaf wholly above
/// the horizon; the leaf's mean cosine otherwise).
fn cosine_mass(tree: &LightTree, k: usize, n: DVec3) -> f64 {
    let node = tree.nodes()[k];
    let range = node.first as usize..(node.first + node.count) as usize;
    tree.leaf_moments()[range].iter().map(|m| m.dot(n).max(0.0)).sum()
}

fn build(ctx: &mut Ctx, k: usize, known: bool, out: &mut Vec<(u32, f32)>) -> Sums {
    let node = ctx.tree.nodes()[k];
    // β = angle(mean direction, n), α = the cone's half-angle; all in cosines and sines (no acos).
    let cos_b = node.mean_direction.dot(ctx.n).clamp(-1.0, 1.0);
    let sin_b = (1.0 - cos_b * cos_b).max(0.0).sqrt();
    let (cos_a, sin_a) = (node.cone_cos.clamp(-1.0, 1.0), node.cone_sin);
    // cos(β − α) is the largest cosine to n inside the cone when β ≥ α (else the cone holds n).
    let max_cos = if cos_b <= cos_a { cos_b * cos_a + sin_b * sin_a } else { 1.0 };
    if max_cos <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    // β + α < π/2: every direction of the node is above the horizon.
    let wholly_above = cos_b * cos_a - sin_b * sin_a > 0.0 && sin_b * cos_a + cos_b * sin_a > 0.0;
    if node.is_leaf() || (known && node.count as usize <= ctx.cell_leaves) {
        // A visibility cell: one ray along its mean direction (cached), V ∈ {0, 1} over the cell.
        let w = if wholly_above { node.moment.dot(ctx.n) } else { cosine_mass(ctx.tree, k, ctx.n) };
        if w <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let v = if cell_visible(ctx, &node) { 1.0 } else { 0.0 };
        out.push((k as u32, v as f32));
        return (w, w * v, 0.0);
    }
    if !known {
        let free = if ctx.redo {
            ctx.free.binary_search(&(k as u32)).is_ok()
        } else {
            let f = ctx.tracer.cone_free(ctx.apex, ctx.nf, node.mean_direction.as_vec3().into(), node.cone_cos as f32);
            if f {
                ctx.free.push(k as u32);
            }
            f
        };
        if free {
            let w = if wholly_above { node.moment.dot(ctx.n) } else { cosine_mass(ctx.tree, k, ctx.n) };
            if w <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            out.push((k as u32, 1.0));
            return (w, w, 0.0);
        }
    }
    if !known && 0.5 * max_cos <= 4.0 * ctx.epsilon {
        // A node so close to the horizon that even a blind guess V = ½ keeps its mean |Ṽ| error within
        // ε (½ Σ Ω c ≤ ε Ω) needs no rays. The O(1) bound Σ Ω c ≤ max cos · Ω screens candidates.
        let w = if wholly_above { node.moment.dot(ctx.n) } else { cosine_mass(ctx.tree, k, ctx.n) };
        if w <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        if 0.5 * w <= ctx.epsilon * node.solid_angle {
            out.push((k as u32, 0.5));
            return (w, 0.5 * w, 0.5 * w);
        }
    }
    let known = known || node.count as usize <= ctx.trace_leaves;
    let start = out.len();
    let (wl, vl, dl) = build(ctx, node.left as usize, known, out);
    let mid = out.len();
    let (wr, vr, dr) = build(ctx, node.right as usize, known, out);
    let w = wl + wr;
    if w <= 0.0 {
        out.truncate(start);
        return (0.0, 0.0, 0.0);
    }
    let v_parent = (vl + vr) / w;
    let dev = dl + dr + (vl - wl * v_parent).abs() + (vr - wr * v_parent).abs();
    let mergeable = mid - start <= 1 && out.len() - mid <= 1;
    if mergeable && dev <= ctx.epsilon * node.solid_angle {
        out.truncate(start);
        out.push((k as u32, v_parent as f32));
    }
    (w, vl + vr, dev)
}

/// Visibility of a cell along its mean direction, traced once per vertex and cached (keyed by the
/// cell's first leaf).
fn cell_visible(ctx: &mut Ctx, node: &crate::sphere::TreeNode) -> bool {
    let leaf = node.first as usize;
    let s = &mut *ctx.scratch;
    if s.stamp[leaf] == s.generation {
        return s.visible[leaf];
    }
    let d = node.mean_direction;
    let visible = !ctx.tracer.occluded(ctx.apex, d.as_vec3().into());
    ctx.rays += 1;
    s.stamp[leaf] = s.generation;
    s.visible[leaf] = visible;
    visible
}
