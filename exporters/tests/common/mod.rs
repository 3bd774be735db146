//! Shared test fixtures: a deterministic anisotropic material, temp folders, and the external tools
//! (Python with usd-core/OpenEXR/numpy, Node with gltf-validator).
//!
//! Inputs: environment (`CI`, `GLINT_PYTHON`). Outputs: fixtures and tool handles.
//! Invariants: a missing tool fails the test when `CI` is "true" and is reported and skipped
//! otherwise; temp folders are unique per test and removed by the caller.

#![allow(dead_code)]

use glint_exporters::brdf::lobes_p;
use glint_exporters::{
    ClearcoatLayer, MaterialDesc, PbrFallback, PhTable, PreviewSurfaceFallback, SceneMesh,
    SheenLayer, SpecularLayer, Weighting,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

pub const LAMBDA: f64 = 81.06; // σ = π/40, the paper's lobe width

/// A small deterministic generator (SplitMix64) for test data.
pub struct Rng(pub u64);
impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A uniform direction on the upper hemisphere with z >= zmin.
    pub fn hemisphere(&mut self, zmin: f64) -> [f64; 3] {
        let z = zmin + (1.0 - zmin) * self.uniform();
        let phi = 2.0 * std::f64::consts::PI * self.uniform();
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

/// J lobe centres on the upper hemisphere (a Fibonacci spiral), unit vectors.
pub fn centres(j: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..j)
        .map(|i| {
            let z = 1.0 - (i as f64 + 0.5) / j as f64; // (0, 1)
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

/// A deterministic anisotropic material with a table of `resolution`.
pub fn material(name: &str, resolution: u32) -> MaterialDesc {
    let j = 49;
    let mut rng = Rng(7);
    let mut coefficients = [vec![0.0; j], vec![0.0; j], vec![0.0; j]];
    for i in 0..j {
        let c = centres(j)[i];
        // A highlight near the normal, tilted towards +x, plus a sparse random rest.
        let base = 3.0 * (-(1.0 - c[2]) * 6.0).exp() * (1.0 + 0.5 * c[0]);
        for (k, ch) in coefficients.iter_mut().enumerate() {
            let r = rng.uniform();
            ch[i] = if r < 0.3 {
                0.0
            } else {
                base * (0.6 + 0.2 * k as f64) + 0.05 * r
            };
        }
    }
    let mut provenance = BTreeMap::new();
    provenance.insert("tool".to_string(), "glint 0.1.0 (test)".to_string());
    provenance.insert("input.scene.sha256".to_string(), "00ff".repeat(16));
    provenance.insert(
        "fit.residual_rms".to_string(),
        "[0.01, 0.02, 0.03]".to_string(),
    );
    provenance.insert(
        "note with \"quotes\" and \\ backslash".to_string(),
        "line1\nline2 – ünïcode".to_string(),
    );
    let mut desc = MaterialDesc {
        name: name.to_string(),
        model: "dbrdf-srbf".into(),
        version: 1,
        lambda: LAMBDA,
        sigma: std::f64::consts::PI / 40.0,
        layout: format!("fibonacci-{j}"),
        isotropic: false,
        centres: centres(j),
        coefficients,
        rho_d: [0.31, 0.22, 0.13],
        f0: 0.04,
        brdf_convention: glint_exporters::material::brdf_convention(false).into(),
        frame_convention: glint_exporters::material::FRAME_CONVENTION.into(),
        provenance,
        table: PhTable::default(),
        fallback: PbrFallback {
            base_color: [0.31, 0.22, 0.13],
            metallic: 0.0,
            roughness: 0.23,
            anisotropy: Some((0.4, 0.25)),
            specular: Some(SpecularLayer {
                factor: 0.8,
                color: [1.5, 1.25, 1.0],
            }),
            clearcoat: Some(ClearcoatLayer {
                factor: 0.6,
                roughness: 0.1,
            }),
            sheen: Some(SheenLayer {
                color: [0.2, 0.2, 0.25],
                roughness: 0.4,
            }),
            relative_error: 0.12,
            uniform_relative_error: 0.14,
            one_lobe_relative_error: 0.2,
            weighting: Weighting::Scene,
        },
        preview_surface: PreviewSurfaceFallback {
            diffuse_color: [0.3, 0.2, 0.1],
            use_specular_workflow: true,
            specular_color: [0.06, 0.05, 0.04],
            metallic: 0.0,
            roughness: 0.25,
            clearcoat: 0.6,
            clearcoat_roughness: 0.1,
            relative_error: 0.13,
            uniform_relative_error: 0.15,
        },
        merl: None,
    };
    desc.table = PhTable::tabulate(resolution, |h| lobes_p(&desc, h));
    desc
}

/// A small closed mesh with normals, tangents and UVs (an octahedron with flat-shaded faces).
pub fn scene_mesh() -> SceneMesh {
    let v = [
        [1.0f32, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let faces = [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let mut m = SceneMesh {
        tangents: Some(Vec::new()),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    for f in faces {
        let (a, b, c) = (v[f[0]], v[f[1]], v[f[2]]);
        let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let el = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
        for (k, p) in [a, b, c].into_iter().enumerate() {
            m.indices.push(m.positions.len() as u32);
            m.positions.push(p);
            m.normals.push([n[0] / l, n[1] / l, n[2] / l]);
            m.tangents
                .as_mut()
                .unwrap()
                .push([e1[0] / el, e1[1] / el, e1[2] / el, 1.0]);
            m.uvs
                .as_mut()
                .unwrap()
                .push([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]][k]);
        }
    }
    m
}

/// A fresh, empty folder for one test.
pub fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("glint-exporters-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Reports a missing tool: panics in CI, otherwise prints why and returns (the caller skips).
pub fn missing(tool: &str, why: &str) {
    if in_ci() {
        panic!(
            "{tool} is required in CI (CI=true) but unavailable: {why}; see exporters/README.md"
        );
    }
    eprintln!(
        "SKIPPED: {tool} unavailable ({why}); see exporters/README.md for the install commands"
    );
}

/// `$GLINT_PYTHON`, else `<workspace>/.venv/bin/python`, if it imports `modules`.
pub fn python(modules: &str) -> Option<PathBuf> {
    let py = std::env::var_os("GLINT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join(".venv/bin/python"));
    match Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .output()
    {
        Ok(o) if o.status.success() => Some(py),
        Ok(o) => {
            missing(
                "python",
                &format!(
                    "{} cannot import {modules}: {}",
                    py.display(),
                    String::from_utf8_lossy(&o.stderr)
                        .lines()
                        .last()
                        .unwrap_or("")
                ),
            );
            None
        }
        Err(e) => {
            missing("python", &format!("{}: {e}", py.display()));
            None
        }
    }
}

/// `node` with `exporters/js/node_modules/gltf-validator` installed.
pub fn node_validator() -> Option<(PathBuf, PathBuf)> {
    let js = workspace().join("exporters/js");
    if !js
        .join("node_modules/gltf-validator/package.json")
        .is_file()
    {
        missing(
            "gltf-validator",
            "exporters/js/node_modules/gltf-validator is not installed (cd exporters/js && npm ci)",
        );
        return None;
    }
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => Some((PathBuf::from("node"), js.join("validate_gltf.mjs"))),
        _ => {
            missing("node", "`node --version` failed");
            None
        }
    }
}

/// Runs a command; returns (success, stdout, stderr).
pub fn run(cmd: &mut Command) -> (bool, String, String) {
    let o = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"));
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A camera looking at the fixture mesh from +Z (what `glint export --scene` attaches).
pub fn scene_camera() -> glint_exporters::SceneCamera {
    let el = 0.3f64;
    glint_exporters::SceneCamera {
        name: "view".into(),
        eye: [0.0, 4.0 * el.sin(), 4.0 * el.cos()],
        forward: [0.0, -el.sin(), -el.cos()],
        up: [0.0, el.cos(), -el.sin()],
        yfov_rad: 40f64.to_radians(),
        width: 64,
        height: 48,
        znear: 1.0,
        zfar: Some(8.0),
    }
}

/// The "fallback" object `python/check_usd.py` compares the stage's UsdPreviewSurface (and the
/// anisotropy kept in customData) with.
pub fn usd_fallback_json(desc: &MaterialDesc, anisotropy: serde_json::Value) -> serde_json::Value {
    let ps = &desc.preview_surface;
    serde_json::json!({
        "diffuse_color": ps.diffuse_color,
        "metallic": ps.metallic,
        "roughness": ps.roughness,
        "clearcoat": ps.clearcoat,
        "clearcoat_roughness": ps.clearcoat_roughness,
        "use_specular_workflow": ps.use_specular_workflow,
        "specular_color": ps.specular_color,
        "anisotropy": anisotropy,
    })
}
