//! The direction set arranged in a binary tree (the "light tree" of visibility cuts, method.md §4).
//!
//! Inputs: a [`DirectionSet`]. Outputs: nodes in depth-first pre-order (root = 0), each covering a
//! contiguous range of leaves in tree order, with its solid angle, solid-angle-weighted mean direction
//! and bounding cone; and the permutation from tree order to direction-set index.
//!
//! Build: recursive median split along the axis of largest extent of the range's directions (ties
//! broken by texel index, so the tree is deterministic). The tree is balanced: depth ⌈log2(6n²)⌉.
//!
//! Invariants: every node's solid angle is the sum of its leaves' (computed bottom-up as left + right);
//! leaves are contiguous per node, so any node's sum of a per-leaf quantity is a difference of prefix
//! sums over tree order; mean directions are unit; `cone_cos` bounds every leaf centre of the node.

use super::DirectionSet;
use glam::DVec3;

/// A sentinel for "no child".
pub const NO_CHILD: u32 = u32::MAX;

/// One node of the light tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreeNode {
    /// First leaf (in tree order) covered by the node.
    pub first: u32,
    /// Number of leaves covered.
    pub count: u32,
    /// Children (pre-order indices), or [`NO_CHILD`] for a leaf.
    pub left: u32,
    pub right: u32,
    /// Σ of the leaves' solid angles (sr).
    pub solid_angle: f64,
    /// normalize(moment): the node's mean direction.
    pub mean_direction: DVec3,
    /// Σ over the leaves of the exact texel moments ∫ ω dω: for a unit n with the node wholly above the
    /// plane, ∫_node max(ω·n, 0) dω = moment·n exactly.
    pub moment: DVec3,
    /// min over leaves of d_i · mean_direction: the node's bounding cone (of leaf centres).
    pub cone_cos: f64,
    /// sin of the cone's half-angle, √(1 − cone_cos²).
    pub cone_sin: f64,
}

impl TreeNode {
    /// True for a single-texel node.
    pub fn is_leaf(&self) -> bool {
        self.left == NO_CHILD
    }
}

/// Binary tree over a direction set.
#[derive(Debug, Clone)]
pub struct LightTree {
    nodes: Vec<TreeNode>,
    leaf_moments: Vec<DVec3>,
    leaf_corners: Vec<[DVec3; 4]>,
    leaf_texel: Vec<u32>,
    leaf_directions: Vec<DVec3>,
    leaf_solid_angles: Vec<f64>,
    depth: usize,
}

impl LightTree {
    /// Builds the tree over every direction of `set`.
    pub fn build(set: &DirectionSet) -> Self {
        let dirs = set.directions();
        let mut order: Vec<u32> = (0..dirs.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * dirs.len());
        let mut depth = 0;
        build_node(&mut nodes, &mut order, 0, set, 0, &mut depth);
        let leaf_directions = order.iter().map(|&i| dirs[i as usize]).collect();
        let leaf_solid_angles = order.iter().map(|&i| set.solid_angles()[i as usize]).collect();
        let leaf_moments = order.iter().map(|&i| set.moments()[i as usize]).collect();
        let leaf_corners = order.iter().map(|&i| set.texel_corners(i as usize)).collect();
        Self { nodes, leaf_moments, leaf_corners, leaf_texel: order, leaf_directions, leaf_solid_angles, depth }
    }

    /// All nodes, pre-order; index 0 is the root.
    pub fn nodes(&self) -> &[TreeNode] {
        &self.nodes
    }

    /// Number of leaves (= directions).
    pub fn leaf_count(&self) -> usize {
        self.leaf_texel.len()
    }

    /// Direction-set index of each leaf, in tree order.
    pub fn leaf_texels(&self) -> &[u32] {
        &self.leaf_texel
    }

    /// Leaf directions in tree order.
    pub fn leaf_directions(&self) -> &[DVec3] {
        &self.leaf_directions
    }

    /// Corner directions of each leaf's texel, tree order.
    pub fn leaf_corners(&self) -> &[[DVec3; 4]] {
        &self.leaf_corners
    }

    /// Exact leaf moments ∫ ω dω in tree order.
    pub fn leaf_moments(&self) -> &[DVec3] {
        &self.leaf_moments
    }

    /// Leaf solid angles in tree order.
    pub fn leaf_solid_angles(&self) -> &[f64] {
        &self.leaf_solid_angles
    }

    /// Maximum depth (root = 0).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The partition of the sphere into the largest nodes whose leaf-centre cone half-angle is at most
    /// `max_half_angle` (radians; leaves always qualify), in leaf order.
    pub fn partition(&self, max_half_angle: f64) -> Partition {
        let mut ranges = Vec::new();
        let mut stack = vec![0usize];
        // Depth-first, left before right: the ranges come out in leaf order.
        while let Some(k) = stack.pop() {
            let node = self.nodes[k];
            if node.is_leaf() || node.cone_cos.clamp(-1.0, 1.0).acos() <= max_half_angle {
                ranges.push((node.first, node.first + node.count));
            } else {
                stack.push(node.right as usize);
                stack.push(node.left as usize);
            }
        }
        let cones = ranges
            .iter()
            .map(|&(a, z)| {
                let axis = self.leaf_moments[a as usize..z as usize].iter().copied().sum::<DVec3>().try_normalize().unwrap_or(DVec3::Z);
                let cos = self.leaf_corners[a as usize..z as usize].iter().flatten().map(|d| d.dot(axis)).fold(1.0f64, f64::min);
                PartitionCone { axis, cos, sin: (1.0 - cos * cos).max(0.0).sqrt() }
            })
            .collect();
        Partition { ranges, cones }
    }

    /// True when every leaf of [a, z) lies wholly on the positive side of the plane with normal `n`:
    /// checked first against `cone` (which bounds every leaf corner of a partition node holding the
    /// range), then corner by corner.
    #[inline]
    pub fn wholly_above(&self, a: usize, z: usize, n: DVec3, cone: &PartitionCone) -> bool {
        let cb = cone.axis.dot(n);
        let sb = (1.0 - cb * cb).max(0.0).sqrt();
        // Every direction of the cone is above the plane when the cone's lowest edge is.
        (cb * cone.cos - sb * cone.sin > 0.0 && sb * cone.cos + cb * cone.sin > 0.0)
            || self.leaf_corners[a..z].iter().all(|c| c.iter().all(|d| d.dot(n) >= 0.0))
    }

    /// ∫ max(ω·n, 0) dω over leaf i, exact (the texel moment when the texel is wholly above the plane,
    /// else the texel clipped to it).
    #[inline]
    pub fn leaf_cosine_integral(&self, i: usize, n: DVec3) -> f64 {
        let corners = &self.leaf_corners[i];
        if corners.iter().all(|d| d.dot(n) >= 0.0) {
            self.leaf_moments[i].dot(n)
        } else {
            super::direction_set::clipped_cosine_integral(corners, n)
        }
    }
}

/// Nodes of the tree no wider than a given angle, covering every leaf once (see [`LightTree::partition`]).
#[derive(Debug, Clone, Default)]
pub struct Partition {
    /// Leaf ranges [first, end), in leaf order.
    pub ranges: Vec<(u32, u32)>,
    /// Per range, a cone holding every corner of its leaves.
    pub cones: Vec<PartitionCone>,
}

/// A cone (axis, cos and sin of the half-angle) bounding a set of directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartitionCone {
    pub axis: DVec3,
    pub cos: f64,
    pub sin: f64,
}

fn build_node(nodes: &mut Vec<TreeNode>, order: &mut [u32], first: usize, set: &DirectionSet, level: usize, depth: &mut usize) -> u32 {
    let (dirs, omegas, moments) = (set.directions(), set.solid_angles(), set.moments());
    *depth = (*depth).max(level);
    let index = nodes.len();
    nodes.push(TreeNode {
        first: first as u32,
        count: order.len() as u32,
        left: NO_CHILD,
        right: NO_CHILD,
        solid_angle: 0.0,
        mean_direction: DVec3::Z,
        moment: DVec3::ZERO,
        cone_cos: 1.0,
        cone_sin: 0.0,
    });
    if order.len() == 1 {
        let i = order[0] as usize;
        nodes[index].solid_angle = omegas[i];
        nodes[index].mean_direction = dirs[i];
        nodes[index].moment = moments[i];
        return index as u32;
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for &i in order.iter() {
        lo = lo.min(dirs[i as usize]);
        hi = hi.max(dirs[i as usize]);
    }
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        dirs[a as usize][axis].total_cmp(&dirs[b as usize][axis]).then(a.cmp(&b))
    });
    let (left_part, right_part) = order.split_at_mut(mid);
    let left = build_node(nodes, left_part, first, set, level + 1, depth);
    let right = build_node(nodes, right_part, first + mid, set, level + 1, depth);
    let (l, r) = (nodes[left as usize], nodes[right as usize]);
    let solid_angle = l.solid_angle + r.solid_angle;
    let moment = l.moment + r.moment;
    let mean_direction = moment.try_normalize().unwrap_or(l.mean_direction);
    let cone_cos = order
        .iter()
        .map(|&i| dirs[i as usize].dot(mean_direction))
        .fold(1.0f64, f64::min);
    let node = &mut nodes[index];
    node.left = left;
    node.right = right;
    node.solid_angle = solid_angle;
    node.mean_direction = mean_direction;
    node.moment = moment;
    node.cone_cos = cone_cos;
    node.cone_sin = (1.0 - cone_cos * cone_cos).max(0.0).sqrt();
    index as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::compensated_sum;

    #[test]
    fn node_solid_angles_are_sums_of_their_leaves() {
        for n in [1, 3, 8, 32] {
            let set = DirectionSet::cube(n).unwrap();
            let tree = LightTree::build(&set);
            assert_eq!(tree.nodes().len(), 2 * set.len() - 1);
            let root = tree.nodes()[0];
            assert_eq!(root.count as usize, set.len());
            assert!((root.solid_angle - 4.0 * std::f64::consts::PI).abs() < 1e-12);
            for node in tree.nodes() {
                let range = node.first as usize..(node.first + node.count) as usize;
                let direct = compensated_sum(range.clone().map(|k| set.solid_angles()[tree.leaf_texels()[k] as usize]));
                assert!((node.solid_angle - direct).abs() <= 1e-14 * direct.max(1.0), "n={n}");
                assert!((node.mean_direction.length() - 1.0).abs() < 1e-12);
                let moment: DVec3 = range.clone().map(|k| set.moments()[tree.leaf_texels()[k] as usize]).sum();
                assert!((moment - node.moment).length() < 1e-13);
                for k in range {
                    assert!(tree.leaf_directions()[k].dot(node.mean_direction) >= node.cone_cos - 1e-15);
                }
                if !node.is_leaf() {
                    let (l, r) = (tree.nodes()[node.left as usize], tree.nodes()[node.right as usize]);
                    assert_eq!(l.first, node.first);
                    assert_eq!(l.count + r.count, node.count);
                    assert_eq!(r.first, node.first + l.count);
                }
            }
            // The leaf order is a permutation of the texels.
            let mut seen = vec![false; set.len()];
            for &t in tree.leaf_texels() {
                assert!(!seen[t as usize]);
                seen[t as usize] = true;
            }
            // Balanced.
            let max_depth = (set.len() as f64).log2().ceil() as usize;
            assert!(tree.depth() <= max_depth, "depth {} > {max_depth}", tree.depth());
        }
    }

    #[test]
    fn build_is_deterministic() {
        let set = DirectionSet::cube(16).unwrap();
        let a = LightTree::build(&set);
        let b = LightTree::build(&set);
        assert_eq!(a.leaf_texels(), b.leaf_texels());
        assert_eq!(a.nodes(), b.nodes());
    }
}
