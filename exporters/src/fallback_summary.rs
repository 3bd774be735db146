//! The fallbacks' summary (`<name>_fallback.json`): what each format shows in tools that cannot run
//! glint's BRDF, and how far it is from that BRDF.
//!
//! Inputs: a validated [`MaterialDesc`]. Outputs: the JSON ([`fallback_summary`]) and the exporter
//! ([`FallbackExporter`]). One object per format: `gltf` (pbrMetallicRoughness and each
//! `KHR_materials_*` extension the fallback uses), `usd` (the UsdPreviewSurface inputs), `mtlx`
//! (the OpenPBR Surface inputs, mapped from the glTF fallback and not evaluated), each with its
//! relative RMS error against the fitted BRDF under the fit's weighting (`scene` or `uniform`) and
//! under uniform weighting; the glTF entry also has the one-lobe fallback's error, the first
//! candidate the layered fit never does worse than. Invariants: keys are sorted, numbers
//! shortest round-trip, so equal inputs give equal bytes.

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::material::{MaterialDesc, SceneMesh};
use serde_json::{Value, json};
use std::path::Path;

/// The summary of every format's fallback.
pub fn fallback_summary(desc: &MaterialDesc) -> Value {
    let fb = &desc.fallback;
    let extensions = crate::gltf::extensions_json(fb);
    let ps = &desc.preview_surface;
    let mut usd = json!({
        "diffuseColor": ps.diffuse_color,
        "metallic": ps.metallic,
        "roughness": ps.roughness,
        "clearcoat": ps.clearcoat,
        "clearcoatRoughness": ps.clearcoat_roughness,
        "useSpecularWorkflow": u8::from(ps.use_specular_workflow),
    });
    if ps.use_specular_workflow {
        usd["specularColor"] = json!(ps.specular_color);
    }
    let mtlx: serde_json::Map<String, Value> = crate::mtlx::open_pbr_inputs(desc)
        .into_iter()
        .map(|i| {
            let v = if i.value.len() == 1 {
                json!(i.value[0])
            } else {
                json!(i.value)
            };
            (i.name.to_string(), v)
        })
        .collect();
    json!({
        "material": desc.name,
        "weighting": fb.weighting.name(),
        "gltf": {
            "pbrMetallicRoughness": {
                "baseColorFactor": fb.base_color,
                "metallicFactor": fb.metallic,
                "roughnessFactor": fb.roughness,
            },
            "extensions": extensions,
            "relative_error": fb.relative_error,
            "uniform_relative_error": fb.uniform_relative_error,
            "one_lobe_relative_error": fb.one_lobe_relative_error,
        },
        "usd": {
            "UsdPreviewSurface": usd,
            "relative_error": ps.relative_error,
            "uniform_relative_error": ps.uniform_relative_error,
        },
        "mtlx": {
            "open_pbr_surface": mtlx,
            "relative_error": null,
            "note": "mapped from the glTF fallback; OpenPBR is not evaluated by glint (see docs/fallback.md)",
        },
    })
}

/// The summary exporter: `<name>_fallback.json`.
pub struct FallbackExporter;

impl Exporter for FallbackExporter {
    fn name(&self) -> &'static str {
        "fallback"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["json"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        _scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        desc.validate()?;
        let mut bytes = serde_json::to_vec_pretty(&fallback_summary(desc)).map_err(|e| {
            ExportError::InvalidMaterial {
                material: desc.name.clone(),
                field: "fallback summary",
                reason: e.to_string(),
            }
        })?;
        bytes.push(b'\n');
        Ok(vec![OutputFile {
            path: dir.join(format!("{}_fallback.json", desc.name)),
            bytes,
        }])
    }
}

/// The fallbacks for people, one line per format (what `glint export` prints).
pub fn summary_text(desc: &MaterialDesc) -> String {
    format!(
        "{}\n{}\nMaterialX fallback (OpenPBR Surface, {}.mtlx and the USD's mtlx surface): mapped from the glTF fallback; glint does not evaluate OpenPBR",
        desc.fallback.summary(desc.isotropic),
        desc.preview_surface.summary(),
        desc.name
    )
}
