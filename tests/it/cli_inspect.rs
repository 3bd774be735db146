//! `glint inspect` end to end, through the built binary: the counts of every .glb in
//! ../shared/assets/glb against the table in ../shared/assets/README.md (parsed, so the reference
//! is the asset documentation, not our importer), the refusal of a file that requires Draco, the
//! DWAB EXRs' clamped texels, and the JSON keys other tools rely on.

use std::path::{Path, PathBuf};

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets")
}

fn glint(args: &[&str]) -> std::process::Output {
    crate::glint_command!()
        .args(args)
        .output()
        .expect("run glint")
}

/// (file, vertices, triangles) from the assets README's mesh table, e.g.
/// "| glb/bunny.glb | Stanford bunny ... | 1,839 / 3,674 | ...".
fn documented_counts() -> Vec<(String, usize, usize)> {
    let readme = std::fs::read_to_string(assets().join("README.md")).expect("assets README");
    let mut out = Vec::new();
    for line in readme.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 5 || !cells[1].ends_with(".glb") {
            continue;
        }
        let counts: Vec<usize> = cells[3]
            .split('/')
            .filter_map(|c| c.trim().replace(',', "").parse().ok())
            .collect();
        if counts.len() == 2 {
            out.push((cells[1].to_string(), counts[0], counts[1]));
        }
    }
    out
}

#[test]
fn inspect_reports_the_documented_counts_of_every_asset() {
    let documented = documented_counts();
    // Every .glb in the folder (not in bad/) must be in the table, and vice versa.
    let mut on_disk: Vec<String> = std::fs::read_dir(assets().join("glb"))
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.ends_with(".glb"))
        .map(|n| format!("glb/{n}"))
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = documented
        .iter()
        .map(|(f, _, _)| f.clone())
        .filter(|f| !f.starts_with("glb/bad/"))
        .collect();
    listed.sort();
    assert_eq!(on_disk, listed, "assets on disk and in the README differ");
    for (file, vertices, triangles) in documented
        .iter()
        .filter(|(f, _, _)| !f.starts_with("glb/bad/"))
    {
        let path = assets().join(file);
        let out = glint(&["inspect", path.to_str().unwrap(), "--json"]);
        assert!(
            out.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
        assert_eq!(json["vertices"].as_u64(), Some(*vertices as u64), "{file}");
        assert_eq!(
            json["triangles"].as_u64(),
            Some(*triangles as u64),
            "{file}"
        );
        assert_eq!(json["meshes"].as_u64(), Some(1), "{file}");
        assert_eq!(
            json["cameras"].as_array().map(|a| a.len()),
            Some(1),
            "{file}"
        );
        assert!(json["env"].is_null());
        println!("{file}: {vertices} vertices, {triangles} triangles");
    }
}

#[test]
fn a_required_draco_extension_is_refused_by_name() {
    let path = assets().join("glb/bad/draco_required.glb");
    let out = glint(&["inspect", path.to_str().unwrap()]);
    let code = out.status.code();
    assert!(
        code.is_some() && code != Some(0) && code != Some(101),
        "exit {code:?}"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("KHR_draco_mesh_compression"), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "one-line error: {stderr}");
    assert!(out.stdout.is_empty());
}

#[test]
fn dwab_environments_decode_with_negative_texels_clamped_and_counted() {
    let scene = assets().join("glb/teapot.glb");
    for name in ["studio", "forest"] {
        let env = assets().join(format!("hdr/dwab/{name}.exr"));
        let out = glint(&[
            "inspect",
            scene.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let env = &json["env"];
        assert_eq!(env["width"].as_u64(), Some(1024));
        assert_eq!(env["height"].as_u64(), Some(512));
        let clamped = env["clamped_texels"].as_u64().unwrap();
        assert!(
            clamped > 0,
            "{name}: the DWAB codec leaves small negatives; none were counted"
        );
        println!("{name}.exr (DWAB): {clamped} texels clamped");
    }
}

#[test]
fn text_output_and_usage_errors() {
    let scene = assets().join("glb/bunny.glb");
    let out = glint(&["inspect", scene.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("vertices   1839") && text.contains("triangles  3674"),
        "{text}"
    );
    // A subcommand without a required argument: clap's usage error, exit 2, nothing run.
    let out = glint(&["study"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--out"));
    // A missing file: one line, exit 1.
    let out = glint(&["inspect", "/nonexistent/x.glb"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr).trim().lines().count(),
        1
    );
}
