//! The standard materials glint's fallbacks are fitted as, each evaluated as its specification
//! defines it: glTF 2.0's pbrMetallicRoughness with `KHR_materials_specular`, `_clearcoat`,
//! `_sheen` and `_anisotropy` ([`GltfParams`]), and UsdPreviewSurface as Storm's reference
//! implementation evaluates it ([`PreviewParams`]); [`StandardMaterial`] is either with its
//! colours. The formulas, with their sources, are in docs/fallback.md.
//!
//! Every evaluation works in the local frame (z = shading normal, x = tangent), with wi towards
//! the light and wo towards the eye, and returns f·cos θi split as A·c + B per channel, where c is
//! the colour the fit solves in closed form (base colour, diffuse colour or specular colour). The
//! glTF model is linear in the base colour; UsdPreviewSurface's metallic workflow is quadratic in
//! it (the diffuse is damped by a Fresnel made from it), so [`PreviewParams::parts`] takes the
//! colour of the previous iterate for that factor.
//!
//! Invariants: no IO; pure functions of their arguments; f = 0 below either horizon.

use glam::DVec3;
use std::f64::consts::PI;

/// The glTF fallback's parameters besides the base colour (which is solved in closed form).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GltfParams {
    pub metallic: f64,
    /// Perceptual roughness; α = roughness².
    pub roughness: f64,
    /// `KHR_materials_specular`: specularFactor (1 without the extension).
    pub specular: f64,
    /// The dielectric's F0 before the factor, min(0.04 · specularColorFactor, 1), grey (0.04
    /// without the extension).
    pub dielectric_f0: f64,
    /// `KHR_materials_clearcoat`: factor (0 without) and perceptual roughness.
    pub clearcoat: f64,
    pub clearcoat_roughness: f64,
    /// `KHR_materials_sheen`: grey sheenColorFactor (0 without) and sheenRoughnessFactor.
    pub sheen: f64,
    pub sheen_roughness: f64,
    /// `KHR_materials_anisotropy`: strength (0 without) and rotation (radians from the tangent).
    pub anisotropy: f64,
    pub rotation: f64,
}

impl Default for GltfParams {
    fn default() -> Self {
        Self {
            metallic: 0.0,
            roughness: 0.5,
            specular: 1.0,
            dielectric_f0: 0.04,
            clearcoat: 0.0,
            clearcoat_roughness: 0.1,
            sheen: 0.0,
            sheen_roughness: 0.5,
            anisotropy: 0.0,
            rotation: 0.0,
        }
    }
}

/// GGX D·V (isotropic, height-correlated Smith V), glTF 2.0 Appendix B.
pub fn ggx_dv(alpha: f64, nl: f64, nv: f64, nh: f64) -> f64 {
    let a2 = (alpha * alpha).max(1e-12);
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let v =
        0.5 / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
    d * v
}

/// `KHR_materials_anisotropy`'s D·V: α_t = mix(α, 1, strength²), α_b = α, t = (cos ρ, sin ρ, 0),
/// V clamped to [0, 1] as the extension does.
pub fn ggx_dv_anisotropic(
    alpha: f64,
    strength: f64,
    rotation: f64,
    wi: DVec3,
    wo: DVec3,
    h: DVec3,
) -> f64 {
    let (sin_r, cos_r) = rotation.sin_cos();
    let along_t = |d: DVec3| cos_r * d.x + sin_r * d.y;
    let along_b = |d: DVec3| cos_r * d.y - sin_r * d.x;
    let ab = alpha.max(1e-6);
    let at = ab * (1.0 - strength * strength) + strength * strength;
    let a2 = at * ab;
    let w2 = a2
        / DVec3::new(ab * along_t(h), at * along_b(h), a2 * h.z.max(0.0))
            .length_squared()
            .max(f64::MIN_POSITIVE);
    let d = a2 * w2 * w2 / PI;
    let ggx_v = wi.z * DVec3::new(at * along_t(wo), ab * along_b(wo), wo.z).length();
    let ggx_l = wo.z * DVec3::new(at * along_t(wi), ab * along_b(wi), wi.z).length();
    d * (0.5 / (ggx_v + ggx_l)).clamp(0.0, 1.0)
}

/// The sheen BRDF without its colour: D_Charlie · V_Charlie (the extension's F = 1).
pub fn sheen_brdf(alpha: f64, nl: f64, nv: f64, nh: f64) -> f64 {
    SheenLobe::new(alpha).eval(nl, nv, nh)
}

/// The sheen lobe of one roughness, with what depends on the roughness alone worked out once:
/// [`sheen_brdf`] at many pairs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheenLobe {
    /// 1/α, and D's normalisation (2 + 1/α)/2π.
    inv: f64,
    norm: f64,
    /// The coefficients of the extension's fitted Λ curve at α, and its value at 0.5.
    curve: [f64; 5],
    l_half: f64,
}

impl SheenLobe {
    pub fn new(alpha: f64) -> Self {
        let inv = 1.0 / alpha.max(1e-3);
        let t = (1.0 - alpha) * (1.0 - alpha);
        let mix = |a: f64, b: f64| a + (b - a) * t;
        let curve = [
            mix(21.5473, 25.3245),
            mix(3.82987, 3.32435),
            mix(0.19823, 0.16801),
            mix(-1.97760, -1.27393),
            mix(-4.32054, -4.85967),
        ];
        let mut lobe = Self {
            inv,
            norm: (2.0 + inv) / (2.0 * PI),
            curve,
            l_half: 0.0,
        };
        lobe.l_half = lobe.l(0.5);
        lobe
    }

    /// The fitted curve L(x).
    fn l(&self, x: f64) -> f64 {
        let [a, b, c, d, e] = self.curve;
        a / (1.0 + b * x.powf(c)) + d * x + e
    }

    /// The sheen visibility's Λ (the extension's fitted curve).
    fn lambda(&self, cos_theta: f64) -> f64 {
        if cos_theta.abs() < 0.5 {
            self.l(cos_theta).exp()
        } else {
            (2.0 * self.l_half - self.l(1.0 - cos_theta)).exp()
        }
    }

    /// `KHR_materials_sheen`'s "Charlie" distribution D (Conty & Kulla 2017).
    pub fn d(&self, nh: f64) -> f64 {
        let sin2 = (1.0 - nh * nh).max(0.0);
        self.norm * sin2.powf(0.5 * self.inv)
    }

    /// D_Charlie · V_Charlie.
    pub fn eval(&self, nl: f64, nv: f64, nh: f64) -> f64 {
        let v = 1.0 / ((1.0 + self.lambda(nv) + self.lambda(nl)) * (4.0 * nv * nl));
        self.d(nh) * v
    }
}

/// The sheen lobe's directional albedo E(cos θo) = ∫ f_sheen(wi, wo) cos θi dwi by an `nt` × `np`
/// midpoint rule in (cos θi, φ).
pub fn sheen_albedo_quadrature(alpha: f64, cos_theta: f64, nt: usize, np: usize) -> f64 {
    let mu = cos_theta.clamp(1e-3, 1.0);
    let wo = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
    let mut sum = 0.0;
    for i in 0..nt {
        let ci = (i as f64 + 0.5) / nt as f64;
        let si = (1.0 - ci * ci).sqrt();
        for j in 0..np {
            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let wi = DVec3::new(si * phi.cos(), si * phi.sin(), ci);
            let h = (wi + wo).normalize();
            sum += sheen_brdf(alpha, ci, mu, h.z) * ci;
        }
    }
    sum * 2.0 * PI / (nt * np) as f64
}

/// Sheen roughnesses and cosines of the albedo table.
const SHEEN_ROUGHNESSES: usize = 65;
const SHEEN_COSINES: usize = 33;

/// The extension's albedo-scaling table E(cos θ, sheenRoughness), computed once by quadrature
/// (48 × 96 per entry) on 65 roughnesses × 33 cosines (k/64, k/32) rather than read from a file,
/// and read bilinearly.
pub fn sheen_albedo(alpha: f64, cos_theta: f64) -> f64 {
    use rayon::prelude::*;
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..SHEEN_ROUGHNESSES * SHEEN_COSINES)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k / SHEEN_COSINES, k % SHEEN_COSINES);
                let alpha = (i as f64 / (SHEEN_ROUGHNESSES - 1) as f64).max(0.01);
                sheen_albedo_quadrature(alpha, j as f64 / (SHEEN_COSINES - 1) as f64, 48, 96)
            })
            .collect()
    });
    let x = alpha.clamp(0.0, 1.0) * (SHEEN_ROUGHNESSES - 1) as f64;
    let y = cos_theta.clamp(0.0, 1.0) * (SHEEN_COSINES - 1) as f64;
    let (i, j) = (
        (x as usize).min(SHEEN_ROUGHNESSES - 2),
        (y as usize).min(SHEEN_COSINES - 2),
    );
    let (tx, ty) = (x - i as f64, y - j as f64);
    let at = |i: usize, j: usize| table[i * SHEEN_COSINES + j];
    (at(i, j) * (1.0 - ty) + at(i, j + 1) * ty) * (1.0 - tx)
        + (at(i + 1, j) * (1.0 - ty) + at(i + 1, j + 1) * ty) * tx
}

impl GltfParams {
    /// f·cos θi = A·c + B for the base colour c (the same A and B for every channel: the
    /// extensions' colours are grey).
    ///
    /// glTF 2.0 Appendix B and the extensions: dielectric = F_d·DV + (1 − F_d)·c/π with F_d =
    /// s·(f0 + (1 − f0)(1 − v·h)⁵) (`KHR_materials_specular`: f0 = min(0.04·colour, 1), F90 = s);
    /// metal = DV·(c + (1 − c)(1 − v·h)⁵); base = mix(dielectric, metal, metallic); sheened =
    /// sheen·D_C·V_C + base·min(1 − sheen·E(n·v), 1 − sheen·E(n·l)); coated = mix(sheened,
    /// DV_coat, clearcoat·(0.04 + 0.96(1 − n·v)⁵)).
    pub fn parts(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let Some(g) = PairGeometry::new(wi, wo) else {
            return (0.0, 0.0);
        };
        if self.anisotropy > 0.0 {
            let dv = ggx_dv_anisotropic(
                self.roughness * self.roughness,
                self.anisotropy,
                self.rotation,
                wi,
                wo,
                g.h,
            );
            self.parts_with(&g, dv, None)
        } else {
            self.parts_at(&g, None)
        }
    }

    /// [`GltfParams::parts`] of an isotropic material (`anisotropy` 0) at a pair's geometry, with
    /// the sheen lobe of [`GltfParams::sheen_lobe`] when given (worked out once for many pairs;
    /// `None`: worked out here where the sheen is on).
    pub fn parts_at(&self, g: &PairGeometry, sheen: Option<&SheenLobe>) -> (f64, f64) {
        let alpha = self.roughness * self.roughness;
        self.parts_with(g, ggx_dv(alpha, g.nl, g.nv, g.nh), sheen)
    }

    /// The sheen layer's lobe.
    pub fn sheen_lobe(&self) -> SheenLobe {
        SheenLobe::new(self.sheen_roughness)
    }

    /// The parts given the base lobe's D·V.
    fn parts_with(&self, g: &PairGeometry, dv: f64, sheen: Option<&SheenLobe>) -> (f64, f64) {
        let (nl, nv, nh, fw) = (g.nl, g.nv, g.nh, g.fw);
        let fd = self.specular * (self.dielectric_f0 + (1.0 - self.dielectric_f0) * fw);
        let m = self.metallic;
        let mut a = (1.0 - m) * (1.0 - fd) / PI + m * dv * (1.0 - fw);
        let mut b = (1.0 - m) * fd * dv + m * dv * fw;
        if self.sheen > 0.0 {
            let r = self.sheen_roughness;
            let e = sheen_albedo(r, nv).max(sheen_albedo(r, nl));
            let scale = 1.0 - self.sheen * e;
            a *= scale;
            let lobe = sheen.copied().unwrap_or_else(|| self.sheen_lobe());
            b = b * scale + self.sheen * lobe.eval(nl, nv, nh);
        }
        if self.clearcoat > 0.0 {
            let fc = self.clearcoat * (0.04 + 0.96 * (1.0 - nv).powi(5));
            let ac = self.clearcoat_roughness * self.clearcoat_roughness;
            a *= 1.0 - fc;
            b = b * (1.0 - fc) + fc * ggx_dv(ac, nl, nv, nh);
        }
        (a * nl, b * nl)
    }
}

/// What the standard models read of a direction pair (wi, wo) in the local frame: the half vector
/// h and the cosines n·l, n·v, n·h, v·h, with Schlick's weight (1 − v·h)⁵. Worked out once per
/// pair where a fit evaluates the models at the same pairs many times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairGeometry {
    pub h: DVec3,
    pub nl: f64,
    pub nv: f64,
    pub nh: f64,
    pub vh: f64,
    pub fw: f64,
}

impl PairGeometry {
    /// `None` where either direction is at or below the horizon or they are opposite (f = 0).
    pub fn new(wi: DVec3, wo: DVec3) -> Option<Self> {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return None;
        }
        let h = (wi + wo).try_normalize()?;
        let vh = wo.dot(h).max(0.0);
        Some(Self {
            h,
            nl: wi.z,
            nv: wo.z,
            nh: h.z.max(0.0),
            vh,
            fw: (1.0 - vh).powi(5),
        })
    }
}

/// The UsdPreviewSurface fallback's parameters besides the solved colours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewParams {
    pub use_specular_workflow: bool,
    pub metallic: f64,
    pub roughness: f64,
    pub clearcoat: f64,
    pub clearcoat_roughness: f64,
}

/// UsdPreviewSurface's specular lobe without its Fresnel: D·G / (4 n·l n·v) with GGX D (α =
/// roughness²) and the Smith–Schlick G (k = α/2) of Storm's reference implementation.
pub fn preview_lobe(roughness: f64, nl: f64, nv: f64, nh: f64) -> f64 {
    let alpha = roughness.max(0.001).powi(2);
    let a2 = alpha * alpha;
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let k = 0.5 * alpha;
    let g = nv / (nv * (1.0 - k) + k) * nl / (nl * (1.0 - k) + k);
    d * g / (4.0 * nl * nv)
}

impl PreviewParams {
    /// f·cos θi per channel as A·x + B, where x is the colour being solved: the diffuse colour
    /// (`solve_specular` false) or the specular colour (true, specular workflow only); `diffuse`
    /// and `specular` are the current colours (the one being solved is used only where the model
    /// is not linear in it: the metallic workflow's diffuse damping).
    ///
    /// Storm's evaluateLight: fw = (1 − e·h)⁵; metallic workflow: spec = mix(1, c, m), F0 =
    /// mix(0.04·spec, spec, m), F90 = spec, diffuse c·(1 − m); specular workflow: F0 =
    /// specularColor, F90 = 1; F = mix(F0, F90, fw); f = c/π·(1 − F) + F·lobe + clearcoat·mix(0.04,
    /// 1, fw)·lobe_coat (ior 1.5; Storm's ε terms left out).
    pub fn parts(
        &self,
        solve_specular: bool,
        diffuse: f64,
        specular: f64,
        wi: DVec3,
        wo: DVec3,
    ) -> (f64, f64) {
        match PairGeometry::new(wi, wo) {
            Some(g) => {
                let (a, b) = self.parts_at(solve_specular, [diffuse; 3], [specular; 3], &g);
                (a[0], b[0])
            }
            None => (0.0, 0.0),
        }
    }

    /// [`PreviewParams::parts`] for the three channels at once, at a pair's geometry (the lobes
    /// are worked out once).
    pub fn parts_at(
        &self,
        solve_specular: bool,
        diffuse: [f64; 3],
        specular: [f64; 3],
        g: &PairGeometry,
    ) -> ([f64; 3], [f64; 3]) {
        let (nl, nv, nh, fw) = (g.nl, g.nv, g.nh, g.fw);
        let lobe = preview_lobe(self.roughness, nl, nv, nh);
        let coat = if self.clearcoat > 0.0 {
            self.clearcoat * (0.04 + 0.96 * fw) * preview_lobe(self.clearcoat_roughness, nl, nv, nh)
        } else {
            0.0
        };
        let channel = |c: usize| {
            let (diffuse, specular) = (diffuse[c], specular[c]);
            let (a, b) = if self.use_specular_workflow {
                if solve_specular {
                    // f = c/π (1 − fw) + fw·lobe + x (1 − fw)(lobe − c/π).
                    (
                        (1.0 - fw) * (lobe - diffuse / PI),
                        diffuse / PI * (1.0 - fw) + fw * lobe + coat,
                    )
                } else {
                    let f = specular * (1.0 - fw) + fw;
                    ((1.0 - f) / PI, f * lobe + coat)
                }
            } else {
                let m = self.metallic;
                // spec = (1 − m) + m·c and F = spec·q, q = (0.04(1 − m) + m)(1 − fw) + fw.
                let q = (0.04 * (1.0 - m) + m) * (1.0 - fw) + fw;
                let f_prev = ((1.0 - m) + m * diffuse) * q;
                (
                    (1.0 - m) * (1.0 - f_prev) / PI + q * m * lobe,
                    q * (1.0 - m) * lobe + coat,
                )
            };
            (a * nl, b * nl)
        };
        let ch = [channel(0), channel(1), channel(2)];
        (ch.map(|x| x.0), ch.map(|x| x.1))
    }
}

/// A standard material with its colours: an exported fallback, as renderers evaluate it.
#[derive(Debug, Clone, PartialEq)]
pub enum StandardMaterial {
    /// glTF: pbrMetallicRoughness and the `KHR_materials_*` layers, with the base colour.
    Gltf {
        params: GltfParams,
        base_color: [f64; 3],
    },
    /// UsdPreviewSurface, with its diffuse and specular colours.
    Preview {
        params: PreviewParams,
        diffuse: [f64; 3],
        specular: [f64; 3],
    },
}

impl StandardMaterial {
    /// f_r(wi, wo) per channel, without the cosine. Where the shading normal faces away from the
    /// eye (wo.z ≤ 0 < wi.z) only the diffuse term is kept, at its normal-incidence weight (glint's
    /// convention for every renderer).
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        if wi.z <= 0.0 {
            return [0.0; 3];
        }
        match self {
            StandardMaterial::Gltf { params, base_color } => {
                if wo.z <= 0.0 {
                    let fd = params.specular * params.dielectric_f0;
                    return base_color.map(|c| (1.0 - params.metallic) * (1.0 - fd) * c / PI);
                }
                let (a, b) = params.parts(wi, wo);
                base_color.map(|c| (a * c + b) / wi.z)
            }
            StandardMaterial::Preview {
                params,
                diffuse,
                specular,
            } => {
                if wo.z <= 0.0 {
                    return std::array::from_fn(|c| {
                        let f0 = if params.use_specular_workflow {
                            specular[c]
                        } else {
                            let m = params.metallic;
                            ((1.0 - m) + m * diffuse[c]) * (0.04 * (1.0 - m) + m)
                        };
                        (1.0 - params.metallic) * diffuse[c] * (1.0 - f0) / PI
                    });
                }
                std::array::from_fn(|c| {
                    let (a, b) = params.parts(false, diffuse[c], specular[c], wi, wo);
                    (a * diffuse[c] + b) / wi.z
                })
            }
        }
    }

    /// The albedo ρ of the diffuse term kept where the shading normal faces away from the eye:
    /// [`StandardMaterial::eval`] is ρ/π there.
    pub fn back_facing_rho(&self) -> [f64; 3] {
        let below = DVec3::new(0.0, 0.0, -1.0);
        self.eval(DVec3::Z, below).map(|f| f * PI)
    }

    /// The GGX α of each specular lobe (base, coat), for importance sampling.
    pub fn lobe_alphas(&self) -> Vec<f64> {
        let (r, coat) = match self {
            StandardMaterial::Gltf { params, .. } => (
                params.roughness,
                (params.clearcoat > 0.0).then_some(params.clearcoat_roughness),
            ),
            StandardMaterial::Preview { params, .. } => (
                params.roughness,
                (params.clearcoat > 0.0).then_some(params.clearcoat_roughness),
            ),
        };
        std::iter::once(r)
            .chain(coat)
            .map(|r| (r * r).max(1e-3))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sheen_albedo_matches_a_monte_carlo_estimate() {
        // Independent estimate: uniform hemisphere sampling, another random stream.
        let mut rng = crate::math::Rng::new(7);
        for alpha in [0.3, 0.7, 1.0] {
            for mu in [0.2f64, 0.5, 0.9] {
                let wo = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let n = 200_000;
                let mut sum = 0.0;
                for _ in 0..n {
                    let z = rng.next_f64();
                    let phi = 2.0 * PI * rng.next_f64();
                    let r = (1.0 - z * z).sqrt();
                    let wi = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                    let h = (wi + wo).normalize();
                    sum += sheen_brdf(alpha, z, mu, h.z) * z * 2.0 * PI;
                }
                let mc = sum / n as f64;
                let e = sheen_albedo(alpha, mu);
                assert!(
                    (e - mc).abs() <= 0.02 * mc.max(0.05),
                    "alpha {alpha} mu {mu}: table {e}, MC {mc}"
                );
                assert!(e > 0.0 && e < 1.0, "albedo {e}");
            }
        }
    }

    #[test]
    fn a_white_clearcoated_sheened_material_reflects_at_most_what_arrives() {
        // White furnace: the directional albedo of the layered glTF material with c = 1 stays
        // ≤ 1 (+ quadrature error) at every view.
        let p = GltfParams {
            metallic: 0.0,
            roughness: 0.4,
            clearcoat: 1.0,
            clearcoat_roughness: 0.1,
            sheen: 1.0,
            sheen_roughness: 0.5,
            ..Default::default()
        };
        for mu in [0.1f64, 0.4, 0.8, 1.0] {
            let wo = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let (nt, np) = (256, 256);
            let mut sum = 0.0;
            for i in 0..nt {
                let ci = (i as f64 + 0.5) / nt as f64;
                let si = (1.0 - ci * ci).sqrt();
                for j in 0..np {
                    let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                    let wi = DVec3::new(si * phi.cos(), si * phi.sin(), ci);
                    let (a, b) = p.parts(wi, wo);
                    sum += a + b;
                }
            }
            let e = sum * 2.0 * PI / (nt * np) as f64;
            assert!(e <= 1.02, "mu {mu}: albedo {e}");
            // Single scattering loses energy at grazing views, never all of it.
            assert!(e > 0.3, "mu {mu}: albedo {e}");
        }
    }

    #[test]
    fn the_preview_metallic_workflow_matches_storm_at_its_ends() {
        // Metallic 0: Storm's F = 0.04 + 0.96 fw, diffuse c/π (1 − F); metallic 1: F = c, no
        // diffuse — both closed forms, evaluated here by hand.
        let wi = DVec3::new(0.3, 0.1, 0.9).normalize();
        let wo = DVec3::new(-0.5, 0.2, 0.7).normalize();
        let h = (wi + wo).normalize();
        let fw = (1.0 - wo.dot(h)).powi(5);
        let lobe = preview_lobe(0.5, wi.z, wo.z, h.z);
        let c = 0.6;
        for (m, expected) in [
            (
                0.0,
                c / PI * (1.0 - (0.04 + 0.96 * fw)) + (0.04 + 0.96 * fw) * lobe,
            ),
            // Storm's metal: F0 = F90 = c.
            (1.0, c * lobe),
        ] {
            let p = PreviewParams {
                use_specular_workflow: false,
                metallic: m,
                roughness: 0.5,
                clearcoat: 0.0,
                clearcoat_roughness: 0.1,
            };
            let (a, b) = p.parts(false, c, 0.0, wi, wo);
            let f = (a * c + b) / wi.z;
            assert!((f - expected).abs() < 1e-12, "m {m}: {f} vs {expected}");
        }
    }
}
