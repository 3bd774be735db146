//! Light sums: the environment's radiance integrated over the light tree's leaves and nodes, for
//! any rotation of the environment about +Y (method.md §4: L_k, the mean radiance over node k).
//!
//! Inputs: an [`EnvMap`], the [`DirectionSet`] and its [`LightTree`], a rotation (radians).
//! Outputs: per leaf (tree order) the mean radiance over its texel, and prefix sums over tree order
//! of Ω·L, Ω and Ω·d, so the radiance, solid angle and mean direction of any node — or of any run
//! of consecutive leaves — cost O(1).
//!
//! Each texel's mean radiance is the smooth part of the map (clamped at 16× its mean) supersampled
//! with the exact cube-face Jacobian, plus the power of what exceeds the clamp (suns) binned into
//! the texel that holds it (see [`texel_radiance`]): the white furnace is exact and a sun's energy
//! is conserved.
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
    /// `prefix_power[i]` = Σ_{l<i} Ω_l L_l.
    prefix_power: Vec<[f64; 3]>,
    /// `prefix_omega[i]` = Σ_{l<i} Ω_l.
    prefix_omega: Vec<f64>,
    /// `prefix_moment[i]` = Σ_{l<i} ∫_l ω dω (exact texel moments).
    prefix_moment: Vec<DVec3>,
    /// `prefix_radiant_moment[i][c]` = Σ_{l<i} L_l,c ∫_l ω dω: per channel, the radiance-weighted
    /// moment (its dot with a normal is the cosine-weighted power of leaves above the horizon; its
    /// direction is where the light of a run comes from).
    prefix_radiant_moment: Vec<[DVec3; 3]>,
    /// The light inside each leaf's texel (from a [`LightSource`] only).
    inside: Option<std::sync::Arc<InsideLight>>,
}

/// An environment prepared for light sums at any rotation: radiance split at τ = 16 × the map's
/// mean (per channel) into a smooth *base* min(L, τ) and the *excess* max(L − τ, 0) of the few
/// texels above it (suns, lamps), the latter as sub-sampled point powers.
#[derive(Debug)]
pub struct LightSource {
    base: EnvMap,
    /// (direction, power Ω·(L − τ)) of 4×4 sub-samples of every texel above τ, unrotated.
    excess: Vec<(DVec3, [f64; 3])>,
    env_texel_angle: f64,
    /// The base part's sample points for the last direction set asked for, kept across rotations.
    samples: std::sync::Mutex<Option<std::sync::Arc<BaseSamples>>>,
}

impl Clone for LightSource {
    fn clone(&self) -> Self {
        let samples = self.samples.lock().map(|s| s.clone()).unwrap_or(None);
        Self {
            base: self.base.clone(),
            excess: self.excess.clone(),
            env_texel_angle: self.env_texel_angle,
            samples: std::sync::Mutex::new(samples),
        }
    }
}

/// Where the base part is read for each direction-set texel: k×k points as equirectangular (u, v)
/// at rotation 0 and their weights. A rotation about +Y only adds rotation/2π to u, so a rotation's
/// sums need no trigonometry (`lookup_uv` at u + shift instead of `lookup` at a rotated direction).
struct BaseSamples {
    resolution: usize,
    k: usize,
    /// (u, v, weight), k² per texel, in texel order.
    points: Vec<(f64, f64, f64)>,
    /// Cells per side of [`InsideLight`] (≤ k) and the cell of each of a texel's k² points.
    cells: usize,
    cell_of: Vec<u8>,
    /// Per texel its cells' unit directions (the weighted mean of their points), texel order.
    cell_directions: std::sync::Arc<Vec<glam::Vec3>>,
}

impl std::fmt::Debug for BaseSamples {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "BaseSamples {{ resolution: {}, k: {}, points: {} }}",
            self.resolution,
            self.k,
            self.points.len()
        )
    }
}

impl BaseSamples {
    fn new(set: &DirectionSet, k: usize) -> Self {
        let points = (0..set.len())
            .into_par_iter()
            .flat_map_iter(|t| {
                set.texel_samples(t, k).map(|(d, w)| {
                    let (u, v) = crate::env::direction_to_uv(d);
                    (u, v, w)
                })
            })
            .collect();
        // Point q = i + j·k lies at (i, j) of the texel's k×k grid (`texel_samples`' order).
        let cells = k.min(INSIDE_CELLS);
        let cell_of: Vec<u8> = (0..k * k)
            .map(|q| ((q % k) * cells / k + (q / k) * cells / k * cells) as u8)
            .collect();
        let cell_directions = (0..set.len())
            .into_par_iter()
            .flat_map_iter(|t| {
                let mut sum = [DVec3::ZERO; INSIDE_CELLS * INSIDE_CELLS];
                for ((d, w), &cell) in set.texel_samples(t, k).zip(&cell_of) {
                    sum[cell as usize] += d * w;
                }
                (0..cells * cells).map(move |c| sum[c].normalize_or_zero().as_vec3())
            })
            .collect();
        Self {
            resolution: set.resolution(),
            k,
            points,
            cells,
            cell_of,
            cell_directions: std::sync::Arc::new(cell_directions),
        }
    }
}

/// Sub-samples per side of an environment texel above τ.
const EXCESS_SUBSAMPLES: usize = 4;

/// Cells per side of a direction-set texel in [`InsideLight`] (fewer where the map has fewer
/// texels across one: the cells are groups of the points the texel's radiance is read at).
pub const INSIDE_CELLS: usize = 4;

/// The light inside each direction-set texel under one rotation: g×g cells per texel, each with
/// its direction and power Ω·L (RGB) — the base part read at the cell's own sample points, the
/// excess (suns) binned into the cell that holds it — so a texel's cells sum to its Ω·L exactly.
/// What the PRT renderer reads where a sharp lobe resolves less than a leaf
/// ([`crate::render::Prt`], `resolve_leaves`). 12 bytes a cell: 4.7 MB at 64 texels per side.
#[derive(Debug, Clone)]
pub struct InsideLight {
    cells: usize,
    /// Per texel, its cells' unit directions (texel order; the same for every rotation).
    directions: std::sync::Arc<Vec<glam::Vec3>>,
    /// Per texel, its cells' power Ω·L (texel order).
    power: Vec<[f32; 3]>,
}

impl InsideLight {
    /// Cells per texel.
    pub fn cells(&self) -> usize {
        self.cells * self.cells
    }

    /// The cells of direction-set texel `t`: (unit direction, power Ω·L).
    #[inline]
    pub fn texel(&self, t: usize) -> impl Iterator<Item = (glam::Vec3, [f32; 3])> + '_ {
        let n = self.cells();
        let range = t * n..(t + 1) * n;
        self.directions[range.clone()]
            .iter()
            .copied()
            .zip(self.power[range].iter().copied())
    }
}

impl LightSource {
    /// Splits `env` (no rotation applied yet).
    pub fn new(env: &EnvMap) -> Self {
        let mean = env.stats().mean_radiance;
        let tau = [16.0 * mean[0], 16.0 * mean[1], 16.0 * mean[2]];
        let (w, h) = (env.width(), env.height());
        let base_texels: Vec<[f32; 3]> = env
            .texels()
            .iter()
            .map(|l| std::array::from_fn(|c| l[c].min(tau[c] as f32)))
            .collect();
        let base =
            EnvMap::from_rgb(w, h, base_texels, env.source()).unwrap_or_else(|_| env.clone());
        let m = EXCESS_SUBSAMPLES;
        let dphi = 2.0 * std::f64::consts::PI / (w * m) as f64;
        let mut excess = Vec::new();
        for row in 0..h {
            for col in 0..w {
                let Some(l) = env.texel(col, row) else {
                    continue;
                };
                let over: [f64; 3] = std::array::from_fn(|c| (l[c] as f64 - tau[c]).max(0.0));
                if over == [0.0; 3] {
                    continue;
                }
                for sub_row in 0..m {
                    let v0 = (row as f64 + sub_row as f64 / m as f64) / h as f64;
                    let v1 = (row as f64 + (sub_row + 1) as f64 / m as f64) / h as f64;
                    let sub_omega = dphi
                        * ((std::f64::consts::PI * v0).cos() - (std::f64::consts::PI * v1).cos());
                    for sub_col in 0..m {
                        let u = (col as f64 + (sub_col as f64 + 0.5) / m as f64) / w as f64;
                        let d = crate::env::uv_to_direction(u, 0.5 * (v0 + v1));
                        excess.push((d, std::array::from_fn(|c| sub_omega * over[c])));
                    }
                }
            }
        }
        Self {
            base,
            excess,
            env_texel_angle: 2.0 * std::f64::consts::PI / w.max(1) as f64,
            samples: std::sync::Mutex::new(None),
        }
    }

    /// Number of excess sub-samples (texels above τ × 16).
    pub fn excess_samples(&self) -> usize {
        self.excess.len()
    }
}

/// Mean radiance of every texel of `set` (texel order) under `env` rotated by `rotation_rad`.
///
/// The base part is integrated over each direction-set texel by a k×k grid of bilinear lookups
/// weighted by the exact cube-face Jacobian (k ≈ the texel's width in environment texels): a
/// uniform environment gives exactly its value in every texel (the white furnace) and smooth maps
/// alias no more than bilinear filtering does. The excess is binned as power into the texel that
/// contains each rotated sub-sample and divided by the texel's exact solid angle, so a sun's energy
/// is conserved exactly and lands where it belongs. (Ratio-binning everything alias-noised smooth
/// regions by ~1 %; power-binning everything put that noise on the furnace.)
pub fn texel_radiance(env: &EnvMap, set: &DirectionSet, rotation_rad: f64) -> Vec<[f64; 3]> {
    texel_radiance_from(&LightSource::new(env), set, rotation_rad)
}

/// [`texel_radiance`] from a prepared [`LightSource`] (what a rotation slider calls).
pub fn texel_radiance_from(
    source: &LightSource,
    set: &DirectionSet,
    rotation_rad: f64,
) -> Vec<[f64; 3]> {
    texel_light(source, set, rotation_rad, false).0
}

/// [`texel_radiance_from`] and, with `inside`, the light inside each texel.
fn texel_light(
    source: &LightSource,
    set: &DirectionSet,
    rotation_rad: f64,
    inside: bool,
) -> (Vec<[f64; 3]>, Option<InsideLight>) {
    let k = ((set.texel_angle() / source.env_texel_angle).ceil() as usize).clamp(1, 8);
    // The sample points of the last set asked for are kept: a rotation slider asks for one set.
    let kept = source
        .samples
        .lock()
        .ok()
        .and_then(|s| s.clone())
        .filter(|s| s.resolution == set.resolution() && s.k == k);
    let samples = kept.unwrap_or_else(|| {
        let made = std::sync::Arc::new(BaseSamples::new(set, k));
        if let Ok(mut slot) = source.samples.lock() {
            *slot = Some(made.clone());
        }
        made
    });
    // lookup(d, θ) reads the map at d rotated by −θ about +Y, whose azimuth is d's plus θ.
    let shift = rotation_rad / (2.0 * std::f64::consts::PI);
    let cells = samples.cells * samples.cells;
    let mut power = vec![[0.0f32; 3]; if inside { set.len() * cells } else { 0 }];
    let mut radiance = vec![[0.0f64; 3]; set.len()];
    let omegas = set.solid_angles();
    // Without `inside` there are no cells to fill.
    let mut cell_chunks: Vec<Option<&mut [[f32; 3]]>> = if inside {
        power.chunks_mut(cells).map(Some).collect()
    } else {
        (0..set.len()).map(|_| None).collect()
    };
    radiance
        .par_iter_mut()
        .zip(samples.points.par_chunks(k * k))
        .zip(cell_chunks.par_iter_mut())
        .enumerate()
        .for_each(|(t, ((sum, points), cell_power))| {
            let mut in_cell = [[0.0f64; 3]; INSIDE_CELLS * INSIDE_CELLS];
            for (&(u, v, w), &cell) in points.iter().zip(&samples.cell_of) {
                let l = source.base.lookup_uv(u + shift, v);
                for c in 0..3 {
                    sum[c] += w * l[c];
                    in_cell[cell as usize][c] += w * l[c];
                }
            }
            if let Some(cell_power) = cell_power.as_deref_mut() {
                for (p, x) in cell_power.iter_mut().zip(&in_cell) {
                    *p = x.map(|x| (x * omegas[t]) as f32);
                }
            }
        });
    drop(cell_chunks);
    for (d, p) in &source.excess {
        let (t, a, b) = set.texel_position(crate::env::rotate_y(*d, rotation_rad));
        let omega = omegas[t];
        for c in 0..3 {
            radiance[t][c] += p[c] / omega;
        }
        if inside {
            let g = samples.cells;
            let at = |x: f64| ((x * g as f64) as usize).min(g - 1);
            let cell = &mut power[t * cells + at(a) + at(b) * g];
            for c in 0..3 {
                cell[c] += p[c] as f32;
            }
        }
    }
    let inside = inside.then(|| InsideLight {
        cells: samples.cells,
        directions: samples.cell_directions.clone(),
        power,
    });
    (radiance, inside)
}

impl LightSums {
    /// Integrates `env` (rotated by `rotation_rad` about +Y) over every leaf of `tree`.
    pub fn new(env: &EnvMap, set: &DirectionSet, tree: &LightTree, rotation_rad: f64) -> Self {
        Self::from_source(&LightSource::new(env), set, tree, rotation_rad)
    }

    /// From a prepared [`LightSource`]: what a rotation slider calls on every move.
    pub fn from_source(
        source: &LightSource,
        set: &DirectionSet,
        tree: &LightTree,
        rotation_rad: f64,
    ) -> Self {
        let (per_texel, inside) = texel_light(source, set, rotation_rad, true);
        let leaf_radiance = tree.in_leaf_order(&per_texel);
        Self {
            inside: inside.map(std::sync::Arc::new),
            ..Self::from_leaf_radiance(tree, leaf_radiance, rotation_rad)
        }
    }

    /// From per-leaf radiance already in tree order.
    pub fn from_leaf_radiance(
        tree: &LightTree,
        leaf_radiance: Vec<[f64; 3]>,
        rotation_rad: f64,
    ) -> Self {
        let n = leaf_radiance.len();
        let mut prefix_power = Vec::with_capacity(n + 1);
        let mut prefix_omega = Vec::with_capacity(n + 1);
        let mut prefix_moment = Vec::with_capacity(n + 1);
        let mut prefix_radiant_moment = Vec::with_capacity(n + 1);
        let (mut p, mut o, mut m, mut rm) = ([0.0f64; 3], 0.0f64, DVec3::ZERO, [DVec3::ZERO; 3]);
        prefix_power.push(p);
        prefix_omega.push(o);
        prefix_moment.push(m);
        prefix_radiant_moment.push(rm);
        for (i, l) in leaf_radiance.iter().enumerate() {
            let w = tree.leaf_solid_angles()[i];
            let lm = tree.leaf_moments()[i];
            for c in 0..3 {
                p[c] += w * l[c];
                rm[c] += lm * l[c];
            }
            o += w;
            m += lm;
            prefix_power.push(p);
            prefix_omega.push(o);
            prefix_moment.push(m);
            prefix_radiant_moment.push(rm);
        }
        Self {
            rotation_rad,
            leaf_radiance,
            prefix_power,
            prefix_omega,
            prefix_moment,
            prefix_radiant_moment,
            inside: None,
        }
    }

    /// The light inside each texel ([`InsideLight`], indexed by texel: see
    /// [`LightTree::leaf_texels`]); `None` for sums made from leaf radiance alone.
    pub fn inside(&self) -> Option<&InsideLight> {
        self.inside.as_deref()
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

    /// Per channel Σ L_l ∫_l ω dω over leaves [a, b): the radiance-weighted moment.
    #[inline]
    pub fn radiant_moment(&self, a: usize, b: usize) -> [DVec3; 3] {
        let (pa, pb) = (
            &self.prefix_radiant_moment[a],
            &self.prefix_radiant_moment[b],
        );
        [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]]
    }

    /// Per channel ∫ L max(ω·n, 0) dω over leaves [a, z) of tree node k's subtree: split by the
    /// horizon of n by a walk down the tree ([`LightTree::split_by_horizon`]), the sub-ranges
    /// wholly above by their radiant moments (exact up to per-leaf constant radiance; `moment` is
    /// [a, z)'s own, already read), the nodes of ≤ `coarse_leaves` leaves astride it clipped at
    /// their mean radiance. Shared by the transfer and the PRT renderer.
    #[allow(clippy::too_many_arguments)] // the node, the horizon and the clip's knobs: plain numbers
    pub fn clipped_cosine_power(
        &self,
        tree: &LightTree,
        k: usize,
        a: usize,
        z: usize,
        n: DVec3,
        coarse_leaves: u32,
        moment: &[DVec3; 3],
    ) -> [f64; 3] {
        let mut cos_power = [0.0f64; 3];
        tree.split_by_horizon(
            k,
            a,
            z,
            n,
            coarse_leaves,
            &mut |lo, hi, clipped| match clipped {
                None => {
                    let own;
                    let m = if (lo, hi) == (a, z) {
                        moment
                    } else {
                        own = self.radiant_moment(lo, hi);
                        &own
                    };
                    for c in 0..3 {
                        cos_power[c] += m[c].dot(n).max(0.0);
                    }
                }
                Some(ci) if hi == lo + 1 => {
                    let l = self.leaf_radiance[lo];
                    for c in 0..3 {
                        cos_power[c] += l[c] * ci;
                    }
                }
                Some(ci) => {
                    for (p, l) in cos_power.iter_mut().zip(self.mean_radiance_of(lo, hi)) {
                        *p += l * ci;
                    }
                }
            },
        );
        cos_power
    }

    /// Mean radiance over leaves [a, b) per channel, power / solid angle (0 for no solid angle).
    #[inline]
    pub fn mean_radiance_of(&self, a: usize, b: usize) -> [f64; 3] {
        let (power, omega) = (self.power(a, b), self.omega(a, b));
        if omega > 0.0 {
            power.map(|p| p / omega)
        } else {
            [0.0; 3]
        }
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

/// Rec. 709 luminance weights (where the light of a run comes from is weighed by luminance).
pub const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The luminance of an RGB triple.
#[inline]
pub fn luminance(rgb: [f64; 3]) -> f64 {
    rgb[0] * LUMINANCE[0] + rgb[1] * LUMINANCE[1] + rgb[2] * LUMINANCE[2]
}

/// A light's spread v_ω = 1 − |moment| / power (0 for no power): 0 for a point, → 1 for an even
/// spread.
#[inline]
pub fn spread(moment: DVec3, power: f64) -> f64 {
    if power > 0.0 {
        (1.0 - moment.length() / power).max(0.0)
    } else {
        0.0
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
            assert!(
                (l[0] - 1.0).abs() < 1e-12
                    && (l[1] - 2.0).abs() < 1e-12
                    && (l[2] - 3.0).abs() < 1e-12
            );
        }
        let total = sums.power(0, tree.leaf_count());
        assert!((total[0] - 4.0 * std::f64::consts::PI).abs() < 1e-10);
    }

    #[test]
    fn a_rotation_as_a_shift_in_u_equals_reading_rotated_directions() {
        // The kept sample points read at u + θ/2π against each texel's samples read at their
        // direction rotated by −θ (trigonometry, no cache), for the set the source keeps and for
        // another one.
        let env = EnvMap::from_fn(128, 64, |d| {
            [
                (1.0 + d.x + 0.5 * d.y * d.z) as f32,
                (1.5 + (3.0 * d.x).sin()) as f32,
                (2.0 + d.z) as f32,
            ]
        })
        .unwrap();
        let source = LightSource::new(&env);
        for resolution in [16, 12, 16] {
            let set = DirectionSet::cube(resolution).unwrap();
            for rotation in [0.0, 0.7, -2.9, 7.5] {
                let got = texel_radiance_from(&source, &set, rotation);
                let k = ((set.texel_angle() / source.env_texel_angle).ceil() as usize).clamp(1, 8);
                for t in (0..set.len()).step_by(7) {
                    let mut want = [0.0f64; 3];
                    for (d, w) in set.texel_samples(t, k) {
                        let l = source.base.lookup(d, rotation);
                        for c in 0..3 {
                            want[c] += w * l[c];
                        }
                    }
                    for c in 0..3 {
                        assert!(
                            (got[t][c] - want[c]).abs() <= 1e-9 * want[c].abs().max(1.0),
                            "n {resolution}, θ {rotation}, texel {t}: {:?} vs {want:?}",
                            got[t]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_light_inside_a_texel_sums_to_the_texel_and_lies_where_it_comes_from() {
        // Per texel, its cells' power sums to the texel's Ω·L (the prefix sums' own figure), every
        // cell's direction lies in its texel's own cell, and a one-texel sun's power sits in the
        // cell that holds the sun's rotated direction (an independent placement: the sun texel's
        // centre on the equirectangular map).
        let mut texels = vec![[0.2f32, 0.3, 0.4]; 256 * 128];
        let (sun_col, sun_row) = (77, 40);
        texels[sun_row * 256 + sun_col] = [5e4, 4e4, 3e4];
        let env = EnvMap::from_rgb(256, 128, texels, "sun").unwrap();
        let set = DirectionSet::cube(16).unwrap();
        let tree = LightTree::build(&set);
        for rotation in [0.0, 1.3] {
            let sums = LightSums::new(&env, &set, &tree, rotation);
            let inside = sums.inside().unwrap();
            assert_eq!(inside.cells(), INSIDE_CELLS * INSIDE_CELLS);
            let g = INSIDE_CELLS as f64;
            let mut brightest = (0.0f64, glam::Vec3::ZERO);
            for (l, &t) in tree.leaf_texels().iter().enumerate() {
                let t = t as usize;
                let mut sum = [0.0f64; 3];
                for (q, (d, p)) in inside.texel(t).enumerate() {
                    let (at, a, b) = set.texel_position(d.as_dvec3());
                    assert_eq!(at, t, "cell {q} of texel {t} lies in texel {at}");
                    let cell = (a * g).floor().min(g - 1.0) as usize
                        + (b * g).floor().min(g - 1.0) as usize * INSIDE_CELLS;
                    assert_eq!(cell, q, "texel {t}: cell {q}'s direction is in cell {cell}");
                    for c in 0..3 {
                        sum[c] += p[c] as f64;
                    }
                    if p[1] as f64 > brightest.0 {
                        brightest = (p[1] as f64, d);
                    }
                }
                let want = sums.power(l, l + 1);
                for c in 0..3 {
                    assert!(
                        (sum[c] - want[c]).abs() <= 1e-5 * want[c],
                        "θ {rotation}, texel {t}, channel {c}: {} vs {}",
                        sum[c],
                        want[c]
                    );
                }
            }
            let sun = crate::env::rotate_y(env.texel_direction(sun_col, sun_row), rotation);
            let cell_angle = set.texel_angle() / g;
            let off = brightest.1.as_dvec3().angle_between(sun);
            assert!(
                off < 1.5 * cell_angle,
                "θ {rotation}: the sun's cell is {:.2}° from the sun (a cell is {:.2}°)",
                off.to_degrees(),
                cell_angle.to_degrees()
            );
        }
    }

    #[test]
    fn texel_integrals_match_the_environment_mean() {
        // Energy is preserved: the solid-angle-weighted mean of the texel integrals equals the
        // map's own solid-angle-weighted mean (an independent sum over the equirectangular texels),
        // for a smooth map and for a map with a one-texel sun.
        let smooth = EnvMap::from_fn(256, 128, |d| {
            [(1.0 + d.x + 0.5 * d.y) as f32, 1.0, (2.0 + d.z) as f32]
        })
        .unwrap();
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
                assert!(
                    rel < 5e-3,
                    "{} c={c}: {} vs {}",
                    env.source(),
                    got[c],
                    want[c]
                );
            }
        }
    }
}
