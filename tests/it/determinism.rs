//! Determinism of the binary across thread counts: `glint bake` and `glint fit` run on the same
//! inputs with `RAYON_NUM_THREADS=1` and `=2` must write the same bytes.
//!
//! Excluded, because they are documented timings (wall-clock seconds, different on every run even
//! with one thread): the bake header's `stats.seconds`, `stats.decision_seconds` and each
//! `stats.stages[i].seconds` (`BakeStats`, in `bake.glint`'s JSON header and in `bake.json`; the
//! stages' names, vertices and rays are compared) and the material's `fit.solve_seconds`
//! (`FitStats`). Everything else is compared exactly: the cut data of `bake.glint` (offsets, nodes,
//! visibility) byte for byte, the rest of the bake header and `bake.json` as JSON values, and the
//! material file line by line with only its `"solve_seconds"` line left out. (The bake file's
//! trailing checksum covers the header, so it differs exactly when the timings do; it is not
//! compared.)

use crate::common;

use std::path::Path;

use serde_json::Value;

const TIMINGS_BAKE: [&str; 2] = ["seconds", "decision_seconds"];
const TIMING_MATERIAL: &str = "solve_seconds";

fn glint(threads: usize, args: &[&str]) {
    let o = crate::glint_command!()
        .args(args)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .expect("run glint");
    assert!(
        o.status.success(),
        "glint {args:?} with {threads} thread(s): {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `bake.glint` split into its header (JSON, timings removed) and its cut data (bytes, no
/// checksum).
fn split_bake(bytes: &[u8]) -> (Value, Vec<u8>) {
    assert_eq!(&bytes[..8], b"GLINTBAK");
    let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let header: Value = serde_json::from_slice(&bytes[16..16 + header_len]).unwrap();
    (
        without_bake_timings(header),
        bytes[16 + header_len..bytes.len() - 8].to_vec(),
    )
}

fn without_bake_timings(mut header: Value) -> Value {
    let stats = header["stats"]
        .as_object_mut()
        .expect("stats in the bake header");
    for key in TIMINGS_BAKE {
        assert!(
            stats.remove(key).is_some(),
            "the bake header has no stats.{key}"
        );
    }
    let stages = stats
        .get_mut("stages")
        .and_then(Value::as_array_mut)
        .expect("stats.stages in the bake header");
    assert!(!stages.is_empty(), "no stages in the bake header");
    for stage in stages {
        assert!(
            stage
                .as_object_mut()
                .and_then(|s| s.remove("seconds"))
                .is_some(),
            "a stage without seconds: {stage}"
        );
    }
    header
}

/// The material's lines but the timing line.
fn material_lines(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<String> = text
        .lines()
        .filter(|l| {
            !l.trim_start()
                .starts_with(&format!("\"{TIMING_MATERIAL}\""))
        })
        .map(String::from)
        .collect();
    assert_eq!(
        lines.len() + 1,
        text.lines().count(),
        "{}: expected exactly one {TIMING_MATERIAL} line",
        path.display()
    );
    lines
}

#[test]
fn bake_and_fit_are_the_same_with_one_and_two_threads() {
    let dir = common::temp_dir("determinism");
    let scene = common::assets().join("glb/teapot.glb");
    let env = common::assets().join("hdr/small/courtyard_512.exr");
    let strokes = dir.join("strokes.json");
    std::fs::write(&strokes, r#"[
        {"view": "default", "image_size": [640, 480], "strokes": [
            {"points": [[300, 200], [340, 220]], "mode": "paint", "color": [2, 2, 2], "radius": 20, "kappa": 0.05},
            {"points": [[250, 300]], "mode": "scale", "scale": 0.5, "radius": 30, "kappa": 0.02}]},
        {"view": {"orbit": [120, 20, 0]}, "image_size": [320, 240], "strokes": [
            {"points": [[150, 100], [170, 140]], "mode": "paint", "color": [1.5, 1.2, 1.0], "radius": 12, "kappa": 0.1}]}
    ]"#)
    .unwrap();
    let mut bakes = Vec::new();
    let mut materials = Vec::new();
    for threads in [1, 2] {
        let bake = dir.join(format!("bake-{threads}"));
        let material = dir.join(format!("material-{threads}.json"));
        let started = std::time::Instant::now();
        glint(
            threads,
            &[
                "bake",
                scene.to_str().unwrap(),
                "--env",
                env.to_str().unwrap(),
                "--out",
                bake.to_str().unwrap(),
                "--fit-size",
                "40x30",
            ],
        );
        glint(
            threads,
            &[
                "fit",
                bake.to_str().unwrap(),
                "--strokes",
                strokes.to_str().unwrap(),
                "--out",
                material.to_str().unwrap(),
                "--fit-size",
                "80x60",
            ],
        );
        println!(
            "{threads} thread(s): bake and fit in {:.2} s",
            started.elapsed().as_secs_f64()
        );
        bakes.push(bake);
        materials.push(material);
    }
    let (h1, cuts1) = split_bake(&std::fs::read(bakes[0].join("bake.glint")).unwrap());
    let (h2, cuts2) = split_bake(&std::fs::read(bakes[1].join("bake.glint")).unwrap());
    assert!(cuts1.len() > 1000, "cut data of {} bytes", cuts1.len());
    assert_eq!(h1, h2, "bake headers differ (timings excluded)");
    let first_difference = cuts1.iter().zip(&cuts2).position(|(a, b)| a != b);
    assert!(
        cuts1 == cuts2,
        "cut data differ: {} vs {} bytes, first difference at byte {first_difference:?}",
        cuts1.len(),
        cuts2.len()
    );
    let json = |p: &Path| {
        without_bake_timings(
            serde_json::from_str(&std::fs::read_to_string(p.join("bake.json")).unwrap()).unwrap(),
        )
    };
    assert_eq!(
        json(&bakes[0]),
        json(&bakes[1]),
        "bake.json differs (timings excluded)"
    );
    let (m1, m2) = (material_lines(&materials[0]), material_lines(&materials[1]));
    for (i, (a, b)) in m1.iter().zip(&m2).enumerate() {
        assert_eq!(a, b, "material line {} differs", i + 1);
    }
    assert_eq!(m1.len(), m2.len());
    // The fit did something: some lobe is on.
    let m = glint::fit::material::Material::parse(&std::fs::read_to_string(&materials[0]).unwrap())
        .unwrap();
    assert!(
        m.coefficients.iter().flatten().any(|&c| c > 0.0),
        "the fit turned no lobe on"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
