//! Light sums: the environment's radiance integrated over the light tree's leaves and nodes, for any
//! rotation of the environment about +Y (method.md §4: L_k, the mean radiance over node k).
//!
//! Inputs: an [`EnvMap`], the [`DirectionSet`] and its [`LightTree`], a rotation (radians). Outputs:
//! per leaf (tree order) the mean radiance over its texel, and prefix sums over tree order of Ω·L, Ω and
//! Ω·d, so the radiance, solid angle and mean direction of any node — or of any run of consecutive
//! leaves — cost O(1).
//!
//! Each texel's mean radiance is integrated by supersampling it on a k×k grid weighted by the exact
//! cube-face Jacobian, k chosen so the samples are about half an environment texel apart (bilinear
//! lookups): the energy of a sun smaller than a texel lands in the texel that contains it.
//!
//! Rotating the environment by θ is the same as rotating every direction by −θ before the lookup
//! (`EnvMap::lookup` does this), so a new rotation costs one pass over the samples and needs no new
//! visibility. Invariants: all sums in f64; radiance ≥ 0; no IO.

use crate::env::EnvMap;
use crate::sphere::{DirectionSet, LightTree, TreeNode};
use glam::DVec3;
use rayon::prelude::*;

/// Prefix sums over the tree's leaf order.
#[derive(Debug, Clone)]
pub struct LightSums {
    rotation_rad: f64,
    /// Mean radiance of each leaf (tree order).
    leaf_radiance: Vec<[f64; 3]>,
    /// prefix_power[i] = Σ_{l<i} Ω_l L_l.
    prefix_power: Vec<[f64; 3]>,
    /// prefix_omega[i] = Σ_{l<i} Ω_l.
    prefix_omega: Vec<f64>,
    /// prefix_moment[i] = Σ_{l<i} ∫_l ω dω (exact texel moments).
    prefix_moment: Vec<DVec3>,
}

/// Sub-samples per environment texel side, chosen so that every direction-set texel receives at least
/// ~256 of them (the ratio estimator's aliasing at texel borders shrinks with their number).
pub fn subsamples_per_env_texel(set: &DirectionSet, env: &EnvMap) -> usize {
    let env_texel = 2.0 * std::f64::consts::PI / env.width().max(1) as f64;
    ((16.0 * env_texel / set.texel_angle()).ceil() as usize).clamp(1, 4)
}

/// Mean radiance of every texel of `set` (texel order) under `env` rotated by `rotation_rad`.
///
/// Every environment texel is split into m×m sub-samples (each with its exact share of the texel's solid
/// angle), and each sub-sample is binned into the direction-set texel that contains its rotated
/// direction. Radiance is split at τ = 16 × the map's mean (per channel) into a base min(L, τ) and an
/// excess max(L − τ, 0):
///   L_texel = Σ_s Ω_s min(L_s, τ) / Σ_s Ω_s  +  Σ_s Ω_s max(L_s − τ, 0) / Ω_texel.
/// The base goes through a ratio estimator, so a uniform environment gives exactly its value in every
/// texel (the white furnace) and smooth maps carry no binning noise; the excess — suns and other
/// spikes — is binned as power over the exact texel solid angle, so its energy is conserved exactly and
/// lands in the texel that contains it. (The ratio estimator alone would scale a spike by the ±1-4 %
/// noise of its solid-angle estimate; power binning alone would put that noise on smooth regions.)
/// A texel that receives no sub-sample (only when the direction set is much finer than the map) takes
/// a bilinear lookup at its centre.
pub fn texel_radiance(env: &EnvMap, set: &DirectionSet, rotation_rad: f64) -> Vec<[f64; 3]> {
    let (w, h) = (env.width(), env.height());
    let m = subsamples_per_env_texel(set, env);
    let dphi = 2.0 * std::f64::consts::PI / (w * m) as f64;
    let mean = env.stats().mean_radiance;
    let tau = [16.0 * mean[0], 16.0 * mean[1], 16.0 * mean[2]];
    type Acc = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<f64>);
    let partial: Vec<Acc> = (0..h)
        .into_par_iter()
        .fold(
            || (vec![[0.0f64; 3]; set.len()], vec![[0.0f64; 3]; set.len()], vec![0.0f64; set.len()]),
            |(mut base, mut excess, mut omega), row| {
                for sub_row in 0..m {
                    let v0 = (row as f64 + sub_row as f64 / m as f64) / h as f64;
                    let v1 = (row as f64 + (sub_row + 1) as f64 / m as f64) / h as f64;
                    let (t0, t1) = (std::f64::consts::PI * v0, std::f64::consts::PI * v1);
                    let sub_omega = dphi * (t0.cos() - t1.cos());
                    let vc = 0.5 * (v0 + v1);
                    for col in 0..w {
                        let l = env.texel(col, row).unwrap_or([0.0; 3]);
                        for sub_col in 0..m {
                            let u = (col as f64 + (sub_col as f64 + 0.5) / m as f64) / w as f64;
                            let d = crate::env::rotate_y(crate::env::uv_to_direction(u, vc), rotation_rad);
                            let t = set.texel_of(d);
                            for c in 0..3 {
                                let v = l[c] as f64;
                                base[t][c] += sub_omega * v.min(tau[c]);
                                excess[t][c] += sub_omega * (v - tau[c]).max(0.0);
                            }
                            omega[t] += sub_omega;
                        }
                    }
                }
                (base, excess, omega)
            },
        )
        .collect();
    let mut base = vec![[0.0f64; 3]; set.len()];
    let mut excess = vec![[0.0f64; 3]; set.len()];
    let mut omega = vec![0.0f64; set.len()];
    for (b, e, o) in partial {
        for t in 0..set.len() {
            for c in 0..3 {
                base[t][c] += b[t][c];
                excess[t][c] += e[t][c];
            }
            omega[t] += o[t];
        }
    }
    (0..set.len())
        .map(|t| {
            if omega[t] > 0.0 {
                let exact = set.solid_angles()[t];
                std::array::from_fn(|c| base[t][c] / omega[t] + excess[t][c] / exact)
            } else {
                env.lookup(set.directions()[t], rotation_rad)
            }
        })
        .collect()
}

impl LightSums {
    /// Integrates `env` (rotated by `rotation_rad` about +Y) over every leaf of `tree`.
    pub fn new(env: &EnvMap, set: &DirectionSet, tree: &LightTree, rotation_rad: f64) -> Self {
        let per_texel = texel_radiance(env, set, rotation_rad);
        let leaf_radiance: Vec<[f64; 3]> = tree.leaf_texels().iter().map(|&t| per_texel[t as usize]).collect();
        Self::from_leaf_radiance(tree, leaf_radiance, rotation_rad)
    }

    /// From per-leaf radiance already in tree order.
    pub fn from_leaf_radiance(tree: &LightTree, leaf_radiance: Vec<[f64; 3]>, rotation_rad: f64) -> Self {
        let n = leaf_radiance.len();
        let mut prefix_power = Vec::with_capacity(n + 1);
        let mut prefix_omega = Vec::with_capacity(n + 1);
        let mut prefix_moment = Vec::with_capacity(n + 1);
        let (mut p, mut o, mut m) = ([0.0f64; 3], 0.0f64, DVec3::ZERO);
        prefix_power.push(p);
        prefix_omega.push(o);
        prefix_moment.push(m);
        for (i, l) in leaf_radiance.iter().enumerate() {
            let w = tree.leaf_solid_angles()[i];
            for c in 0..3 {
                p[c] += w * l[c];
            }
            o += w;
            m += tree.leaf_moments()[i];
            prefix_power.push(p);
            prefix_omega.push(o);
            prefix_moment.push(m);
        }
        Self { rotation_rad, leaf_radiance, prefix_power, prefix_omega, prefix_moment }
    }

    /// The rotation these sums were made for.
    pub fn rotation_rad(&self) -> f64 {
        self.rotation_rad
    }

    /// Mean radiance of each leaf, tree order.
    pub fn leaf_radiance(&self) -> &[[f64; 3]] {
        &self.leaf_radiance
    }

    /// Σ Ω_l L_l over leaves [a, b) (tree order).
    #[inline]
    pub fn power(&self, a: usize, b: usize) -> [f64; 3] {
        let (pa, pb) = (self.prefix_power[a], self.prefix_power[b]);
        [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]]
    }

    /// Σ Ω_l over leaves [a, b).
    #[inline]
    pub fn omega(&self, a: usize, b: usize) -> f64 {
        self.prefix_omega[b] - self.prefix_omega[a]
    }

    /// Σ of the exact moments ∫ ω dω of leaves [a, b).
    #[inline]
    pub fn moment(&self, a: usize, b: usize) -> DVec3 {
        self.prefix_moment[b] - self.prefix_moment[a]
    }

    /// |C_k| L_k: the node's radiant power per unit area (Σ over its leaves of Ω L).
    pub fn node_power(&self, node: &TreeNode) -> [f64; 3] {
        self.power(node.first as usize, (node.first + node.count) as usize)
    }

    /// L_k: the node's mean radiance.
    pub fn node_radiance(&self, node: &TreeNode) -> [f64; 3] {
        let p = self.node_power(node);
        let w = node.solid_angle.max(f64::MIN_POSITIVE);
        [p[0] / w, p[1] / w, p[2] / w]
    }

    /// Mean radiance over the whole sphere (1/4π Σ Ω L).
    pub fn mean_radiance(&self) -> [f64; 3] {
        let n = self.leaf_radiance.len();
        let p = self.power(0, n);
        let w = self.omega(0, n).max(f64::MIN_POSITIVE);
        [p[0] / w, p[1] / w, p[2] / w]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_environment_gives_uniform_sums() {
        let env = EnvMap::uniform(64, 32, [1.0, 2.0, 3.0]).unwrap();
        let set = DirectionSet::cube(8).unwrap();
        let tree = LightTree::build(&set);
        let sums = LightSums::new(&env, &set, &tree, 0.7);
        for node in tree.nodes() {
            let l = sums.node_radiance(node);
            assert!((l[0] - 1.0).abs() < 1e-12 && (l[1] - 2.0).abs() < 1e-12 && (l[2] - 3.0).abs() < 1e-12);
        }
        let total = sums.power(0, tree.leaf_count());
        assert!((total[0] - 4.0 * std::f64::consts::PI).abs() < 1e-10);
    }

    #[test]
    fn texel_integrals_match_the_environment_mean() {
        // Energy is preserved: the solid-angle-weighted mean of the texel integrals equals the map's own
        // solid-angle-weighted mean (an independent sum over the equirectangular texels), for a smooth
        // map and for a map with a one-texel sun.
        let smooth = EnvMap::from_fn(256, 128, |d| [(1.0 + d.x + 0.5 * d.y) as f32, 1.0, (2.0 + d.z) as f32]).unwrap();
        let mut texels = vec![[0.01f32; 3]; 256 * 128];
        texels[40 * 256 + 77] = [5e4; 3];
        let sun = EnvMap::from_rgb(256, 128, texels, "sun").unwrap();
        for env in [smooth, sun] {
            let set = DirectionSet::cube(16).unwrap();
            let tree = LightTree::build(&set);
            let sums = LightSums::new(&env, &set, &tree, 0.0);
            let got = sums.mean_radiance();
            let want = env.stats().mean_radiance;
            for c in 0..3 {
                let rel = ((got[c] - want[c]) / want[c]).abs();
                println!("{} c={c}: relative energy error {rel:.2e}", env.source());
                assert!(rel < 5e-3, "{} c={c}: {} vs {}", env.source(), got[c], want[c]);
            }
        }
    }
}
