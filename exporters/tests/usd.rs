//! USD export checked by usd-core (`exporters/python/check_usd.py`): stage metadata, UsdShade
//! wiring, binding, compliance checks, and every number of the lobe table against the material
//! JSON.
//!
//! Inputs: the fixture material, with a scene mesh and without. Outputs: pass/fail.
//! Invariants: fails in CI when Python/usd-core is missing.

mod common;

use common::*;
use glint_exporters::{Exporter, UsdExporter};
use std::process::Command;

fn check(scene: bool, isotropic_fallback: bool) {
    let Some(py) = python("pxr, numpy") else {
        return;
    };
    let tag = format!("usd-{scene}-{isotropic_fallback}");
    let dir = temp_dir(&tag);
    let mut desc = material("bunny-v2.final", 64);
    if isotropic_fallback {
        desc.fallback.anisotropy = None;
    }
    let mut mesh = scene_mesh();
    mesh.camera = Some(scene_camera());
    let files = UsdExporter
        .export(&desc, scene.then_some(&mesh), &dir)
        .unwrap();
    assert_eq!(files.len(), 2, "{files:?}");
    let mut json = desc.lobe_table_json();
    json["fallback"] = usd_fallback_json(&desc, serde_json::json!(desc.fallback.anisotropy));
    if scene {
        let c = scene_camera();
        json["camera"] = serde_json::json!({ "eye": c.eye, "forward": c.forward, "up": c.up, "yfov_deg": c.yfov_rad.to_degrees(), "width": c.width, "height": c.height });
    }
    let json_path = dir.join("material.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    let script = workspace().join("exporters/python/check_usd.py");
    let (ok, out, err) = run(Command::new(&py)
        .arg(&script)
        .arg(dir.join("bunny-v2.final.usda"))
        .arg(&json_path));
    assert!(ok, "check_usd.py failed:\n{out}\n{err}");
    // Opening, resolving and checking the stage prints nothing (usd-core's diagnostics go to
    // stderr).
    assert!(err.trim().is_empty(), "usd-core printed on stderr:\n{err}");
    assert!(out.contains("OK"), "{out}");
    eprintln!("{}", out.trim());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn usd_with_a_scene_passes_usd_core() {
    check(true, false);
}

#[test]
fn usd_material_only_passes_usd_core() {
    check(false, true);
}

/// The checker itself must catch a wrong number (so a pass means something).
#[test]
fn check_usd_catches_a_mismatch() {
    let Some(py) = python("pxr, numpy") else {
        return;
    };
    let dir = temp_dir("usd-mismatch");
    let desc = material("m", 16);
    UsdExporter.export(&desc, None, &dir).unwrap();
    let mut json = desc.lobe_table_json();
    json["coefficients"][1][5] = serde_json::json!(desc.coefficients[1][5] * (1.0 + 1e-5) + 1e-9);
    let json_path = dir.join("material.json");
    std::fs::write(&json_path, json.to_string()).unwrap();
    let script = workspace().join("exporters/python/check_usd.py");
    let (ok, out, err) = run(Command::new(&py)
        .arg(&script)
        .arg(dir.join("m.usda"))
        .arg(&json_path));
    assert!(!ok, "a mismatch passed:\n{out}\n{err}");
    assert!(
        out.contains("coefficients[1][5]") && out.trim().lines().count() == 1,
        "{out}{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The anisotropy comparison must be able to fail too: a wrong rotation, an anisotropy the stage
/// lost, and one the stage has but the fallback does not.
#[test]
fn check_usd_catches_a_lost_or_wrong_anisotropy() {
    let Some(py) = python("pxr, numpy") else {
        return;
    };
    let script = workspace().join("exporters/python/check_usd.py");
    let aniso = material("m", 16);
    let mut iso = aniso.clone();
    iso.fallback.anisotropy = None;
    let (s, r) = aniso
        .fallback
        .anisotropy
        .expect("the fixture is anisotropic");
    let cases = [
        (
            "wrong",
            &aniso,
            serde_json::json!([s, r * (1.0 + 1e-4)]),
            "fallback.anisotropy[1]",
        ),
        ("lost", &iso, serde_json::json!([s, r]), "missing"),
        ("extra", &aniso, serde_json::Value::Null, "present"),
    ];
    for (tag, desc, anisotropy, needle) in cases {
        let dir = temp_dir(&format!("usd-aniso-{tag}"));
        UsdExporter.export(desc, None, &dir).unwrap();
        let mut json = desc.lobe_table_json();
        json["fallback"] = usd_fallback_json(desc, anisotropy);
        let json_path = dir.join("material.json");
        std::fs::write(&json_path, json.to_string()).unwrap();
        let (ok, out, err) = run(Command::new(&py)
            .arg(&script)
            .arg(dir.join("m.usda"))
            .arg(&json_path));
        assert!(!ok, "{tag}: a mismatch passed:\n{out}\n{err}");
        assert!(
            out.contains(needle) && out.trim().lines().count() == 1,
            "{tag}: {out}{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
