//! glTF 2.0 binary (`<name>.glb`): the material on the caller's mesh, or on a preview sphere.
//!
//! Inputs: a validated [`MaterialDesc`] and an optional [`SceneMesh`]. Outputs: the GLB bytes
//! ([`encode_glb`]) and the exporter ([`GltfExporter`]), which also writes the `<name>_ph.exr`
//! table the GLB points at. The material is `pbrMetallicRoughness` from the fallback
//! (baseColorFactor, metallicFactor, roughnessFactor), plus each of `KHR_materials_specular`,
//! `_clearcoat`, `_sheen` and `_anisotropy` the fallback uses (in `extensionsUsed`, not required:
//! a viewer without them still shows the base); `material.extras.glint`
//! carries the whole lobe table (f64, shortest round-trip), the provenance, and the table's
//! relative URI and parameterisation.
//!
//! The preview sphere carries positions and normals, plus tangents when the material is anisotropic
//! (`KHR_materials_anisotropy` needs them); a caller's mesh keeps its tangents and UVs.
//!
//! When the scene carries a camera (the view glint renders, docs/conventions.md §4), it is a second
//! node with a perspective camera (yfov, aspect ratio W/H, near and far planes) and a rigid matrix.
//!
//! Invariants: one scene, one mesh node (and a camera node when given), one mesh, one primitive
//! (triangles, u32 indices), one material; POSITION has exact min/max; normals and tangents are
//! unit (the mesh is validated and normalised); each attribute has its own 4-byte-aligned buffer
//! view with a target; JSON keys come from `serde_json`'s ordered map, so equal inputs give equal
//! bytes. Khronos glTF-Validator (2.0.0-dev.3.10) reports no error, warning or hint, and no info
//! for the isotropic preview; its only infos are UNUSED_MESH_TANGENT when anisotropic (it counts
//! tangents as used only with a normal texture, not for anisotropy) and UNUSED_OBJECT for a
//! caller's TEXCOORD_0 (the material has no texture) — tested.

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::exr::{encode_ph_exr, ph_exr_file_name};
use crate::material::{CleanMesh, MaterialDesc, SceneMesh};
use crate::sphere::preview_sphere;
use crate::table::{PARAMETERISATION, PARAMETERISATION_FORMULA};
use serde_json::{Value, json};
use std::path::Path;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends one tightly packed attribute (f32 components) or the u32 indices; returns the
    /// accessor.
    fn push(&mut self, data: &[u8], target: u32, accessor: Value) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let view = self.views.len();
        self.views.push(json!({ "buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len(), "target": target }));
        self.bytes.extend_from_slice(data);
        let mut a = accessor;
        a["bufferView"] = json!(view);
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, items: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let data: Vec<u8> = items
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let mut a = json!({ "componentType": FLOAT, "count": items.len(), "type": kind });
        if bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in items {
                for k in 0..N {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            a["min"] = json!(lo.to_vec());
            a["max"] = json!(hi.to_vec());
        }
        self.push(&data, ARRAY_BUFFER, a)
    }
}

/// The material's JSON object (shared by the scene and material-only files).
fn material_json(desc: &MaterialDesc) -> (Value, bool) {
    let fb = &desc.fallback;
    let mut glint = desc.lobe_table_json();
    glint["table"] = json!({
        "uri": ph_exr_file_name(&desc.name),
        "parameterisation": PARAMETERISATION,
        "formula": PARAMETERISATION_FORMULA,
        "resolution": desc.table.resolution,
        "channels": "RGB float32, linear, p(h) in 1/sr",
    });
    glint["fallback_relative_error"] = json!(fb.relative_error);
    glint["fallback_uniform_relative_error"] = json!(fb.uniform_relative_error);
    glint["fallback_one_lobe_relative_error"] = json!(fb.one_lobe_relative_error);
    glint["fallback_weighting"] = json!(fb.weighting.name());
    let mut m = json!({
        "name": desc.name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [fb.base_color[0], fb.base_color[1], fb.base_color[2], 1.0],
            "metallicFactor": fb.metallic,
            "roughnessFactor": fb.roughness,
        },
        "extras": { "glint": glint },
    });
    let extensions = extensions_json(fb);
    if !extensions.is_empty() {
        m["extensions"] = Value::Object(extensions);
    }
    (m, fb.anisotropy.is_some())
}

/// The `KHR_materials_*` objects of a fallback, by extension name (empty when it has none).
pub(crate) fn extensions_json(fb: &crate::material::PbrFallback) -> serde_json::Map<String, Value> {
    let mut extensions = serde_json::Map::new();
    if let Some((strength, rotation)) = fb.anisotropy {
        extensions.insert(
            "KHR_materials_anisotropy".into(),
            json!({ "anisotropyStrength": strength, "anisotropyRotation": rotation }),
        );
    }
    if let Some(c) = fb.clearcoat {
        extensions.insert(
            "KHR_materials_clearcoat".into(),
            json!({ "clearcoatFactor": c.factor, "clearcoatRoughnessFactor": c.roughness }),
        );
    }
    if let Some(s) = fb.sheen {
        extensions.insert(
            "KHR_materials_sheen".into(),
            json!({ "sheenColorFactor": s.color, "sheenRoughnessFactor": s.roughness }),
        );
    }
    if let Some(s) = fb.specular {
        extensions.insert(
            "KHR_materials_specular".into(),
            json!({ "specularFactor": s.factor, "specularColorFactor": s.color }),
        );
    }
    extensions
}

/// The GLB bytes for a validated description and mesh (the preview sphere when `scene` is `None`).
pub fn encode_glb(desc: &MaterialDesc, scene: Option<&SceneMesh>) -> Result<Vec<u8>, ExportError> {
    desc.validate()?;
    let mesh: CleanMesh = match scene {
        Some(s) => s.validated()?,
        None => {
            // Only what the material uses, so validators find nothing unused: tangents for
            // anisotropy.
            let mut sphere = preview_sphere();
            sphere.uvs = None;
            if desc.fallback.anisotropy.is_none() {
                sphere.tangents = None;
            }
            sphere.validated()?
        }
    };
    let mut bin = Bin {
        bytes: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut attributes = serde_json::Map::new();
    attributes.insert(
        "POSITION".into(),
        json!(bin.floats(&mesh.positions, "VEC3", true)),
    );
    attributes.insert(
        "NORMAL".into(),
        json!(bin.floats(&mesh.normals, "VEC3", false)),
    );
    if let Some(t) = &mesh.tangents {
        attributes.insert("TANGENT".into(), json!(bin.floats(t, "VEC4", false)));
    }
    if let Some(uv) = &mesh.uvs {
        attributes.insert("TEXCOORD_0".into(), json!(bin.floats(uv, "VEC2", false)));
    }
    let index_bytes: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let indices = bin.push(
        &index_bytes,
        ELEMENT_ARRAY_BUFFER,
        json!({ "componentType": UNSIGNED_INT, "count": mesh.indices.len(), "type": "SCALAR" }),
    );
    while !bin.bytes.len().is_multiple_of(4) {
        bin.bytes.push(0);
    }
    let (material, _) = material_json(desc);
    let mesh_name = if scene.is_some() {
        desc.name.clone()
    } else {
        format!("{}_preview_sphere", desc.name)
    };
    let mut root = json!({
        "asset": { "version": "2.0", "generator": concat!("glint-exporters ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "name": desc.name, "nodes": [0] }],
        "nodes": [{ "name": mesh_name, "mesh": 0 }],
        "meshes": [{ "name": mesh_name, "primitives": [{ "attributes": attributes, "indices": indices, "material": 0 }] }],
        "materials": [material],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{ "byteLength": bin.bytes.len() }],
    });
    let used = desc.fallback.extensions();
    if !used.is_empty() {
        root["extensionsUsed"] = json!(used);
    }
    if let Some(camera) = scene.and_then(|s| s.camera.as_ref()) {
        let (r, u, f, e) = (camera.right(), camera.up, camera.forward, camera.eye);
        let mut perspective = json!({ "yfov": camera.yfov_rad, "aspectRatio": camera.width as f64 / camera.height as f64, "znear": camera.znear });
        if let Some(far) = camera.zfar {
            perspective["zfar"] = json!(far);
        }
        root["cameras"] =
            json!([{ "name": camera.name, "type": "perspective", "perspective": perspective }]);
        // Column-major camera-to-world: +X right, +Y up, +Z back (glTF cameras look down −Z).
        let matrix = [
            r[0], r[1], r[2], 0.0, u[0], u[1], u[2], 0.0, -f[0], -f[1], -f[2], 0.0, e[0], e[1],
            e[2], 1.0,
        ];
        if let Some(nodes) = root["nodes"].as_array_mut() {
            nodes.push(json!({ "name": camera.name, "camera": 0, "matrix": matrix }));
        }
        root["scenes"][0]["nodes"] = json!([0, 1]);
    }
    let mut text = serde_json::to_vec(&root).map_err(|e| ExportError::InvalidMaterial {
        material: desc.name.clone(),
        field: "glTF JSON",
        reason: e.to_string(),
    })?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.bytes.len();
    if total > u32::MAX as usize {
        return Err(ExportError::InvalidMesh {
            reason: format!("the GLB would be {total} bytes; GLB files are limited to 4 GiB"),
        });
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin.bytes);
    Ok(out)
}

/// Writes `<name>.glb` and the `<name>_ph.exr` it references.
#[derive(Debug, Clone, Copy, Default)]
pub struct GltfExporter;

impl Exporter for GltfExporter {
    fn name(&self) -> &'static str {
        "gltf"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["glb", "exr"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        let glb = encode_glb(desc, scene)?;
        Ok(vec![
            OutputFile {
                path: dir.join(format!("{}.glb", desc.name)),
                bytes: glb,
            },
            OutputFile {
                path: dir.join(ph_exr_file_name(&desc.name)),
                bytes: encode_ph_exr(desc)?,
            },
        ])
    }
}
