//! Helpers shared by integration tests: synthetic scenes built in memory.
#![allow(dead_code)]

use glam::{Vec3, Vec4};
use glint::scene::{AttributeSource, Bounds, Mesh, PartInfo, Scene, default_camera};
use std::path::{Path, PathBuf};

pub fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets")
}

/// Packs a GLB 2 container: JSON chunk (space padded) and, if non-empty, a BIN chunk (zero padded).
pub fn pack_glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes()); // patched below
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        let mut b = bin.to_vec();
        while !b.len().is_multiple_of(4) {
            b.push(0);
        }
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    out
}

/// A scene around a mesh (normals given), with the default camera.
pub fn scene_from_mesh(mesh: Mesh) -> Scene {
    let bounds = Bounds::from_points(&mesh.positions).expect("non-empty mesh");
    let part = PartInfo {
        mesh_name: "synthetic".into(),
        node_name: "synthetic".into(),
        primitive: 0,
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        normals: AttributeSource::Present,
        tangents: if mesh.tangents.is_some() {
            AttributeSource::Present
        } else {
            AttributeSource::Absent
        },
        uvs: AttributeSource::Absent,
    };
    Scene {
        source: PathBuf::from("synthetic"),
        cameras: vec![default_camera(&bounds)],
        mesh,
        parts: vec![part],
        mesh_count: 1,
        bounds,
        skipped_primitives: 0,
        normal_fallbacks: 0,
        warnings: Vec::new(),
    }
}

/// A UV sphere of radius r with `segments` longitudes and `rings` latitude bands, exact normals.
/// With `tangents`, the tangent follows +φ (about +Y).
pub fn uv_sphere(r: f32, segments: u32, rings: u32, tangents: bool) -> Mesh {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut tan = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            let n = Vec3::new(
                theta.sin() * phi.sin(),
                theta.cos(),
                theta.sin() * phi.cos(),
            );
            positions.push(n * r);
            normals.push(n);
            tan.push(Vec4::new(phi.cos(), 0.0, -phi.sin(), 1.0));
        }
    }
    let mut triangles = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let c = (i + 1) * segments + j;
            let d = (i + 1) * segments + (j + 1) % segments;
            if i != 0 {
                triangles.push([a, c, b]);
            }
            if i != rings - 1 {
                triangles.push([b, c, d]);
            }
        }
    }
    Mesh {
        positions,
        normals,
        tangents: tangents.then_some(tan),
        uvs: None,
        triangles,
    }
}

/// Clarabel (an interior-point solver sharing no code with glint's) on
/// min ½cᵀHc + qᵀc s.t. c ≥ 0, Gc ≤ u; H n×n and G m×n row-major. Returns c.
pub fn clarabel_qp(h: &[f64], q: &[f64], g: &[f64], u: &[f64], n: usize, m: usize) -> Vec<f64> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT,
    };
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for j in 0..n {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(h[i * n + j]);
        }
        colptr.push(rowval.len());
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for j in 0..n {
        rowval.push(j);
        nzval.push(-1.0);
        for l in 0..m {
            rowval.push(n + l);
            nzval.push(g[l * n + j]);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(n + m, n, colptr, rowval, nzval);
    let b: Vec<f64> = std::iter::repeat_n(0.0, n)
        .chain(u.iter().copied())
        .collect();
    let cones: [SupportedConeT<f64>; 1] = [NonnegativeConeT(n + m)];
    let settings = DefaultSettings {
        verbose: false,
        tol_gap_abs: 1e-10,
        tol_gap_rel: 1e-10,
        tol_feas: 1e-10,
        max_iter: 200,
        ..DefaultSettings::default()
    };
    let mut solver = DefaultSolver::new(&p, q, &a, &b, &cones, settings).expect("clarabel setup");
    solver.solve();
    let status = solver.solution.status;
    assert!(
        matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved),
        "clarabel: {status:?}"
    );
    solver.solution.x.clone()
}

/// ½cᵀHc + qᵀc.
pub fn qp_objective(h: &[f64], q: &[f64], c: &[f64], n: usize) -> f64 {
    let mut f = 0.0;
    for i in 0..n {
        let hc: f64 = (0..n).map(|j| h[i * n + j] * c[j]).sum();
        f += 0.5 * c[i] * hc + q[i] * c[i];
    }
    f
}

/// Runs the built `glint` binary. Only for integration tests (CARGO_BIN_EXE_glint is set for them).
#[macro_export]
macro_rules! run_glint {
    ($args:expr) => {
        $crate::glint_command!()
            .args($args)
            .output()
            .expect("run glint")
    };
}

/// A command for the built `glint` binary, its energy-table cache in a folder of this test process
/// (not the user's cache; `GLINT_CACHE_DIR`). A macro, as `env!` would not build in the benches
/// that share this file.
#[macro_export]
macro_rules! glint_command {
    () => {{
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_glint"));
        cmd.env("GLINT_CACHE_DIR", $crate::common::energy_cache_dir());
        cmd
    }};
}

/// The energy-table cache folder the tests' `glint` processes share.
pub fn energy_cache_dir() -> PathBuf {
    std::env::temp_dir().join(format!("glint-it-energy-cache-{}", std::process::id()))
}

/// A fresh, empty temporary folder named for the test, the process and a per-process counter (the
/// tests share one process, so two tests asking for the same name get different folders).
pub fn temp_dir(name: &str) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("glint-{name}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Whether the tests run in CI (`CI=true`), where a missing tool fails its test instead of
/// skipping it.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// The 400 vertices, spread evenly over a mesh's `n` vertex indices, that the bake's visibility
/// error is measured at (`bake_visibility::`, the million's bench, `bake_studies`).
pub fn error_sample(n: usize) -> Vec<u32> {
    (0..400).map(|i| ((2 * i + 1) * n / 800) as u32).collect()
}

/// The visibility error of a cut at vertex `v` against a ray per direction, as
/// (Σ_ℓ L_ℓ Ω_ℓ c_ℓ |V_ℓ − V_true,ℓ|, Σ_ℓ L_ℓ Ω_ℓ c_ℓ) over the leaf directions ℓ above the horizon
/// (L the luminance per leaf, c the cosine; V_ℓ the value of the cut node holding ℓ, 0 where
/// none), traced from the vertex's ray origin with `baker`'s tracer.
pub fn visibility_error(
    baker: &glint::bake::Baker,
    luminance: &[f64],
    v: u32,
    entries: &[(u32, f32)],
) -> (f64, f64) {
    let tree = &baker.tree;
    let (origin, normal) = baker.ray_origin(v as usize).unwrap();
    let mut leaf_v = vec![0.0f32; tree.leaf_count()];
    for &(k, value) in entries {
        let node = tree.nodes()[k as usize];
        leaf_v[node.first as usize..(node.first + node.count) as usize].fill(value);
    }
    let (mut wrong, mut total) = (0.0, 0.0);
    for l in 0..tree.leaf_count() {
        let w = luminance[l] * tree.leaf_moments()[l].dot(normal).max(0.0);
        if w <= 0.0 {
            continue;
        }
        let d = tree.leaf_directions()[l];
        let hit = baker
            .tracer
            .occluded(origin.as_vec3().into(), glam::Vec3A::from(d.as_vec3()));
        wrong += w * (leaf_v[l] as f64 - if hit { 0.0 } else { 1.0 }).abs();
        total += w;
    }
    (wrong, total)
}

/// The environment's luminance (mean of R, G, B) per leaf direction of `baker`'s set, unrotated.
pub fn leaf_luminance(env: &glint::env::EnvMap, baker: &glint::bake::Baker) -> Vec<f64> {
    glint::light::LightSums::new(env, &baker.set, &baker.tree, 0.0)
        .leaf_radiance()
        .iter()
        .map(|c| (c[0] + c[1] + c[2]) / 3.0)
        .collect()
}
