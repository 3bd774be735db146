//! The MaterialX document and the fallback summary: MaterialX 1.39's own library (`validate()`,
//! the OpenPBR node definition) reads the `.mtlx`, every input has the value the glTF fallback maps
//! to, and a document with a wrong value or an unknown shader fails the check. The summary lists
//! every format with its error.

mod common;

use common::*;
use glint_exporters::{Exporter, FallbackExporter, MtlxExporter, fallback_summary};
use std::process::Command;

fn expected(desc: &glint_exporters::MaterialDesc) -> serde_json::Value {
    fallback_summary(desc)["mtlx"]["open_pbr_surface"].clone()
}

#[test]
fn the_mtlx_document_validates_and_carries_the_mapped_fallback() {
    let desc = material("coated", 16);
    let dir = temp_dir("mtlx");
    let files = MtlxExporter.export(&desc, None, &dir).unwrap();
    assert_eq!(files, vec![dir.join("coated.mtlx")]);
    let text = std::fs::read_to_string(&files[0]).unwrap();
    // The fixture has every layer: coat, fuzz, specular weight and anisotropy are all mapped.
    for input in [
        "coat_weight",
        "coat_roughness",
        "fuzz_color",
        "fuzz_roughness",
        "specular_weight",
        "specular_ior",
        "specular_roughness_anisotropy",
    ] {
        assert!(
            text.contains(&format!("name=\"{input}\"")),
            "{input}:\n{text}"
        );
    }
    let ior = expected(&desc)["specular_ior"].as_f64().unwrap();
    let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
    let s = desc.fallback.specular.unwrap();
    assert!((f0 - 0.04 * s.color[1]).abs() < 1e-9, "F0 {f0}");
    let Some(py) = python("MaterialX") else {
        return;
    };
    let script = workspace().join("exporters/python/check_mtlx.py");
    let check = |doc: &std::path::Path, want: &serde_json::Value| {
        let json_path = dir.join("expected.json");
        std::fs::write(&json_path, want.to_string()).unwrap();
        run(Command::new(&py).arg(&script).arg(doc).arg(&json_path))
    };
    let (ok, out, err) = check(&files[0], &expected(&desc));
    assert!(ok, "{out}\n{err}");
    println!("{out}");
    // It can fail: a wrong value, and a shader MaterialX does not define.
    let mut wrong = expected(&desc);
    wrong["coat_weight"] = serde_json::json!(0.61);
    let (ok, out, _) = check(&files[0], &wrong);
    assert!(!ok && out.contains("coat_weight"), "{out}");
    let bad = dir.join("bad.mtlx");
    std::fs::write(&bad, text.replace("open_pbr_surface", "open_pbr_surfacex")).unwrap();
    let (ok, out, _) = check(&bad, &expected(&desc));
    assert!(!ok, "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_summary_lists_every_format_and_its_error() {
    let desc = material("coated", 16);
    let dir = temp_dir("summary");
    let files = FallbackExporter.export(&desc, None, &dir).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&files[0]).unwrap()).unwrap();
    assert_eq!(json["weighting"], "scene");
    assert_eq!(json["gltf"]["relative_error"], desc.fallback.relative_error);
    assert_eq!(
        json["gltf"]["one_lobe_relative_error"],
        desc.fallback.one_lobe_relative_error
    );
    assert_eq!(
        json["usd"]["relative_error"],
        desc.preview_surface.relative_error
    );
    assert_eq!(json["usd"]["UsdPreviewSurface"]["useSpecularWorkflow"], 1);
    for ext in [
        "KHR_materials_specular",
        "KHR_materials_clearcoat",
        "KHR_materials_sheen",
        "KHR_materials_anisotropy",
    ] {
        assert!(json["gltf"]["extensions"][ext].is_object(), "{ext}");
    }
    assert!(json["mtlx"]["relative_error"].is_null());
    std::fs::remove_dir_all(&dir).unwrap();
}
