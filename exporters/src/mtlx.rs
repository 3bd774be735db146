//! MaterialX (`<name>.mtlx`): the fallback as an OpenPBR Surface, for MaterialX-aware renderers.
//!
//! Inputs: a validated [`MaterialDesc`]. Outputs: the document ([`encode_mtlx`]), the exporter
//! ([`MtlxExporter`]) and the shader's inputs ([`open_pbr_inputs`]), which the USD exporter also
//! writes as the Material's `mtlx` render-context surface.
//!
//! The OpenPBR Surface is mapped from the glTF fallback ([`crate::PbrFallback`]) input by input:
//! base_color, base_metalness and specular_roughness from pbrMetallicRoughness (OpenPBR's α is
//! roughness², as glTF's); `KHR_materials_specular` as specular_weight = specularFactor and
//! specular_ior = the IOR whose F0 is min(0.04 · specularColorFactor, 1) (the factor's colour is
//! grey in glint's fits, so specular_color stays white); `KHR_materials_clearcoat` as coat_weight
//! and coat_roughness (coat_ior 1.5, as glTF's coat); `KHR_materials_sheen` as fuzz_weight 1,
//! fuzz_color and fuzz_roughness; `KHR_materials_anisotropy`'s strength as
//! specular_roughness_anisotropy. OpenPBR layers its lobes with energy conservation where glTF
//! mixes by Fresnel, so the same numbers do not give the same BRDF: glint does not evaluate
//! OpenPBR, and the document reports the glTF fallback's error, not its own (docs/fallback.md).
//!
//! Invariants: element names are MaterialX identifiers; numbers are f32 shortest round-trip; no
//! timestamps, so equal inputs give equal bytes. MaterialX 1.39's `validate()` passes against its
//! standard libraries (tested by `python/check_mtlx.py`).

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::material::MaterialDesc;
use std::fmt::Write as _;
use std::path::Path;

/// The OpenPBR node definition the document and the USD `mtlx` surface use.
pub const OPEN_PBR_NODEDEF: &str = "ND_open_pbr_surface_surfaceshader";

/// One input of the OpenPBR Surface: name, MaterialX type (`float` or `color3`) and value.
#[derive(Debug, Clone, PartialEq)]
pub struct OpenPbrInput {
    pub name: &'static str,
    pub value: Vec<f64>,
}

/// The IOR whose normal-incidence reflectance is `f0` (1.0 for f0 = 0; capped at 1e3 for f0 → 1).
fn ior_for(f0: f64) -> f64 {
    let r = f0.clamp(0.0, 1.0).sqrt();
    ((1.0 + r) / (1.0 - r).max(1e-9)).min(1e3)
}

/// The OpenPBR Surface's inputs mapped from the glTF fallback (see the module doc), sorted by name.
pub fn open_pbr_inputs(desc: &MaterialDesc) -> Vec<OpenPbrInput> {
    let fb = &desc.fallback;
    let mut inputs = vec![
        OpenPbrInput {
            name: "base_color",
            value: fb.base_color.to_vec(),
        },
        OpenPbrInput {
            name: "base_metalness",
            value: vec![fb.metallic],
        },
        OpenPbrInput {
            name: "base_weight",
            value: vec![1.0],
        },
        OpenPbrInput {
            name: "specular_roughness",
            value: vec![fb.roughness],
        },
    ];
    let (weight, f0) = fb
        .specular
        .map_or((1.0, 0.04), |s| (s.factor, (0.04 * s.color[1]).min(1.0)));
    inputs.push(OpenPbrInput {
        name: "specular_ior",
        value: vec![ior_for(f0)],
    });
    inputs.push(OpenPbrInput {
        name: "specular_weight",
        value: vec![weight],
    });
    if let Some((strength, _)) = fb.anisotropy {
        inputs.push(OpenPbrInput {
            name: "specular_roughness_anisotropy",
            value: vec![strength],
        });
    }
    if let Some(c) = fb.clearcoat {
        inputs.push(OpenPbrInput {
            name: "coat_ior",
            value: vec![1.5],
        });
        inputs.push(OpenPbrInput {
            name: "coat_roughness",
            value: vec![c.roughness],
        });
        inputs.push(OpenPbrInput {
            name: "coat_weight",
            value: vec![c.factor],
        });
    }
    if let Some(s) = fb.sheen {
        inputs.push(OpenPbrInput {
            name: "fuzz_color",
            value: s.color.to_vec(),
        });
        inputs.push(OpenPbrInput {
            name: "fuzz_roughness",
            value: vec![s.roughness],
        });
        inputs.push(OpenPbrInput {
            name: "fuzz_weight",
            value: vec![1.0],
        });
    }
    inputs.sort_by_key(|i| i.name);
    inputs
}

/// f32 shortest round-trip text.
fn num(x: f64) -> String {
    format!("{:?}", x as f32)
}

/// The `.mtlx` document for a validated description.
pub fn encode_mtlx(desc: &MaterialDesc) -> Result<String, ExportError> {
    desc.validate()?;
    // MaterialX element names follow the same rule as USD prim names.
    let id = crate::usd::prim_name(&desc.name);
    let fb = &desc.fallback;
    let mut o = String::new();
    // Writing to a String cannot fail; the results are ignored below.
    let _ = writeln!(o, "<?xml version=\"1.0\"?>");
    let _ = writeln!(o, "<materialx version=\"1.39\" colorspace=\"lin_rec709\">");
    let _ = writeln!(
        o,
        "  <!-- glint material {id}: OpenPBR Surface mapped from the glTF fallback (relative RMS error of the glTF fallback against glint's BRDF: {:.4}, {} weighting; OpenPBR itself is not evaluated). Lobe table: {id}.glb / {id}.usda. See glint docs/fallback.md. Written by glint-exporters {}. -->",
        fb.relative_error,
        fb.weighting.name(),
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        o,
        "  <open_pbr_surface name=\"SR_{id}\" type=\"surfaceshader\">"
    );
    for input in open_pbr_inputs(desc) {
        let (ty, value) = if input.value.len() == 3 {
            (
                "color3",
                format!(
                    "{}, {}, {}",
                    num(input.value[0]),
                    num(input.value[1]),
                    num(input.value[2])
                ),
            )
        } else {
            ("float", num(input.value[0]))
        };
        let _ = writeln!(
            o,
            "    <input name=\"{}\" type=\"{ty}\" value=\"{value}\" />",
            input.name
        );
    }
    let _ = writeln!(o, "  </open_pbr_surface>");
    let _ = writeln!(o, "  <surfacematerial name=\"M_{id}\" type=\"material\">");
    let _ = writeln!(
        o,
        "    <input name=\"surfaceshader\" type=\"surfaceshader\" nodename=\"SR_{id}\" />"
    );
    let _ = writeln!(o, "  </surfacematerial>");
    let _ = writeln!(o, "</materialx>");
    Ok(o)
}

/// The MaterialX exporter: `<name>.mtlx`.
pub struct MtlxExporter;

impl Exporter for MtlxExporter {
    fn name(&self) -> &'static str {
        "mtlx"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["mtlx"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        _scene: Option<&crate::material::SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        Ok(vec![OutputFile {
            path: dir.join(format!("{}.mtlx", desc.name)),
            bytes: encode_mtlx(desc)?.into_bytes(),
        }])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ior_gives_back_its_reflectance() {
        for f0 in [0.0, 0.02, 0.04, 0.2, 0.9] {
            let n = ior_for(f0);
            let back = ((n - 1.0) / (n + 1.0)).powi(2);
            assert!((back - f0).abs() < 1e-12, "{f0}: ior {n} gives {back}");
        }
        assert!((ior_for(0.04) - 1.5).abs() < 1e-12);
    }
}
