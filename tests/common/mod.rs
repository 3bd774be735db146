//! Helpers shared by integration tests: synthetic scenes built in memory.
#![allow(dead_code)]

use glam::{Vec3, Vec4};
use glint::scene::{AttributeSource, Bounds, Mesh, PartInfo, Scene, default_camera};
use std::path::{Path, PathBuf};

pub fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets")
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
        tangents: if mesh.tangents.is_some() { AttributeSource::Present } else { AttributeSource::Absent },
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
            let n = Vec3::new(theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos());
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
    Mesh { positions, normals, tangents: tangents.then_some(tan), uvs: None, triangles }
}
