//! The tabulated distribution p(h): what a frame reads instead of summing J lobes (method.md §7).
//!
//! Inputs: a lobe set and its 3 × J coefficients; a resolution R. Output: a [`PhPyramid`] of RGB
//! p(h) on the hemi-octahedral map ([`crate::sphere::hemi_oct`]), sampled on a corner-aligned grid:
//! texel (x, y) holds p at (u, v) = (x/(R − 1), y/(R − 1)), row-major, so the outermost texels lie
//! on the horizon and bilinear interpolation covers the whole square without clamping (a half-texel
//! clamp at the horizon cost up to 4 % of the peak there); plus a stack of *pre-filtered* levels
//! for the renderers.
//!
//! Pre-filtering: a renderer that sums light over a run of directions evaluates the BRDF once, at
//! the run's light direction. The run's light has an angular spread (per-axis variance v_ω, rad²:
//! for a run of mean resultant length r, v_ω = 1 − r); in half-vector space that is v_h = v_ω / (4
//! wo·h). The mean of a lobe exp(2λ(h·ξ − 1)) ≈ exp(−λ α²) under a Gaussian jitter of per-axis
//! variance v is the lobe with λ' = λ/(1 + 2λv), scaled by λ'/λ (variances add; the integral is
//! kept). Level ℓ holds p with λ_ℓ = λ / 2^(ℓ/2) (half-octave steps); a lookup blends the two
//! levels around ℓ = 2·log2(1 + 2λ v_h) linearly. Level 0 is p itself; the exported table is
//! level 0. [`filtered_exact`] is the closed form the levels sample, for tests.
//!
//! Isotropic lobe sets (rings: p depends on θ_h only) are evaluated exactly on a polar profile per
//! level, p at q = √(1 − cos θ_h) on 8 R + 1 points, and the texels interpolate it; the profile is
//! kept for the CPU frame's lookups ([`PhPyramid::lookup_profile_filtered`]: no 2D interpolation
//! error).
//!
//! One table type: the tabulated data is [`glint_exporters::PhTable`] (what files hold and readers
//! look up); a [`PhPyramid`] is that table ([`PhPyramid::to_table`], level 0) plus the pre-filtered
//! levels and profiles the renderers read.
//!
//! Invariants: texels ≥ 0 (coefficients are ≥ 0); levels shrink with the lobes' width, never below
//! 16 texels a side; building only evaluates lobes whose support (G ≥ e^−14) reaches a texel (or,
//! for isotropic sets, every active lobe at the profile's points); no IO.

use crate::sphere::{LobeSet, hemi_oct, srbf};
use glam::DVec3;
use rayon::prelude::*;

/// Levels are spaced by this many octaves of 1 + 2λv.
const LEVEL_STEP_OCTAVES: f64 = 0.5;
/// Lobes are skipped where G < e^−CUTOFF.
const CUTOFF: f64 = 14.0;

/// One level: an R×R RGB grid, and for isotropic lobe sets the polar profile it was filled from.
#[derive(Debug, Clone)]
struct Level {
    resolution: usize,
    texels: Vec<[f32; 3]>,
    /// Isotropic sets only (else empty): p at q = √(1 − h·n) = k / (len − 1), k = 0..len, q ∈ [0,
    /// 1] (q ≈ θ_h/√2 near the normal, 1 at the horizon).
    profile: Vec<[f32; 3]>,
}

/// p(h) tabulated, with pre-filtered levels (level 0 is the [`glint_exporters::PhTable`]).
#[derive(Debug, Clone)]
pub struct PhPyramid {
    lambda: f64,
    levels: Vec<Level>,
}

/// The resolution for lobes of width σ: at least 16/σ texels a side, as a power of two in 64..=2048
/// (256 for the paper's σ = π/40: bilinear error under 1 % of the peak, tests below).
pub fn default_resolution(lambda: f64) -> usize {
    let sigma = srbf::sigma_from_lambda(lambda).unwrap_or(0.08);
    ((16.0 / sigma).ceil() as usize)
        .next_power_of_two()
        .clamp(64, 2048)
}

impl PhPyramid {
    /// Level 0 as the tabulated data files hold.
    pub fn to_table(&self) -> glint_exporters::PhTable {
        glint_exporters::PhTable {
            resolution: self.resolution() as u32,
            texels: self.texels().to_vec(),
        }
    }

    /// Tabulates p(h) = Σ_j c_j G_j(h) per channel at `resolution` (level 0) and its pre-filtered
    /// levels.
    pub fn build(lobes: &LobeSet, coefficients: [&[f64]; 3], resolution: usize) -> Self {
        Self::build_levels(lobes, coefficients, resolution, true)
    }

    /// Level 0 only (what is exported; lookups with a spread then read level 0).
    pub fn build_unfiltered(lobes: &LobeSet, coefficients: [&[f64]; 3], resolution: usize) -> Self {
        Self::build_levels(lobes, coefficients, resolution, false)
    }

    fn build_levels(
        lobes: &LobeSet,
        coefficients: [&[f64]; 3],
        resolution: usize,
        filtered: bool,
    ) -> Self {
        let lambda = lobes.lambda();
        let resolution = resolution.clamp(16, 8192);
        // Lobes with any positive coefficient.
        let active: Vec<usize> = (0..lobes.len())
            .filter(|&j| {
                coefficients
                    .iter()
                    .any(|c| c.get(j).copied().unwrap_or(0.0) > 0.0)
            })
            .collect();
        let mut levels = Vec::new();
        let mut level = 0usize;
        loop {
            let factor = 2f64.powf(level as f64 * LEVEL_STEP_OCTAVES);
            let lambda_l = lambda / factor;
            // Lobe width grows as √factor: the grid may shrink as much.
            let res = ((resolution as f64 / factor.sqrt()).round() as usize)
                .max(16)
                .min(resolution);
            levels.push(tabulate(
                lobes,
                &active,
                coefficients,
                lambda_l,
                lambda_l / lambda,
                res,
            ));
            level += 1;
            // Stop once the lobes are nearly flat (λ < ¼) or after 40 levels (λ up to 2^20).
            if !filtered || lambda_l < 0.25 || level >= 40 {
                break;
            }
        }
        Self { lambda, levels }
    }

    /// λ of the lobes tabulated at level 0.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Resolution of level 0.
    pub fn resolution(&self) -> usize {
        self.levels[0].resolution
    }

    /// Level 0's texels (row-major, RGB): the table that is exported.
    pub fn texels(&self) -> &[[f32; 3]] {
        &self.levels[0].texels
    }

    /// Number of pre-filtered levels (level 0 included).
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// (resolution, texels) of each level, for the GPU upload.
    pub fn levels(&self) -> impl Iterator<Item = (usize, &[[f32; 3]])> {
        self.levels
            .iter()
            .map(|l| (l.resolution, l.texels.as_slice()))
    }

    /// Bytes of all levels (texels and polar profiles).
    pub fn bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| (l.texels.len() + l.profile.len()) * 12)
            .sum()
    }

    /// p(h) at a local unit half-vector (bilinear on level 0).
    #[inline]
    pub fn lookup(&self, h: DVec3) -> [f64; 3] {
        bilinear(&self.levels[0], h)
    }

    /// p(h) averaged under an angular jitter of per-axis variance `spread` (rad², in half-vector
    /// space): linear between the two levels around 2·log2(1 + 2λ·spread).
    #[inline]
    pub fn lookup_filtered(&self, h: DVec3, spread: f64) -> [f64; 3] {
        self.blend_levels(spread, |level| bilinear(level, h))
    }

    /// `sample` on the two levels around a spread's continuous level, blended linearly.
    #[inline]
    fn blend_levels(&self, spread: f64, sample: impl Fn(&Level) -> [f64; 3]) -> [f64; 3] {
        let t = level_position(self.lambda, spread).min((self.levels.len() - 1) as f64);
        let i = t as usize;
        let f = t - i as f64;
        let a = sample(&self.levels[i]);
        if f <= 0.0 || i + 1 >= self.levels.len() {
            return a;
        }
        let b = sample(&self.levels[i + 1]);
        [
            a[0] + (b[0] - a[0]) * f,
            a[1] + (b[1] - a[1]) * f,
            a[2] + (b[2] - a[2]) * f,
        ]
    }

    /// Whether the table holds polar profiles (isotropic lobe sets):
    /// [`PhPyramid::lookup_profile_filtered`].
    pub fn has_profile(&self) -> bool {
        !self.levels[0].profile.is_empty()
    }

    /// As [`PhPyramid::lookup_filtered`], from the levels' polar profiles instead of their texels
    /// (same levels, same blend): no 2D interpolation error and two cache lines per level instead
    /// of four texels spread over a 2D grid. `None` for anisotropic tables.
    #[inline]
    pub fn lookup_profile_filtered(&self, h: DVec3, spread: f64) -> Option<[f64; 3]> {
        if !self.has_profile() {
            return None;
        }
        // q = √(1 − h·n) once for both levels (profile_at's position, shared).
        let q = (1.0 - h.z).max(0.0).sqrt();
        Some(self.blend_levels(spread, |level| profile_at_q(&level.profile, q)))
    }
}

/// The continuous level of a spread: 2·log2(1 + 2λ·spread) (0 for no spread).
#[inline]
pub fn level_position(lambda: f64, spread: f64) -> f64 {
    if !(spread > 0.0) {
        return 0.0;
    }
    // A blend weight between levels needs no more than fast_log2's 1e-4 octaves.
    fast_log2((1.0 + 2.0 * lambda * spread) as f32) as f64 / LEVEL_STEP_OCTAVES
}

/// log2 of a positive finite f32 to within 1e-4: the exponent from the bits plus a quintic in the
/// mantissa m ∈ [1, 2) (a fifth of libm's log2f in the frame's profile: it ran once per run).
#[inline]
fn fast_log2(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) {
        return x.log2();
    }
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32;
    if e == 0 {
        return x.log2(); // subnormal
    }
    // t = m − 1 ∈ [0, 1): a least-squares quintic in t, within 2.9e-5 of log2(1 + t).
    let t = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000) - 1.0;
    let p = t
        * (1.441_825_8
            + t * (-0.708_682_1 + t * (0.415_421_95 + t * (-0.194_422_67 + t * 0.045_885_527))));
    (e - 127) as f32 + p
}

/// The closed form the levels sample: Σ c_j (λ'/λ) G_j(h; λ'), λ' = λ/(1 + 2λ·spread), per channel.
pub fn filtered_exact(
    lobes: &LobeSet,
    coefficients: [&[f64]; 3],
    h: DVec3,
    spread: f64,
) -> [f64; 3] {
    let lambda = lobes.lambda();
    let lp = lambda / (1.0 + 2.0 * lambda * spread.max(0.0));
    let mut out = [0.0f64; 3];
    for j in 0..lobes.len() {
        if coefficients
            .iter()
            .all(|c| c.get(j).copied().unwrap_or(0.0) == 0.0)
        {
            continue;
        }
        let g = lobes.eval_exact_lambda(j, h, lp) * (lp / lambda);
        for c in 0..3 {
            out[c] += coefficients[c].get(j).copied().unwrap_or(0.0) * g;
        }
    }
    out
}

/// Samples of the polar profile that isotropic tables interpolate, per texel of the level's side: 8
/// R intervals of q = √(1 − cos θ_h) over [0, 1] (2048 at R = 256, 24 KB) keep the linear
/// interpolation's error, about (Δq/σ_q)²/8 of the peak with σ_q ≈ σ/√2, near 1e-5 (R grows as
/// 16/σ, so Δq/σ_q stays below √2/128).
const PROFILE_SAMPLES_PER_TEXEL: usize = 8;

fn tabulate(
    lobes: &LobeSet,
    active: &[usize],
    coefficients: [&[f64]; 3],
    lambda_l: f64,
    scale: f64,
    res: usize,
) -> Level {
    if lobes.layout().is_isotropic() {
        tabulate_isotropic(lobes, active, coefficients, lambda_l, scale, res)
    } else {
        tabulate_direct(lobes, active, coefficients, lambda_l, scale, res)
    }
}

/// Every texel sums the lobes whose support reaches it.
fn tabulate_direct(
    lobes: &LobeSet,
    active: &[usize],
    coefficients: [&[f64]; 3],
    lambda_l: f64,
    scale: f64,
    res: usize,
) -> Level {
    let support = LobeSet::support_angle(lambda_l, CUTOFF);
    // A texel's bilinear footprint reaches about 1.5 texels; the map's texels are at most ~π/R
    // wide.
    let slack = 1.5 * std::f64::consts::PI / (res - 1) as f64;
    let texels: Vec<[f32; 3]> = (0..res * res)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % res, k / res);
            let h = hemi_oct::decode(x as f64 / (res - 1) as f64, y as f64 / (res - 1) as f64);
            let mut p = [0.0f64; 3];
            for &j in active {
                if lobes.distance(j, h) > support + slack {
                    continue;
                }
                let g = lobes.eval_exact_lambda(j, h, lambda_l) * scale;
                for c in 0..3 {
                    p[c] += coefficients[c].get(j).copied().unwrap_or(0.0).max(0.0) * g;
                }
            }
            p.map(|v| v as f32)
        })
        .collect();
    Level {
        resolution: res,
        texels,
        profile: Vec::new(),
    }
}

/// Ring lobes depend on the half-vector's polar angle only: p is evaluated exactly on a fine
/// profile over q = √(1 − cos θ_h) ∈ [0, 1] and each texel interpolates it linearly (J lobe
/// evaluations per profile sample instead of per texel: 18 levels of 256² texels took 0.2 s, the
/// profile a few ms). The profile is kept: the CPU frame reads it instead of the texels
/// ([`PhPyramid::lookup_profile_filtered`]).
fn tabulate_isotropic(
    lobes: &LobeSet,
    active: &[usize],
    coefficients: [&[f64]; 3],
    lambda_l: f64,
    scale: f64,
    res: usize,
) -> Level {
    let samples = PROFILE_SAMPLES_PER_TEXEL * res;
    let profile: Vec<[f64; 3]> = (0..=samples)
        .into_par_iter()
        .map(|i| {
            let q = i as f64 / samples as f64;
            let z = 1.0 - q * q;
            let h = DVec3::new((1.0 - z * z).max(0.0).sqrt(), 0.0, z);
            let mut p = [0.0f64; 3];
            for &j in active {
                let g = lobes.eval_exact_lambda(j, h, lambda_l) * scale;
                for c in 0..3 {
                    p[c] += coefficients[c].get(j).copied().unwrap_or(0.0).max(0.0) * g;
                }
            }
            p
        })
        .collect();
    let texels: Vec<[f32; 3]> = (0..res * res)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % res, k / res);
            let h = hemi_oct::decode(x as f64 / (res - 1) as f64, y as f64 / (res - 1) as f64);
            profile_at(&profile, h.z).map(|v| v as f32)
        })
        .collect();
    Level {
        resolution: res,
        texels,
        profile: profile.iter().map(|p| p.map(|v| v as f32)).collect(),
    }
}

/// Linear interpolation of a q-profile at cos θ_h = z.
#[inline]
fn profile_at<T: Copy + Into<f64>>(profile: &[[T; 3]], z: f64) -> [f64; 3] {
    profile_at_q(profile, (1.0 - z).max(0.0).sqrt())
}

/// [`profile_at`] at q = √(1 − z) already taken.
#[inline]
fn profile_at_q<T: Copy + Into<f64>>(profile: &[[T; 3]], q: f64) -> [f64; 3] {
    let last = profile.len() - 1;
    let t = (q * last as f64).min(last as f64);
    let i = (t as usize).min(last - 1);
    let f = t - i as f64;
    let (a, b) = (profile[i], profile[i + 1]);
    std::array::from_fn(|c| a[c].into() + (b[c].into() - a[c].into()) * f)
}

#[inline]
fn bilinear(level: &Level, h: DVec3) -> [f64; 3] {
    let r = level.resolution;
    let (u, v) = hemi_oct::encode(h);
    let x = (u * (r - 1) as f64).clamp(0.0, (r - 1) as f64);
    let y = (v * (r - 1) as f64).clamp(0.0, (r - 1) as f64);
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(r - 1), (y0 + 1).min(r - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let t = &level.texels;
    let (a, b, c, d) = (
        t[y0 * r + x0],
        t[y0 * r + x1],
        t[y1 * r + x0],
        t[y1 * r + x1],
    );
    std::array::from_fn(|k| {
        let top = a[k] as f64 + (b[k] as f64 - a[k] as f64) * fx;
        let bottom = c[k] as f64 + (d[k] as f64 - c[k] as f64) * fx;
        top + (bottom - top) * fy
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn fast_log2_is_within_1e_4_of_log2() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let x = 1.0f32 + i as f32 * 1e-3;
            worst = worst.max((super::fast_log2(x) as f64 - (x as f64).log2()).abs());
            let y = 1e-3f32 * (1.0 + i as f32 * 1e-5);
            worst = worst.max((super::fast_log2(y) as f64 - (y as f64).log2()).abs());
        }
        assert!(worst < 1e-4, "{worst}");
    }

    use super::*;
    use crate::math::Rng;
    use crate::sphere::LobeLayout;

    fn random_coefficients(j: usize, seed: u64) -> [Vec<f64>; 3] {
        let mut rng = Rng::new(seed);
        std::array::from_fn(|_| {
            (0..j)
                .map(|_| {
                    if rng.next_f64() < 0.3 {
                        rng.next_f64()
                    } else {
                        0.0
                    }
                })
                .collect()
        })
    }

    #[test]
    fn level_zero_matches_the_lobe_sum() {
        // Bilinear interpolation at the default resolution against the exact sum, at random
        // half-vectors where p is not negligible: relative error ≤ 0.5 % (measured worst printed).
        for layout in [LobeLayout::PAPER, LobeLayout::Isotropic { count: 24 }] {
            let lobes =
                LobeSet::new(layout, srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap()).unwrap();
            let c = random_coefficients(lobes.len(), 5);
            let cr = [c[0].as_slice(), c[1].as_slice(), c[2].as_slice()];
            let table = PhPyramid::build(&lobes, cr, default_resolution(lobes.lambda()));
            let mut rng = Rng::new(9);
            let peak = (0..2000)
                .map(|_| lobes.p(&c[0], rng.hemisphere_vector()))
                .fold(0.0f64, f64::max);
            // Error relative to the peak (what a render sees), and relative to the value where p is
            // at least half its peak.
            let (mut worst_peak, mut worst_half) = (0.0f64, 0.0f64);
            for _ in 0..20_000 {
                let h = rng.hemisphere_vector();
                let want = filtered_exact(&lobes, cr, h, 0.0);
                let got = table.lookup(h);
                for k in 0..3 {
                    worst_peak = worst_peak.max((got[k] - want[k]).abs() / peak);
                    if want[k] > 0.5 * peak {
                        worst_half = worst_half.max((got[k] - want[k]).abs() / want[k]);
                    }
                }
            }
            println!(
                "{}: R = {}, worst error {worst_peak:.2e} of the peak, {worst_half:.2e} relative where p > peak/2",
                layout.name(),
                table.resolution()
            );
            // Measured at R = 256: hemicube 8.3e-3 of the peak, 1.3e-2 relative near peaks
            // (bilinear flattens the lobes' tops where the map's texels are widest); renders
            // average this down to < 0.1 % (tests/it/render.rs).
            assert!(
                worst_peak < 1e-2 && worst_half < 1.5e-2,
                "{}: {worst_peak} {worst_half}",
                layout.name()
            );
        }
    }

    #[test]
    fn isotropic_profile_equals_texel_by_texel_sums() {
        // The polar-angle profile against summing the lobes at every texel, on every level.
        let lobes = LobeSet::new(
            LobeLayout::Isotropic { count: 24 },
            srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
        )
        .unwrap();
        let c = random_coefficients(lobes.len(), 11);
        let cr = [c[0].as_slice(), c[1].as_slice(), c[2].as_slice()];
        let active: Vec<usize> = (0..lobes.len())
            .filter(|&j| c.iter().any(|ch| ch[j] > 0.0))
            .collect();
        for (level, factor) in [(0, 1.0f64), (3, 2f64.powf(1.5)), (9, 2f64.powf(4.5))] {
            let lambda_l = lobes.lambda() / factor;
            let res = ((256.0 / factor.sqrt()).round() as usize).max(16);
            let fast = tabulate_isotropic(
                &lobes,
                &active,
                cr,
                lambda_l,
                lambda_l / lobes.lambda(),
                res,
            );
            let direct = tabulate_direct(
                &lobes,
                &active,
                cr,
                lambda_l,
                lambda_l / lobes.lambda(),
                res,
            );
            let peak = direct
                .texels
                .iter()
                .flatten()
                .fold(0.0f32, |a, b| a.max(*b));
            let worst = fast
                .texels
                .iter()
                .zip(&direct.texels)
                .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
                .fold(0.0f32, f32::max);
            println!(
                "level {level}: R = {res}, worst {:.2e} of the peak {peak:.3}",
                worst / peak
            );
            assert!(
                peak > 0.0 && worst <= 2e-5 * peak,
                "level {level}: {worst} of {peak}"
            );
        }
    }

    #[test]
    fn profile_lookups_match_the_lobe_sum_and_the_texel_lookups() {
        let lobes = LobeSet::new(
            LobeLayout::Isotropic { count: 24 },
            srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
        )
        .unwrap();
        let c = random_coefficients(lobes.len(), 21);
        let cr = [c[0].as_slice(), c[1].as_slice(), c[2].as_slice()];
        let table = PhPyramid::build(&lobes, cr, default_resolution(lobes.lambda()));
        assert!(table.has_profile());
        let mut rng = Rng::new(3);
        let peak = (0..2000)
            .map(|_| rng.hemisphere_vector())
            .flat_map(|h| c.iter().map(move |ch| (ch, h)))
            .map(|(ch, h)| lobes.p(ch, h))
            .fold(0.0f64, f64::max);
        let (mut vs_exact, mut vs_texels) = (0.0f64, 0.0f64);
        for k in 0..20_000 {
            let h = rng.hemisphere_vector();
            // Unfiltered: the profile against the closed form.
            let got = table.lookup_profile_filtered(h, 0.0).unwrap();
            let want = filtered_exact(&lobes, cr, h, 0.0);
            // Filtered: the same levels and blend as the texel lookup, so they differ by the
            // texels' bilinear error only.
            let spread = [1e-4, 1e-3, 1e-2][k % 3];
            let (p, t) = (
                table.lookup_profile_filtered(h, spread).unwrap(),
                table.lookup_filtered(h, spread),
            );
            for ch in 0..3 {
                vs_exact = vs_exact.max((got[ch] - want[ch]).abs() / peak);
                vs_texels = vs_texels.max((p[ch] - t[ch]).abs() / peak);
            }
        }
        println!(
            "profile: worst {vs_exact:.2e} of the peak against the lobe sum, {vs_texels:.2e} against the texel lookups"
        );
        // Measured: 1.05e-5 and 1.23e-3 (the texels' bilinear error near the pole).
        assert!(vs_exact < 3e-5, "{vs_exact}");
        assert!(vs_texels < 2.5e-3, "{vs_texels}");
        // Anisotropic tables have no profile.
        let aniso = LobeSet::new(LobeLayout::PAPER, lobes.lambda()).unwrap();
        let ca = random_coefficients(aniso.len(), 2);
        let t = PhPyramid::build(&aniso, [&ca[0], &ca[1], &ca[2]], 64);
        assert!(!t.has_profile() && t.lookup_profile_filtered(DVec3::Z, 0.0).is_none());
    }

    #[test]
    fn filtered_levels_match_the_closed_form_and_a_monte_carlo_average() {
        let lambda = srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap();
        let lobes = LobeSet::new(LobeLayout::PAPER, lambda).unwrap();
        let mut c = vec![0.0; lobes.len()];
        let top = (0..lobes.len())
            .max_by(|&a, &b| lobes.centres()[a].z.total_cmp(&lobes.centres()[b].z))
            .unwrap();
        c[top] = 1.0; // the lobe nearest the pole
        let cr = [c.as_slice(), c.as_slice(), c.as_slice()];
        let table = PhPyramid::build(&lobes, cr, 256);
        let top = (0..lobes.len())
            .max_by(|&a, &b| lobes.centres()[a].z.total_cmp(&lobes.centres()[b].z))
            .unwrap();
        let xi = lobes.centres()[top];
        let frame = crate::sphere::Frame::from_normal(xi);
        let mut rng = Rng::new(1);
        for spread in [1e-4f64, 1e-3, 4e-3, 2e-2] {
            for offset_deg in [0.0f64, 3.0, 8.0] {
                let a = offset_deg.to_radians();
                let h = frame.to_world(DVec3::new(a.sin(), 0.0, a.cos()));
                let around_h = crate::sphere::Frame::from_normal(h);
                // Monte Carlo: the lobe averaged under a Gaussian tangent-plane jitter of variance
                // `spread`.
                let n = 200_000;
                let mut sum = 0.0;
                for _ in 0..n {
                    let (g1, g2) = rng.gaussian_pair();
                    let (dx, dy) = (g1 * spread.sqrt(), g2 * spread.sqrt());
                    let d = around_h.to_world(DVec3::new(dx, dy, 1.0).normalize());
                    sum += srbf::gaussian(d.dot(xi), lambda);
                }
                let mc = sum / n as f64;
                let exact = filtered_exact(&lobes, cr, h, spread)[0];
                let tab = table.lookup_filtered(h, spread)[0];
                println!(
                    "spread {spread:.0e} offset {offset_deg}°: MC {mc:.5}, closed form {exact:.5}, table {tab:.5}"
                );
                // The closed form is a small-angle approximation: within 3 % of the true average
                // (or 1e-3 absolute where both are tiny); the table follows the closed form within
                // 3 %.
                assert!(
                    (exact - mc).abs() <= 0.03 * mc + 1e-3,
                    "closed form {exact} vs MC {mc}"
                );
                assert!(
                    (tab - exact).abs() <= 0.03 * exact + 1e-3,
                    "table {tab} vs closed form {exact}"
                );
            }
        }
    }
}
