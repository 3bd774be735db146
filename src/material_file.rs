//! Reading a material from a file: glint's material JSON (`glint fit`), or the lobe table that a
//! glint export carries — a `.glb`/`.gltf` (`extras.glint`) or a `.usda` (the `GlintDbrdf` shader's
//! inputs), read by `glint_exporters::import`. Wherever glint takes a material (`render
//! --material`, `export`), any of these will do; a round trip JSON → export → glint gives the same
//! lobe table.
//!
//! Also the fallback an export carries, as the standard material renderers evaluate
//! ([`read_fallback`]).
//!
//! Inputs: a path. Outputs: a validated [`Material`] (or [`StandardMaterial`]) or a one-line
//! [`MaterialFileError`].
//! Invariants: only the named file is read (a USD layer is parsed alone, without composition, and
//! the table it names is not opened); every number is validated against the layout
//! ([`Material::parse`]).

use crate::brdf::standard::{GltfParams, PreviewParams, StandardMaterial};
use crate::fit::material::{Material, MaterialError};
use std::path::{Path, PathBuf};

/// Why a material file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MaterialFileError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Invalid {
        path: PathBuf,
        source: MaterialError,
    },
    #[error(transparent)]
    Export(#[from] glint_exporters::ExportError),
    #[error("{path}: the fallback's {field} is missing or out of range")]
    Fallback { path: PathBuf, field: &'static str },
}

/// Reads a material by extension: `.glb`, `.gltf`, `.usda`, `.usd` are exports read back; anything
/// else is glint's material JSON.
pub fn read_material(path: &Path) -> Result<Material, MaterialFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let invalid = |source| MaterialFileError::Invalid {
        path: path.to_path_buf(),
        source,
    };
    match ext.as_str() {
        "glb" | "gltf" | "usda" | "usd" => {
            let table = glint_exporters::import::read_lobe_table(path)?;
            Material::from_lobe_table(&table).map_err(invalid)
        }
        _ => {
            let text = std::fs::read_to_string(path).map_err(|source| MaterialFileError::Read {
                path: path.to_path_buf(),
                source,
            })?;
            Material::parse(&text).map_err(invalid)
        }
    }
}

/// Reads the fallback an export carries, as renderers evaluate it: the glTF material of a
/// `.glb`/`.gltf` (pbrMetallicRoughness with `KHR_materials_specular`, `_clearcoat`, `_sheen`,
/// `_anisotropy`; a specular or sheen colour that is not grey is read by its green channel, as
/// glint writes grey ones) or the UsdPreviewSurface of a `.usda`.
pub fn read_fallback(path: &Path) -> Result<StandardMaterial, MaterialFileError> {
    use serde_json::Value;
    let v = glint_exporters::import::read_fallback(path)?;
    let missing = |field| MaterialFileError::Fallback {
        path: path.to_path_buf(),
        field,
    };
    let num =
        |v: &Value, field: &'static str, default: Option<f64>| -> Result<f64, MaterialFileError> {
            match v.as_f64() {
                Some(x) if x.is_finite() && (0.0..=1e3).contains(&x) => Ok(x),
                None if v.is_null() => default.ok_or_else(|| missing(field)),
                _ => Err(missing(field)),
            }
        };
    let rgb = |v: &Value,
               field: &'static str,
               default: [f64; 3]|
     -> Result<[f64; 3], MaterialFileError> {
        match v.as_array() {
            None if v.is_null() => Ok(default),
            Some(a) if a.len() >= 3 => {
                let mut out = [0.0; 3];
                for (k, o) in out.iter_mut().enumerate() {
                    *o = num(&a[k], field, None)?;
                }
                Ok(out)
            }
            _ => Err(missing(field)),
        }
    };
    if let Some(ps) = v.get("UsdPreviewSurface") {
        let params = PreviewParams {
            use_specular_workflow: num(
                &ps["useSpecularWorkflow"],
                "useSpecularWorkflow",
                Some(0.0),
            )? != 0.0,
            metallic: num(&ps["metallic"], "metallic", Some(0.0))?,
            roughness: num(&ps["roughness"], "roughness", Some(0.5))?,
            clearcoat: num(&ps["clearcoat"], "clearcoat", Some(0.0))?,
            clearcoat_roughness: num(&ps["clearcoatRoughness"], "clearcoatRoughness", Some(0.01))?,
        };
        return Ok(StandardMaterial::Preview {
            params,
            diffuse: rgb(&ps["diffuseColor"], "diffuseColor", [0.18; 3])?,
            specular: rgb(&ps["specularColor"], "specularColor", [0.0; 3])?,
        });
    }
    let pbr = &v["pbrMetallicRoughness"];
    let base = rgb(&pbr["baseColorFactor"], "baseColorFactor", [1.0; 3])?;
    let ext = &v["extensions"];
    let spec = &ext["KHR_materials_specular"];
    let coat = &ext["KHR_materials_clearcoat"];
    let sheen = &ext["KHR_materials_sheen"];
    let aniso = &ext["KHR_materials_anisotropy"];
    let params = GltfParams {
        metallic: num(&pbr["metallicFactor"], "metallicFactor", Some(1.0))?,
        roughness: num(&pbr["roughnessFactor"], "roughnessFactor", Some(1.0))?,
        specular: num(&spec["specularFactor"], "specularFactor", Some(1.0))?,
        dielectric_f0: (0.04
            * rgb(
                &spec["specularColorFactor"],
                "specularColorFactor",
                [1.0; 3],
            )?[1])
            .min(1.0),
        clearcoat: num(&coat["clearcoatFactor"], "clearcoatFactor", Some(0.0))?,
        clearcoat_roughness: num(
            &coat["clearcoatRoughnessFactor"],
            "clearcoatRoughnessFactor",
            Some(0.0),
        )?,
        sheen: rgb(&sheen["sheenColorFactor"], "sheenColorFactor", [0.0; 3])?[1],
        sheen_roughness: num(
            &sheen["sheenRoughnessFactor"],
            "sheenRoughnessFactor",
            Some(0.0),
        )?,
        anisotropy: num(
            &aniso["anisotropyStrength"],
            "anisotropyStrength",
            Some(0.0),
        )?,
        rotation: aniso["anisotropyRotation"]
            .as_f64()
            .filter(|r| r.is_finite())
            .unwrap_or(0.0),
    };
    Ok(StandardMaterial::Gltf {
        params,
        base_color: base,
    })
}
