//! Transfer: T_j and the irradiance E for the pixels of a view (method.md §4, eq. 5-7).
//!
//! T_j(x) = ∫ L(wi) Ṽ(x, wi) G(h·ξ_j) s(wi, wo(x)) dwi,  E(x) = ∫ L Ṽ dwi,  Ṽ = V·max(wi·n, 0),
//! so that the rendered radiance is B(x) = ρd/π·E(x) + Σ_j c_j T_j(x) (per colour channel).
//!
//! Inputs: the bake's cuts, the light tree and [`LightSums`] (for the environment's rotation), a
//! [`LobeSet`], the mesh (positions, normals, tangents or none), a camera and a fit resolution, and
//! F0. Output: a [`Transfer`] — per covered pixel its sample (triangle, barycentrics, position,
//! normal), T (3 × J per pixel, f32) and E (RGB, f64).
//!
//! How a pixel is summed: its triangle's three vertex cuts and a *shading partition* (tree nodes no
//! wider than a fraction of the lobe's width, finer for grazing views: `SHADING_TIERS`) are
//! merged into elementary runs of consecutive leaves (cut nodes are leaf ranges in tree order). For
//! each run the prefix sums give its radiant moment Σ L ∫ ω dω per channel and its power in O(1); V
//! is the barycentric blend of the three vertices' V_k; ∫ L Ṽ uses the pixel's interpolated normal,
//! exact (radiant moment · n) when the run lies above the horizon, and where it straddles it split
//! into sub-ranges above (exact) and the nodes of ≤ 16 leaves the horizon cuts (clipped whole by a
//! disc model at their mean radiance): for a run that is a whole shading node, from that node's
//! flat list of such pieces (`HorizonPiece`), for a part of one by a walk down the tree
//! ([`LightTree::split_by_horizon`]). The BRDF is evaluated at the direction the run's light comes
//! from (its luminance-weighted moment: a sun inside a node is seen where it is). Ring lobes
//! (isotropic sets) depend on the half-vector's polar angle alone: a run's weight goes into a
//! per-pixel histogram over t = √(1 − cos θh) and over *filter levels* — the lobes pre-filtered by
//! the spread of the run's light, v_ω = 1 − |moment|/power, as v_ω/(4 wo·h) in half-vector space
//! (`RingFilter`) — and each lobe is the dot product of the histogram with its tabulated rows
//! once per pixel: the same sums as evaluating every (filtered) lobe per run, regrouped. Other lobe
//! sets are evaluated per run where their support (G > e^-14) can reach the half-vector
//! ([`LobeGrid`]).
//!
//! Invariants: no ray tracing (visibility comes from the bake; a new view or rotation only
//! re-sums); pixels are independent, so the result does not depend on the thread count; no IO.

use crate::bake::{Cuts, Span, for_each_run};
use crate::brdf::dbrdf::{half_vector_cosines_masked, static_term, static_term_parts};
use crate::light::LightSums;
use crate::light::{LUMINANCE, luminance, spread};
use crate::raster::{Fragment, rasterize};
use crate::scene::{Camera, Mesh};
use crate::sphere::light_tree::{
    COARSE_HORIZON_LEAVES, Partition, PartitionCone, disc_clipped_cosine,
};
use crate::sphere::{Frame, LightTree, LobeSet, hemi_oct, srbf};
use glam::{DVec3, Vec3, Vec4};
use rayon::prelude::*;

/// Relative threshold under which a lobe is not evaluated: G < e^-14 ≈ 8e-7.
pub const LOBE_CUTOFF_EXPONENT: f64 = 14.0;

/// Where the ring table's rows end (relative to a lobe's peak of 1): e^-10 ≈ 4.5e-5. What lies
/// beyond is a fraction erfc(√10) ≈ 8e-6 of a lobe's integral (e^-14, the lobe grid's cutoff,
/// flushed 20 % more points per pixel for nothing visible in T).
pub const RING_CUTOFF_EXPONENT: f64 = 10.0;

/// Which lobes can be non-negligible at a half-vector: an octahedral grid over the upper hemisphere
/// of local half-vectors, each cell listing the lobes whose support cone meets the cell's bounding
/// cap. (Ring lobes need no grid: the transfer sums them through the ring table.)
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
                // Bounding cap of the cell: centre and the largest angle to its corners and edge
                // midpoints.
                let centre = hemi_oct::decode(
                    (cx as f64 + 0.5) / size as f64,
                    (cy as f64 + 0.5) / size as f64,
                );
                let mut radius = 0.0f64;
                for (a, b) in [
                    (0.0, 0.0),
                    (1.0, 0.0),
                    (0.0, 1.0),
                    (1.0, 1.0),
                    (0.5, 0.0),
                    (0.0, 0.5),
                    (1.0, 0.5),
                    (0.5, 1.0),
                ] {
                    let p = hemi_oct::decode(
                        (cx as f64 + a) / size as f64,
                        (cy as f64 + b) / size as f64,
                    );
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
        Self {
            size,
            offsets,
            lobes: list,
        }
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

/// Ring lobes pre-filtered by a run's angular spread, tabulated for the transfer's histogram.
///
/// A run's light is spread over its directions: averaged under a Gaussian jitter of per-axis
/// variance v (rad², half-vector space) a lobe of sharpness λ becomes (λ'/λ) G(h; λ') with λ' =
/// λ/(1 + x), x = 2λv (the closed form [`crate::render::table::filtered_exact`] also uses), and so
/// does its azimuthal average, the ring lobe. Rows are tabulated at a few levels of x in t = √(1 −
/// cos θh) and a run's weight is split bilinearly between the two levels and two points around (x,
/// t).
#[derive(Debug, Clone)]
struct RingFilter {
    /// Intervals in t.
    res: usize,
    /// 1/(1 + x) of each level: the filtered lobe's peak, in which levels are blended.
    peaks: [f64; FILTER_LEVELS],
    /// `1 / (peaks[l] − peaks[l + 1])`.
    inv_gaps: [f64; FILTER_LEVELS - 1],
    /// 2λ, to turn a spread into x.
    two_lambda: f64,
    /// Rows, ((level · J) + j) · (res + 1) + k.
    rows: Vec<f64>,
    /// Per level and lobe, the points [first, last] where the row exceeds the cutoff.
    support: Vec<(usize, usize)>,
    lobes: usize,
}

impl RingFilter {
    /// Table intervals per unit of σ: a lobe σ wide in θh is narrowest in t = √(1 − cos θh) at the
    /// equator (dt/dθ = ½ there), so 20/σ intervals put 10 points within its σ in t, where linear
    /// interpolation is within (1/10)²/8 ≈ 1.3e-3 of its peak (and averages out over a run's spread
    /// of half-vectors). Paper lobes (σ = π/40) get 256; sharp ones more (λ = 5000: 1472), where a
    /// fixed 256 gave 3.9 % instead of 2.8 % in `tests/it/hard_cases.rs`.
    const RES_PER_INVERSE_SIGMA: f64 = 20.0;
    /// Table intervals, at least and at most (a multiple of 64 in between).
    const RES_RANGE: (usize, usize) = (256, 4096);
    /// Levels of x = 2λv: spreads up to x = 2 (λ' = λ/3) are filtered, larger ones clamp to it.
    const LEVELS: [f64; FILTER_LEVELS] = [0.0, 0.0625, 0.1875, 0.4375, 0.9375, 2.0];

    fn new(lobes: &LobeSet) -> Self {
        let lambda = lobes.lambda();
        let sigma = srbf::sigma_from_lambda(lambda).unwrap_or(srbf::PAPER_SIGMA);
        let res = ((Self::RES_PER_INVERSE_SIGMA / sigma / 64.0).ceil() as usize * 64)
            .clamp(Self::RES_RANGE.0, Self::RES_RANGE.1);
        let cutoff = (-RING_CUTOFF_EXPONENT).exp();
        let polar: Vec<(f64, f64)> = lobes
            .centres()
            .iter()
            .map(|c| (c.z, (c.x * c.x + c.y * c.y).sqrt()))
            .collect();
        let mut rows = Vec::with_capacity(FILTER_LEVELS * polar.len() * (res + 1));
        let mut support = Vec::new();
        for &x in &Self::LEVELS {
            let lp = lambda / (1.0 + x);
            for &(cj, sj) in &polar {
                let start = rows.len();
                rows.extend((0..=res).map(|k| {
                    let t = k as f64 / res as f64;
                    let ch = 1.0 - t * t;
                    lp / lambda * srbf::ring_lobe(ch, (1.0 - ch * ch).max(0.0).sqrt(), cj, sj, lp)
                }));
                let row = &rows[start..];
                let first = row.iter().position(|&g| g > cutoff).unwrap_or(row.len());
                let last = row.iter().rposition(|&g| g > cutoff).unwrap_or(0);
                support.push((first, last));
            }
        }
        let peaks = Self::LEVELS.map(|x| 1.0 / (1.0 + x));
        let inv_gaps = std::array::from_fn(|l| 1.0 / (peaks[l] - peaks[l + 1]));
        Self {
            res,
            peaks,
            inv_gaps,
            two_lambda: 2.0 * lambda,
            rows,
            support,
            lobes: polar.len(),
        }
    }

    /// Level and the weight of the level above for a spread v (rad², half-vector space). (The
    /// transfer computes the peak in one division, [`ring_entries`]; the tests read the table by
    /// this.)
    #[cfg(test)]
    fn level(&self, spread: f64) -> (usize, f64) {
        // x = 0 gives p = 1 (level 0); x < 0 or NaN too.
        self.level_at_peak(1.0 / (1.0 + self.two_lambda * spread))
    }

    /// `Self::level` from the filtered lobe's peak p = 1/(1 + x) ∈ (0, 1]. Without branches on p
    /// (a chain of selects over the few levels), so that [`ring_entries`] vectorises.
    #[inline(always)]
    fn level_at_peak(&self, p: f64) -> (usize, f64) {
        let last = FILTER_LEVELS - 1;
        // The highest level whose peak is ≥ p (peaks fall with the level; levels 1..last − 1).
        let (mut l, mut peak, mut inv_gap) = (0usize, self.peaks[0], self.inv_gaps[0]);
        for i in 1..last {
            let above = self.peaks[i] >= p;
            l = if above { i } else { l };
            peak = if above { self.peaks[i] } else { peak };
            inv_gap = if above { self.inv_gaps[i] } else { inv_gap };
        }
        // Linear in 1/(1 + x), the filtered lobe's peak, rather than in x: exact at the peak, and
        // within 0.3 % of it between levels
        // (`filtered_ring_rows_match_a_monte_carlo_average_under_jitter`).
        let fl = (peak - p) * inv_gap;
        // No spread (p ≥ 1, or NaN): level 0 alone; beyond the last level: clamped to it.
        let wide = p <= self.peaks[last];
        let narrow = !(p < 1.0);
        (
            if wide {
                last - 1
            } else if narrow {
                0
            } else {
                l
            },
            if wide {
                1.0
            } else if narrow {
                0.0
            } else {
                fl
            },
        )
    }

    /// Table position of cos θh: point k and the weight of k + 1.
    #[inline]
    fn position(&self, cos_h: f64) -> (usize, f64) {
        let x = (1.0 - cos_h.clamp(0.0, 1.0)).sqrt() * self.res as f64;
        // Through i32 (x ∈ [0, res]), which vector units convert directly.
        let k = ((x as i32).max(0) as usize).min(self.res - 1);
        (k, x - k as f64)
    }

    fn row(&self, level: usize, j: usize) -> &[f64] {
        let n = self.res + 1;
        let start = (level * self.lobes + j) * n;
        &self.rows[start..start + n]
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
                    let spec: f64 = self
                        .t_row(p, c)
                        .iter()
                        .zip(coefficients[c])
                        .map(|(t, k)| *t as f64 * k)
                        .sum();
                    rho_d[c] / std::f64::consts::PI * self.irradiance[p][c] + spec
                })
            })
            .collect()
    }
}

/// A shading node's light under the current rotation (read once per compute, not per run).
#[derive(Debug, Clone, Copy)]
struct NodeLight {
    /// Per channel Σ L ∫ ω dω (the radiance-weighted moment).
    radiant: [DVec3; 3],
    /// Where the light comes from, [`run_direction`] (`None`: no light).
    direction: Option<(DVec3, f64)>,
}

/// Where a run's light comes from and how spread it is: the unit direction of its
/// luminance-weighted moment and v_ω = 1 − |moment| / power (luminance; 0 for a single direction).
/// `None` when the run has no light.
#[inline]
fn run_direction(radiant: &[DVec3; 3], power: [f64; 3]) -> Option<(DVec3, f64)> {
    let lum = radiant[0] * LUMINANCE[0] + radiant[1] * LUMINANCE[1] + radiant[2] * LUMINANCE[2];
    let lum_len = lum.length();
    if !(lum_len > 0.0 && lum_len.is_finite()) {
        return None;
    }
    Some((lum * (1.0 / lum_len), spread(lum, luminance(power))))
}

/// The light of every shading partition's nodes and horizon pieces under the current rotation.
struct PartitionLights<'a> {
    nodes: &'a [Vec<NodeLight>],
    pieces: &'a [Vec<PieceLight>],
}

/// A pixel's lit runs waiting for their ring-lobe histogram entries, by component (so that
/// [`ring_entries`] loads several runs at once): each run's light direction and spread
/// ([`run_direction`]) and its visible cosine-weighted power per channel.
#[derive(Debug, Default)]
struct LitRuns {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    v_omega: Vec<f64>,
    power: Vec<[f64; 3]>,
}

impl LitRuns {
    fn clear(&mut self) {
        for v in [&mut self.x, &mut self.y, &mut self.z, &mut self.v_omega] {
            v.clear();
        }
        self.power.clear();
    }

    #[inline]
    fn push(&mut self, direction: DVec3, v_omega: f64, power: [f64; 3]) {
        self.x.push(direction.x);
        self.y.push(direction.y);
        self.z.push(direction.z);
        self.v_omega.push(v_omega);
        self.power.push(power);
    }
}

/// A thread's scratch space, reused from pixel to pixel.
struct Scratch {
    /// The ring histogram (table points × 3 channels, interleaved, per filter level), all zero
    /// between pixels.
    hist: Vec<f64>,
    /// The pixel's lit runs (ring lobes).
    runs: LitRuns,
    /// Their histogram entries.
    entries: RingEntries,
}

/// The shading partitions of ring (isotropic) lobe sets: (node half-angle in units of the lobe's σ,
/// the smallest wo·n of a pixel that uses it), coarsest first. A lobe σ wide in half-vector space
/// is about 2σ·(wo·h) wide in wi-space along one axis, so grazing views need finer nodes. What the
/// node size costs (release, 2 cores):
/// - alone, under a uniform sky (`tests/it/hard_cases.rs`, one ring lobe along n at the paper's σ
///   on a sphere, against brute-force albedo, relative L1 over the image): every pixel at σ/4 0.08
///   %, σ/2 0.21 %, 0.75σ 0.44 %, σ 0.73 %, 1.5σ 1.6 % (pre-filtering takes 1.5σ from 2.3 % to 1.6
///   %); these tiers 0.41 % (0.75σ from wo·n ≥ 0.6: 0.27 %; 1.5σ: 0.67 %);
/// - with visibility (`tests/it/transfer.rs`, suzanne under courtyard, T against direct
///   integration): at wo·n < 0.15 nodes of σ or σ/2 are 2.4–4.6 % off where σ/4 is 0.8–1.7 %; the
///   test's 14 pixels 0.58 % (σ/4 everywhere 0.43 %);
/// - time, dragon_100k's default view at 160×120 (2,681 pixels, 76 % at wo·n ≥ 0.6, 3.4 % below
///   0.15): 0.076 s against 0.30 s at σ/4 everywhere (0.109 s with 0.75σ first, 0.055 s with 1.5σ).
const SHADING_TIERS: [(f64, f64); 4] = [(1.0, 0.6), (0.75, 0.3), (0.5, 0.15), (0.25, 0.0)];

/// The widest shading node of the tiers (radians, ~6.9°): wide lobes (σ of 30° and more, λ ≲ 2) are
/// not evaluated over nodes of σ, which would be far wider than the Gaussian spread the filter
/// models well (never finer than σ/4, the single partition before the tiers: λ = 1 in
/// `tests/it/hard_cases.rs` is 8.7 % off with uncapped tiers from 1.5σ, 0.34 % with this cap). The
/// paper's σ = π/40 = 0.079 is unaffected.
const MAX_SHADING_ANGLE: f64 = 0.12;

/// Filter levels of [`RingFilter`].
const FILTER_LEVELS: usize = 6;

/// The lit runs' places in the ring histogram ([`ring_entries`]), by component: per run the lower
/// filter level with the weight s·(1 − f) of it and s·f of the level above, and the lower table
/// point k with the weight of k + 1. Weights of 0: the run adds nothing (no half-vector, or no
/// specular term).
#[derive(Debug, Default)]
struct RingEntries {
    lower: Vec<f64>,
    upper: Vec<f64>,
    fk: Vec<f64>,
    level: Vec<u32>,
    k: Vec<u32>,
}

/// The ring-histogram entries of a pixel's lit runs: the half-vector's cosines
/// ([`half_vector_cosines_masked`]), the static term, the filter level of the run's spread and the
/// table position, with no branch on the data (invalid runs get weights of 0), so that the loop
/// runs several runs per instruction. The scatter into the histogram stays a loop of its own.
fn ring_entries(
    ring: &RingFilter,
    runs: &LitRuns,
    normal: DVec3,
    wo_world: DVec3,
    wo_z: f64,
    f0: f64,
    out: &mut RingEntries,
) {
    let n = runs.x.len();
    for v in [&mut out.lower, &mut out.upper, &mut out.fk] {
        v.clear();
        v.resize(n, 0.0);
    }
    for v in [&mut out.level, &mut out.k] {
        v.clear();
        v.resize(n, 0);
    }
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above); the function is the portable loop compiled
        // for it, with the same IEEE arithmetic (no fused operations are formed).
        unsafe { ring_entries_avx2(ring, runs, normal, wo_world, wo_z, f0, out) };
        return;
    }
    ring_entries_loop(ring, runs, normal, wo_world, wo_z, f0, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn ring_entries_avx2(
    ring: &RingFilter,
    runs: &LitRuns,
    normal: DVec3,
    wo_world: DVec3,
    wo_z: f64,
    f0: f64,
    out: &mut RingEntries,
) {
    ring_entries_loop(ring, runs, normal, wo_world, wo_z, f0, out);
}

#[inline(always)]
fn ring_entries_loop(
    ring: &RingFilter,
    runs: &LitRuns,
    normal: DVec3,
    wo_world: DVec3,
    wo_z: f64,
    f0: f64,
    out: &mut RingEntries,
) {
    let n = runs.x.len();
    let (x, y, z, v_omega) = (&runs.x[..n], &runs.y[..n], &runs.z[..n], &runs.v_omega[..n]);
    let (lower, upper, fks) = (&mut out.lower[..n], &mut out.upper[..n], &mut out.fk[..n]);
    let (levels, ks) = (&mut out.level[..n], &mut out.k[..n]);
    for i in 0..n {
        let k1 = x[i] * normal.x + y[i] * normal.y + z[i] * normal.z;
        let c = x[i] * wo_world.x + y[i] * wo_world.y + z[i] * wo_world.z;
        let (valid, wo_h, cos_h) = half_vector_cosines_masked(k1, wo_z, c);
        let s = static_term_parts(k1, wo_z, wo_h, f0);
        let s = if valid && s > 0.0 { s } else { 0.0 };
        // The spread in half-vector space: v = v_ω / (4 wo·h) (the geometric mean of its two axes'
        // scales), as the filtered peak 1/(1 + 2λv) = 4 wo·h / (4 wo·h + 2λ v_ω) (one division).
        let m = 4.0 * wo_h.max(1e-3);
        let (l, fl) = ring.level_at_peak(m / (m + ring.two_lambda * v_omega[i]));
        let (k, fk) = ring.position(cos_h);
        lower[i] = s * (1.0 - fl);
        upper[i] = s * fl;
        fks[i] = fk;
        levels[i] = l as u32;
        ks[i] = k as u32;
    }
}

/// A partition of the sphere into shading nodes.
struct ShadingPartition {
    /// The largest cone half-angle of a node (radians).
    angle: f64,
    /// The smallest wo·n of a pixel that uses it.
    min_wo_z: f64,
    /// Leaf ranges [first, end), in order.
    ranges: Vec<(u32, u32)>,
    /// Per node, its light-tree node (where the walk that splits a run at the horizon starts).
    nodes: Vec<u32>,
    /// Per node, its corner cone (copied from the tree so that runs read them in order).
    cones: Vec<PartitionCone>,
    /// Per node, the range of `pieces` that tile it (`pieces[piece_offsets[i]..piece_offsets[i +
    /// 1]]`).
    piece_offsets: Vec<u32>,
    /// The largest tree nodes of at most `coarse_leaves` leaves under each node, in leaf order,
    /// with what clipping them at a horizon needs ([`HorizonPiece`]).
    pieces: Vec<HorizonPiece>,
}

/// A tree node of at most `coarse_leaves` leaves that a shading node astride a horizon is split
/// into: wholly above (its radiant moment · n, exact), wholly below (nothing), or astride (its mean
/// radiance times [`disc_clipped_cosine`]) — what [`LightSums::clipped_cosine_power`]'s walk down
/// the tree computes, read from a flat list instead of the tree and the prefix sums.
#[derive(Debug, Clone, Copy)]
struct HorizonPiece {
    cone: PartitionCone,
    solid_angle: f64,
    moment: DVec3,
    /// Leaf range [first, end).
    first: u32,
    end: u32,
}

/// A [`HorizonPiece`]'s light under the current rotation.
#[derive(Debug, Clone, Copy)]
struct PieceLight {
    /// Per channel Σ L ∫ ω dω.
    radiant: [DVec3; 3],
    /// Per channel its mean radiance (power / solid angle).
    radiance: [f64; 3],
}

impl ShadingPartition {
    fn new(tree: &LightTree, angle: f64, min_wo_z: f64, coarse_leaves: u32) -> Self {
        let Partition { ranges, nodes, .. } = tree.partition(angle.max(1e-6));
        let cones = nodes
            .iter()
            .map(|&k| *tree.corner_cone(k as usize))
            .collect();
        let mut piece_offsets = vec![0u32];
        let mut pieces = Vec::new();
        for &k in &nodes {
            for p in crate::bake::decisions::nodes_of_at_most(tree, coarse_leaves, k as usize) {
                let node = &tree.nodes()[p];
                pieces.push(HorizonPiece {
                    cone: *tree.corner_cone(p),
                    solid_angle: node.solid_angle,
                    moment: node.moment,
                    first: node.first,
                    end: node.first + node.count,
                });
            }
            piece_offsets.push(pieces.len() as u32);
        }
        Self {
            angle,
            min_wo_z,
            ranges,
            nodes,
            cones,
            piece_offsets,
            pieces,
        }
    }

    /// ∫ L max(ω·n, 0) dω over node `si` (whole), per channel, split at the horizon of n into its
    /// pieces; `light` holds the pieces' light, index for index.
    #[inline]
    fn clipped_cosine_power(&self, si: usize, light: &[PieceLight], n: DVec3) -> [f64; 3] {
        let range = self.piece_offsets[si] as usize..self.piece_offsets[si + 1] as usize;
        let mut cos_power = [0.0f64; 3];
        for (piece, pl) in self.pieces[range.clone()].iter().zip(&light[range]) {
            let cone = &piece.cone;
            let cb = cone.axis.dot(n);
            if cone.cos > 0.0 && cb > cone.sin {
                for (p, m) in cos_power.iter_mut().zip(&pl.radiant) {
                    *p += m.dot(n).max(0.0);
                }
            } else if cone.cos > 0.0 && cb < -cone.sin {
                continue;
            } else {
                let clipped = disc_clipped_cosine(piece.solid_angle, piece.moment.dot(n));
                if clipped > 0.0 {
                    for (p, l) in cos_power.iter_mut().zip(pl.radiance) {
                        *p += l * clipped;
                    }
                }
            }
        }
        cos_power
    }
}

/// What stays fixed across views and rotations: built once per bake and lobe set.
pub struct TransferContext<'a> {
    pub mesh: &'a Mesh,
    pub cuts: &'a Cuts,
    pub tree: &'a LightTree,
    pub lobes: &'a LobeSet,
    pub tangents: Option<&'a [Vec4]>,
    grid: LobeGrid,
    /// Shading partitions, coarsest first; a pixel uses the first whose `min_wo_z` its view cosine
    /// reaches.
    partitions: Vec<ShadingPartition>,
    /// Nodes astride a horizon are clipped whole up to about 5.6° across (16 leaves at 64 per cube
    /// side, [`COARSE_HORIZON_LEAVES`]); on coarser direction sets, fewer leaves.
    coarse_leaves: u32,
    /// Ring lobes only: their pre-filtered tables.
    ring: Option<RingFilter>,
}

impl<'a> TransferContext<'a> {
    /// `shading_angle`: the largest cone half-angle (radians) of a shading node, for every pixel;
    /// `None` picks per pixel from `SHADING_TIERS` by its view cosine for ring lobe sets (nodes
    /// of σ where wo·n ≥ 0.6 down to σ/4 at grazing views) and σ/4 for the others (whose lobes are
    /// not pre-filtered).
    pub fn new(
        mesh: &'a Mesh,
        cuts: &'a Cuts,
        tree: &'a LightTree,
        lobes: &'a LobeSet,
        tangents: Option<&'a [Vec4]>,
        shading_angle: Option<f64>,
    ) -> Self {
        let sigma = srbf::sigma_from_lambda(lobes.lambda()).unwrap_or(0.08);
        let ring = lobes
            .layout()
            .is_isotropic()
            .then(|| RingFilter::new(lobes));
        let coarse_leaves =
            (COARSE_HORIZON_LEAVES as usize * tree.leaf_count() / (6 * 64 * 64)).max(1) as u32;
        let partitions = match shading_angle {
            Some(angle) => vec![ShadingPartition::new(tree, angle, 0.0, coarse_leaves)],
            None if ring.is_some() => SHADING_TIERS
                .iter()
                .map(|&(angle, min_wo_z)| {
                    ShadingPartition::new(
                        tree,
                        (angle * sigma).min(MAX_SHADING_ANGLE.max(0.25 * sigma)),
                        min_wo_z,
                        coarse_leaves,
                    )
                })
                .collect(),
            None => vec![ShadingPartition::new(
                tree,
                0.25 * sigma,
                0.0,
                coarse_leaves,
            )],
        };
        Self {
            mesh,
            cuts,
            tree,
            lobes,
            tangents,
            grid: LobeGrid::new(lobes),
            partitions,
            coarse_leaves,
            ring,
        }
    }

    /// Number of nodes in each shading partition (over the whole sphere), coarsest first, with its
    /// node half-angle (radians) and the smallest wo·n of a pixel that uses it.
    pub fn shading_partitions(&self) -> Vec<(usize, f64, f64)> {
        self.partitions
            .iter()
            .map(|p| (p.ranges.len(), p.angle, p.min_wo_z))
            .collect()
    }

    fn spans(&self, v: usize) -> Vec<Span> {
        self.cuts.spans(v, self.tree).collect()
    }

    /// T and E for the pixels of `camera` at `width`×`height`, environment sums `light`, Fresnel
    /// F0.
    pub fn compute(
        &self,
        light: &LightSums,
        camera: &Camera,
        width: u32,
        height: u32,
        f0: f64,
    ) -> Transfer {
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
        let spans: Vec<Option<Vec<Span>>> = used
            .par_iter()
            .enumerate()
            .map(|(v, &u)| u.then(|| self.spans(v)))
            .collect();
        let j_count = self.lobes.len();
        // Each shading node's light, read once per run instead of two prefix-sum entries per array
        // (nearly every run is a whole shading node: cut nodes are much wider).
        let node_light: Vec<Vec<NodeLight>> = self
            .partitions
            .iter()
            .map(|part| {
                part.ranges
                    .iter()
                    .map(|&(a, z)| {
                        let (a, z) = (a as usize, z as usize);
                        let radiant = light.radiant_moment(a, z);
                        NodeLight {
                            radiant,
                            direction: run_direction(&radiant, light.power(a, z)),
                        }
                    })
                    .collect()
            })
            .collect();
        let piece_light: Vec<Vec<PieceLight>> = self
            .partitions
            .iter()
            .map(|part| {
                part.pieces
                    .iter()
                    .map(|p| {
                        let (a, z) = (p.first as usize, p.end as usize);
                        PieceLight {
                            radiant: light.radiant_moment(a, z),
                            radiance: light.mean_radiance_of(a, z),
                        }
                    })
                    .collect()
            })
            .collect();
        let lights = PartitionLights {
            nodes: &node_light,
            pieces: &piece_light,
        };
        let bins = self
            .ring
            .as_ref()
            .map_or(0, |r| FILTER_LEVELS * (r.res + 1));
        let results: Vec<(PixelSample, Vec<f32>, [f64; 3])> = fragments
            .par_iter()
            .map_init(
                || Scratch {
                    hist: vec![0.0f64; 3 * bins],
                    runs: LitRuns::default(),
                    entries: RingEntries::default(),
                },
                |scratch, f| self.pixel(f, &spans, light, &lights, eye, f0, j_count, scratch),
            )
            .collect();
        let mut pixels = Vec::with_capacity(results.len());
        let mut t = Vec::with_capacity(results.len() * 3 * j_count);
        let mut irradiance = Vec::with_capacity(results.len());
        for (p, row, e) in results {
            pixels.push(p);
            t.extend_from_slice(&row);
            irradiance.push(e);
        }
        Transfer {
            width,
            height,
            pixels,
            lobes: j_count,
            t,
            irradiance,
            seconds: start.elapsed().as_secs_f64(),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn pixel(
        &self,
        f: &Fragment,
        spans: &[Option<Vec<Span>>],
        light: &LightSums,
        lights: &PartitionLights,
        eye: DVec3,
        f0: f64,
        j_count: usize,
        scratch: &mut Scratch,
    ) -> (PixelSample, Vec<f32>, [f64; 3]) {
        let Scratch {
            hist,
            runs,
            entries,
        } = scratch;
        runs.clear();
        let tri = self.mesh.triangles[f.triangle as usize];
        let b = f.bary.map(|x| x as f64);
        let position: DVec3 = (0..3)
            .map(|i| self.mesh.positions[tri[i] as usize].as_dvec3() * b[i])
            .sum();
        let normal = (0..3)
            .map(|i| self.mesh.normals[tri[i] as usize].as_dvec3() * b[i])
            .sum::<DVec3>()
            .try_normalize()
            .unwrap_or(DVec3::Y);
        let frame = match self.tangents {
            Some(t) => {
                let tw: Vec4 = (0..3).map(|i| t[tri[i] as usize] * f.bary[i]).sum();
                Frame::from_normal_tangent(
                    normal,
                    tw.truncate().as_dvec3(),
                    if tw.w < 0.0 { -1.0 } else { 1.0 },
                )
            }
            None => Frame::from_normal(normal),
        };
        let wo_world = (eye - position).try_normalize().unwrap_or(normal);
        let wo = frame.to_local(wo_world);
        let sample = PixelSample {
            x: f.x,
            y: f.y,
            triangle: f.triangle,
            bary: f.bary,
            position: position.as_vec3(),
            normal: normal.as_vec3(),
        };
        let mut acc = vec![0.0f64; 3 * j_count];
        let mut e = [0.0f64; 3];
        // Where the interpolated shading normal faces away from the eye (silhouettes), the specular
        // term is 0 and the diffuse term is kept: the convention every renderer shares.
        let specular = wo.z > 0.0;
        let vertex_spans: [&[Span]; 3] =
            std::array::from_fn(|i| spans[tri[i] as usize].as_deref().unwrap_or(&[]));
        let leaves = self.tree.leaf_count() as u32;
        // Per filter level, the histogram points [lo, hi] this pixel touched.
        let mut touched = [(usize::MAX, 0usize); FILTER_LEVELS];
        // The coarsest partition this view direction allows (grazing views narrow the lobes in wi).
        // A pixel with no specular term (wo below its shading horizon) needs only E: the coarsest.
        let pi = if specular {
            self.partitions
                .iter()
                .position(|p| wo.z >= p.min_wo_z)
                .unwrap_or(self.partitions.len() - 1)
        } else {
            0
        };
        let (part, node_light, piece_light) =
            (&self.partitions[pi], &lights.nodes[pi], &lights.pieces[pi]);
        for_each_run(&vertex_spans, &b, &part.ranges, leaves, |a, z, vis, si| {
            let whole = part.ranges[si] == (a as u32, z as u32);
            // ∫ L max(ω·n, 0) dω over the run, per channel: its radiant moment · n (exact up to
            // per-leaf constant radiance) when it lies wholly above the horizon (the shading node's
            // corner cone settles most runs at once), else split into sub-ranges above (their
            // radiant moments) and nodes astride (clipped at their mean radiance): a whole node by
            // its pieces, a part of one by a walk down the tree. A run in a shading node wholly
            // below the horizon is skipped by its cone.
            let cone = &part.cones[si];
            let cb = cone.axis.dot(normal);
            if cone.cos > 0.0 && cb < -cone.sin {
                return;
            }
            let radiant = if whole {
                node_light[si].radiant
            } else {
                light.radiant_moment(a, z)
            };
            let cos_power: [f64; 3] = if cone.cos > 0.0 && cb > cone.sin {
                std::array::from_fn(|c| radiant[c].dot(normal))
            } else if whole {
                part.clipped_cosine_power(si, piece_light, normal)
            } else {
                light.clipped_cosine_power(
                    self.tree,
                    part.nodes[si] as usize,
                    a,
                    z,
                    normal,
                    self.coarse_leaves,
                    &radiant,
                )
            };
            if cos_power.iter().all(|&x| x <= 0.0) {
                return;
            }
            let power = cos_power.map(|x| vis * x.max(0.0));
            for c in 0..3 {
                e[c] += power[c];
            }
            if !specular {
                return;
            }
            // Where the run's light comes from: its luminance-weighted moment.
            let Some((dir, v_omega)) = (if whole {
                node_light[si].direction
            } else {
                run_direction(&radiant, light.power(a, z))
            }) else {
                return;
            };
            if self.ring.is_some() {
                // Ring lobes: the histogram entries after the walk, in a loop of their own (no walk
                // in between, so the runs' arithmetic overlaps).
                runs.push(dir, v_omega, power);
                return;
            }
            let wi = frame.to_local(dir);
            if wi.z <= 0.0 {
                return;
            }
            let s = static_term(wi, wo, f0);
            let Some(h) = (wi + wo).try_normalize() else {
                return;
            };
            if s <= 0.0 {
                return;
            }
            let ws = s;
            let wp = [ws * power[0], ws * power[1], ws * power[2]];
            for &j in self.grid.candidates(h) {
                let j = j as usize;
                let g = self.lobes.eval_one(j, h);
                acc[j] += wp[0] * g;
                acc[j_count + j] += wp[1] * g;
                acc[2 * j_count + j] += wp[2] * g;
            }
        });
        if let Some(ring) = &self.ring {
            // Ring lobes need only h·n ([`half_vector_cosines_masked`]: no local frame). Each run's
            // weight goes to the two filter levels and two table points around (x, t): Σ_j g_j(x,
            // t) w.
            let stride = 3 * (ring.res + 1);
            ring_entries(ring, runs, normal, wo_world, wo.z, f0, entries);
            for (i, power) in runs.power.iter().enumerate() {
                let (l, k, fk) = (
                    entries.level[i] as usize,
                    entries.k[i] as usize,
                    entries.fk[i],
                );
                for (level, wl) in [(l, entries.lower[i]), (l + 1, entries.upper[i])] {
                    if wl == 0.0 {
                        continue;
                    }
                    let (below, above) = (wl * (1.0 - fk), wl * fk);
                    let b = level * stride + 3 * k;
                    for c in 0..3 {
                        hist[b + c] += below * power[c];
                        hist[b + 3 + c] += above * power[c];
                    }
                    touched[level] = (touched[level].0.min(k), touched[level].1.max(k + 1));
                }
            }
            for (level, &(k_lo, k_hi)) in touched.iter().enumerate() {
                if k_lo > k_hi {
                    continue;
                }
                let h = &mut hist[level * stride..(level + 1) * stride];
                for j in 0..j_count {
                    let (first, last) = ring.support[level * j_count + j];
                    let (a, z) = (first.max(k_lo), last.min(k_hi));
                    if a > z {
                        continue;
                    }
                    let row = &ring.row(level, j)[a..=z];
                    let (mut s0, mut s1, mut s2) = (0.0f64, 0.0f64, 0.0f64);
                    for (t, r) in h[3 * a..3 * z + 3].chunks_exact(3).zip(row) {
                        s0 += t[0] * r;
                        s1 += t[1] * r;
                        s2 += t[2] * r;
                    }
                    acc[j] += s0;
                    acc[j_count + j] += s1;
                    acc[2 * j_count + j] += s2;
                }
                h[3 * k_lo..3 * k_hi + 3].fill(0.0);
            }
        }
        (sample, acc.iter().map(|&x| x as f32).collect(), e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::LobeLayout;

    #[test]
    fn filtered_ring_rows_match_a_monte_carlo_average_under_jitter() {
        // The ring lobe averaged under a Gaussian tangent-plane jitter of h (per-axis variance v),
        // by Monte Carlo over the unfiltered closed form, against the table read as the transfer
        // reads it (level and point interpolated), for spreads between and on the levels.
        let lambda = srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap();
        let lobes = LobeSet::new(LobeLayout::Isotropic { count: 24 }, lambda).unwrap();
        let ring = RingFilter::new(&lobes);
        let mut rng = crate::math::Rng::new(3);
        let mut worst = 0.0f64;
        for j in [0usize, 5, 17] {
            let xi = lobes.centres()[j];
            let (cj, sj) = (xi.z, (xi.x * xi.x + xi.y * xi.y).sqrt());
            for x in [0.03, 0.1875, 0.6, 1.5] {
                let v = x / (2.0 * lambda);
                let (l, fl) = ring.level(v);
                for offset in [-1.5, 0.0, 0.7, 2.0] {
                    let theta = (cj.clamp(-1.0, 1.0).acos() + offset * srbf::PAPER_SIGMA).max(0.01);
                    let h = DVec3::new(theta.sin(), 0.0, theta.cos());
                    let (k, fk) = ring.position(h.z);
                    let read = |level: usize| {
                        ring.row(level, j)[k] * (1.0 - fk) + ring.row(level, j)[k + 1] * fk
                    };
                    let table = read(l) * (1.0 - fl) + read(l + 1) * fl;
                    let n = 40_000;
                    let mut mc = 0.0;
                    for _ in 0..n {
                        let (g1, g2) = rng.gaussian_pair();
                        let (t1, t2) = (DVec3::new(h.z, 0.0, -h.x), DVec3::Y);
                        let hj = (h + (t1 * g1 + t2 * g2) * v.sqrt()).normalize();
                        mc += srbf::ring_lobe(
                            hj.z,
                            (1.0 - hj.z * hj.z).max(0.0).sqrt(),
                            cj,
                            sj,
                            lambda,
                        );
                    }
                    mc /= n as f64;
                    worst = worst.max((table - mc).abs());
                }
            }
        }
        // Relative to the lobe's peak of 1 (Monte Carlo noise ~3e-3 at the peak).
        println!("worst |table - Monte Carlo| {worst:.2e}");
        assert!(worst < 0.008, "worst {worst}");
    }

    #[test]
    fn grid_candidates_hold_every_lobe_that_is_not_negligible() {
        // At random half-vectors, every lobe above the cutoff (relative to its peak of 1) is among
        // the grid cell's candidates, for ring and for hemicube lobes.
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
                        assert!(
                            candidates.contains(&(j as u32)),
                            "{layout:?}: lobe {j} at h = {h} missing from the grid"
                        );
                    }
                }
            }
            assert!(seen > 20_000, "{seen}");
        }
    }
}
