//! The export interface: registry, determinism (byte-identical re-exports), atomicity (no temporary
//! files left, nothing written on failure), and refusals with one-line errors.
//!
//! Inputs: the fixture material and mesh. Outputs: pass/fail. Invariants: no external tools needed.

mod common;

use common::*;
use glint_exporters::merl::MerlTable;
use glint_exporters::{ExportError, export_all, find_exporter, registry};
use std::collections::BTreeMap;
use std::path::Path;

fn listing(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

fn small_merl() -> MerlTable {
    MerlTable::sample(|wi, wo| [0.1 + 0.01 * wi[2], 0.2 + 0.01 * wo[2], 0.3])
}

#[test]
fn registry_lists_every_format() {
    let names: Vec<_> = registry().iter().map(|e| e.name()).collect();
    assert_eq!(
        names,
        ["exr", "gltf", "usd", "mtlx", "fallback", "merl", "mitsuba"]
    );
    for e in registry() {
        assert!(!e.extensions().is_empty());
        assert_eq!(find_exporter(e.name()).unwrap().name(), e.name());
    }
    assert!(find_exporter("fbx").is_none());
}

#[test]
fn exports_are_deterministic_and_leave_no_temporary_files() {
    let a = temp_dir("det-a");
    let b = temp_dir("det-b");
    let mut desc = material("det", 64);
    desc.merl = Some(small_merl());
    let mesh = scene_mesh();
    let written = export_all(&desc, Some(&mesh), &a, &[]).unwrap();
    let names: Vec<_> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "det_ph.exr",
            "det.glb",
            "det.usda",
            "det.mtlx",
            "det_fallback.json",
            "det.binary"
        ]
    );
    // Twice into the same folder, and once into another (a fresh process state for the counters).
    export_all(&desc, Some(&mesh), &a, &[]).unwrap();
    export_all(
        &desc.clone(),
        Some(&mesh.clone()),
        &b,
        &["merl", "fallback", "usd", "mtlx", "gltf", "exr"],
    )
    .unwrap();
    let (la, lb) = (listing(&a), listing(&b));
    assert_eq!(
        la.keys().collect::<Vec<_>>(),
        [
            "det.binary",
            "det.glb",
            "det.mtlx",
            "det.usda",
            "det_fallback.json",
            "det_ph.exr"
        ],
        "stray files: {:?}",
        la.keys()
    );
    for (name, bytes) in &la {
        assert!(&lb[name] == bytes, "{name} differs between exports");
    }
    // Material-only exports are deterministic too.
    let c = temp_dir("det-c");
    export_all(&desc, None, &c, &["gltf", "usd"]).unwrap();
    let first = listing(&c);
    export_all(&desc, None, &c, &["gltf", "usd"]).unwrap();
    assert_eq!(first, listing(&c));
    for d in [a, b, c] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn failures_write_nothing_and_say_why_in_one_line() {
    let dir = temp_dir("fail");
    let desc = material("fail", 16);
    let one_line = |e: ExportError| {
        let m = e.to_string();
        assert!(!m.contains('\n') && !m.is_empty(), "{m:?}");
        m
    };
    // The destination is a file, not a folder.
    let file = dir.join("not-a-dir");
    std::fs::write(&file, b"x").unwrap();
    let m = one_line(export_all(&desc, None, &file, &[]).unwrap_err());
    assert!(
        m.contains("not-a-dir") && m.contains("not an existing directory"),
        "{m}"
    );
    for e in registry() {
        assert!(matches!(
            e.export(&desc, None, &file),
            Err(ExportError::NotADirectory { .. })
        ));
    }
    // A missing folder.
    assert!(matches!(
        export_all(&desc, None, &dir.join("missing"), &["exr"]),
        Err(ExportError::NotADirectory { .. })
    ));
    // An unknown format is refused before anything is written, even after a valid one.
    let m = one_line(export_all(&desc, None, &dir, &["exr", "fbx"]).unwrap_err());
    assert!(
        m.contains("'fbx'") && m.contains("exr, gltf, usd, mtlx, fallback, merl"),
        "{m}"
    );
    // No MERL table: the MERL exporter refuses, and export_all writes nothing (it builds all
    // first).
    let m = one_line(export_all(&desc, None, &dir, &["exr", "merl"]).unwrap_err());
    assert!(m.contains("no MERL table"), "{m}");
    // Bad descriptions.
    let mut bad = desc.clone();
    bad.coefficients[2].pop();
    assert!(
        one_line(export_all(&bad, None, &dir, &["gltf"]).unwrap_err()).contains("coefficients")
    );
    let mut bad = desc.clone();
    bad.lambda = f64::NAN;
    assert!(one_line(export_all(&bad, None, &dir, &["usd"]).unwrap_err()).contains("lambda"));
    let mut bad = desc.clone();
    bad.table.texels.pop();
    assert!(one_line(export_all(&bad, None, &dir, &["exr"]).unwrap_err()).contains("table"));
    let mut bad = desc.clone();
    bad.name = "../escape".into();
    assert!(matches!(
        export_all(&bad, None, &dir, &[]),
        Err(ExportError::InvalidName { .. })
    ));
    let mut bad = desc.clone();
    bad.fallback.roughness = 1.5;
    assert!(one_line(export_all(&bad, None, &dir, &["gltf"]).unwrap_err()).contains("fallback"));
    // A bad mesh.
    let mut mesh = scene_mesh();
    mesh.indices.push(999);
    mesh.indices.extend_from_slice(&[0, 1]);
    assert!(
        one_line(export_all(&desc, Some(&mesh), &dir, &["gltf", "usd"]).unwrap_err())
            .contains("index 999")
    );
    // A bad MERL table (non-finite).
    let mut bad = desc.clone();
    bad.merl = Some(MerlTable::sample(|_, _| [f64::INFINITY, 0.0, 0.0]));
    assert!(one_line(export_all(&bad, None, &dir, &["merl"]).unwrap_err()).contains("not finite"));
    // Nothing at all was written by any of these.
    let left: Vec<_> = listing(&dir).into_keys().collect();
    assert_eq!(left, ["not-a-dir"]);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn an_io_failure_leaves_no_partial_file() {
    // The GLB's destination is a folder: the rename fails after the temporary file was written.
    let dir = temp_dir("iofail");
    let desc = material("io", 16);
    std::fs::create_dir(dir.join("io.glb")).unwrap();
    let m = export_all(&desc, None, &dir, &["gltf"])
        .unwrap_err()
        .to_string();
    assert!(m.contains("io.glb") && !m.contains('\n'), "{m}");
    // The temporary file is gone and nothing after the failure was written.
    let left: Vec<_> = listing_names(&dir);
    assert_eq!(left, ["io.glb"], "{left:?}");
    assert!(dir.join("io.glb").is_dir());
    std::fs::remove_dir_all(dir).unwrap();
}

fn listing_names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}
