//! Runs: walking up to three vertex cuts together with a partition of the light tree's leaves — the
//! loop the transfer (per pixel) and the PRT renderer (per shading point) share.
//!
//! Inputs: per vertex its cut as leaf ranges ([`Span`], from [`Cuts::spans`]) and a weight (the
//! barycentric), the partition's leaf ranges. Output: a callback for each maximal run [a, z) of
//! leaves on which every cut node and the partition node are constant, with V = Σ wᵢ Vᵢ and the
//! partition node's index; runs with V ≤ 0 (occluded, or below every horizon) are skipped.
//!
//! Invariants: spans are disjoint and in leaf order (cut nodes are stored in pre-order); each call
//! is O(runs); no IO.

use super::Cuts;
use crate::sphere::LightTree;

/// A cut node as the leaf range [first, end) it covers, with its V.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub first: u32,
    pub end: u32,
    pub v: f32,
}

impl Cuts {
    /// Vertex v's cut as leaf ranges, in leaf order.
    pub fn spans<'a>(&'a self, v: usize, tree: &'a LightTree) -> impl Iterator<Item = Span> + 'a {
        self.cut(v).map(move |(k, vis)| {
            let node = tree.nodes()[k as usize];
            Span {
                first: node.first,
                end: node.first + node.count,
                v: vis,
            }
        })
    }
}

/// Calls `f(a, z, vis, partition_index)` for every run of leaves [a, z) with vis > 0, in leaf
/// order. `lists` and `weights` pair up (at most three are used); `partition` covers [0, leaves) in
/// order.
///
/// Two levels: the cuts are merged into segments on which every cut node is constant (cut nodes are
/// much wider than partition nodes), and each segment with vis > 0 is cut at the partition's
/// boundaries in a loop of its own; gaps (vis = 0) are skipped by a binary search of the partition.
#[inline]
pub fn for_each_run(
    lists: &[&[Span]],
    weights: &[f64],
    partition: &[(u32, u32)],
    leaves: u32,
    mut f: impl FnMut(usize, usize, f64, usize),
) {
    let n = lists.len().min(weights.len()).min(3);
    let mut idx = [0usize; 3];
    let (mut pos, mut si) = (0u32, 0usize);
    let end = leaves.min(partition.last().map_or(0, |p| p.1));
    while pos < end {
        let mut next = end;
        let mut vis = 0.0f64;
        for c in 0..n {
            let list = lists[c];
            while idx[c] < list.len() && list[idx[c]].end <= pos {
                idx[c] += 1;
            }
            if let Some(sp) = list.get(idx[c]) {
                if sp.first <= pos {
                    vis += weights[c] * sp.v as f64;
                    next = next.min(sp.end);
                } else {
                    next = next.min(sp.first);
                }
            }
        }
        if vis > 0.0 {
            // The partition node holding pos: usually the next one, else a search.
            if partition[si].1 <= pos {
                si += 1;
                if partition[si].1 <= pos {
                    si += partition[si..].partition_point(|p| p.1 <= pos);
                }
            }
            let mut a = pos;
            loop {
                let part_end = partition[si].1;
                if part_end >= next {
                    f(a as usize, next as usize, vis, si);
                    break;
                }
                f(a as usize, part_end as usize, vis, si);
                a = part_end;
                si += 1;
            }
        }
        pos = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_split_at_every_boundary_and_blend_visibility() {
        let a = [
            Span {
                first: 0,
                end: 4,
                v: 1.0,
            },
            Span {
                first: 6,
                end: 8,
                v: 0.5,
            },
        ];
        let b = [Span {
            first: 2,
            end: 8,
            v: 0.25,
        }];
        let partition = [(0, 3), (3, 8)];
        let mut runs = Vec::new();
        for_each_run(&[&a, &b], &[0.5, 0.5], &partition, 8, |a, z, v, si| {
            runs.push((a, z, v, si))
        });
        // [0,2): a only; [2,3) and [3,4): both, split by the partition; [4,6): b only; [6,8): both.
        assert_eq!(
            runs,
            vec![
                (0, 2, 0.5, 0),
                (2, 3, 0.625, 0),
                (3, 4, 0.625, 1),
                (4, 6, 0.125, 1),
                (6, 8, 0.375, 1)
            ]
        );
    }
}
