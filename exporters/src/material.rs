//! The plain material description every exporter takes, and the scene mesh some of them embed.
//!
//! Inputs: data the caller fills (the fitted lobe table, the tabulated p(h), a PBR fallback, an
//! optional MERL table, an optional triangle mesh). Outputs: the types, [`MaterialDesc::validate`]
//! and [`SceneMesh::validate`], and [`MaterialDesc::lobe_table_json`] (the JSON object written into
//! glTF extras, shaped like glint's material JSON). Invariants: no IO; validation rejects what
//! would make a file invalid or a reader divide by zero (lengths, non-finite numbers, names that
//! are not plain file names) before anything is written; maps are `BTreeMap`s so every output is
//! byte-deterministic.

use crate::error::ExportError;
use crate::merl::MerlTable;
use crate::table::PhTable;
use crate::view::{SceneCamera, SceneEnvironment};
use std::collections::BTreeMap;

/// The model name glint writes.
pub const MODEL: &str = "dbrdf-srbf";

/// Where every file points for the exact conventions (BRDF, frame, table, camera, environment).
pub const CONVENTIONS_DOC: &str = "glint docs/conventions.md";

/// The BRDF of an isotropic layout (ring lobes), as every file states it.
pub const BRDF_CONVENTION_ISOTROPIC: &str = "f_r(wi, wo) = rho_d/pi + p(h) s(wi, wo), without the cosine, in the local frame (z = shading normal); h = normalize(wi + wo); isotropic layout, ring lobes: p(h) = sum_j c_j exp(2 lambda (cos_h cos_j - 1)) I0(2 lambda sin_h sin_j) = sum_j c_j exp(2 lambda (cos(theta_h - theta_j) - 1)) I0e(2 lambda sin_h sin_j), cos_h = h.z, cos_j = xi_j.z (centres listed at azimuth 0; NOT point lobes); s = F(c) / (4 (k1 + k2 - k1 k2)), F(c) = f0 + (1 - f0) (1 - c)^5, c = wi.h, k1 = wi.z, k2 = wo.z; f_r = 0 for k1 <= 0; f_r = rho_d/pi for k2 <= 0 < k1 (silhouette rule); see glint docs/conventions.md";

/// The BRDF of an anisotropic layout (point lobes), as every file states it.
pub const BRDF_CONVENTION_ANISOTROPIC: &str = "f_r(wi, wo) = rho_d/pi + p(h) s(wi, wo), without the cosine, in the local frame (x = tangent, y = (n x t) * sign(tangent.w), z = shading normal); h = normalize(wi + wo); anisotropic layout, point lobes: p(h) = sum_j c_j exp(2 lambda (h.xi_j - 1)), xi_j in the local frame; s = F(c) / (4 (k1 + k2 - k1 k2)), F(c) = f0 + (1 - f0) (1 - c)^5, c = wi.h, k1 = wi.z, k2 = wo.z; f_r = 0 for k1 <= 0; f_r = rho_d/pi for k2 <= 0 < k1 (silhouette rule); see glint docs/conventions.md";

/// The local frame, as every file states it.
pub const FRAME_CONVENTION: &str = "local frame: z = shading normal (the interpolated vertex normals, normalised), x = tangent (the interpolated glTF TANGENT xyz, else MikkTSpace tangents from TEXCOORD_0, made orthogonal to z and normalised), y = (z x x) * sign(interpolated tangent.w); isotropic layouts depend on h.z only; see glint docs/conventions.md";

/// The BRDF convention string for a layout.
pub fn brdf_convention(isotropic: bool) -> &'static str {
    if isotropic {
        BRDF_CONVENTION_ISOTROPIC
    } else {
        BRDF_CONVENTION_ANISOTROPIC
    }
}

/// A fitted material, as plain data.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialDesc {
    /// Base of every file name: `<name>.glb`, `<name>.usda`, `<name>_ph.exr`, `<name>.binary`.
    /// ASCII letters, digits, `.`, `-`, `_`; not starting with `.`; at most 128 bytes.
    pub name: String,
    /// `"dbrdf-srbf"`.
    pub model: String,
    /// Material format version (1).
    pub version: u32,
    pub lambda: f64,
    pub sigma: f64,
    /// Layout name, e.g. `"hemicube-7"` or `"isotropic-24"`.
    pub layout: String,
    pub isotropic: bool,
    /// J unit vectors in the local frame (z = normal, x = tangent).
    pub centres: Vec<[f64; 3]>,
    /// R, G, B coefficients, each J long.
    pub coefficients: [Vec<f64>; 3],
    pub rho_d: [f64; 3],
    pub f0: f64,
    pub brdf_convention: String,
    pub frame_convention: String,
    /// Tool version, input hashes, fit statistics, … (sorted keys, so outputs are deterministic).
    pub provenance: BTreeMap<String, String>,
    /// The tabulated p(h) (hemi-octahedral; see the crate docs).
    pub table: PhTable,
    /// The glTF approximation viewers show (pbrMetallicRoughness and extensions); the MaterialX
    /// document's OpenPBR surface is mapped from it.
    pub fallback: PbrFallback,
    /// The UsdPreviewSurface approximation USD viewers show.
    pub preview_surface: PreviewSurfaceFallback,
    /// The MERL table; `None` makes the MERL exporter refuse.
    pub merl: Option<MerlTable>,
}

/// `KHR_materials_specular` of the glTF fallback: the dielectric's F0 = min(0.04 · color, 1) ·
/// factor and F90 = factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpecularLayer {
    /// `specularFactor`, in [0, 1].
    pub factor: f64,
    /// `specularColorFactor`, linear RGB in [0, 25] (25 · 0.04 = F0 of 1).
    pub color: [f64; 3],
}

/// `KHR_materials_clearcoat` of the glTF fallback (the coat of the USD and MaterialX ones).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearcoatLayer {
    /// `clearcoatFactor`, in [0, 1].
    pub factor: f64,
    /// `clearcoatRoughnessFactor` (perceptual), in [0, 1].
    pub roughness: f64,
}

/// `KHR_materials_sheen` of the glTF fallback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheenLayer {
    /// `sheenColorFactor`, linear RGB in [0, 1].
    pub color: [f64; 3],
    /// `sheenRoughnessFactor`, in [0, 1].
    pub roughness: f64,
}

/// How a fallback's error is weighted over direction pairs (see glint docs/fallback.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Weighting {
    /// Cosine-weighted pairs over the whole hemisphere (no scene known).
    #[default]
    Uniform,
    /// The exported scene's view directions over the object, light weighted by the environment.
    Scene,
}

impl Weighting {
    pub fn name(self) -> &'static str {
        match self {
            Weighting::Uniform => "uniform",
            Weighting::Scene => "scene",
        }
    }
}

/// The glTF approximation of the material: pbrMetallicRoughness with the extensions that lower
/// the error (`KHR_materials_specular`, `_clearcoat`, `_sheen`, `_anisotropy`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PbrFallback {
    /// Linear RGB in [0, 1].
    pub base_color: [f64; 3],
    /// In [0, 1].
    pub metallic: f64,
    /// Perceptual roughness in [0, 1].
    pub roughness: f64,
    /// `(strength in [0, 1], rotation in radians)` for `KHR_materials_anisotropy`; `None`:
    /// isotropic.
    pub anisotropy: Option<(f64, f64)>,
    pub specular: Option<SpecularLayer>,
    pub clearcoat: Option<ClearcoatLayer>,
    pub sheen: Option<SheenLayer>,
    /// How far the fallback is from the fitted BRDF, relative RMS under `weighting` (reported in
    /// metadata, not used).
    pub relative_error: f64,
    /// The same under uniform weighting.
    pub uniform_relative_error: f64,
    /// What the one-lobe fallback (pbrMetallicRoughness, with anisotropy where it helps) scores
    /// under `weighting`: the first candidate, which the layered fit never does worse than.
    pub one_lobe_relative_error: f64,
    pub weighting: Weighting,
}

impl PbrFallback {
    /// The glTF extensions this fallback uses, sorted.
    pub fn extensions(&self) -> Vec<&'static str> {
        let mut e = Vec::new();
        if self.anisotropy.is_some() {
            e.push("KHR_materials_anisotropy");
        }
        if self.clearcoat.is_some() {
            e.push("KHR_materials_clearcoat");
        }
        if self.sheen.is_some() {
            e.push("KHR_materials_sheen");
        }
        if self.specular.is_some() {
            e.push("KHR_materials_specular");
        }
        e
    }

    /// One line for people: the parameters and the error against the fitted BRDF (`isotropic`: the
    /// material is; an anisotropic material that got an isotropic fallback says why).
    pub fn summary(&self, isotropic: bool) -> String {
        let [r, g, b] = self.base_color;
        let mut layers = String::new();
        if let Some(s) = self.specular {
            let [sr, sg, sb] = s.color;
            layers += &format!(
                "; KHR_materials_specular factor {:.3}, colour [{sr:.3}, {sg:.3}, {sb:.3}]",
                s.factor
            );
        }
        if let Some(c) = self.clearcoat {
            layers += &format!(
                "; KHR_materials_clearcoat {:.3}, roughness {:.3}",
                c.factor, c.roughness
            );
        }
        if let Some(s) = self.sheen {
            let [sr, sg, sb] = s.color;
            layers += &format!(
                "; KHR_materials_sheen colour [{sr:.3}, {sg:.3}, {sb:.3}], roughness {:.3}",
                s.roughness
            );
        }
        match self.anisotropy {
            Some((strength, rotation)) => {
                layers += &format!(
                    "; KHR_materials_anisotropy strength {strength:.3}, rotation {rotation:.3} rad"
                )
            }
            None if isotropic => {}
            None => layers += " (isotropic: an anisotropic fallback fitted no better)",
        }
        format!(
            "glTF fallback: base colour [{r:.3}, {g:.3}, {b:.3}], metallic {:.2}, roughness {:.3}{layers}; relative RMS error against the fitted BRDF {:.1} % ({} weighting; uniform {:.1} %; one-lobe fallback {:.1} %)",
            self.metallic,
            self.roughness,
            self.relative_error * 100.0,
            self.weighting.name(),
            self.uniform_relative_error * 100.0,
            self.one_lobe_relative_error * 100.0,
        )
    }
}

/// The UsdPreviewSurface approximation of the material, evaluated as Storm's reference
/// implementation does (see glint docs/fallback.md).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PreviewSurfaceFallback {
    /// `diffuseColor`, linear RGB in [0, 1].
    pub diffuse_color: [f64; 3],
    /// `useSpecularWorkflow`: `specularColor` is F0; else `metallic` mixes.
    pub use_specular_workflow: bool,
    /// `specularColor`, linear RGB in [0, 1] (used in the specular workflow).
    pub specular_color: [f64; 3],
    /// `metallic`, in [0, 1] (0 in the specular workflow).
    pub metallic: f64,
    /// `roughness`, in [0, 1].
    pub roughness: f64,
    /// `clearcoat` and `clearcoatRoughness`, in [0, 1].
    pub clearcoat: f64,
    pub clearcoat_roughness: f64,
    /// Relative RMS error against the fitted BRDF under the glTF fallback's weighting.
    pub relative_error: f64,
    pub uniform_relative_error: f64,
}

impl PreviewSurfaceFallback {
    /// One line for people.
    pub fn summary(&self) -> String {
        let [r, g, b] = self.diffuse_color;
        let workflow = if self.use_specular_workflow {
            let [sr, sg, sb] = self.specular_color;
            format!("specular workflow, specularColor [{sr:.3}, {sg:.3}, {sb:.3}]")
        } else {
            format!("metallic {:.2}", self.metallic)
        };
        let coat = if self.clearcoat > 0.0 {
            format!(
                ", clearcoat {:.3}, clearcoatRoughness {:.3}",
                self.clearcoat, self.clearcoat_roughness
            )
        } else {
            String::new()
        };
        format!(
            "USD fallback (UsdPreviewSurface): diffuseColor [{r:.3}, {g:.3}, {b:.3}], {workflow}, roughness {:.3}{coat}; relative RMS error {:.1} % (uniform {:.1} %)",
            self.roughness,
            self.relative_error * 100.0,
            self.uniform_relative_error * 100.0
        )
    }
}

/// A triangle mesh to carry the material (positions in metres, Y up, counter-clockwise front
/// faces).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SceneMesh {
    pub positions: Vec<[f32; 3]>,
    /// Per vertex; normalised on export (a zero or non-finite normal is an error).
    pub normals: Vec<[f32; 3]>,
    /// Per vertex `(x, y, z, w)`, w = ±1 handedness; xyz normalised and w snapped to its sign on
    /// export.
    pub tangents: Option<Vec<[f32; 4]>>,
    /// Per vertex TEXCOORD_0.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Triangle list; every index < `positions.len()`.
    pub indices: Vec<u32>,
    /// The view glint renders the scene from: written as a camera into the glTF and USD files, and
    /// as the sensor of the Mitsuba scene.
    pub camera: Option<SceneCamera>,
    /// The environment that lights the scene (the Mitsuba scene's emitter).
    pub environment: Option<SceneEnvironment>,
}

fn finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl MaterialDesc {
    /// Number of lobes J.
    pub fn lobe_count(&self) -> usize {
        self.centres.len()
    }

    fn invalid(&self, field: &'static str, reason: impl Into<String>) -> ExportError {
        ExportError::InvalidMaterial {
            material: self.name.clone(),
            field,
            reason: reason.into(),
        }
    }

    /// Checks everything an exporter relies on. Every exporter calls it before building any file.
    pub fn validate(&self) -> Result<(), ExportError> {
        validate_name(&self.name)?;
        let j = self.centres.len();
        if j == 0 {
            return Err(self.invalid("centres", "is empty (J = 0)"));
        }
        for (c, channel) in self.coefficients.iter().zip(["R", "G", "B"]) {
            if c.len() != j {
                return Err(self.invalid(
                    "coefficients",
                    format!("{channel} has {} values for J = {j} centres", c.len()),
                ));
            }
            if !finite(c) {
                return Err(
                    self.invalid("coefficients", format!("{channel} has a non-finite value"))
                );
            }
        }
        for (i, c) in self.centres.iter().enumerate() {
            let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if !finite(c) || (n - 1.0).abs() > 1e-6 {
                return Err(self.invalid("centres", format!("[{i}] is not a unit vector")));
            }
        }
        if !(self.lambda.is_finite() && self.lambda > 0.0) {
            return Err(self.invalid(
                "lambda",
                format!("must be finite and > 0, got {}", self.lambda),
            ));
        }
        if !self.sigma.is_finite() {
            return Err(self.invalid("sigma", "is not finite"));
        }
        if !finite(&self.rho_d) || !self.f0.is_finite() {
            return Err(self.invalid("rho_d/f0", "has a non-finite value"));
        }
        let fb = &self.fallback;
        let mut numbers = vec![
            fb.metallic,
            fb.roughness,
            fb.relative_error,
            fb.uniform_relative_error,
            fb.one_lobe_relative_error,
        ];
        numbers.extend_from_slice(&fb.base_color);
        if let Some((s, r)) = fb.anisotropy {
            numbers.extend_from_slice(&[s, r]);
        }
        let mut units = vec![fb.metallic, fb.roughness];
        units.extend_from_slice(&fb.base_color);
        units.extend(fb.anisotropy.map(|(s, _)| s));
        if let Some(s) = fb.specular {
            numbers.push(s.factor);
            numbers.extend_from_slice(&s.color);
            units.push(s.factor);
            units.extend(s.color.map(|c| c / 25.0));
        }
        if let Some(c) = fb.clearcoat {
            units.extend_from_slice(&[c.factor, c.roughness]);
        }
        if let Some(s) = fb.sheen {
            units.push(s.roughness);
            units.extend_from_slice(&s.color);
        }
        let ps = &self.preview_surface;
        units.extend_from_slice(&ps.diffuse_color);
        units.extend_from_slice(&ps.specular_color);
        units.extend_from_slice(&[
            ps.metallic,
            ps.roughness,
            ps.clearcoat,
            ps.clearcoat_roughness,
        ]);
        numbers.extend_from_slice(&units);
        numbers.extend_from_slice(&[ps.relative_error, ps.uniform_relative_error]);
        if !finite(&numbers) {
            return Err(self.invalid("fallback", "has a non-finite value"));
        }
        if !units.iter().all(|x| (0.0..=1.0).contains(x)) {
            return Err(self.invalid("fallback", "a colour, factor or roughness lies outside [0, 1] (specularColorFactor outside [0, 25]): the glTF and UsdPreviewSurface ranges"));
        }
        for (label, s) in [
            ("model", &self.model),
            ("layout", &self.layout),
            ("brdf_convention", &self.brdf_convention),
            ("frame_convention", &self.frame_convention),
        ] {
            if s.contains('\0') {
                return Err(self.invalid("strings", format!("{label} contains a NUL byte")));
            }
        }
        if self
            .provenance
            .iter()
            .any(|(k, v)| k.contains('\0') || v.contains('\0'))
        {
            return Err(self.invalid("provenance", "contains a NUL byte"));
        }
        self.table
            .validate()
            .map_err(|reason| self.invalid("table", reason))?;
        Ok(())
    }

    /// The lobe table as JSON, with the field names of glint's material JSON (`lambda`, `sigma`,
    /// `layout`, `centres`, `coefficients` as 3 × J, `rho_d`, `f0`, `frame`, `brdf_convention`),
    /// plus `isotropic` and `provenance`. f64 numbers are written shortest-round-trip, so they are
    /// exact.
    pub fn lobe_table_json(&self) -> serde_json::Value {
        serde_json::json!({
            "model": self.model,
            "version": self.version,
            "lambda": self.lambda,
            "sigma": self.sigma,
            "layout": self.layout,
            "isotropic": self.isotropic,
            "centres": self.centres,
            "coefficients": [self.coefficients[0], self.coefficients[1], self.coefficients[2]],
            "rho_d": self.rho_d,
            "f0": self.f0,
            "frame": self.frame_convention,
            "brdf_convention": self.brdf_convention,
            "conventions": CONVENTIONS_DOC,
            "provenance": self.provenance,
        })
    }
}

/// Checks that `name` is a plain, portable file-name stem.
pub fn validate_name(name: &str) -> Result<(), ExportError> {
    let bad = |reason| {
        Err(ExportError::InvalidName {
            name: name.escape_debug().to_string(),
            reason,
        })
    };
    if name.is_empty() {
        return bad("it is empty");
    }
    if name.len() > 128 {
        return bad("it is longer than 128 bytes");
    }
    if name.starts_with('.') {
        return bad("it starts with '.'");
    }
    if !name
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
    {
        return bad("only ASCII letters, digits, '.', '-' and '_' are allowed");
    }
    Ok(())
}

impl SceneMesh {
    /// Checks lengths, index range and finiteness (what every exporter checks before writing).
    pub fn validate(&self) -> Result<(), ExportError> {
        self.validated().map(|_| ())
    }

    /// Checks lengths, index range and finiteness; returns unit normals and sanitised tangents.
    pub(crate) fn validated(&self) -> Result<CleanMesh, ExportError> {
        let bad = |reason: String| Err(ExportError::InvalidMesh { reason });
        let n = self.positions.len();
        if n == 0 || self.indices.is_empty() {
            return bad("it has no vertices or no triangles".into());
        }
        if n > u32::MAX as usize {
            return bad(format!("{n} vertices do not fit u32 indices"));
        }
        if !self.indices.len().is_multiple_of(3) {
            return bad(format!(
                "{} indices is not a multiple of 3",
                self.indices.len()
            ));
        }
        if let Some(i) = self.indices.iter().find(|&&i| i as usize >= n) {
            return bad(format!("index {i} is out of range for {n} vertices"));
        }
        if self.normals.len() != n {
            return bad(format!("{} normals for {n} positions", self.normals.len()));
        }
        if self.positions.iter().flatten().any(|x| !x.is_finite()) {
            return bad("a position is not finite".into());
        }
        let mut normals = Vec::with_capacity(n);
        for (i, v) in self.normals.iter().enumerate() {
            match normalize_f32(*v) {
                Some(u) => normals.push(u),
                None => return bad(format!("normal {i} is zero or not finite")),
            }
        }
        let tangents = match &self.tangents {
            None => None,
            Some(t) if t.len() != n => {
                return bad(format!("{} tangents for {n} positions", t.len()));
            }
            Some(t) => {
                let mut out = Vec::with_capacity(n);
                for (i, v) in t.iter().enumerate() {
                    match normalize_f32([v[0], v[1], v[2]]) {
                        Some(u) if v[3].is_finite() => {
                            out.push([u[0], u[1], u[2], if v[3] < 0.0 { -1.0 } else { 1.0 }])
                        }
                        _ => return bad(format!("tangent {i} is zero or not finite")),
                    }
                }
                Some(out)
            }
        };
        let uvs = match &self.uvs {
            None => None,
            Some(t) if t.len() != n => return bad(format!("{} uvs for {n} positions", t.len())),
            Some(t) if t.iter().flatten().any(|x| !x.is_finite()) => {
                return bad("a uv is not finite".into());
            }
            Some(t) => Some(t.clone()),
        };
        if let Some(c) = &self.camera {
            c.validate()?;
        }
        if let Some(e) = &self.environment {
            e.validate()?;
        }
        Ok(CleanMesh {
            positions: self.positions.clone(),
            normals,
            tangents,
            uvs,
            indices: self.indices.clone(),
        })
    }
}

/// A validated mesh: unit normals, unit tangents with w = ±1, indices in range.
#[derive(Debug, Clone)]
pub(crate) struct CleanMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub tangents: Option<Vec<[f32; 4]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    pub indices: Vec<u32>,
}

/// Normalises in f64 and rounds to f32 (so |v| is 1 to f32 precision); `None` for zero or
/// non-finite.
fn normalize_f32(v: [f32; 3]) -> Option<[f32; 3]> {
    let d = [v[0] as f64, v[1] as f64, v[2] as f64];
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if !n.is_finite() || n < 1e-30 {
        return None;
    }
    Some([(d[0] / n) as f32, (d[1] / n) as f32, (d[2] / n) as f32])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_be_plain() {
        for ok in ["bunny", "bunny.v2", "a-b_c"] {
            assert!(validate_name(ok).is_ok(), "{ok}");
        }
        for bad in ["", ".hidden", "a/b", "..", "a b", "é", "a\\b"] {
            let e = validate_name(bad).unwrap_err().to_string();
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn meshes_are_checked() {
        let mut m = SceneMesh {
            positions: vec![[0.0; 3]; 3],
            normals: vec![[0.0, 0.0, 2.0]; 3],
            indices: vec![0, 1, 2],
            ..Default::default()
        };
        assert_eq!(m.validated().unwrap().normals[0], [0.0, 0.0, 1.0]);
        m.indices = vec![0, 1, 3];
        assert!(m.validated().unwrap_err().to_string().contains("index 3"));
        m.indices = vec![0, 1, 2];
        m.normals[1] = [0.0; 3];
        assert!(m.validated().is_err());
    }
}
