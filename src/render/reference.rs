//! The Monte Carlo reference: ground truth for tests and the accuracy study (method.md §2, §7).
//!
//! Per pixel (the same pixel-centre hit as the PRT raster, so both renderers shade the same points)
//! it estimates B = ∫ L(ωi) V(x, ωi) f_r(ωi, ωo) max(ωi·n, 0) dωi with
//! - L: the environment map itself, read as constant over each texel ([`EnvMap::lookup_nearest`],
//!   rotated), not the direction set;
//! - V: a ray per sample against the mesh (obvhs CWBVH any-hit), from the point lifted onto the
//!   smooth surface its vertex normals describe (the shadow-terminator fix of Hanika 2021, which
//!   Blender's Cycles also applies) and offset along its shading normal by the bake's offset;
//! - f_r: the exact lobe sum (closed form, no table), ρd/π + p(h) s(ωi, ωo);
//! - two strategies combined by multiple importance sampling (power heuristic): the environment
//!   (texels ∝ luminance × sin θ, uniform within the texel, mixed with 10 % uniform directions:
//!   L/pdf is then nearly constant, even for a one-texel sun) and the BRDF (cosine lobe for ρd, the
//!   lobes themselves for p: a lobe picked ∝ its coefficient, h drawn from its von Mises–Fisher
//!   density exp(2λ(h·ξ − 1))).
//!
//! Inputs: the scene's mesh and tangents, a [`Tracer`], the environment and rotation, the material
//! (glint's exact lobes, or a standard material — an exported fallback — sampled by the cosine and
//! its GGX lobes: [`render_reference_standard`]), a camera, a size, samples per pixel and a seed.
//! Output: an [`Image`] (object pixels only). Invariants: each pixel has its own random stream
//! seeded from (seed, pixel), so the image does not depend on the thread count; f64 accumulation;
//! no IO.

use super::image::Image;
use crate::bake::tracer::Tracer;
use crate::brdf::dbrdf::static_term;
use crate::brdf::standard::StandardMaterial;
use crate::env::{EnvMap, direction_to_uv, rotate_y, uv_to_direction};
use crate::math::Rng;
use crate::raster::rasterize;
use crate::scene::{Camera, Mesh};
use crate::sphere::{Frame, LobeSet};
use glam::{DVec3, Vec3A, Vec4};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Share of environment samples drawn uniformly over the sphere (defensive mixture).
const UNIFORM_SHARE: f64 = 0.1;

/// The material as the reference needs it: the exact lobes.
#[derive(Debug, Clone, Copy)]
pub struct ExactMaterial<'a> {
    pub lobes: &'a LobeSet,
    pub coefficients: [&'a [f64]; 3],
    pub rho_d: [f64; 3],
    pub f0: f64,
}

/// Importance sampling of the environment map.
pub struct EnvSampler<'a> {
    env: &'a EnvMap,
    rotation_rad: f64,
    /// Cumulative row weights (len H + 1) and per-row cumulative column weights (H × (W + 1)).
    rows: Vec<f64>,
    cols: Vec<f64>,
    total: f64,
}

impl<'a> EnvSampler<'a> {
    /// Builds the tables for `env` rotated by `rotation_rad` about +Y.
    pub fn new(env: &'a EnvMap, rotation_rad: f64) -> Self {
        let (w, h) = (env.width(), env.height());
        let lum = |c: usize, r: usize| -> f64 {
            let t = env.texel(c, r).unwrap_or([0.0; 3]);
            let l = 0.2126 * t[0] as f64 + 0.7152 * t[1] as f64 + 0.0722 * t[2] as f64;
            if l.is_finite() { l.max(0.0) } else { 0.0 }
        };
        let mut cols = Vec::with_capacity(h * (w + 1));
        let mut rows = vec![0.0];
        for r in 0..h {
            let sin = ((r as f64 + 0.5) / h as f64 * PI).sin();
            let mut acc = 0.0;
            cols.push(0.0);
            for c in 0..w {
                acc += lum(c, r) * sin;
                cols.push(acc);
            }
            rows.push(rows[r] + acc);
        }
        let total = rows[h];
        Self {
            env,
            rotation_rad,
            rows,
            cols,
            total,
        }
    }

    /// A direction (world) and its density (per steradian) under the mixture.
    pub fn sample(&self, rng: &mut Rng) -> (DVec3, f64) {
        let (a, b) = (rng.next_f64(), rng.next_f64());
        self.sample_with(rng, a, b)
    }

    /// [`Self::sample`] with the texel chosen by the point (a, b) ∈ [0, 1)² (stratified callers).
    pub fn sample_with(&self, rng: &mut Rng, a: f64, b: f64) -> (DVec3, f64) {
        let d = if self.total <= 0.0 || rng.next_f64() < UNIFORM_SHARE {
            rng.unit_vector()
        } else {
            let (w, h) = (self.env.width(), self.env.height());
            let r = search(&self.rows, a * self.total);
            let row = &self.cols[r * (w + 1)..(r + 1) * (w + 1)];
            let c = search(row, b * row[w]);
            let (u, v) = (
                (c as f64 + rng.next_f64()) / w as f64,
                (r as f64 + rng.next_f64()) / h as f64,
            );
            rotate_y(uv_to_direction(u, v), self.rotation_rad)
        };
        (d, self.pdf(d))
    }

    /// Density of the mixture at a world direction.
    pub fn pdf(&self, d: DVec3) -> f64 {
        let uniform = 1.0 / (4.0 * PI);
        if self.total <= 0.0 {
            return uniform;
        }
        let (w, h) = (self.env.width(), self.env.height());
        let (u, v) = direction_to_uv(rotate_y(d, -self.rotation_rad));
        let c = ((u * w as f64) as usize).min(w - 1);
        let r = ((v * h as f64) as usize).min(h - 1);
        let weight = self.cols[r * (w + 1) + c + 1] - self.cols[r * (w + 1) + c];
        let sin = (v * PI).sin().max(1e-12);
        let texel = weight / self.total * (w * h) as f64 / (2.0 * PI * PI * sin);
        UNIFORM_SHARE * uniform + (1.0 - UNIFORM_SHARE) * texel
    }
}

/// Van der Corput radical inverse in base 2.
fn radical_inverse(i: u32) -> f64 {
    i.reverse_bits() as f64 * (1.0 / 4_294_967_296.0)
}

/// Index i with `cdf[i] ≤ x < cdf[i + 1]` (cdf ascending, `cdf[0] = 0`), skipping empty bins.
fn search(cdf: &[f64], x: f64) -> usize {
    let n = cdf.len() - 1;
    let i = cdf
        .partition_point(|&c| c <= x)
        .saturating_sub(1)
        .min(n - 1);
    // Land on a bin of positive width (x may sit exactly on a boundary).
    let mut k = i;
    while k + 1 < n && cdf[k + 1] <= cdf[k] {
        k += 1;
    }
    k
}

/// What the reference needs of a BRDF (local frame, f without the cosine).
trait Shade: Sync {
    fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3];
    /// Density of [`Shade::sample`]'s wi per steradian.
    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64;
    fn sample(&self, wo: DVec3, rng: &mut Rng) -> DVec3;
}

/// The BRDF as sampled and evaluated by the reference (local frame).
struct Brdf<'a> {
    m: ExactMaterial<'a>,
    /// Lobe choice ∝ luminance of the coefficients (cumulative), and their total.
    lobe_cdf: Vec<f64>,
    /// Probability of sampling the specular lobes rather than the cosine.
    q_spec: f64,
    kappa: f64,
    /// vMF normalisation κ / (2π (1 − e^−2κ)).
    vmf_norm: f64,
}

impl<'a> Brdf<'a> {
    fn new(m: ExactMaterial<'a>) -> Self {
        let mut lobe_cdf = vec![0.0];
        for j in 0..m.lobes.len() {
            let w: f64 = (0..3)
                .map(|c| {
                    [0.2126, 0.7152, 0.0722][c]
                        * m.coefficients[c].get(j).copied().unwrap_or(0.0).max(0.0)
                })
                .sum();
            lobe_cdf.push(lobe_cdf[j] + w);
        }
        let kappa = 2.0 * m.lobes.lambda();
        // Rough albedos: the lobes' Σ c_j ∫G (∫G ≈ π/λ) against ρd.
        let spec = lobe_cdf[m.lobes.len()] * PI / m.lobes.lambda();
        let diff = 0.2126 * m.rho_d[0] + 0.7152 * m.rho_d[1] + 0.0722 * m.rho_d[2];
        let q_spec = if lobe_cdf[m.lobes.len()] <= 0.0 {
            0.0
        } else {
            (spec / (spec + diff).max(1e-300)).clamp(0.2, 0.8)
        };
        let vmf_norm = kappa / (2.0 * PI * -(-2.0 * kappa).exp_m1());
        Self {
            m,
            lobe_cdf,
            q_spec,
            kappa,
            vmf_norm,
        }
    }

    /// Density of the half-vector mixture at h (per steradian of h).
    fn pdf_h(&self, h: DVec3) -> f64 {
        let total = *self.lobe_cdf.last().unwrap_or(&0.0);
        if total <= 0.0 {
            return 0.0;
        }
        let mut acc = 0.0;
        for j in 0..self.m.lobes.len() {
            let w = self.lobe_cdf[j + 1] - self.lobe_cdf[j];
            if w > 0.0 {
                acc += w * self.m.lobes.eval_exact(j, h);
            }
        }
        acc / total * self.vmf_norm
    }
}

impl Shade for Brdf<'_> {
    fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        let diffuse = self.m.rho_d.map(|r| r / PI);
        if wi.z <= 0.0 {
            return [0.0; 3];
        }
        if wo.z <= 0.0 {
            // Shading normal facing away from the eye: diffuse only (the renderers' shared
            // convention).
            return diffuse;
        }
        if self.q_spec == 0.0 {
            return diffuse;
        }
        let Some(h) = (wi + wo).try_normalize() else {
            return diffuse;
        };
        let s = static_term(wi, wo, self.m.f0);
        let mut p = [0.0f64; 3];
        for j in 0..self.m.lobes.len() {
            if self.lobe_cdf[j + 1] <= self.lobe_cdf[j] {
                continue;
            }
            let g = self.m.lobes.eval_exact(j, h);
            for c in 0..3 {
                p[c] += self.m.coefficients[c].get(j).copied().unwrap_or(0.0) * g;
            }
        }
        std::array::from_fn(|c| diffuse[c] + p[c] * s)
    }

    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let diffuse = if wi.z > 0.0 { wi.z / PI } else { 0.0 };
        let spec = if self.q_spec > 0.0 {
            match (wi + wo).try_normalize() {
                Some(h) if wo.dot(h) > 0.0 => self.pdf_h(h) / (4.0 * wo.dot(h)),
                _ => 0.0,
            }
        } else {
            0.0
        };
        (1.0 - self.q_spec) * diffuse + self.q_spec * spec
    }

    fn sample(&self, wo: DVec3, rng: &mut Rng) -> DVec3 {
        if rng.next_f64() >= self.q_spec {
            // Cosine-weighted hemisphere.
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let r = u1.sqrt();
            let phi = 2.0 * PI * u2;
            return DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
        }
        let total = *self.lobe_cdf.last().unwrap_or(&0.0);
        let j = search(&self.lobe_cdf, rng.next_f64() * total);
        let mut xi = self.m.lobes.centres()[j];
        if self.m.lobes.layout().is_isotropic() {
            // A ring lobe is its centre's lobe averaged over the azimuth: rotate the centre at
            // random.
            let phi = 2.0 * PI * rng.next_f64();
            let r = (xi.x * xi.x + xi.y * xi.y).sqrt();
            xi = DVec3::new(r * phi.cos(), r * phi.sin(), xi.z);
        }
        // vMF about ξ: cos α = 1 + ln(u + (1 − u) e^−2κ)/κ.
        let u = rng.next_f64();
        let cos_a =
            (1.0 + (u + (1.0 - u) * (-2.0 * self.kappa).exp()).ln() / self.kappa).clamp(-1.0, 1.0);
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        let phi = 2.0 * PI * rng.next_f64();
        let h = Frame::from_normal(xi).to_world(DVec3::new(
            sin_a * phi.cos(),
            sin_a * phi.sin(),
            cos_a,
        ));
        2.0 * wo.dot(h) * h - wo
    }
}

/// A standard material (an exported fallback) as the reference samples it: the cosine and each
/// GGX lobe (base, coat) in equal shares, h drawn from D(h)·cos θh.
struct StandardShade<'a> {
    m: &'a StandardMaterial,
    alphas: Vec<f64>,
}

impl StandardShade<'_> {
    fn share(&self) -> f64 {
        1.0 / (1 + self.alphas.len()) as f64
    }
}

/// GGX D(h) cos θh: the density of h per steradian.
fn ggx_pdf_h(alpha: f64, cos_h: f64) -> f64 {
    if cos_h <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t) * cos_h
}

impl Shade for StandardShade<'_> {
    fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        self.m.eval(wi, wo)
    }

    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let share = self.share();
        let mut pdf = if wi.z > 0.0 { share * wi.z / PI } else { 0.0 };
        if let Some(h) = (wi + wo).try_normalize()
            && wo.dot(h) > 0.0
        {
            for &alpha in &self.alphas {
                pdf += share * ggx_pdf_h(alpha, h.z) / (4.0 * wo.dot(h));
            }
        }
        pdf
    }

    fn sample(&self, wo: DVec3, rng: &mut Rng) -> DVec3 {
        let pick = (rng.next_f64() * (1 + self.alphas.len()) as f64) as usize;
        if pick == 0 || pick > self.alphas.len() {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let r = u1.sqrt();
            let phi = 2.0 * PI * u2;
            return DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
        }
        let alpha = self.alphas[pick - 1];
        let u = rng.next_f64();
        // tan² θh = α² u / (1 − u).
        let t2 = alpha * alpha * u / (1.0 - u).max(1e-300);
        let cos_h = 1.0 / (1.0 + t2).sqrt();
        let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
        let phi = 2.0 * PI * rng.next_f64();
        let h = DVec3::new(sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
        2.0 * wo.dot(h) * h - wo
    }
}

/// Renders the Monte Carlo reference of a standard material (an exported fallback,
/// [`StandardMaterial`]) with the same estimator, visibility and conventions as
/// [`render_reference`].
pub fn render_reference_standard(
    scene: &ReferenceScene,
    material: &StandardMaterial,
    camera: &Camera,
    size: (u32, u32),
    spp: u32,
    seed: u64,
) -> Image {
    let shade = StandardShade {
        m: material,
        alphas: material.lobe_alphas(),
    };
    render_with(scene, &shade, &shade, camera, size, spp, seed)
}

/// What every reference render shares: the mesh and its tangents, its visibility (a tracer and the
/// shadow rays' offset) and its light (the environment and its rotation).
#[derive(Clone, Copy)]
pub struct ReferenceScene<'a> {
    pub mesh: &'a Mesh,
    pub tangents: Option<&'a [Vec4]>,
    pub tracer: &'a Tracer,
    pub ray_offset: f64,
    pub env: &'a EnvMap,
    pub rotation_rad: f64,
}

/// Renders the Monte Carlo reference at `spp` samples per pixel (each sample: one environment
/// sample and one BRDF sample, MIS-weighted).
#[allow(clippy::too_many_arguments)]
pub fn render_reference(
    mesh: &Mesh,
    tangents: Option<&[Vec4]>,
    tracer: &Tracer,
    ray_offset: f64,
    env: &EnvMap,
    rotation_rad: f64,
    material: ExactMaterial,
    camera: &Camera,
    width: u32,
    height: u32,
    spp: u32,
    seed: u64,
) -> Image {
    let full = Brdf::new(material);
    // Where the shading normal faces away from the eye only the diffuse term is kept (as in the PRT
    // renderer and the transfer): sampled by the cosine alone.
    let zero = vec![0.0; material.lobes.len()];
    let diffuse_only = Brdf::new(ExactMaterial {
        coefficients: [&zero, &zero, &zero],
        ..material
    });
    let scene = ReferenceScene {
        mesh,
        tangents,
        tracer,
        ray_offset,
        env,
        rotation_rad,
    };
    render_with(
        &scene,
        &full,
        &diffuse_only,
        camera,
        (width, height),
        spp,
        seed,
    )
}

/// The estimator: `full` where the shading normal faces the eye, `back` where it faces away.
fn render_with(
    scene: &ReferenceScene,
    full: &dyn Shade,
    back: &dyn Shade,
    camera: &Camera,
    (width, height): (u32, u32),
    spp: u32,
    seed: u64,
) -> Image {
    let ReferenceScene {
        mesh,
        tangents,
        tracer,
        ray_offset,
        env,
        rotation_rad,
    } = *scene;
    let sampler = EnvSampler::new(env, rotation_rad);
    let eye = camera.eye().as_dvec3();
    let fragments = rasterize(mesh, camera, width, height);
    let shaded: Vec<(u32, u32, [f64; 3])> = fragments
        .par_iter()
        .map(|f| {
            let tri = mesh.triangles[f.triangle as usize];
            let b = f.bary.map(|x| x as f64);
            let position: DVec3 = (0..3)
                .map(|i| mesh.positions[tri[i] as usize].as_dvec3() * b[i])
                .sum();
            let normal = (0..3)
                .map(|i| mesh.normals[tri[i] as usize].as_dvec3() * b[i])
                .sum::<DVec3>()
                .try_normalize()
                .unwrap_or(DVec3::Y);
            let frame = match tangents {
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
            let wo = frame.to_local((eye - position).try_normalize().unwrap_or(normal));
            let brdf = if wo.z > 0.0 { full } else { back };
            // Rays leave from the smooth surface the normals describe, not from the flat facet:
            // from the facet, directions above the shading normal's horizon but below the facet's
            // plane hit the facet itself, which darkened coarse meshes in stripes along their
            // facets (the shadow terminator; the bake's rays leave from vertices, which lie on that
            // surface).
            let origin = crate::scene::smooth_surface_point(
                mesh,
                &[(tri[0], b[0]), (tri[1], b[1]), (tri[2], b[2])],
                position,
            ) + normal * ray_offset;
            let o = Vec3A::new(origin.x as f32, origin.y as f32, origin.z as f32);
            let visible =
                |d: DVec3| !tracer.occluded(o, Vec3A::new(d.x as f32, d.y as f32, d.z as f32));
            let mut rng = Rng::new(
                seed ^ ((f.y as u64) << 32 | f.x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            );
            // Environment samples are stratified: a Hammersley set rotated per pixel
            // (Cranley–Patterson), so a few bright lights are each visited in proportion, not by
            // chance.
            let (shift_a, shift_b) = (rng.next_f64(), rng.next_f64());
            let mut sum = [0.0f64; 3];
            for s in 0..spp {
                // Environment sample.
                let a = (s as f64 / spp as f64 + shift_a).fract();
                let b = (radical_inverse(s) + shift_b).fract();
                let (d, pdf_e) = sampler.sample_with(&mut rng, a, b);
                let wi = frame.to_local(d);
                if wi.z > 0.0 && pdf_e > 0.0 {
                    let fr = brdf.eval(wi, wo);
                    if fr.iter().any(|&x| x > 0.0) && visible(d) {
                        let pdf_b = brdf.pdf(wi, wo);
                        let mis = pdf_e * pdf_e / (pdf_e * pdf_e + pdf_b * pdf_b);
                        let l = env.lookup_nearest(d, rotation_rad);
                        for c in 0..3 {
                            sum[c] += l[c] * fr[c] * wi.z * mis / pdf_e;
                        }
                    }
                }
                // BRDF sample.
                let wi = brdf.sample(wo, &mut rng);
                if wi.z > 0.0 {
                    let pdf_b = brdf.pdf(wi, wo);
                    let d = frame.to_world(wi);
                    if pdf_b > 0.0 && visible(d) {
                        let pdf_e = sampler.pdf(d);
                        let mis = pdf_b * pdf_b / (pdf_e * pdf_e + pdf_b * pdf_b);
                        let fr = brdf.eval(wi, wo);
                        let l = env.lookup_nearest(d, rotation_rad);
                        for c in 0..3 {
                            sum[c] += l[c] * fr[c] * wi.z * mis / pdf_b;
                        }
                    }
                }
            }
            (f.x, f.y, sum.map(|s| s / spp as f64))
        })
        .collect();
    let mut image = Image::new(width, height);
    for (x, y, rgb) in shaded {
        image.set(x, y, rgb.map(|v| v as f32));
    }
    image
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn environment_sampling_integrates_the_map_with_low_variance() {
        // ∫ L dω by sampling the map itself: unbiased against the map's own texel sum, and the
        // weights L/pdf nearly constant (the map is importance-sampled), for a smooth map and a map
        // with a sun.
        let smooth = EnvMap::from_fn(256, 128, |d| {
            [(1.0 + d.x + 0.5 * d.y) as f32, 1.0, (2.0 + d.z) as f32]
        })
        .unwrap();
        let mut texels = vec![[0.01f32; 3]; 256 * 128];
        texels[40 * 256 + 77] = [5e4; 3];
        let sun = EnvMap::from_rgb(256, 128, texels, "sun").unwrap();
        for env in [smooth, sun] {
            let want = env.stats().mean_radiance[1] * 4.0 * PI;
            for rotation in [0.0, 1.3] {
                let sampler = EnvSampler::new(&env, rotation);
                let mut rng = Rng::new(4);
                let n = 400_000;
                let (mut sum, mut sum2) = (0.0, 0.0);
                for _ in 0..n {
                    let (d, pdf) = sampler.sample(&mut rng);
                    assert!(
                        (pdf - sampler.pdf(d)).abs() <= 1e-9 * pdf,
                        "pdf consistency"
                    );
                    let x = env.lookup_nearest(d, rotation)[1] / pdf;
                    sum += x;
                    sum2 += x * x;
                }
                let mean = sum / n as f64;
                let rel_sd = ((sum2 / n as f64 - mean * mean).max(0.0)).sqrt() / mean;
                println!(
                    "{} rot {rotation}: estimate {mean:.5} vs {want:.5}, per-sample relative sd {rel_sd:.3}",
                    env.source()
                );
                assert!((mean - want).abs() < 0.01 * want, "{mean} vs {want}");
                assert!(rel_sd < 0.5, "relative sd {rel_sd}");
            }
        }
    }
}
