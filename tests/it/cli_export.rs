//! `glint export` end to end on a fitted material (bunny, sample strokes): every format written,
//! byte-identical on a second export, the USD checked by usd-core against the material JSON, the
//! GLB by Khronos' gltf-validator (0 errors, 0 warnings), the MERL file read back at cell centres
//! against glint's exact lobe sum (independent of the table the file was made from), and `glint
//! render` writing both image formats. An anisotropic material's export carries
//! KHR_materials_anisotropy (gltf-validator: 0 errors, 0 warnings) and its USD keeps the same
//! anisotropy (usd-core).
//!
//! The Python (usd-core) and node (gltf-validator) tools come from `.ci/test`; under CI=true a
//! missing tool fails the test, elsewhere the check is skipped with a note.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn tool(path: PathBuf, what: &str) -> Option<PathBuf> {
    if path.exists() {
        return Some(path);
    }
    assert!(
        !common::in_ci(),
        "{what} is required in CI but {} is missing (run .ci/test)",
        path.display()
    );
    eprintln!("SKIPPED: {what} not installed at {}", path.display());
    None
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Khronos gltf-validator on a GLB: asserts 0 errors and 0 warnings, returns the report (None when
/// the validator is not installed outside CI).
fn validate_glb(glb: &Path) -> Option<serde_json::Value> {
    tool(
        repo().join("exporters/js/node_modules/gltf-validator/package.json"),
        "npm gltf-validator",
    )?;
    let o = Command::new("node")
        .arg(repo().join("exporters/js/validate_gltf.mjs"))
        .arg(glb)
        .output()
        .unwrap();
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("validator report");
    let issues = &report["issues"];
    println!(
        "gltf-validator: {} errors, {} warnings, {} infos, {} hints",
        issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]
    );
    assert_eq!(issues["numErrors"], 0, "{}", issues["messages"]);
    assert_eq!(issues["numWarnings"], 0, "{}", issues["messages"]);
    Some(report)
}

/// Bakes the bundled bunny under the small studio map and fits the sample strokes; returns
/// (folder, bake folder, material path).
fn fitted(tag: &str) -> (PathBuf, PathBuf, PathBuf) {
    let dir = common::temp_dir(tag);
    let bake = dir.join("bunny.bake");
    let env = common::assets().join("hdr/small/studio_512.exr");
    let out = run_glint!([
        "bake".as_ref(),
        repo().join("samples/bunny.glb").as_os_str(),
        "--env".as_ref(),
        env.as_os_str(),
        "--out".as_ref(),
        bake.as_os_str()
    ]);
    assert!(
        out.status.success(),
        "bake: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let material = dir.join("shiny.json");
    let strokes = repo().join("samples/strokes/bunny-highlight.json");
    let out = run_glint!([
        "fit".as_ref(),
        bake.as_os_str(),
        "--strokes".as_ref(),
        strokes.as_os_str(),
        "--out".as_ref(),
        material.as_os_str()
    ]);
    assert!(
        out.status.success(),
        "fit: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (dir, bake, material)
}

#[test]
fn export_writes_every_format_and_independent_readers_agree() {
    let (dir, _bake, material) = fitted("export");
    let to = dir.join("out");
    let args = |to: &Path| {
        vec![
            "export".into(),
            material.clone().into_os_string(),
            "--to".into(),
            to.as_os_str().to_owned(),
            "--scene".into(),
            repo().join("samples/bunny.glb").into_os_string(),
        ]
    };
    let out = run_glint!(args(&to));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "export: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{stdout}");
    assert!(
        stdout.contains("relative RMS error"),
        "the fallback's error is reported: {stdout}"
    );
    let names = ["shiny_ph.exr", "shiny.glb", "shiny.usda", "shiny.binary"];
    for n in names {
        assert!(to.join(n).is_file(), "{n} missing");
    }
    // Exporting twice gives identical bytes.
    let again = dir.join("again");
    assert!(run_glint!(args(&again)).status.success());
    for n in names {
        assert_eq!(
            std::fs::read(to.join(n)).unwrap(),
            std::fs::read(again.join(n)).unwrap(),
            "{n} differs between two exports"
        );
    }
    // No temporary files left behind.
    for entry in std::fs::read_dir(&to).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "leftover {name}");
    }

    // usd-core: validation and every number against the material JSON, with nothing on stderr.
    if let Some(py) = tool(repo().join(".venv/bin/python"), "python venv with usd-core") {
        let o = Command::new(py)
            .arg(repo().join("exporters/python/check_usd.py"))
            .arg(to.join("shiny.usda"))
            .arg(&material)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "check_usd: {text}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(
            o.stderr.is_empty(),
            "usd-core printed on stderr: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        println!("{}", text.trim());
    }
    // gltf-validator: 0 errors and 0 warnings.
    validate_glb(&to.join("shiny.glb"));

    // MERL read back at cell centres against glint's exact BRDF (the ring lobes in closed form).
    let m = glint::fit::material::Material::parse(&std::fs::read_to_string(&material).unwrap())
        .unwrap();
    let lobes = m.lobes().unwrap();
    let merl = glint_exporters::read_merl(&to.join("shiny.binary")).unwrap();
    let mut rng = glint::math::Rng::new(3);
    let (mut worst, mut checked) = (0.0f64, 0);
    while checked < 2000 {
        let (ih, id, ip) = (
            (rng.next_f64() * 90.0) as usize,
            (rng.next_f64() * 90.0) as usize,
            (rng.next_f64() * 180.0) as usize,
        );
        let (th, td, pd) = glint_exporters::merl::cell_centre(ih, id, ip);
        let (wi, wo) = glint_exporters::merl::half_diff_to_dirs(th, td, pd);
        let (wi, wo) = (glam::DVec3::from(wi), glam::DVec3::from(wo));
        if wi.z < 0.1 || wo.z < 0.1 {
            continue;
        }
        let h = (wi + wo).normalize();
        let s = glint::brdf::dbrdf::static_term(wi, wo, m.f0);
        let got = merl.lookup(wi.to_array(), wo.to_array());
        for c in 0..3 {
            let p: f64 = (0..lobes.len())
                .map(|j| m.coefficients[c][j] * lobes.eval_exact(j, h))
                .sum();
            let want = m.rho_d[c] / std::f64::consts::PI + p * s;
            // MERL stores float64 values divided by its scale: the read-back is exact to rounding,
            // so what remains is the p(h) table's interpolation.
            worst = worst.max((got[c] - want).abs() / want);
        }
        checked += 1;
    }
    println!("MERL at {checked} cell centres (θi, θo < 84°): worst relative error {worst:.2e}");
    assert!(worst < 0.01, "MERL vs exact BRDF: {worst}");
    std::fs::remove_dir_all(dir).unwrap();
}

/// The JSON chunk of a GLB.
fn glb_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

/// An anisotropic material (hemicube 7×7 at λ = 30, coefficients an elongated Gaussian of the
/// centre's tangent-plane position with its long axis at 0.7 rad) through `glint export` (preview
/// sphere, every format): the GLB carries KHR_materials_anisotropy along that axis and passes
/// gltf-validator with 0 errors and 0 warnings; the USD records the same anisotropy (customData)
/// and passes usd-core, its fallback compared with the GLB's.
#[test]
fn export_of_an_anisotropic_material_carries_khr_materials_anisotropy() {
    use glint::sphere::{LobeLayout, LobeSet};
    let dir = common::temp_dir("export-aniso");
    let axis: f64 = 0.7;
    let lobes = LobeSet::new(LobeLayout::Hemicube { n: 7 }, 30.0).unwrap();
    let weight = |x: &glam::DVec3| {
        let (s, c) = (-axis).sin_cos();
        let (u, v) = (c * x.x - s * x.y, s * x.x + c * x.y);
        (-(u / 0.5).powi(2) - (v / 0.15).powi(2)).exp()
    };
    let coefficients: [Vec<f64>; 3] = std::array::from_fn(|ch| {
        lobes
            .centres()
            .iter()
            .map(|x| [2.0, 1.6, 1.2][ch] * weight(x))
            .collect()
    });
    let sigma = glint::sphere::srbf::sigma_from_lambda(lobes.lambda()).unwrap();
    let m = glint::fit::material::Material::new(
        &lobes,
        sigma,
        coefficients,
        [0.02, 0.02, 0.02],
        0.6,
        Default::default(),
    );
    let material = dir.join("brushed.json");
    std::fs::write(&material, m.to_json()).unwrap();
    let to = dir.join("out");
    let out = run_glint!([
        "export".as_ref(),
        material.as_os_str(),
        "--to".as_ref(),
        to.as_os_str()
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "export: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{stdout}");

    let json = glb_json(&to.join("brushed.glb"));
    let mat = &json["materials"][0];
    let ext = &mat["extensions"]["KHR_materials_anisotropy"];
    let (strength, rotation) = (
        ext["anisotropyStrength"]
            .as_f64()
            .expect("anisotropyStrength"),
        ext["anisotropyRotation"]
            .as_f64()
            .expect("anisotropyRotation"),
    );
    let off = (rotation - axis).rem_euclid(std::f64::consts::PI);
    let off = off.min(std::f64::consts::PI - off);
    println!(
        "KHR_materials_anisotropy: strength {strength}, rotation {rotation} (coefficients' axis {axis}, {:.2}° off)",
        off.to_degrees()
    );
    assert!(strength > 0.0 && strength <= 1.0, "{ext}");
    // The hemicube's centres are ~15° apart: p's long axis follows the coefficients' within a few
    // degrees.
    assert!(
        off < 5f64.to_radians(),
        "rotation {rotation} vs the coefficients' axis {axis}"
    );
    assert!(
        json["extensionsUsed"]
            .as_array()
            .is_some_and(|e| e.iter().any(|e| e == "KHR_materials_anisotropy")),
        "{}",
        json["extensionsUsed"]
    );
    assert!(
        json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"].is_u64(),
        "the preview sphere needs tangents"
    );
    let glint = &mat["extras"]["glint"];
    assert!(
        glint["provenance"]["fallback_isotropic_relative_error"].is_string(),
        "the isotropic one-lobe fit's error is in the provenance"
    );
    let layered = glint["fallback_relative_error"].as_f64().unwrap();
    let one_lobe = glint["fallback_one_lobe_relative_error"].as_f64().unwrap();
    assert!(
        layered <= one_lobe,
        "layered fit {layered} vs one-lobe {one_lobe}"
    );

    if let Some(report) = validate_glb(&to.join("brushed.glb")) {
        assert!(
            report["info"]["extensionsUsed"]
                .as_array()
                .is_some_and(|e| e.iter().any(|e| e == "KHR_materials_anisotropy")),
            "{report}"
        );
    }
    // usd-core: the stage against the material JSON, and the anisotropy it keeps in customData
    // against the GLB's.
    if let Some(py) = tool(repo().join(".venv/bin/python"), "python venv with usd-core") {
        let mut expected: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
        expected["fallback"] = serde_json::json!({ "anisotropy": [strength, rotation] });
        let expected_path = dir.join("expected.json");
        std::fs::write(&expected_path, expected.to_string()).unwrap();
        let o = Command::new(py)
            .arg(repo().join("exporters/python/check_usd.py"))
            .arg(to.join("brushed.usda"))
            .arg(&expected_path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "check_usd: {text}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(text.contains("with its anisotropy"), "{text}");
        println!("{}", text.trim());
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn render_writes_png_and_exr_and_refuses_bad_arguments() {
    let (dir, bake, material) = fitted("render");
    let mut cases = vec![
        ("prt.png", vec![]),
        ("prt.exr", vec!["--rotate", "45"]),
        ("mc.exr", vec!["--reference", "4"]),
        ("traced.exr", vec!["--trace-visibility", "--rotate", "45"]),
        (
            "traced4.exr",
            vec!["--trace-visibility", "--trace-levels", "4"],
        ),
        (
            "traced_all_edges.exr",
            vec!["--trace-visibility", "--trace-budget", "0"],
        ),
    ];
    // The wgpu preview where an adapter exists (always in CI: lavapipe; tests/it/gpu.rs checks its
    // values).
    if std::env::var("CI").is_ok_and(|v| v == "true") || glint::gpu::GpuContext::headless().is_ok()
    {
        cases.push(("gpu.exr", vec!["--gpu", "--rotate", "45"]));
    }
    for (name, extra) in cases {
        let out_path = dir.join(name);
        let mut argv: Vec<std::ffi::OsString> = vec![
            "render".into(),
            bake.clone().into(),
            "--material".into(),
            material.clone().into(),
            "--size".into(),
            "64x48".into(),
            "--out".into(),
            out_path.clone().into(),
        ];
        argv.extend(extra.iter().map(|s| s.into()));
        let out = run_glint!(argv);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        if name.starts_with("traced") {
            let said = String::from_utf8_lossy(&out.stdout);
            assert!(said.contains("visibility traced at"), "{said}");
        }
        let bytes = std::fs::read(&out_path).unwrap();
        if name.ends_with(".png") {
            assert_eq!(&bytes[1..4], b"PNG");
        } else {
            assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic");
        }
    }
    // Bad input: one line, exit 1, no output file.
    let bad = dir.join("bad.png");
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        bake.join("bake.json").as_os_str(),
        "--out".as_ref(),
        bad.as_os_str()
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!bad.exists());
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--size".as_ref(),
        "16x12".as_ref(),
        "--out".as_ref(),
        dir.join("x.jpg").as_os_str()
    ]);
    assert_eq!(out.status.code(), Some(1));
    // Traced visibility is for the PRT frame: with the reference it is a usage error.
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--reference".as_ref(),
        "4".as_ref(),
        "--trace-visibility".as_ref(),
        "--out".as_ref(),
        dir.join("y.exr").as_os_str()
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.join("y.exr").exists());
    // --trace-levels refines the traced frame's cells: without --trace-visibility, a usage error.
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--trace-levels".as_ref(),
        "4".as_ref(),
        "--out".as_ref(),
        dir.join("z.exr").as_os_str()
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.join("z.exr").exists());
    // --trace-budget is a share of the light: 2 is refused with one line, nothing written.
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--trace-visibility".as_ref(),
        "--trace-budget".as_ref(),
        "2".as_ref(),
        "--out".as_ref(),
        dir.join("w.exr").as_os_str()
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a share of the light"));
    assert!(!dir.join("w.exr").exists());
    std::fs::remove_dir_all(dir).unwrap();
}

/// A material of `layout` with coefficients of every magnitude (17 significant digits,
/// subnormal-free tiny values, zeros), written as glint's JSON.
fn material_of(
    layout: glint::sphere::LobeLayout,
    lambda: f64,
    seed: u64,
) -> glint::fit::material::Material {
    let lobes = glint::sphere::LobeSet::new(layout, lambda).unwrap();
    let mut rng = glint::math::Rng::new(seed);
    let coefficients: [Vec<f64>; 3] = std::array::from_fn(|_| {
        (0..lobes.len())
            .map(|j| match j % 4 {
                0 => 0.0,
                1 => rng.next_f64() * 1e-200,
                _ => rng.next_f64() * 3.0 + std::f64::consts::PI * 1e-9,
            })
            .collect()
    });
    let sigma = glint::sphere::srbf::sigma_from_lambda(lambda).unwrap();
    glint::fit::material::Material::new(
        &lobes,
        sigma,
        coefficients,
        [0.1 + 1.0 / 3.0, 0.2, std::f64::consts::E / 10.0],
        0.04 + 1e-12,
        Default::default(),
    )
}

/// JSON → .glb / .usda → glint gives the same lobe table, bit for bit, for every kind of layout;
/// and `render` and `export` take the exported files as materials.
#[test]
fn materials_round_trip_through_glb_and_usda_for_every_layout() {
    use glint::sphere::LobeLayout;
    let dir = common::temp_dir("round-trip");
    for (k, layout) in [
        LobeLayout::Isotropic { count: 24 },
        LobeLayout::Hemicube { n: 3 },
        LobeLayout::Fibonacci { count: 20 },
    ]
    .into_iter()
    .enumerate()
    {
        let m = material_of(layout, 81.06 + k as f64 * 7.3, 40 + k as u64);
        let name = format!("rt{k}");
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, m.to_json()).unwrap();
        let to = dir.join(&name);
        let out = run_glint!([
            "export".as_ref(),
            path.as_os_str(),
            "--to".as_ref(),
            to.as_os_str(),
            "--formats".as_ref(),
            "gltf,usd".as_ref(),
            "--table-resolution".as_ref(),
            "32".as_ref()
        ]);
        assert!(
            out.status.success(),
            "export: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        for ext in ["glb", "usda"] {
            let back = glint::material_file::read_material(&to.join(format!("{name}.{ext}")))
                .unwrap_or_else(|e| panic!("{} {ext}: {e}", layout.name()));
            assert_eq!(back.layout, m.layout, "{ext}");
            assert_eq!(back.model, m.model);
            assert_eq!(back.version, m.version);
            assert_eq!(
                back.lambda.to_bits(),
                m.lambda.to_bits(),
                "{} {ext}: lambda",
                layout.name()
            );
            assert_eq!(
                back.sigma.to_bits(),
                m.sigma.to_bits(),
                "{} {ext}: sigma",
                layout.name()
            );
            assert_eq!(
                back.f0.to_bits(),
                m.f0.to_bits(),
                "{} {ext}: f0",
                layout.name()
            );
            assert_eq!(back.rho_d, m.rho_d, "{} {ext}: rho_d", layout.name());
            assert_eq!(back.centres, m.centres, "{} {ext}: centres", layout.name());
            assert_eq!(
                back.coefficients,
                m.coefficients,
                "{} {ext}: coefficients",
                layout.name()
            );
            assert_eq!(back.brdf_convention, m.brdf_convention);
            // The CLI takes the export wherever it takes a material: export it again, from the
            // export.
            let again = dir.join(format!("{name}-{ext}"));
            let out = run_glint!([
                "export".as_ref(),
                to.join(format!("{name}.{ext}")).as_os_str(),
                "--to".as_ref(),
                again.as_os_str(),
                "--formats".as_ref(),
                "gltf".as_ref(),
                "--table-resolution".as_ref(),
                "32".as_ref()
            ]);
            assert!(
                out.status.success(),
                "export from {ext}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let g = glb_json(&again.join(format!("{name}.glb")));
            assert_eq!(
                g["materials"][0]["extras"]["glint"]["coefficients"],
                serde_json::json!(m.coefficients),
                "{ext} → glb"
            );
        }
        println!(
            "{}: JSON → .glb / .usda → glint: identical lobe table (J = {})",
            layout.name(),
            m.centres.len()
        );
    }
    // `render --material` takes a .usda (isotropic material on the bunny bake).
    let (rdir, bake, _) = fitted("round-trip-render");
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        dir.join("rt0/rt0.usda").as_os_str(),
        "--size".as_ref(),
        "32x24".as_ref(),
        "--out".as_ref(),
        rdir.join("usd.exr").as_os_str()
    ]);
    assert!(
        out.status.success(),
        "render --material .usda: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(rdir).unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

/// Hostile material files — truncated, wrong types, missing inputs, absurd arrays, a table path
/// that leaves the folder, a glTF that is not a glint export — are refused with one line, exit 1,
/// and no output.
#[test]
fn hostile_exported_materials_are_refused_with_one_line() {
    use glint::sphere::LobeLayout;
    let dir = common::temp_dir("hostile-materials");
    let m = material_of(LobeLayout::Isotropic { count: 8 }, 40.0, 7);
    let path = dir.join("m.json");
    std::fs::write(&path, m.to_json()).unwrap();
    let to = dir.join("ok");
    assert!(
        run_glint!([
            "export".as_ref(),
            path.as_os_str(),
            "--to".as_ref(),
            to.as_os_str(),
            "--formats".as_ref(),
            "gltf,usd".as_ref(),
            "--table-resolution".as_ref(),
            "16".as_ref()
        ])
        .status
        .success()
    );
    let glb = std::fs::read(to.join("m.glb")).unwrap();
    let usda = std::fs::read_to_string(to.join("m.usda")).unwrap();
    let doc = glb_json(&to.join("m.glb"));
    let with_glint = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut d = doc.clone();
        f(&mut d["materials"][0]["extras"]["glint"]);
        common::pack_glb(&d, &[])
    };
    let huge: Vec<f64> = vec![0.5; 200_001];
    let line = |prefix: &str| {
        usda.lines()
            .find(|l| l.trim_start().starts_with(prefix))
            .unwrap_or_else(|| panic!("no line {prefix}"))
            .to_string()
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated.glb", glb[..glb.len() / 2].to_vec(), "truncated"),
        (
            "garbage.glb",
            b"glTF\x02\x00\x00\x00".to_vec(),
            "truncated GLB header",
        ),
        (
            "not-glint.glb",
            std::fs::read(repo().join("samples/bunny.glb")).unwrap(),
            "not a glint export",
        ),
        (
            "wrong-type.glb",
            with_glint(&|g| g["lambda"] = "81".into()),
            "lambda",
        ),
        (
            "missing.glb",
            with_glint(&|g| drop(g.as_object_mut().unwrap().remove("coefficients"))),
            "coefficients",
        ),
        (
            "absurd.glb",
            with_glint(&|g| g["coefficients"][0] = serde_json::json!(huge)),
            "coefficients",
        ),
        (
            "escape.glb",
            with_glint(&|g| g["table"]["uri"] = "../../outside_ph.exr".into()),
            "leaves the material's folder",
        ),
        (
            "absolute.glb",
            with_glint(&|g| g["table"]["uri"] = "/etc/m_ph.exr".into()),
            "leaves the material's folder",
        ),
        (
            "truncated.usda",
            usda.as_bytes()[..usda.len() / 3].to_vec(),
            "USD parse error",
        ),
        (
            "wrong-type.usda",
            usda.replace(
                &line("double inputs:lambda"),
                "string inputs:lambda = \"81\"",
            )
            .into_bytes(),
            "wrong type",
        ),
        (
            "missing.usda",
            usda.replace(&line("double inputs:f0"), "").into_bytes(),
            "inputs:f0",
        ),
        (
            "absurd.usda",
            usda.replace(
                &line("double[] inputs:coefficients_r"),
                &format!("double[] inputs:coefficients_r = {huge:?}"),
            )
            .into_bytes(),
            "more than the 100000",
        ),
        (
            "escape.usda",
            usda.replace("@./m_ph.exr@", "@../../../etc/passwd@")
                .into_bytes(),
            "leaves the material's folder",
        ),
        (
            "binary.usda",
            b"PXR-USDC\x00\x00".to_vec(),
            "not a USD text layer",
        ),
    ];
    // Random damage never panics: every mutant is read or refused (in-process, so a panic fails
    // here).
    let mut rng = glint::math::Rng::new(11);
    for (ext, good) in [("glb", glb.clone()), ("usda", usda.as_bytes().to_vec())] {
        let (mut read, mut refused) = (0, 0);
        for k in 0..300 {
            let mut bytes = good.clone();
            match k % 3 {
                0 => bytes.truncate((rng.next_f64() * bytes.len() as f64) as usize),
                1 => {
                    for _ in 0..1 + k % 7 {
                        let at = (rng.next_f64() * bytes.len() as f64) as usize % bytes.len();
                        bytes[at] = (rng.next_f64() * 256.0) as u8;
                    }
                }
                _ => {
                    let at = (rng.next_f64() * bytes.len() as f64) as usize % bytes.len();
                    let len = ((rng.next_f64() * 64.0) as usize).min(bytes.len() - at);
                    bytes.drain(at..at + len);
                }
            }
            let p = dir.join(format!("mutant.{ext}"));
            std::fs::write(&p, &bytes).unwrap();
            match glint::material_file::read_material(&p) {
                Ok(_) => read += 1,
                Err(e) => {
                    assert!(!e.to_string().contains('\n'), "{e}");
                    refused += 1;
                }
            }
        }
        println!("{ext}: 300 damaged copies, {read} still read, {refused} refused, no panic");
    }
    for (name, bytes, needle) in cases {
        let bad = dir.join(name);
        std::fs::write(&bad, bytes).unwrap();
        let out_dir = dir.join(format!("out-{name}"));
        let out = run_glint!([
            "export".as_ref(),
            bad.as_os_str(),
            "--to".as_ref(),
            out_dir.as_os_str(),
            "--formats".as_ref(),
            "exr".as_ref()
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: {err}");
        assert!(
            err.contains(needle),
            "{name}: expected '{needle}' in: {err}"
        );
        assert!(
            !out_dir.exists() || std::fs::read_dir(&out_dir).unwrap().next().is_none(),
            "{name}: wrote output"
        );
        println!("{name}: {}", err.trim());
    }
    std::fs::remove_dir_all(dir).unwrap();
}

/// `glint render --json` prints the camera (docs/conventions.md §4) and the EXR's alpha is the
/// coverage; `glint export --formats mitsuba --bake` writes the scene, and its sensor is that
/// camera.
#[test]
fn render_prints_its_camera_and_mitsuba_export_uses_it() {
    let (dir, bake, material) = fitted("render-camera");
    let exr = dir.join("mc.exr");
    let out = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--reference".as_ref(),
        "2".as_ref(),
        "--orbit".as_ref(),
        "20,15,2.5".as_ref(),
        "--size".as_ref(),
        "48x36".as_ref(),
        "--out".as_ref(),
        exr.as_os_str(),
        "--json".as_ref()
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let cam = &report["camera"];
    assert_eq!(
        (
            cam["width"].as_u64(),
            cam["height"].as_u64(),
            cam["name"].as_str()
        ),
        (Some(48), Some(36), Some("orbit"))
    );
    assert!((cam["yfov_deg"].as_f64().unwrap() - 40.0).abs() < 1e-4);
    // Orbit 20° azimuth, 15° elevation: the camera looks back along (cos el sin az, sin el, cos el
    // cos az).
    let (az, el) = (20f64.to_radians(), 15f64.to_radians());
    let dir_out = [el.cos() * az.sin(), el.sin(), el.cos() * az.cos()];
    let fwd: Vec<f64> = serde_json::from_value(cam["forward"].clone()).unwrap();
    for k in 0..3 {
        assert!(
            (fwd[k] + dir_out[k]).abs() < 1e-5,
            "forward {fwd:?} vs {dir_out:?}"
        );
    }
    // Alpha: 1 on exactly the object pixels the report counts, 0 elsewhere.
    let image = exr::prelude::read_first_rgba_layer_from_file(
        &exr,
        |r, _| vec![[0f32; 4]; r.width() * r.height()],
        |px: &mut Vec<[f32; 4]>, p, (r, g, b, a): (f32, f32, f32, f32)| {
            px[p.y() * 48 + p.x()] = [r, g, b, a]
        },
    )
    .unwrap();
    let pixels = &image.layer_data.channel_data.pixels;
    let covered = pixels.iter().filter(|p| p[3] == 1.0).count();
    assert!(pixels.iter().all(|p| p[3] == 0.0 || p[3] == 1.0));
    assert_eq!(covered as u64, report["object_pixels"].as_u64().unwrap());

    // The Mitsuba scene for the same view.
    let to = dir.join("mitsuba");
    let out = run_glint!([
        "export".as_ref(),
        material.as_os_str(),
        "--to".as_ref(),
        to.as_os_str(),
        "--formats".as_ref(),
        "mitsuba".as_ref(),
        "--bake".as_ref(),
        bake.as_os_str(),
        "--orbit".as_ref(),
        "20,15,2.5".as_ref(),
        "--size".as_ref(),
        "48x36".as_ref(),
        "--rotate".as_ref(),
        "90".as_ref()
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for n in [
        "shiny_mitsuba.xml",
        "shiny_mesh.ply",
        "shiny_env.exr",
        "shiny_ph.exr",
        "shiny_lobes.json",
    ] {
        assert!(to.join(n).is_file(), "{n}");
    }
    let xml = std::fs::read_to_string(to.join("shiny_mitsuba.xml")).unwrap();
    let eye: Vec<f64> = serde_json::from_value(cam["eye"].clone()).unwrap();
    assert!(
        xml.contains(&format!(
            "origin=\"{:?}, {:?}, {:?}\"",
            eye[0], eye[1], eye[2]
        )),
        "{xml}"
    );
    assert!(
        xml.contains("<integer name=\"width\" value=\"48\"/>") && xml.contains("angle=\"90.0\""),
        "{xml}"
    );
    // A Mitsuba scene needs a scene and an environment: one line, exit 1.
    let out = run_glint!([
        "export".as_ref(),
        material.as_os_str(),
        "--to".as_ref(),
        dir.join("no-scene").as_os_str(),
        "--formats".as_ref(),
        "mitsuba".as_ref()
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.trim().lines().count() == 1 && err.contains("mitsuba"),
        "{err}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// A GLB of `mesh` (POSITION, NORMAL, TANGENT when present, u32 indices), no material.
fn mesh_glb(mesh: &glint::scene::Mesh) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bytes: Vec<u8>,
                    count: usize,
                    kind: &str,
                    component: u32,
                    bounds: Option<(Vec<f32>, Vec<f32>)>| {
        views.push(
            serde_json::json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() }),
        );
        let mut a = serde_json::json!({ "bufferView": views.len() - 1, "componentType": component, "count": count, "type": kind });
        if let Some((lo, hi)) = bounds {
            a["min"] = lo.into();
            a["max"] = hi.into();
        }
        accessors.push(a);
        bin.extend_from_slice(&bytes);
        accessors.len() - 1
    };
    let f32s = |v: Vec<f32>| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let n = mesh.positions.len();
    let (lo, hi) = mesh.positions.iter().fold(
        (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    let pos = push(
        f32s(mesh.positions.iter().flat_map(|p| p.to_array()).collect()),
        n,
        "VEC3",
        5126,
        Some((lo.to_array().to_vec(), hi.to_array().to_vec())),
    );
    let nor = push(
        f32s(mesh.normals.iter().flat_map(|p| p.to_array()).collect()),
        n,
        "VEC3",
        5126,
        None,
    );
    let mut attributes = serde_json::json!({ "POSITION": pos, "NORMAL": nor });
    if let Some(t) = &mesh.tangents {
        attributes["TANGENT"] = push(
            f32s(t.iter().flat_map(|p| p.to_array()).collect()),
            n,
            "VEC4",
            5126,
            None,
        )
        .into();
    }
    let idx: Vec<u8> = mesh
        .triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let indices = push(idx, mesh.triangles.len() * 3, "SCALAR", 5125, None);
    let doc = serde_json::json!({
        "asset": { "version": "2.0", "generator": "glint tests/cli_export.rs (write_brushed_sphere)", "copyright": "CC0-1.0 (generated)" },
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": attributes, "indices": indices }] }],
        "accessors": accessors, "bufferViews": views, "buffers": [{ "byteLength": bin.len() }],
    });
    common::pack_glb(&doc, &bin)
}

/// A tangent-carrying scene: a UV sphere (tangents along +φ) on a ground square (tangents +X).
fn tangent_scene() -> glint::scene::Mesh {
    let mut m = common::uv_sphere(1.0, 64, 32, true);
    let tangents = m.tangents.as_mut().unwrap();
    let base = m.positions.len() as u32;
    let k = 8u32;
    for i in 0..=k {
        for j in 0..=k {
            m.positions.push(glam::Vec3::new(
                -3.0 + 6.0 * j as f32 / k as f32,
                -1.0,
                -3.0 + 6.0 * i as f32 / k as f32,
            ));
            m.normals.push(glam::Vec3::Y);
            tangents.push(glam::Vec4::new(1.0, 0.0, 0.0, 1.0));
        }
    }
    for i in 0..k {
        for j in 0..k {
            let a = base + i * (k + 1) + j;
            let (b, c, d) = (a + 1, a + k + 1, a + k + 2);
            m.triangles.push([a, c, b]);
            m.triangles.push([b, c, d]);
        }
    }
    m
}

/// `samples/brushed_sphere.glb` is what [`tangent_scene`] makes (regenerate it with the ignored
/// `write_brushed_sphere`).
#[test]
fn brushed_sphere_sample_matches_its_generator() {
    let on_disk = std::fs::read(repo().join("samples/brushed_sphere.glb"))
        .expect("samples/brushed_sphere.glb (run write_brushed_sphere)");
    assert!(
        on_disk == mesh_glb(&tangent_scene()),
        "samples/brushed_sphere.glb differs from its generator (run write_brushed_sphere)"
    );
    let scene = glint::scene::import(&repo().join("samples/brushed_sphere.glb")).unwrap();
    assert!(scene.mesh.tangents.is_some(), "the sample carries TANGENT");
}

/// Writes samples/brushed_sphere.glb's generator output into a temporary folder and prints the
/// command that copies it over the sample (tests write nowhere else).
#[test]
#[ignore = "run by hand: cargo test --test it cli_export:: -- --ignored --nocapture write_brushed_sphere"]
fn write_brushed_sphere() {
    let path = common::temp_dir("brushed-sphere").join("brushed_sphere.glb");
    std::fs::write(&path, mesh_glb(&tangent_scene())).unwrap();
    println!(
        "cp {} {}",
        path.display(),
        repo().join("samples/brushed_sphere.glb").display()
    );
}

/// (relative RMSE, object pixels, mean ratio a/b) of two RGBA EXRs over the pixels both cover
/// (alpha ≥ 0.5 in both).
fn compare_exr(a: &Path, b: &Path) -> (f64, usize, f64) {
    let read = |p: &Path| {
        let img = exr::prelude::read_first_rgba_layer_from_file(
            p,
            |r, _| (r.width(), vec![[0f32; 4]; r.width() * r.height()]),
            |(w, px): &mut (usize, Vec<[f32; 4]>), q, (r, g, b, a): (f32, f32, f32, f32)| {
                px[q.y() * *w + q.x()] = [r, g, b, a]
            },
        )
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        img.layer_data.channel_data.pixels.1
    };
    let (pa, pb) = (read(a), read(b));
    assert_eq!(pa.len(), pb.len(), "image sizes differ");
    let (mut num, mut den, mut n, mut sa, mut sb) = (0f64, 0f64, 0usize, 0f64, 0f64);
    for (x, y) in pa.iter().zip(&pb) {
        if x[3] >= 0.5 && y[3] >= 0.5 {
            for c in 0..3 {
                num += (x[c] as f64 - y[c] as f64).powi(2);
                den += (y[c] as f64).powi(2);
                sa += x[c] as f64;
                sb += y[c] as f64;
            }
            n += 1;
        }
    }
    ((num / den).sqrt(), n, sa / sb)
}

/// Mitsuba 3 (an independent renderer, with the glint plugin) renders `glint export --formats
/// mitsuba` scenes as `glint render --reference` renders the same view: relative RMSE ≤ 2 % over
/// object pixels. A Lambertian copy first isolates camera, environment and visibility; then (a) the
/// bunny's fitted highlight in the default view, (b) the same in an orbit view with the environment
/// rotated 90°, (c) an anisotropic material on a tangent-carrying mesh (the frame of
/// docs/conventions.md §2).
#[test]
fn mitsuba_renders_exported_scenes_as_glint_does() {
    use glint::sphere::{LobeLayout, LobeSet};
    let Some(py) = tool(
        repo().join(".venv/bin/python"),
        "python venv with mitsuba and glint_mitsuba",
    ) else {
        return;
    };
    let probe = Command::new(&py)
        .args(["-c", "import mitsuba, glint_mitsuba"])
        .output()
        .unwrap();
    if !probe.status.success() {
        assert!(
            !common::in_ci(),
            "mitsuba and glint_mitsuba are required in CI: {}",
            String::from_utf8_lossy(&probe.stderr)
        );
        eprintln!("SKIPPED: mitsuba / glint_mitsuba not importable");
        return;
    }
    let dir = common::temp_dir("mitsuba");
    let studio = repo().join("samples/studio_1k.exr");
    let bake = |name: &str, scene: &Path| {
        let b = dir.join(format!("{name}.bake"));
        let out = run_glint!([
            "bake".as_ref(),
            scene.as_os_str(),
            "--env".as_ref(),
            studio.as_os_str(),
            "--out".as_ref(),
            b.as_os_str()
        ]);
        assert!(
            out.status.success(),
            "bake {name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        b
    };
    let bunny = bake("bunny", &repo().join("samples/bunny.glb"));
    let highlight = dir.join("highlight.json");
    let strokes = repo().join("samples/strokes/bunny-highlight.json");
    let out = run_glint!([
        "fit".as_ref(),
        bunny.as_os_str(),
        "--strokes".as_ref(),
        strokes.as_os_str(),
        "--out".as_ref(),
        highlight.as_os_str()
    ]);
    assert!(
        out.status.success(),
        "fit: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut lambertian =
        glint::fit::material::Material::parse(&std::fs::read_to_string(&highlight).unwrap())
            .unwrap();
    lambertian
        .coefficients
        .iter_mut()
        .for_each(|c| c.iter_mut().for_each(|x| *x = 0.0));
    lambertian.rho_d = [0.7, 0.55, 0.4];
    let lambertian_path = dir.join("lambertian.json");
    std::fs::write(&lambertian_path, lambertian.to_json()).unwrap();
    // (c): an anisotropic highlight stretched along the tangent, on the brushed-sphere sample (a UV
    // sphere whose tangents follow +φ, over a ground square).
    let sphere = bake("sphere", &repo().join("samples/brushed_sphere.glb"));
    let lobes = LobeSet::new(LobeLayout::Hemicube { n: 5 }, 40.0).unwrap();
    let coefficients: [Vec<f64>; 3] = std::array::from_fn(|ch| {
        lobes
            .centres()
            .iter()
            .map(|x| [1.2, 1.0, 0.8][ch] * (-(x.x / 0.6).powi(2) - (x.y / 0.15).powi(2)).exp())
            .collect()
    });
    let aniso = glint::fit::material::Material::new(
        &lobes,
        glint::sphere::srbf::sigma_from_lambda(40.0).unwrap(),
        coefficients,
        [0.15, 0.12, 0.1],
        0.3,
        Default::default(),
    );
    let aniso_path = dir.join("brushed.json");
    std::fs::write(&aniso_path, aniso.to_json()).unwrap();

    let size = "96x72";
    let cases: [(&str, &Path, &Path, &[&str]); 5] = [
        ("lambertian, default view", &bunny, &lambertian_path, &[]),
        (
            "lambertian, orbit, rotated 90°",
            &bunny,
            &lambertian_path,
            &["--orbit", "20,15,2.5", "--rotate", "90"],
        ),
        ("(a) bunny highlight, default view", &bunny, &highlight, &[]),
        (
            "(b) bunny highlight, orbit, rotated 90°",
            &bunny,
            &highlight,
            &["--orbit", "20,15,2.5", "--rotate", "90"],
        ),
        (
            "(c) anisotropic, tangent-carrying sphere",
            &sphere,
            &aniso_path,
            &["--orbit", "30,25,0"],
        ),
    ];
    let mut worst = 0f64;
    for (k, (label, bake, material, view)) in cases.iter().enumerate() {
        let glint_exr = dir.join(format!("glint{k}.exr"));
        let mut argv: Vec<std::ffi::OsString> = vec![
            "render".into(),
            bake.into(),
            "--material".into(),
            material.into(),
            "--reference".into(),
            "2048".into(),
            "--size".into(),
            size.into(),
            "--out".into(),
            glint_exr.clone().into(),
        ];
        argv.extend(view.iter().map(|s| s.into()));
        let out = run_glint!(argv);
        assert!(
            out.status.success(),
            "{label}: render: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let scene_dir = dir.join(format!("scene{k}"));
        let mut argv: Vec<std::ffi::OsString> = vec![
            "export".into(),
            material.into(),
            "--to".into(),
            scene_dir.clone().into(),
            "--formats".into(),
            "mitsuba".into(),
            "--bake".into(),
            bake.into(),
            "--size".into(),
            size.into(),
            "--table-resolution".into(),
            "256".into(),
        ];
        argv.extend(view.iter().map(|s| s.into()));
        let out = run_glint!(argv);
        assert!(
            out.status.success(),
            "{label}: export: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stem = material.file_stem().unwrap().to_string_lossy().into_owned();
        let mitsuba_exr = dir.join(format!("mitsuba{k}.exr"));
        let start = std::time::Instant::now();
        let out = Command::new(&py)
            .args(["-m", "glint_mitsuba", "render"])
            .arg(scene_dir.join(format!("{stem}_mitsuba.xml")))
            .arg("--out")
            .arg(&mitsuba_exr)
            .args(["--spp", "2048"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{label}: mitsuba: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        let (rmse, pixels, ratio) = compare_exr(&mitsuba_exr, &glint_exr);
        println!(
            "{label}: Mitsuba ({}, {:.1} s) vs glint's reference, 2048 spp each, {size}: relative RMSE {:.2} % over {pixels} object pixels, mean ratio {ratio:.4}",
            String::from_utf8_lossy(&out.stdout).trim(),
            start.elapsed().as_secs_f64(),
            100.0 * rmse
        );
        assert!(pixels > 500, "{label}: only {pixels} object pixels");
        assert!(rmse <= 0.02, "{label}: relative RMSE {rmse} > 2 %");
        worst = worst.max(rmse);
        if k == 2 {
            // Mitsuba's own noise at this spp: the same scene with another seed.
            let again = dir.join("mitsuba-seed1.exr");
            let out = Command::new(&py)
                .args(["-m", "glint_mitsuba", "render"])
                .arg(scene_dir.join(format!("{stem}_mitsuba.xml")))
                .arg("--out")
                .arg(&again)
                .args(["--spp", "2048", "--seed", "1"])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let (noise, _, _) = compare_exr(&again, &mitsuba_exr);
            println!(
                "    Mitsuba seed 1 vs seed 0: relative RMSE {:.2} % (one image's noise ≈ {:.2} %)",
                100.0 * noise,
                100.0 * noise / 2f64.sqrt()
            );
        }
        if k == 2 || k == 4 {
            // docs/conventions.md alone suffices: a Python implementation of its formulas matches
            // the exported table, and the plugin's exact-lobe path (the page's formulas, from the
            // lobe JSON, no table) renders the same pixels.
            let o = Command::new(&py)
                .arg(repo().join("exporters/python/check_conventions.py"))
                .arg(scene_dir.join(format!("{stem}_ph.exr")))
                .arg(scene_dir.join(format!("{stem}_lobes.json")))
                .output()
                .unwrap();
            let text = String::from_utf8_lossy(&o.stdout);
            assert!(
                o.status.success(),
                "{label}: {text}{}",
                String::from_utf8_lossy(&o.stderr)
            );
            println!("    {}", text.trim());
            let xml = scene_dir.join(format!("{stem}_mitsuba.xml"));
            let text = std::fs::read_to_string(&xml).unwrap();
            let lobes_xml = scene_dir.join(format!("{stem}_lobes_mitsuba.xml"));
            std::fs::write(
                &lobes_xml,
                text.replace(
                    &format!("value=\"{stem}_ph.exr\""),
                    &format!("value=\"{stem}_lobes.json\""),
                ),
            )
            .unwrap();
            let exact = dir.join(format!("mitsuba{k}-lobes.exr"));
            let out = Command::new(&py)
                .args(["-m", "glint_mitsuba", "render"])
                .arg(&lobes_xml)
                .arg("--out")
                .arg(&exact)
                .args(["--spp", "2048"])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let (rmse, pixels, ratio) = compare_exr(&exact, &glint_exr);
            println!(
                "    the exact lobes (docs/conventions.md, from {stem}_lobes.json) in Mitsuba: relative RMSE {:.2} % over {pixels} object pixels, mean ratio {ratio:.4}",
                100.0 * rmse
            );
            assert!(
                rmse <= 0.02,
                "{label}, exact lobes: relative RMSE {rmse} > 2 %"
            );
        }
        if k == 3 {
            // The comparison can fail: the same scene with the environment turned the other way.
            let xml = scene_dir.join(format!("{stem}_mitsuba.xml"));
            let text = std::fs::read_to_string(&xml).unwrap();
            assert!(text.contains("angle=\"90.0\""), "{text}");
            std::fs::write(&xml, text.replace("angle=\"90.0\"", "angle=\"-90.0\"")).unwrap();
            let wrong = dir.join("mitsuba-wrong.exr");
            let out = Command::new(&py)
                .args(["-m", "glint_mitsuba", "render"])
                .arg(&xml)
                .arg("--out")
                .arg(&wrong)
                .args(["--spp", "256"])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let (bad, _, _) = compare_exr(&wrong, &glint_exr);
            println!(
                "    control: the environment rotated by -90° instead: relative RMSE {:.1} %",
                100.0 * bad
            );
            assert!(bad > 0.05, "a wrongly rotated environment passed: {bad}");
        }
    }
    println!("worst relative RMSE {:.2} %", 100.0 * worst);
    std::fs::remove_dir_all(dir).unwrap();
}

/// `glint render --fallback` renders the fallback an export carries: the glTF material of the
/// `.glb` and the UsdPreviewSurface of the `.usda`, by the PRT and by the Monte Carlo reference,
/// which agree; the fallback's picture differs from glint's own by about its error, not by nothing
/// (it is not glint's BRDF drawn again); a material JSON has no fallback and is refused in one
/// line.
#[test]
fn render_fallback_draws_the_exported_fallback_by_prt_and_reference() {
    let (dir, bake, material) = fitted("render-fallback");
    let to = dir.join("out");
    let size = "64x48";
    let out = run_glint!([
        "export".as_ref(),
        material.as_os_str(),
        "--to".as_ref(),
        to.as_os_str(),
        "--bake".as_ref(),
        bake.as_os_str(),
        "--size".as_ref(),
        size.as_ref(),
        "--formats".as_ref(),
        "gltf,usd".as_ref()
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let render = |m: &Path, reference: Option<&str>, fallback: bool, out: &Path| {
        let mut argv: Vec<std::ffi::OsString> = vec![
            "render".into(),
            bake.clone().into(),
            "--material".into(),
            m.into(),
            "--size".into(),
            size.into(),
            "--out".into(),
            out.into(),
        ];
        if let Some(spp) = reference {
            argv.extend(["--reference".into(), spp.into()]);
        }
        if fallback {
            argv.push("--fallback".into());
        }
        let o = run_glint!(argv);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let own = dir.join("own.exr");
    render(&material, Some("2048"), false, &own);
    for (file, what) in [
        ("shiny.glb", "glTF fallback"),
        ("shiny.usda", "UsdPreviewSurface fallback"),
    ] {
        let (prt, mc) = (
            dir.join(format!("{file}.prt.exr")),
            dir.join(format!("{file}.mc.exr")),
        );
        let said = render(&to.join(file), None, true, &prt);
        assert!(said.contains(&format!("PRT of the {what}")), "{said}");
        let said = render(&to.join(file), Some("2048"), true, &mc);
        assert!(said.contains(&format!("reference of the {what}")), "{said}");
        let (prt_vs_mc, n, _) = compare_exr(&prt, &mc);
        let (mc_vs_own, _, _) = compare_exr(&mc, &own);
        println!(
            "{what}: PRT vs reference {:.2} %, reference vs glint's own {:.2} % ({n} pixels)",
            prt_vs_mc * 100.0,
            mc_vs_own * 100.0
        );
        assert!(n > 300, "{n} pixels");
        assert!(prt_vs_mc < 0.04, "{what}: PRT vs reference {prt_vs_mc}");
        assert!(
            mc_vs_own > 0.02 && mc_vs_own < 0.3,
            "{what}: vs glint's own {mc_vs_own}"
        );
    }
    let o = run_glint!([
        "render".as_ref(),
        bake.as_os_str(),
        "--material".as_ref(),
        material.as_os_str(),
        "--fallback".as_ref(),
        "--out".as_ref(),
        dir.join("x.exr").as_os_str()
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.lines().count() == 1 && err.contains("fallback"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
