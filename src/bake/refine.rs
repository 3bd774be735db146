//! Adaptive refinement of the baked mesh (decision (e)): visibility is sampled at vertices and
//! interpolated across triangles, so a shadow edge that falls between two vertices is smeared over
//! the triangles between them. Where the visibility of an edge's two ends differs, the edge is
//! split at its midpoint (conformingly, [`split_edges`]) and the new vertex is traced; up to
//! `rounds` times.
//!
//! The criterion is light-aware but rotation-invariant (the user turns the light about +Y): per
//! leaf direction ℓ a weight r_ℓ = the brightest luminance the environment has at ℓ's elevation
//! (over all azimuths, i.e. over every rotation), and per edge (a, b) with mean normal n̄
//!   D(a, b) = Σ_ℓ |V_a(ℓ) − V_b(ℓ)| r_ℓ Ω_ℓ max(d_ℓ·n̄, 0) / Σ_ℓ r_ℓ Ω_ℓ max(d_ℓ·n̄, 0),
//! the fraction of the (rotation-worst) irradiance whose visibility differs between the ends, with
//! V(ℓ) read from each end's cut (V_k of the cut node holding ℓ, 0 below the horizon). Both cuts
//! are leaf ranges in leaf order, so D costs one merge of the two cuts (prefix sums of r Ω d over
//! leaf order). An edge is split while D > `threshold` and it is longer than `min_edge` × the
//! bounding-box diagonal (which keeps dense meshes, whose vertices already resolve their shadows,
//! from growing).
//!
//! Inputs: the base mesh, its vertices' cuts, the light tree, the per-leaf weights. Outputs: a
//! [`Refinement`] (new vertices as parent edges, and the refined triangle list), which
//! [`Refinement::apply`] replays on the base mesh. Invariants: the surface does not change
//! (midpoints lie on the flat triangles); the first V vertices are the base mesh's, in order;
//! deterministic; no IO.

use crate::scene::{Mesh, split_edges};
use crate::sphere::LightTree;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Knobs of the refinement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RefineSettings {
    /// Rounds of splitting (0: off). Each round at most halves the longest edges.
    pub rounds: u32,
    /// Split an edge while its ends' visibility differs by more than this fraction D of the
    /// irradiance.
    pub threshold: f64,
    /// Never split an edge shorter than this fraction of the bounding-box diagonal.
    pub min_edge: f64,
    /// Vertex sampling (decision (f), [`super::sparse`]): a vertex whose edges are all shorter than
    /// `min_edge` and whose traced neighbours agree within `threshold` is interpolated from them
    /// instead of traced.
    #[serde(default = "interpolate_default")]
    pub interpolate: bool,
    /// Vertex sampling's reach for taking cells ([`super::sparse`] rules 4 and 5), a fraction of
    /// the bounding-box diagonal: a traced vertex whose edges are all at most this long takes
    /// every visibility cell that its traced neighbours (or the level above's, each within this
    /// distance) know alike, instead of casting its own rays there. Interpolation (rule 2) keeps
    /// `min_edge`.
    #[serde(default = "take_reach_default")]
    pub take_reach: f64,
}

fn interpolate_default() -> bool {
    true
}

fn take_reach_default() -> f64 {
    RefineSettings::default().take_reach
}

impl Default for RefineSettings {
    fn default() -> Self {
        Self {
            rounds: 3,
            threshold: 0.02,
            min_edge: 1.0 / 128.0,
            interpolate: true,
            take_reach: 1.0 / 128.0,
        }
    }
}

/// How a refined mesh is made from the base mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Refinement {
    /// Vertex V + k is the midpoint of the edge `parents[k]` (indices < V + k).
    pub parents: Vec<[u32; 2]>,
    /// The refined mesh's triangles (empty when nothing was split: the base triangles stand).
    pub triangles: Vec<[u32; 3]>,
}

/// Why a refinement cannot be replayed on a mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RefineError {
    #[error("refinement vertex {index} has parent {parent}, which does not exist yet")]
    Parent { index: usize, parent: u32 },
    #[error("refined triangle {index} uses vertex {vertex} of {count}")]
    Triangle {
        index: usize,
        vertex: u32,
        count: usize,
    },
}

impl Refinement {
    /// True when nothing was split.
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// The refined mesh: the base vertices, the midpoints in order, the refined triangles.
    pub fn apply(&self, base: &Mesh) -> Result<Mesh, RefineError> {
        let mut mesh = base.clone();
        if self.is_empty() {
            return Ok(mesh);
        }
        mesh.positions.reserve(self.parents.len());
        for (k, &[a, b]) in self.parents.iter().enumerate() {
            let count = mesh.positions.len() as u32;
            if let Some(&parent) = [a, b].iter().find(|&&p| p >= count) {
                return Err(RefineError::Parent {
                    index: base.positions.len() + k,
                    parent,
                });
            }
            crate::scene::push_midpoint(&mut mesh, a, b);
        }
        let count = mesh.positions.len();
        for (index, t) in self.triangles.iter().enumerate() {
            if let Some(&vertex) = t.iter().find(|&&v| v as usize >= count) {
                return Err(RefineError::Triangle {
                    index,
                    vertex,
                    count,
                });
            }
        }
        mesh.triangles = self.triangles.clone();
        Ok(mesh)
    }
}

/// Each midpoint of `parents` (vertex `base_count + k` halves edge `parents[k]`) as a blend of base
/// vertices, (vertex, weight) with weights summing to 1: where it lies on the imported mesh, whose
/// smooth surface ([`crate::scene::smooth_surface_point`]) its rays start from. A midpoint lies on
/// one base triangle, so a blend has at most three vertices on a conforming refinement.
pub fn base_blends(base_count: usize, parents: &[[u32; 2]]) -> Vec<Vec<(u32, f64)>> {
    let mut blends: Vec<Vec<(u32, f64)>> = Vec::with_capacity(parents.len());
    for &[a, b] in parents {
        push_midpoint_blend(&mut blends, base_count, a, b);
    }
    blends
}

/// Vertex v as a blend of base vertices ([`base_blends`], those made so far in `blends`).
pub fn blend_of(blends: &[Vec<(u32, f64)>], base_count: usize, v: u32) -> Vec<(u32, f64)> {
    match (v as usize).checked_sub(base_count) {
        None => vec![(v, 1.0)],
        Some(k) => blends.get(k).cloned().unwrap_or_default(),
    }
}

/// Appends to `blends` the blend of the midpoint of edge (a, b) ([`base_blends`]).
pub fn push_midpoint_blend(blends: &mut Vec<Vec<(u32, f64)>>, base_count: usize, a: u32, b: u32) {
    let mut blend = blend_of(blends, base_count, a);
    for (v, w) in blend_of(blends, base_count, b) {
        match blend.iter_mut().find(|(u, _)| *u == v) {
            Some(entry) => entry.1 += w,
            None => blend.push((v, w)),
        }
    }
    blend.iter_mut().for_each(|e| e.1 *= 0.5);
    blends.push(blend);
}

/// Per leaf (tree order), r_ℓ Ω_ℓ d_ℓ as prefix sums (length L + 1): r_ℓ is the largest luminance
/// of `leaf_radiance` (mean radiance per leaf, tree order, at any rotation) among leaves within
/// about a leaf's size of ℓ's elevation — the brightest light that some rotation about +Y brings to
/// ℓ.
pub fn ring_weight_prefix(tree: &LightTree, leaf_radiance: &[[f64; 3]]) -> Vec<DVec3> {
    let dirs = tree.leaf_directions();
    let n = dirs.len().max(1);
    // Bins of elevation about as wide as a leaf: 6n² leaves of ~(π/2n)² sr.
    let leaf_angle = (4.0 * std::f64::consts::PI / n as f64).sqrt();
    let bins = ((std::f64::consts::PI / leaf_angle).ceil() as usize).max(1);
    let bin_of = |d: &DVec3| {
        (((d.y.clamp(-1.0, 1.0).asin() / std::f64::consts::PI + 0.5) * bins as f64) as usize)
            .min(bins - 1)
    };
    let mut bin_max = vec![0.0f64; bins];
    for (d, l) in dirs.iter().zip(leaf_radiance) {
        let y = 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2];
        let b = bin_of(d);
        bin_max[b] = bin_max[b].max(y.max(0.0));
    }
    let mut prefix = Vec::with_capacity(dirs.len() + 1);
    let mut sum = DVec3::ZERO;
    prefix.push(sum);
    for (d, m) in dirs.iter().zip(tree.leaf_moments()) {
        let b = bin_of(d);
        let r = bin_max[b.saturating_sub(1)..(b + 2).min(bins)]
            .iter()
            .fold(0.0f64, |a, &x| a.max(x));
        sum += *m * r;
        prefix.push(sum);
    }
    prefix
}

/// The rotation-worst light of a map as the bake weighs visibility by it: the prefix sums of
/// [`ring_weight_prefix`] and their hemisphere totals per normal (empty where nothing is traced).
#[derive(Debug, Clone, Default)]
pub struct RingLight {
    pub prefix: Vec<DVec3>,
    pub totals: HemisphereTotals,
}

impl RingLight {
    /// From the mean radiance per leaf (tree order) at any rotation.
    pub fn new(tree: &LightTree, leaf_radiance: &[[f64; 3]]) -> Self {
        let prefix = ring_weight_prefix(tree, leaf_radiance);
        let totals = HemisphereTotals::new(tree, &prefix);
        Self { prefix, totals }
    }

    /// The boundary refinement's gate at a vertex of unit normal `n`.
    pub fn gate(&self, n: DVec3) -> super::cuts::LightGate<'_> {
        super::cuts::LightGate {
            prefix: &self.prefix,
            total: self.totals.at(n),
        }
    }
}

/// The weight Σ max(r Ω d·n, 0) of the whole hemisphere about a normal n, per n. The weights r
/// depend on the elevation only (the rotation-worst light, [`ring_weight_prefix`]),
/// so the total depends on n·Y only: tabulated at [`HemisphereTotals::SAMPLES`] values,
/// interpolated linearly.
#[derive(Debug, Clone, Default)]
pub struct HemisphereTotals {
    table: Vec<f64>,
}

impl HemisphereTotals {
    /// Table points over n·Y ∈ [−1, 1].
    pub const SAMPLES: usize = 129;

    pub fn new(tree: &LightTree, prefix: &[DVec3]) -> Self {
        let table = (0..Self::SAMPLES)
            .map(|i| {
                let y = -1.0 + 2.0 * i as f64 / (Self::SAMPLES - 1) as f64;
                let n = DVec3::new((1.0 - y * y).max(0.0).sqrt(), y, 0.0);
                hemisphere_weight(tree, prefix, 0, 0, tree.leaf_count() as u32, n)
            })
            .collect();
        Self { table }
    }

    /// The total for unit normal `n` (0 for an empty table).
    pub fn at(&self, n: DVec3) -> f64 {
        if self.table.len() < 2 {
            return 0.0;
        }
        let x = (n.y.clamp(-1.0, 1.0) + 1.0) * 0.5 * (self.table.len() - 1) as f64;
        let i = (x as usize).min(self.table.len() - 2);
        let f = x - i as f64;
        self.table[i] * (1.0 - f) + self.table[i + 1] * f
    }
}

/// Σ max(r Ω d·n, 0) over the leaves of node `k` within [lo, hi) (prefix sums of r Ω d in `prefix`;
/// empty: 0): O(1) per node wholly above the horizon, recursing only where the horizon cuts
/// through.
pub fn hemisphere_weight(
    tree: &LightTree,
    prefix: &[DVec3],
    k: u32,
    lo: u32,
    hi: u32,
    normal: DVec3,
) -> f64 {
    if prefix.len() <= tree.leaf_count() {
        return 0.0;
    }
    let node = tree.nodes()[k as usize];
    let (first, end) = (node.first.max(lo), (node.first + node.count).min(hi));
    if end <= first {
        return 0.0;
    }
    let (up, wholly_above) = node.above(normal);
    if !up {
        return 0.0;
    }
    if wholly_above || node.is_leaf() {
        return (prefix[end as usize] - prefix[first as usize])
            .dot(normal)
            .max(0.0);
    }
    hemisphere_weight(tree, prefix, node.left, lo, hi, normal)
        + hemisphere_weight(tree, prefix, node.right, lo, hi, normal)
}

/// D(a, b) of the module docs: the weighted fraction of directions whose visibility differs between
/// two cuts ((node, V) in pre-order), for the mean normal `n`. 0 when neither end sees any weight.
pub fn visibility_difference(
    tree: &LightTree,
    prefix: &[DVec3],
    a: &[(u32, f32)],
    b: &[(u32, f32)],
    n: DVec3,
) -> f64 {
    let nodes = tree.nodes();
    let range = |c: &[(u32, f32)], i: usize| -> Option<(u32, u32, f32)> {
        c.get(i).and_then(|&(k, v)| {
            nodes
                .get(k as usize)
                .map(|node| (node.first, node.first + node.count, v))
        })
    };
    let weight = |s: u32, e: u32| -> f64 {
        match (prefix.get(s as usize), prefix.get(e as usize)) {
            (Some(&p), Some(&q)) => (q - p).dot(n).max(0.0),
            _ => 0.0,
        }
    };
    let (mut i, mut j) = (0usize, 0usize);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    // Sweep the leaf order: at each step, the next boundary of either cut ends the current
    // interval.
    let mut x = 0u32;
    loop {
        let (ra, rb) = (range(a, i), range(b, j));
        if ra.is_none() && rb.is_none() {
            break;
        }
        // Skip ranges that end at or before x.
        if ra.is_some_and(|r| r.1 <= x) {
            i += 1;
            continue;
        }
        if rb.is_some_and(|r| r.1 <= x) {
            j += 1;
            continue;
        }
        // The next interval starts at x, or at the next range start if both are ahead.
        let start = [ra, rb]
            .iter()
            .flatten()
            .map(|r| r.0.max(x))
            .min()
            .unwrap_or(x);
        let va = ra.filter(|r| r.0 <= start).map_or(0.0, |r| r.2);
        let vb = rb.filter(|r| r.0 <= start).map_or(0.0, |r| r.2);
        // It ends at the nearest boundary after `start`.
        let end = [ra, rb]
            .iter()
            .flatten()
            .flat_map(|r| [r.0, r.1])
            .filter(|&p| p > start)
            .min()
            .unwrap_or(start);
        if end <= start {
            break;
        }
        let w = weight(start, end);
        num += (va - vb).abs() as f64 * w;
        den += w;
        x = end;
    }
    if den > 0.0 { num / den } else { 0.0 }
}

/// Edges (min, max) of `mesh` longer than `min_length`, sorted, each once.
pub fn long_edges(mesh: &Mesh, min_length: f32) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .filter(|&(a, b)| {
            match (
                mesh.positions.get(a as usize),
                mesh.positions.get(b as usize),
            ) {
                (Some(p), Some(q)) => (*p - *q).length() > min_length,
                _ => false,
            }
        })
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Splits every edge in `marked` (sorted (min, max) pairs) and returns the new vertices' parents.
pub fn split_marked(mesh: &mut Mesh, marked: &[(u32, u32)]) -> Vec<[u32; 2]> {
    split_edges(mesh, &|a, b| marked.binary_search(&(a, b)).is_ok())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::DirectionSet;

    fn tree() -> LightTree {
        LightTree::build(&DirectionSet::cube(8).unwrap())
    }

    /// Brute force: V per leaf from each cut, weights per leaf.
    fn brute(tree: &LightTree, r: &[f64], a: &[(u32, f32)], b: &[(u32, f32)], n: DVec3) -> f64 {
        let per_leaf = |c: &[(u32, f32)]| {
            let mut v = vec![0.0f64; tree.leaf_count()];
            for &(k, x) in c {
                let node = tree.nodes()[k as usize];
                for l in node.first..node.first + node.count {
                    v[l as usize] = x as f64;
                }
            }
            v
        };
        let (va, vb) = (per_leaf(a), per_leaf(b));
        let (mut num, mut den) = (0.0, 0.0);
        // The prefix uses exact texel moments, so a leaf's weight is r Ω max(moment·n, 0) summed
        // per interval; per leaf the same holds wherever the leaf lies wholly above the plane.
        for l in 0..tree.leaf_count() {
            if va[l] == 0.0 && vb[l] == 0.0 {
                continue;
            }
            let w = (tree.leaf_moments()[l] * r[l]).dot(n).max(0.0);
            num += (va[l] - vb[l]).abs() * w;
            den += w;
        }
        num / den
    }

    #[test]
    fn the_difference_of_two_cuts_matches_a_per_leaf_sum() {
        let tree = tree();
        let leaves = tree.leaf_count();
        let radiance: Vec<[f64; 3]> = (0..leaves)
            .map(|l| [1.0 + (l % 7) as f64, 1.0, 0.5])
            .collect();
        let prefix = ring_weight_prefix(&tree, &radiance);
        let r: Vec<f64> = (0..leaves)
            .map(|l| (prefix[l + 1] - prefix[l]).length() / tree.leaf_moments()[l].length())
            .collect();
        // Two cuts over the upper hemisphere of +Z at different depths: every leaf above is in one
        // node.
        let n = DVec3::Z;
        let cut = |depth_bias: u32, seed: u32| -> Vec<(u32, f32)> {
            let mut out = Vec::new();
            let mut stack = vec![0u32];
            while let Some(k) = stack.pop() {
                let node = tree.nodes()[k as usize];
                let above = (node.first..node.first + node.count)
                    .any(|l| tree.leaf_directions()[l as usize].dot(n) > 0.0);
                if !above {
                    continue;
                }
                if node.is_leaf()
                    || (node.count <= 8 << depth_bias && !(k + seed).is_multiple_of(3))
                {
                    out.push((k, ((k * 37 + seed) % 11) as f32 / 10.0));
                } else {
                    stack.push(node.right);
                    stack.push(node.left);
                }
            }
            out
        };
        let (a, b) = (cut(0, 1), cut(2, 5));
        let got = visibility_difference(&tree, &prefix, &a, &b, n);
        let want = brute(&tree, &r, &a, &b, n);
        assert!(got > 0.05, "the cuts differ: {got}");
        // Intervals that straddle the horizon are weighted by their clamped moment, leaves by
        // theirs: they agree to the weight of the few leaves the plane cuts.
        assert!((got - want).abs() < 0.02, "merge {got} vs per-leaf {want}");
        assert_eq!(visibility_difference(&tree, &prefix, &a, &a, n), 0.0);
        assert!(
            (visibility_difference(&tree, &prefix, &a, &b, n)
                - visibility_difference(&tree, &prefix, &b, &a, n))
            .abs()
                < 1e-12
        );
        // A fully visible against a fully hidden hemisphere differs everywhere.
        let all: Vec<(u32, f32)> = a.iter().map(|&(k, _)| (k, 1.0)).collect();
        let none: Vec<(u32, f32)> = a.iter().map(|&(k, _)| (k, 0.0)).collect();
        assert!((visibility_difference(&tree, &prefix, &all, &none, n) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn ring_weights_spread_a_light_over_its_elevation() {
        let tree = tree();
        let dirs = tree.leaf_directions();
        // One bright leaf at elevation ~30°: every leaf near that elevation gets its radiance.
        let bright = dirs.iter().position(|d| (d.y - 0.5).abs() < 0.05).unwrap();
        let radiance: Vec<[f64; 3]> = (0..dirs.len())
            .map(|l| if l == bright { [100.0; 3] } else { [1.0; 3] })
            .collect();
        let prefix = ring_weight_prefix(&tree, &radiance);
        let r = |l: usize| (prefix[l + 1] - prefix[l]).length() / tree.leaf_moments()[l].length();
        for l in 0..dirs.len() {
            let dy = (dirs[l].y.asin() - 0.5f64.asin()).abs();
            if dy < 0.02 {
                assert!(
                    (r(l) - 100.0).abs() < 1e-9,
                    "leaf {l} at the light's elevation: {}",
                    r(l)
                );
            }
            if dy > 0.6 {
                assert!((r(l) - 1.0).abs() < 1e-9, "leaf {l} far from it: {}", r(l));
            }
        }
    }

    #[test]
    fn a_refinement_replays_onto_the_base_mesh() {
        let (mesh, _) = crate::raster::tests::unit_quad_scene();
        let mut refined = mesh.clone();
        let edges = long_edges(&refined, 0.0);
        let marked = vec![edges[0]];
        let parents = split_marked(&mut refined, &marked);
        assert_eq!(parents.len(), 1);
        let r = Refinement {
            parents,
            triangles: refined.triangles.clone(),
        };
        assert_eq!(r.apply(&mesh).unwrap(), refined);
        let bad = Refinement {
            parents: vec![[0, 99]],
            triangles: vec![],
        };
        assert!(matches!(bad.apply(&mesh), Err(RefineError::Parent { .. })));
        let bad = Refinement {
            parents: vec![[0, 1]],
            triangles: vec![[0, 1, 5]],
        };
        assert!(matches!(
            bad.apply(&mesh),
            Err(RefineError::Triangle { .. })
        ));
    }
}
