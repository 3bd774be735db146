//! glTF export: the Khronos glTF-Validator (`exporters/js/validate_gltf.mjs`) reports no error,
//! warning, info or hint for the scene and material-only files, with and without anisotropy; and
//! the GLB's JSON carries the fallback material and the exact lobe table.
//!
//! Inputs: the fixture material and mesh. Outputs: pass/fail. Invariants: the validator half fails
//! in CI when node or the validator is missing.

mod common;

use common::*;
use glint_exporters::{Exporter, GltfExporter};
use serde_json::Value;
use std::process::Command;

/// The JSON chunk of a GLB.
fn glb_json(bytes: &[u8]) -> Value {
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
        bytes.len()
    );
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

#[test]
fn glb_carries_the_fallback_and_the_exact_lobe_table() {
    let dir = temp_dir("gltf-json");
    let desc = material("mat", 16);
    let files = GltfExporter.export(&desc, None, &dir).unwrap();
    assert_eq!(files, [dir.join("mat.glb"), dir.join("mat_ph.exr")]);
    let json = glb_json(&std::fs::read(&files[0]).unwrap());
    let m = &json["materials"][0];
    let pbr = &m["pbrMetallicRoughness"];
    assert_eq!(
        pbr["baseColorFactor"],
        serde_json::json!([0.31, 0.22, 0.13, 1.0])
    );
    assert_eq!(pbr["roughnessFactor"], 0.23);
    assert_eq!(
        m["extensions"]["KHR_materials_anisotropy"]["anisotropyStrength"],
        0.4
    );
    // Every layer of the fixture, as its extension defines it; used, never required (a viewer
    // without them still shows the base).
    assert_eq!(
        json["extensionsUsed"],
        serde_json::json!([
            "KHR_materials_anisotropy",
            "KHR_materials_clearcoat",
            "KHR_materials_sheen",
            "KHR_materials_specular"
        ])
    );
    let e = &m["extensions"];
    assert_eq!(e["KHR_materials_clearcoat"]["clearcoatFactor"], 0.6);
    assert_eq!(
        e["KHR_materials_clearcoat"]["clearcoatRoughnessFactor"],
        0.1
    );
    assert_eq!(
        e["KHR_materials_sheen"]["sheenColorFactor"],
        serde_json::json!([0.2, 0.2, 0.25])
    );
    assert_eq!(e["KHR_materials_sheen"]["sheenRoughnessFactor"], 0.4);
    assert_eq!(e["KHR_materials_specular"]["specularFactor"], 0.8);
    assert_eq!(
        e["KHR_materials_specular"]["specularColorFactor"],
        serde_json::json!([1.5, 1.25, 1.0])
    );
    assert!(json.get("extensionsRequired").is_none());
    let g = &m["extras"]["glint"];
    assert_eq!(g["lambda"].as_f64().unwrap(), desc.lambda);
    assert_eq!(g["table"]["uri"], "mat_ph.exr");
    assert_eq!(g["table"]["parameterisation"], "hemi-octahedral");
    // The writer is shortest-round-trip (exact for JS, Python and Rust's str::parse); serde_json's
    // default reader is not correctly rounded, hence the 1-ulp slack.
    let ulp = |a: f64, b: f64| (a.to_bits() as i64 - b.to_bits() as i64).abs() <= 1;
    for k in 0..3 {
        let c: Vec<f64> = serde_json::from_value(g["coefficients"][k].clone()).unwrap();
        assert!(
            c.len() == desc.coefficients[k].len()
                && c.iter()
                    .zip(&desc.coefficients[k])
                    .all(|(a, b)| ulp(*a, *b))
        );
    }
    let centres: Vec<[f64; 3]> = serde_json::from_value(g["centres"].clone()).unwrap();
    assert!(
        centres
            .iter()
            .flatten()
            .zip(desc.centres.iter().flatten())
            .all(|(a, b)| ulp(*a, *b))
    );
    assert_eq!(g["provenance"]["tool"], "glint 0.1.0 (test)");
    // A one-lobe isotropic fallback: no extension at all.
    let mut iso = desc.clone();
    iso.fallback.anisotropy = None;
    iso.fallback.specular = None;
    iso.fallback.clearcoat = None;
    iso.fallback.sheen = None;
    GltfExporter
        .export(&iso, Some(&scene_mesh()), &dir)
        .unwrap();
    let json = glb_json(&std::fs::read(dir.join("mat.glb")).unwrap());
    assert!(
        json.get("extensionsUsed").is_none() && json["materials"][0].get("extensions").is_none()
    );
    assert_eq!(json["accessors"][0]["count"], 24);
    assert!(json.get("cameras").is_none(), "no view given, no camera");
    // With a view: a camera node whose matrix is the camera's frame (+X right, +Y up, +Z back,
    // eye).
    let mut mesh = scene_mesh();
    let cam = scene_camera();
    mesh.camera = Some(cam.clone());
    GltfExporter.export(&iso, Some(&mesh), &dir).unwrap();
    let json = glb_json(&std::fs::read(dir.join("mat.glb")).unwrap());
    let p = &json["cameras"][0]["perspective"];
    assert!(
        (p["yfov"].as_f64().unwrap() - cam.yfov_rad).abs() < 1e-12
            && p["aspectRatio"].as_f64().unwrap() == 64.0 / 48.0
    );
    assert_eq!(json["scenes"][0]["nodes"], serde_json::json!([0, 1]));
    let m: Vec<f64> = serde_json::from_value(json["nodes"][1]["matrix"].clone()).unwrap();
    let back = [-cam.forward[0], -cam.forward[1], -cam.forward[2]];
    for k in 0..3 {
        assert!(
            (m[4 + k] - cam.up[k]).abs() < 1e-12
                && (m[8 + k] - back[k]).abs() < 1e-12
                && (m[12 + k] - cam.eye[k]).abs() < 1e-12
        );
    }
    std::fs::remove_dir_all(dir).unwrap();
}

fn validate(scene: bool, anisotropic: bool) {
    let Some((node, script)) = node_validator() else {
        return;
    };
    let dir = temp_dir(&format!("gltf-val-{scene}-{anisotropic}"));
    let mut desc = material("val", 16);
    if !anisotropic {
        desc.fallback.anisotropy = None;
    }
    let mut mesh = scene_mesh();
    mesh.camera = Some(scene_camera());
    GltfExporter
        .export(&desc, scene.then_some(&mesh), &dir)
        .unwrap();
    let (ok, out, err) = run(Command::new(node).arg(&script).arg(dir.join("val.glb")));
    let report: Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("no report ({e}):\n{out}\n{err}"));
    let issues = &report["issues"];
    let all = serde_json::to_string_pretty(&issues["messages"]).unwrap();
    for k in ["numErrors", "numWarnings", "numHints"] {
        assert_eq!(issues[k], 0, "{k} in {all}");
    }
    // Infos: only the two the validator cannot avoid reporting (see src/gltf.rs), and only when
    // they apply; the isotropic material-only file has none at all.
    let mut allowed: Vec<(&str, &str)> = Vec::new();
    if anisotropic {
        allowed.push((
            "UNUSED_MESH_TANGENT",
            "/meshes/0/primitives/0/attributes/TANGENT",
        ));
    }
    if scene {
        allowed.push((
            "UNUSED_MESH_TANGENT",
            "/meshes/0/primitives/0/attributes/TANGENT",
        ));
        allowed.push((
            "UNUSED_OBJECT",
            "/meshes/0/primitives/0/attributes/TEXCOORD_0",
        ));
    }
    let infos: Vec<(String, String)> = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            (
                m["code"].as_str().unwrap().to_string(),
                m["pointer"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect();
    for (code, pointer) in &infos {
        assert!(
            allowed.iter().any(|(c, p)| c == code && p == pointer),
            "unexpected info {code} at {pointer} in {all}"
        );
    }
    if !scene && !anisotropic {
        assert!(ok && infos.is_empty(), "{all}{err}");
    }
    let info = &report["info"];
    assert_eq!(info["materialCount"], 1);
    if anisotropic {
        assert!(
            report["info"]["extensionsUsed"]
                .as_array()
                .unwrap()
                .iter()
                .any(|e| e == "KHR_materials_anisotropy")
        );
    }
    eprintln!(
        "gltf-validator {}: scene={scene} anisotropic={anisotropic}: 0 errors, 0 warnings, 0 hints, infos {:?}",
        report["validatorVersion"],
        infos.iter().map(|i| &i.0).collect::<Vec<_>>()
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// The validator path must be able to fail (so a pass means something).
#[test]
fn validator_reports_a_broken_file() {
    let Some((node, script)) = node_validator() else {
        return;
    };
    let dir = temp_dir("gltf-broken");
    let desc = material("broken", 16);
    GltfExporter.export(&desc, None, &dir).unwrap();
    let mut bytes = std::fs::read(dir.join("broken.glb")).unwrap();
    bytes.truncate(bytes.len() - 64); // cut into the BIN chunk
    std::fs::write(dir.join("cut.glb"), &bytes).unwrap();
    let (ok, out, _) = run(Command::new(node).arg(&script).arg(dir.join("cut.glb")));
    let report: Value = serde_json::from_str(&out).unwrap();
    assert!(
        !ok && report["issues"]["numErrors"].as_u64().unwrap() > 0,
        "{out}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn validator_is_clean_with_a_scene() {
    validate(true, true);
    validate(true, false);
}

#[test]
fn validator_is_clean_material_only() {
    validate(false, true);
    validate(false, false);
}
