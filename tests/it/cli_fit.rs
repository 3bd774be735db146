//! `glint fit` end to end: bake, fit a stroke file, read the material back, check the `--dump-qp`
//! arrays; bad stroke files and unknown views give one-line errors, exit 1 and no output file.

use crate::common;

use std::path::Path;

fn glint(args: &[&str]) -> std::process::Output {
    run_glint!(args)
}

/// Shape of an .npy file from its header.
fn npy_shape(path: &Path) -> Vec<usize> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
    let inside = header
        .split("'shape': (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap();
    let shape: Vec<usize> = inside
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    assert_eq!(
        bytes.len(),
        10 + hlen + 8 * shape.iter().product::<usize>(),
        "{path:?}"
    );
    shape
}

#[test]
fn fit_writes_a_material_and_a_reloadable_problem() {
    let dir = common::temp_dir("clifit");
    let scene = common::assets().join("glb/teapot.glb");
    let env = common::assets().join("hdr/small/courtyard_512.exr");
    let bake = dir.join("teapot.bake");
    let o = glint(&[
        "bake",
        scene.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "--out",
        bake.to_str().unwrap(),
        "--resolution",
        "32",
        "--fit-size",
        "40x30",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let strokes = dir.join("strokes.json");
    std::fs::write(&strokes, r#"{"view": "default", "image_size": [640, 480], "strokes": [
        {"points": [[300, 200], [340, 220]], "mode": "paint", "color": [2, 2, 2], "radius": 20, "kappa": 0.05}]}"#).unwrap();
    let material = dir.join("teapot.material.json");
    let dump = dir.join("qp");
    let o = glint(&[
        "fit",
        bake.to_str().unwrap(),
        "--strokes",
        strokes.to_str().unwrap(),
        "--out",
        material.to_str().unwrap(),
        "--dump-qp",
        dump.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(report["fit"]["solve_seconds"].as_f64().unwrap() > 0.0);
    let m = glint::fit::material::Material::parse(&std::fs::read_to_string(&material).unwrap())
        .unwrap();
    assert_eq!(m.model, "dbrdf-srbf");
    assert!(m.coefficients.iter().flatten().any(|&c| c > 0.0));
    let (n, j) = (m.fit.pixels, m.centres.len());
    assert_eq!(npy_shape(&dump.join("T.npy")), vec![n, 3, j]);
    assert_eq!(npy_shape(&dump.join("B.npy")), vec![n, 3]);
    assert_eq!(npy_shape(&dump.join("w.npy")), vec![n]);
    assert_eq!(npy_shape(&dump.join("E.npy")), vec![n, 3]);
    assert_eq!(npy_shape(&dump.join("energy_rows.npy")), vec![33, j]); // 32 elevations + the horizon (energy::default_outgoing)
    assert_eq!(npy_shape(&dump.join("bounds.npy")), vec![3]);
    assert_eq!(npy_shape(&dump.join("c.npy")), vec![3, j]);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dump.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["pixels"].as_u64(), Some(n as u64));

    // Bad stroke files: one line, exit 1, no material written.
    for (name, text, needle) in [
        ("malformed", "{\"view\": ", "JSON"),
        (
            "no-such-view",
            r#"{"view": "side", "image_size": [640, 480], "strokes": []}"#,
            "side",
        ),
        (
            "bad-radius",
            r#"{"view": 0, "image_size": [640, 480], "strokes": [{"points": [[1, 1]], "mode": "paint", "radius": 0, "kappa": 1}]}"#,
            "radius",
        ),
    ] {
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, text).unwrap();
        let out_path = dir.join(format!("{name}.material.json"));
        let o = glint(&[
            "fit",
            bake.to_str().unwrap(),
            "--strokes",
            path.to_str().unwrap(),
            "--out",
            out_path.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{name}");
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            stderr.contains(needle) && stderr.trim().lines().count() == 1,
            "{name}: {stderr}"
        );
        assert!(!out_path.exists(), "{name}: wrote an output");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
