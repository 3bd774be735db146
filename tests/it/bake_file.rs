//! The bake file and `glint bake` end to end: reuse when nothing changed; a corrupt, truncated or
//! older-version bake is detected, reported and rebuilt; `--json` carries the documented keys;
//! baking the fit view's vertices first gives that view the same transfer as the full bake.

use crate::common;

use glint::bake::{BakeSettings, Baker, file};
use glint::light::LightSums;
use glint::raster::visible_vertices;
use glint::sphere::{LobeLayout, LobeSet, srbf};
use glint::transfer::TransferContext;
use std::path::Path;

fn glint(args: &[&str]) -> std::process::Output {
    run_glint!(args)
}

fn bake_json(out: &Path) -> (serde_json::Value, String) {
    let scene = common::assets().join("glb/teapot.glb");
    let env = common::assets().join("hdr/small/courtyard_512.exr");
    let o = glint(&[
        "bake",
        scene.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
        "--fit-size",
        "80x60",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (
        serde_json::from_slice(&o.stdout).expect("one JSON object"),
        String::from_utf8_lossy(&o.stderr).to_string(),
    )
}

#[test]
fn bake_is_reused_and_bad_bakes_are_rebuilt() {
    let dir = common::temp_dir("bakefile");
    let out = dir.join("teapot.bake");
    let (first, _) = bake_json(&out);
    for key in [
        "vertices",
        "rays_traced",
        "mean_cut_size",
        "seconds",
        "decisions",
        "transfer_seconds",
        "bytes_per_vertex",
        "tracer",
        "stages",
    ] {
        assert!(!first[key].is_null(), "missing key {key}");
    }
    // CI installs Embree (.ci/test): there the bake must trace with it.
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        assert_eq!(
            first["tracer"], "embree",
            "CI builds with Embree (build.rs)"
        );
    }
    // The teapot's 529 vertices, plus the midpoints of edges the refinement split (decision (e)).
    let vertices = first["vertices"].as_u64().unwrap();
    assert!(
        vertices > 529,
        "the teapot under courtyard is refined: {vertices}"
    );
    assert_eq!(
        first["decisions"]["refined_vertices"].as_u64(),
        Some(vertices)
    );
    assert!(
        first["decisions"]["refine_reason"]
            .as_str()
            .unwrap()
            .contains("edges split"),
        "{}",
        first["decisions"]["refine_reason"]
    );
    assert_eq!(first["reused"].as_bool(), Some(false));
    assert!(first["rays_traced"].as_u64().unwrap() > 0);
    // The stages account for every vertex once and every ray, counted apart from the totals (the
    // vertex records): the imported vertices in sampling's stages, the new ones in the rounds.
    let stages = first["stages"].as_array().expect("stages");
    let sum = |pick: &dyn Fn(&serde_json::Value) -> bool, key: &str| -> f64 {
        stages
            .iter()
            .filter(|s| pick(s))
            .map(|s| s[key].as_f64().unwrap())
            .sum()
    };
    let round = |s: &serde_json::Value| s["stage"].as_str().unwrap().starts_with("refinement");
    let names: Vec<&str> = stages
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        names[..3],
        ["sampled", "interpolated", "traced"],
        "{names:?}"
    );
    assert_eq!(sum(&|s| !round(s), "vertices"), 529.0, "{stages:?}");
    assert_eq!(sum(&round, "vertices"), (vertices - 529) as f64);
    assert_eq!(
        sum(&|_| true, "rays"),
        first["rays_traced"].as_f64().unwrap()
    );
    assert_eq!(
        sum(&|s| s["stage"] == "interpolated", "vertices"),
        first["decisions"]["interpolated_vertices"]
            .as_f64()
            .unwrap()
    );
    assert_eq!(sum(&|s| s["stage"] == "interpolated", "rays"), 0.0);
    let after_decisions =
        first["seconds"].as_f64().unwrap() - first["decision_seconds"].as_f64().unwrap();
    assert!(
        sum(&|_| true, "seconds") <= after_decisions,
        "{stages:?} within {after_decisions} s"
    );
    let (second, _) = bake_json(&out);
    assert_eq!(second["reused"].as_bool(), Some(true));
    let path = out.join("bake.glint");
    let good = std::fs::read(&path).unwrap();
    // Corrupt one byte in the cut data.
    let mut corrupt = good.clone();
    let k = corrupt.len() - 20;
    corrupt[k] ^= 0x55;
    std::fs::write(&path, &corrupt).unwrap();
    let (again, stderr) = bake_json(&out);
    assert_eq!(again["reused"].as_bool(), Some(false));
    assert!(
        stderr.contains("checksum") && stderr.contains("rebuilding"),
        "{stderr}"
    );
    // Truncated.
    std::fs::write(&path, &good[..good.len() / 2]).unwrap();
    let (again, stderr) = bake_json(&out);
    assert_eq!(again["reused"].as_bool(), Some(false));
    assert!(stderr.contains("rebuilding"), "{stderr}");
    // An older format version.
    let mut old = std::fs::read(&path).unwrap();
    old[8..12].copy_from_slice(&0u32.to_le_bytes());
    std::fs::write(&path, &old).unwrap();
    let (again, stderr) = bake_json(&out);
    assert_eq!(again["reused"].as_bool(), Some(false));
    assert!(
        stderr.contains("version 0") && stderr.contains("rebuilding"),
        "{stderr}"
    );
    // Not a bake at all.
    std::fs::write(&path, b"hello").unwrap();
    let (_, stderr) = bake_json(&out);
    assert!(stderr.contains("rebuilding"), "{stderr}");
    // After all that, the bake reads back to the same cuts as the first one.
    let (_, a, ra) = file::decode(&path, &std::fs::read(&path).unwrap()).unwrap();
    let (_, b, rb) = file::decode(&path, &good).unwrap();
    assert_eq!(a, b, "rebuilt bake differs from the first");
    assert_eq!(ra, rb, "rebuilt refinement differs from the first");
    // The refinement replays onto the scene's mesh: one cut per vertex of the refined mesh, the
    // surface unchanged (same area).
    let scene = glint::scene::import(&common::assets().join("glb/teapot.glb")).unwrap();
    let refined = ra.apply(&scene.mesh).unwrap();
    assert_eq!(refined.positions.len(), a.vertex_count());
    let area = |m: &glint::scene::Mesh| -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                (m.positions[t[1] as usize] - m.positions[t[0] as usize])
                    .cross(m.positions[t[2] as usize] - m.positions[t[0] as usize])
                    .length() as f64
                    * 0.5
            })
            .sum()
    };
    assert!(
        (area(&refined) / area(&scene.mesh) - 1.0).abs() < 1e-5,
        "{} vs {}",
        area(&refined),
        area(&scene.mesh)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn decode_rejects_every_truncation() {
    let dir = common::temp_dir("trunc");
    let out = dir.join("b");
    bake_json(&out);
    let good = std::fs::read(out.join("bake.glint")).unwrap();
    for cut in (0..good.len()).step_by(good.len() / 97 + 1) {
        assert!(
            file::decode(Path::new("x"), &good[..cut]).is_err(),
            "accepted {cut} of {} bytes",
            good.len()
        );
    }
    assert!(file::decode(Path::new("x"), &good).is_ok());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn baking_the_view_first_gives_the_same_transfer() {
    let scene = glint::scene::import(&common::assets().join("glb/teapot.glb")).unwrap();
    let env = glint::env::load(&common::assets().join("hdr/small/courtyard_512.exr")).unwrap();
    let baker = Baker::new(
        &scene,
        &env,
        BakeSettings {
            resolution: Some(32),
            ..BakeSettings::default()
        },
    )
    .unwrap();
    let camera = &scene.cameras[0];
    let first = visible_vertices(&scene.mesh, camera, 160, 120);
    assert!(
        !first.is_empty() && first.len() < scene.mesh.positions.len(),
        "{} of {}",
        first.len(),
        scene.mesh.positions.len()
    );
    // Only the view's vertices: the others get empty cuts (not needed by this view).
    // As the app does it ([`Baker::bake_set`], with vertex sampling).
    let mut state = glint::bake::PartialBake::new(scene.mesh.positions.len());
    baker.bake_set(&first, &mut state, &|_| {});
    let partial = state.cuts;
    let full = baker.bake_all(None, &|_| {});
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
    )
    .unwrap();
    let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
    let a = TransferContext::new(&scene.mesh, &partial, &baker.tree, &lobes, None, None)
        .compute(&light, camera, 160, 120, 0.04);
    let b = TransferContext::new(&scene.mesh, &full.cuts, &baker.tree, &lobes, None, None)
        .compute(&light, camera, 160, 120, 0.04);
    assert_eq!(a.t, b.t);
    assert_eq!(a.irradiance, b.irradiance);
    println!(
        "first fit possible after {} of {} vertices",
        first.len(),
        scene.mesh.positions.len()
    );
}
