//! Tests of `glint::scene::import`: the real assets, small glTFs built here (JSON + buffers, or GLB
//! bytes packed by hand), and refusal of bad input with the right error variant.
//!
//! References are independent of the code under test: counts from the assets' README, bounds from
//! the assets' own POSITION accessor min/max (read here with serde_json), transforms and normals
//! computed by hand, and winding checked with cross products written out here.
//! No bad input may panic the library: each bad case asserts the error variant, and a mutation
//! sweep imports hundreds of corrupted files.

use crate::common;

use std::path::{Path, PathBuf};

use base64::Engine as _;
use common::pack_glb;
use glam::{Vec3, Vec4};
use glint::scene::{self, AttributeSource, ImportError, Scene};
use serde_json::{Value, json};

const ASSETS: &str = "/work/shared/assets/glb";

// ---------------------------------------------------------------------------------------------
// Helpers

/// A fresh, empty scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("glint_gltf_import_{}_{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Buffer bytes plus the bufferViews and accessors describing them.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, data: &[u8], stride: Option<usize>) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, v: &[[f32; N]], ty: &str) -> usize {
        let data: Vec<u8> = v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&data, None);
        let mut a =
            json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": ty});
        if N == 3 && !v.is_empty() {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for p in v {
                for k in 0..N {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            a["min"] = json!(lo.to_vec());
            a["max"] = json!(hi.to_vec());
        }
        self.accessor(a)
    }

    fn vec3(&mut self, v: &[[f32; 3]]) -> usize {
        self.floats(v, "VEC3")
    }

    fn vec4(&mut self, v: &[[f32; 4]]) -> usize {
        self.floats(v, "VEC4")
    }

    fn indices_u16(&mut self, idx: &[u16]) -> usize {
        let data: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&data, None);
        self.accessor(json!({"bufferView": view, "componentType": 5123, "count": idx.len(), "type": "SCALAR"}))
    }

    fn indices_u32(&mut self, idx: &[u32]) -> usize {
        let data: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&data, None);
        self.accessor(json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}))
    }

    /// A document using these buffers: buffer 0 with `uri` (or the BIN chunk), scene 0 with
    /// `scene_nodes`, and the given nodes and meshes.
    fn doc(&self, uri: Option<&str>, scene_nodes: &[usize], nodes: Value, meshes: Value) -> Value {
        let mut buffer = json!({"byteLength": self.bytes.len()});
        if let Some(uri) = uri {
            buffer["uri"] = json!(uri);
        }
        json!({
            "asset": {"version": "2.0", "generator": "glint tests"},
            "scene": 0,
            "scenes": [{"nodes": scene_nodes}],
            "nodes": nodes,
            "meshes": meshes,
            "buffers": [buffer],
            "bufferViews": self.views,
            "accessors": self.accessors,
        })
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&path, bytes).unwrap();
    path
}

fn write_glb(dir: &Path, name: &str, doc: &Value, bin: &[u8]) -> PathBuf {
    write(dir, name, &pack_glb(doc, bin))
}

fn write_json(dir: &Path, name: &str, doc: &Value) -> PathBuf {
    write(dir, name, &serde_json::to_vec_pretty(doc).unwrap())
}

fn import_ok(path: &Path) -> Scene {
    match scene::import(path) {
        Ok(s) => s,
        Err(e) => panic!("import of {} failed: {e}", path.display()),
    }
}

/// The error of importing `path`, checking that its message is one line naming the file.
fn import_err(path: &Path) -> ImportError {
    match scene::import(path) {
        Ok(_) => panic!("{} was accepted", path.display()),
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains('\n'), "multi-line message: {msg}");
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            assert!(msg.contains(&name), "message does not name {name}: {msg}");
            e
        }
    }
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).length() <= tol
}

/// Right-hand-rule normal of triangle `t` of `s`'s merged mesh.
fn face_normal(s: &Scene, t: [u32; 3]) -> Vec3 {
    let p = |i: u32| s.mesh.positions[i as usize];
    (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]))
}

fn single_triangle() -> (Bin, usize) {
    let mut b = Bin::default();
    let pos = b.vec3(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    (b, pos)
}

// ---------------------------------------------------------------------------------------------
// Real assets

/// The POSITION accessor min/max of a GLB's first primitive, read independently with serde_json.
fn accessor_bounds(bytes: &[u8]) -> (Vec3, Vec3) {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    let pos = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let v = |k: &str| {
        let a = &doc["accessors"][pos][k];
        Vec3::new(
            a[0].as_f64().unwrap() as f32,
            a[1].as_f64().unwrap() as f32,
            a[2].as_f64().unwrap() as f32,
        )
    };
    (v("min"), v("max"))
}

fn has_normalization_extras(bytes: &[u8]) -> bool {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    doc["asset"]["extras"]["normalization"].is_object()
}

#[test]
fn real_assets_counts_bounds_normals_camera() {
    // (file, vertices, triangles) from /work/shared/assets/README.md.
    let table = [
        ("bunny.glb", 1_839, 3_674),
        ("teapot.glb", 529, 992),
        ("suzanne.glb", 7_503, 14_842),
        ("dragon.glb", 14_892, 29_999),
        ("dragon_100k.glb", 49_892, 99_999),
    ];
    let mut normalised = 0;
    for (file, vertices, triangles) in table {
        let path = Path::new(ASSETS).join(file);
        let bytes = std::fs::read(&path).unwrap();
        let s = import_ok(&path);
        assert_eq!(s.mesh.positions.len(), vertices, "{file} vertices");
        assert_eq!(s.mesh.triangles.len(), triangles, "{file} triangles");
        assert_eq!(s.mesh.normals.len(), vertices);
        assert_eq!(s.mesh_count, 1);
        assert_eq!(s.parts.len(), 1);
        assert_eq!(s.parts[0].vertices, vertices);
        assert_eq!(s.parts[0].triangles, triangles);
        assert_eq!(s.parts[0].normals, AttributeSource::Present, "{file}");
        assert_eq!(s.skipped_primitives, 0);
        assert_eq!(s.normal_fallbacks, 0, "{file}");
        assert!(
            s.mesh
                .normals
                .iter()
                .all(|n| (n.length() - 1.0).abs() < 1e-4)
        );
        assert!(
            s.mesh
                .triangles
                .iter()
                .flatten()
                .all(|&i| (i as usize) < vertices)
        );

        // Bounds equal the file's own POSITION min/max (the node has no transform).
        let (lo, hi) = accessor_bounds(&bytes);
        assert!(
            close(s.bounds.min, lo, 1e-6),
            "{file}: {:?} vs {lo:?}",
            s.bounds.min
        );
        assert!(
            close(s.bounds.max, hi, 1e-6),
            "{file}: {:?} vs {hi:?}",
            s.bounds.max
        );
        // README: largest side 1, centred at the origin. True for the files that record their
        // normalisation in asset.extras; suzanne.glb records none and is not normalised
        // (bounds x ±0.93, y −0.67..0.67, z −0.54..0.58).
        if has_normalization_extras(&bytes) {
            normalised += 1;
            assert!((s.bounds.size().max_element() - 1.0).abs() < 1e-3, "{file}");
            assert!(
                s.bounds.centre().length() < 1e-3,
                "{file}: {:?}",
                s.bounds.centre()
            );
        }

        // Vertex normals agree with the triangles' winding (glTF: counter-clockwise = front).
        let agree = s
            .mesh
            .triangles
            .iter()
            .filter(|t| {
                let f = face_normal(&s, **t);
                let n: Vec3 = t.iter().map(|&i| s.mesh.normals[i as usize]).sum();
                f.dot(n) > 0.0
            })
            .count();
        assert!(
            agree as f64 > 0.95 * triangles as f64,
            "{file}: {agree}/{triangles}"
        );

        // One default camera, seeing the bounds centre in the middle of its image.
        assert_eq!(s.cameras.len(), 1);
        let c = &s.cameras[0];
        assert!(c.is_default);
        assert_eq!(c.name, "default");
        assert_eq!((c.width, c.height), (640, 480));
        let clip = c.clip_from_world() * s.bounds.centre().extend(1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-4 && ndc.y.abs() < 1e-4 && ndc.z > 0.0 && ndc.z < 1.0);
        // Every bounding-box corner lies inside the view frustum.
        for k in 0..8 {
            let corner = Vec3::new(
                if k & 1 == 0 {
                    s.bounds.min.x
                } else {
                    s.bounds.max.x
                },
                if k & 2 == 0 {
                    s.bounds.min.y
                } else {
                    s.bounds.max.y
                },
                if k & 4 == 0 {
                    s.bounds.min.z
                } else {
                    s.bounds.max.z
                },
            );
            let clip = c.clip_from_world() * corner.extend(1.0);
            let ndc = clip.truncate() / clip.w;
            assert!(ndc.x.abs() < 1.0 && ndc.y.abs() < 1.0 && ndc.z > 0.0 && ndc.z < 1.0);
        }
    }
    assert_eq!(normalised, 4);
}

#[test]
fn draco_required_is_refused_naming_the_extension() {
    let path = Path::new(ASSETS).join("bad/draco_required.glb");
    match import_err(&path) {
        ImportError::RequiredExtension { extension, .. } => {
            assert_eq!(extension, "KHR_draco_mesh_compression")
        }
        other => panic!("{other:?}"),
    }
    let msg = scene::import(&path).unwrap_err().to_string();
    assert!(
        msg.ends_with(
            "draco_required.glb: requires glTF extension KHR_draco_mesh_compression, which glint does not implement"
        ),
        "{msg}"
    );
}

#[test]
fn ignorable_required_extensions_are_accepted() {
    let dir = scratch("ignorable_ext");
    let (mut b, pos) = single_triangle();
    let idx = b.indices_u16(&[0, 1, 2]);
    let mut doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "material": 0}]}]),
    );
    doc["extensionsUsed"] = json!(["KHR_materials_clearcoat", "KHR_texture_transform"]);
    doc["extensionsRequired"] = json!(["KHR_materials_clearcoat", "KHR_texture_transform"]);
    // A material referencing a texture that does not exist: ignored, so not an error.
    doc["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 7}}}]);
    let s = import_ok(&write_glb(&dir, "ext.glb", &doc, &b.bytes));
    assert_eq!(s.mesh.triangles.len(), 1);

    doc["extensionsRequired"] = json!(["KHR_texture_transform", "EXT_meshopt_compression"]);
    let path = write_glb(&dir, "meshopt.glb", &doc, &b.bytes);
    match import_err(&path) {
        ImportError::RequiredExtension { extension, .. } => {
            assert_eq!(extension, "EXT_meshopt_compression")
        }
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Geometry

/// Unit cube with 8 shared corners and 12 outward counter-clockwise triangles.
fn cube() -> (Vec<[f32; 3]>, Vec<u16>) {
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            let s = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
            [s(1), s(2), s(4)]
        })
        .collect();
    let at = |v: [i32; 3]| -> u16 {
        ((v[0] > 0) as u16) | (((v[1] > 0) as u16) << 1) | (((v[2] > 0) as u16) << 2)
    };
    let mut tris = Vec::new();
    for axis in 0..3 {
        for sign in [-1, 1] {
            let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
            let quad: Vec<u16> = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
                .iter()
                .map(|&(a, c)| {
                    let mut v = [0; 3];
                    v[axis] = sign;
                    v[u] = a;
                    v[w] = c;
                    at(v)
                })
                .collect();
            for t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                // Orient outward: the face normal must point along +sign on `axis`.
                let p = |i: u16| Vec3::from(corners[i as usize]);
                let n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                if n[axis] * sign as f32 > 0.0 {
                    tris.extend_from_slice(&t);
                } else {
                    tris.extend_from_slice(&[t[0], t[2], t[1]]);
                }
            }
        }
    }
    (corners, tris)
}

#[test]
fn cube_without_normals_gets_angle_weighted_corner_normals() {
    let dir = scratch("cube");
    let (corners, tris) = cube();
    let mut b = Bin::default();
    let pos = b.vec3(&corners);
    let idx = b.indices_u16(&tris);
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0, "name": "cube node"}]),
        json!([{"name": "cube", "primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]),
    );
    let s = import_ok(&write_glb(&dir, "cube.glb", &doc, &b.bytes));
    assert_eq!(s.mesh.positions.len(), 8);
    assert_eq!(s.mesh.triangles.len(), 12);
    assert_eq!(s.parts[0].normals, AttributeSource::Generated);
    assert_eq!(s.parts[0].tangents, AttributeSource::Absent);
    assert_eq!(s.parts[0].uvs, AttributeSource::Absent);
    assert_eq!(s.parts[0].mesh_name, "cube");
    assert_eq!(s.parts[0].node_name, "cube node");
    assert!(s.mesh.tangents.is_none() && s.mesh.uvs.is_none());
    assert_eq!(s.normal_fallbacks, 0);
    // Each corner touches three faces with a right angle each (whatever the diagonal split), so
    // the angle-weighted normal is the corner direction / √3.
    for (p, n) in s.mesh.positions.iter().zip(&s.mesh.normals) {
        assert!(close(*n, *p / 3f32.sqrt(), 1e-6), "{p:?}: {n:?}");
    }
    // Bounds and default camera of the cube.
    assert_eq!(s.bounds.min, Vec3::splat(-1.0));
    assert_eq!(s.bounds.max, Vec3::splat(1.0));
    assert!((s.bounds.radius() - 3f32.sqrt()).abs() < 1e-6);
    let c = &s.cameras[0];
    let d = c.eye() - s.bounds.centre();
    assert!(close(
        d.normalize(),
        Vec3::new(0.0, 0.3, 1.0).normalize(),
        1e-5
    ));
    // The sphere fits the vertical field of view (40°, the smaller one) with 10 % margin.
    let expected = 1.1 * s.bounds.radius() / 20f32.to_radians().sin();
    assert!((d.length() - expected).abs() < 1e-4 * expected);
}

#[test]
fn node_transforms_apply_to_positions_and_normals() {
    let dir = scratch("transform");
    let mut b = Bin::default();
    let pos = b.vec3(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let r = std::f32::consts::FRAC_1_SQRT_2;
    let nrm = b.vec3(&[[r, r, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]);
    let idx = b.indices_u16(&[0, 1, 2]);
    // Node 0: translation (1, 2, 3), parent of node 1: rotation 90° about +Y, scale (2, 1, 0.5).
    // Node 2: the same world transform as one column-major matrix, written by hand:
    // columns R·S = (0,0,−2), (0,1,0), (0.5,0,0), translation (1,2,3).
    let nodes = json!([
        {"name": "parent", "translation": [1.0, 2.0, 3.0], "children": [1]},
        {"name": "child", "mesh": 0, "rotation": [0.0, r, 0.0, r], "scale": [2.0, 1.0, 0.5]},
        {"name": "matrix", "mesh": 0,
         "matrix": [0.0, 0.0, -2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 1.0]}
    ]);
    let meshes =
        json!([{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx}]}]);
    let s = import_ok(&write_glb(
        &dir,
        "trs.glb",
        &b.doc(None, &[0, 2], nodes, meshes),
        &b.bytes,
    ));
    assert_eq!(s.mesh_count, 1);
    assert_eq!(s.parts.len(), 2);
    assert_eq!(s.mesh.positions.len(), 6);
    assert_eq!(s.mesh.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(s.parts[0].node_name, "child");
    assert_eq!(s.parts[1].node_name, "matrix");
    assert_eq!(s.parts[0].mesh_name, "mesh 0");
    // By hand: p → S p → R_y(90°) (x, y, z) ↦ (z, y, −x) → + (1, 2, 3).
    let expected_p = [
        Vec3::new(1.0, 2.0, 1.0),
        Vec3::new(1.0, 3.0, 3.0),
        Vec3::new(1.5, 2.0, 3.0),
    ];
    // Normals: n → S⁻¹ n → R → normalise.  (1,1,0)/√2 → (0.5,1,0) → (0,1,−0.5);
    // (0,0,1) → (0,0,2) → (2,0,0); (1,0,0) → (0.5,0,0) → (0,0,−0.5).
    let expected_n = [
        Vec3::new(0.0, 1.0, -0.5) / 1.25f32.sqrt(),
        Vec3::X,
        -Vec3::Z,
    ];
    for inst in 0..2 {
        for k in 0..3 {
            let i = inst * 3 + k;
            assert!(
                close(s.mesh.positions[i], expected_p[k], 1e-5),
                "{i}: {:?}",
                s.mesh.positions[i]
            );
            assert!(
                close(s.mesh.normals[i], expected_n[k], 1e-5),
                "{i}: {:?}",
                s.mesh.normals[i]
            );
        }
    }
}

#[test]
fn mirrored_transform_flips_winding_normals_and_tangent_sign() {
    let dir = scratch("mirror");
    let mut b = Bin::default();
    let pos = b.vec3(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let r = std::f32::consts::FRAC_1_SQRT_2;
    let nrm = b.vec3(&[[0.0, 0.0, 1.0], [r, 0.0, r], [0.0, 0.0, 1.0]]);
    let tan = b.vec4(&[[1.0, 0.0, 0.0, 1.0]; 3]);
    let idx = b.indices_u16(&[0, 1, 2]);
    let nodes = json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]);
    let meshes = json!([{"primitives": [
        {"attributes": {"POSITION": pos, "NORMAL": nrm, "TANGENT": tan}, "indices": idx},
        {"attributes": {"POSITION": pos}, "indices": idx}
    ]}]);
    let s = import_ok(&write_glb(
        &dir,
        "mirror.glb",
        &b.doc(None, &[0], nodes, meshes),
        &b.bytes,
    ));
    assert_eq!(s.mesh.triangles, vec![[0, 2, 1], [3, 5, 4]]);
    // Positions mirrored in x.
    assert_eq!(s.mesh.positions[1], Vec3::new(-1.0, 0.0, 0.0));
    // The mirrored triangle still faces +Z (counter-clockwise seen from +Z).
    for t in &s.mesh.triangles {
        assert!(face_normal(&s, *t).normalize().dot(Vec3::Z) > 0.999);
    }
    // Given normals: x negated (inverse transpose of diag(−1, 1, 1)).
    assert!(close(s.mesh.normals[0], Vec3::Z, 1e-6));
    assert!(close(s.mesh.normals[1], Vec3::new(-r, 0.0, r), 1e-6));
    // Generated normals agree with the flipped winding.
    for n in &s.mesh.normals[3..] {
        assert!(close(*n, Vec3::Z, 1e-6), "{n:?}");
    }
    assert_eq!(s.parts[0].tangents, AttributeSource::Present);
    assert_eq!(s.parts[1].tangents, AttributeSource::Absent);
    assert_eq!(s.parts[1].normals, AttributeSource::Generated);
    // Not every part has tangents, so the merged mesh has none.
    assert!(s.mesh.tangents.is_none());

    // Alone, the tangent part keeps its tangents: xyz mirrored, w negated.
    let nodes = json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]);
    let meshes = json!([{"primitives": [
        {"attributes": {"POSITION": pos, "NORMAL": nrm, "TANGENT": tan}, "indices": idx}
    ]}]);
    let s = import_ok(&write_glb(
        &dir,
        "mirror_t.glb",
        &b.doc(None, &[0], nodes, meshes),
        &b.bytes,
    ));
    let t = s.mesh.tangents.as_ref().unwrap();
    assert_eq!(t.len(), 3);
    for t in t {
        assert!(
            (*t - Vec4::new(-1.0, 0.0, 0.0, -1.0)).length() < 1e-6,
            "{t:?}"
        );
    }
}

#[test]
fn triangle_strip_and_fan_are_converted() {
    let dir = scratch("strip");
    let mut b = Bin::default();
    let pos = b.vec3(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ]);
    let fan = b.vec3(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ]);
    let nodes = json!([{"mesh": 0}]);
    let meshes = json!([{"primitives": [
        {"attributes": {"POSITION": pos}, "mode": 5},
        {"attributes": {"POSITION": fan}, "mode": 6}
    ]}]);
    let s = import_ok(&write_glb(
        &dir,
        "strip.glb",
        &b.doc(None, &[0], nodes, meshes),
        &b.bytes,
    ));
    assert_eq!(s.parts[0].triangles, 2);
    assert_eq!(s.parts[1].triangles, 3);
    assert_eq!(&s.mesh.triangles[..2], &[[0, 1, 2], [2, 1, 3]]);
    assert_eq!(&s.mesh.triangles[2..], &[[4, 5, 6], [4, 6, 7], [4, 7, 8]]);
    // All counter-clockwise seen from +Z.
    for t in &s.mesh.triangles {
        assert!(face_normal(&s, *t).z > 0.0, "{t:?}");
    }
    assert!(s.mesh.normals.iter().all(|n| close(*n, Vec3::Z, 1e-6)));
}

#[test]
fn cameras_from_nodes() {
    let dir = scratch("camera");
    let (b, pos) = single_triangle();
    let r = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = json!([
        {"mesh": 0},
        {"name": "camnode", "camera": 0, "translation": [0.0, 1.0, 5.0]},
        {"name": "second", "camera": 1, "translation": [3.0, 0.0, 0.0], "rotation": [0.0, r, 0.0, r]},
        {"name": "ortho", "camera": 2}
    ]);
    let meshes = json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]);
    let mut doc = b.doc(None, &[0, 1, 2, 3], nodes, meshes);
    doc["cameras"] = json!([
        {"name": "Cam1", "type": "perspective",
         "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 100.0, "aspectRatio": 1.5}},
        {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}},
        {"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}
    ]);
    let s = import_ok(&write_glb(&dir, "cams.glb", &doc, &b.bytes));
    assert_eq!(s.cameras.len(), 2, "{:?}", s.cameras);
    let c = &s.cameras[0];
    assert_eq!(c.name, "Cam1");
    assert!(!c.is_default);
    assert!(close(c.eye(), Vec3::new(0.0, 1.0, 5.0), 1e-6));
    assert!(close(c.forward(), -Vec3::Z, 1e-6));
    assert!((c.yfov_rad - 0.8).abs() < 1e-7 && (c.aspect - 1.5).abs() < 1e-7);
    assert_eq!((c.znear, c.zfar), (0.1, Some(100.0)));
    assert_eq!((c.width, c.height), (640, 427));
    // A point 5 units in front of the camera projects to the image centre.
    let clip = c.clip_from_world() * Vec4::new(0.0, 1.0, 0.0, 1.0);
    assert!((clip.x / clip.w).abs() < 1e-6 && (clip.y / clip.w).abs() < 1e-6);
    assert!(
        c.view_from_world()
            .transform_point3(Vec3::new(0.0, 1.0, 0.0))
            .z
            < 0.0
    );

    let c = &s.cameras[1];
    assert_eq!(c.name, "second"); // no camera name: the node's
    assert!(close(c.eye(), Vec3::new(3.0, 0.0, 0.0), 1e-6));
    // Rotated 90° about +Y: −Z turns into −X.
    assert!(close(c.forward(), -Vec3::X, 1e-6));
    assert_eq!(c.zfar, None);
    assert_eq!((c.width, c.height), (640, 480)); // no aspect: 640/480
    assert!(
        s.warnings.iter().any(|w| w.contains("orthographic")),
        "{:?}",
        s.warnings
    );

    // Only an orthographic camera: skipped, and the default camera is added.
    doc["scenes"] = json!([{"nodes": [0, 3]}]);
    let s = import_ok(&write_glb(&dir, "ortho.glb", &doc, &b.bytes));
    assert_eq!(s.cameras.len(), 1);
    assert!(s.cameras[0].is_default);
}

#[test]
fn orbit_camera_geometry() {
    let bounds = scene::Bounds {
        min: Vec3::new(1.0, 1.0, 1.0),
        max: Vec3::new(3.0, 5.0, 1.0),
    };
    let c = scene::orbit_camera(&bounds, 90.0, 30.0, 2.0, 800, 400);
    let d = c.eye() - bounds.centre();
    assert!((d.length() - 2.0 * bounds.radius()).abs() < 1e-5);
    let (s, co) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
    assert!(close(d.normalize(), Vec3::new(co, s, 0.0), 1e-6), "{d:?}");
    assert!(close(c.forward(), -d.normalize(), 1e-6));
    assert_eq!((c.width, c.height), (800, 400));
    assert!((c.aspect - 2.0).abs() < 1e-7);
    assert!(!c.is_default);
    // Up stays in the vertical plane containing the view direction: no roll.
    let right = c.world_from_camera.x_axis.truncate();
    assert!(right.y.abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Buffers and URIs

fn external_doc(b: &Bin, pos: usize, uri: &str) -> Value {
    b.doc(
        Some(uri),
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
    )
}

#[test]
fn data_uri_buffer() {
    let dir = scratch("data_uri");
    let (b, pos) = single_triangle();
    for prefix in [
        "data:application/octet-stream;base64,",
        "data:application/gltf-buffer;base64,",
    ] {
        let uri = format!(
            "{prefix}{}",
            base64::engine::general_purpose::STANDARD.encode(&b.bytes)
        );
        let s = import_ok(&write_json(&dir, "data.gltf", &external_doc(&b, pos, &uri)));
        assert_eq!(s.mesh.positions[1], Vec3::X);
        assert_eq!(s.mesh.triangles, vec![[0, 1, 2]]);
    }
    let bad = external_doc(&b, pos, "data:application/octet-stream;base64,@@@@");
    let path = write_json(&dir, "bad_data.gltf", &bad);
    assert!(matches!(import_err(&path), ImportError::BadDataUri { .. }));
}

#[test]
fn external_bin_beside_the_file() {
    let dir = scratch("external");
    let (b, pos) = single_triangle();
    write(&dir, "tri.bin", &b.bytes);
    let s = import_ok(&write_json(
        &dir,
        "tri.gltf",
        &external_doc(&b, pos, "tri.bin"),
    ));
    assert_eq!(s.mesh.triangles.len(), 1);
    // Percent-encoded names and subfolders resolve inside the folder.
    write(&dir, "sub/my data.bin", &b.bytes);
    let s = import_ok(&write_json(
        &dir,
        "tri2.gltf",
        &external_doc(&b, pos, "sub/./my%20data.bin"),
    ));
    assert_eq!(s.mesh.positions[2], Vec3::Y);
    let s = import_ok(&write_json(
        &dir,
        "tri3.gltf",
        &external_doc(&b, pos, "sub/../sub/my%20data.bin"),
    ));
    assert_eq!(s.mesh.positions.len(), 3);
}

#[test]
fn buffer_outside_the_folder_is_refused() {
    let base = scratch("outside");
    let (b, pos) = single_triangle();
    // The outside file exists and holds valid data, so only the path check can refuse it.
    write(&base, "outside.bin", &b.bytes);
    let dir = base.join("scene");
    for (name, uri) in [
        ("up.gltf", "../outside.bin"),
        ("up2.gltf", "sub/../../outside.bin"),
        ("up3.gltf", "%2E%2E/outside.bin"),
    ] {
        let path = write_json(&dir, name, &external_doc(&b, pos, uri));
        match import_err(&path) {
            ImportError::BufferUriOutsideFolder { uri: u, .. } => assert_eq!(u, uri),
            other => panic!("{uri}: {other:?}"),
        }
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(base.join("outside.bin"), dir.join("link.bin")).unwrap();
        let path = write_json(&dir, "link.gltf", &external_doc(&b, pos, "link.bin"));
        assert!(matches!(
            import_err(&path),
            ImportError::BufferUriOutsideFolder { .. }
        ));
    }
}

#[test]
fn absolute_and_foreign_uris_are_refused() {
    let dir = scratch("absolute");
    let (b, pos) = single_triangle();
    type Check = fn(&ImportError) -> bool;
    let cases: [(&str, Check); 6] = [
        ("/etc/passwd", |e| {
            matches!(e, ImportError::AbsoluteUri { .. })
        }),
        ("%2Fetc%2Fpasswd", |e| {
            matches!(e, ImportError::AbsoluteUri { .. })
        }),
        ("C:\\Windows\\x.bin", |e| {
            matches!(e, ImportError::AbsoluteUri { .. })
        }),
        ("\\\\server\\share\\x.bin", |e| {
            matches!(e, ImportError::AbsoluteUri { .. })
        }),
        (
            "file:///etc/passwd",
            |e| matches!(e, ImportError::UnsupportedUriScheme { scheme, .. } if scheme == "file"),
        ),
        (
            "http://example.com/x.bin",
            |e| matches!(e, ImportError::UnsupportedUriScheme { scheme, .. } if scheme == "http"),
        ),
    ];
    for (i, (uri, check)) in cases.iter().enumerate() {
        let path = write_json(&dir, &format!("abs{i}.gltf"), &external_doc(&b, pos, uri));
        let e = import_err(&path);
        assert!(check(&e), "{uri}: {e:?}");
    }
}

#[test]
fn missing_and_short_buffers() {
    let dir = scratch("missing");
    let (b, pos) = single_triangle();
    let path = write_json(&dir, "missing.gltf", &external_doc(&b, pos, "nothere.bin"));
    match import_err(&path) {
        ImportError::MissingBuffer { uri, buffer, .. } => {
            assert_eq!((uri.as_str(), buffer), ("nothere.bin", 0))
        }
        other => panic!("{other:?}"),
    }
    // A .gltf buffer without uri has no BIN chunk to use.
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
    );
    let path = write_json(&dir, "nouri.gltf", &doc);
    assert!(matches!(
        import_err(&path),
        ImportError::MissingBuffer { .. }
    ));
    // The file is shorter than the declared byteLength.
    write(&dir, "short.bin", &b.bytes[..20]);
    let path = write_json(&dir, "short.gltf", &external_doc(&b, pos, "short.bin"));
    match import_err(&path) {
        ImportError::BufferTooShort {
            declared, actual, ..
        } => {
            assert_eq!((declared, actual), (36, 20))
        }
        other => panic!("{other:?}"),
    }
    // GLB whose BIN chunk is shorter than the buffer's byteLength.
    let mut doc = external_doc(&b, pos, "x");
    doc["buffers"] = json!([{"byteLength": 400}]);
    let path = write_glb(&dir, "shortbin.glb", &doc, &b.bytes);
    assert!(matches!(
        import_err(&path),
        ImportError::BufferTooShort { .. }
    ));
}

// ---------------------------------------------------------------------------------------------
// Containers

#[test]
fn truncated_and_lying_glb_containers() {
    let dir = scratch("container");
    let bunny = std::fs::read(Path::new(ASSETS).join("bunny.glb")).unwrap();

    let path = write(&dir, "half.glb", &bunny[..bunny.len() / 2]);
    assert!(matches!(
        import_err(&path),
        ImportError::Truncated { .. } | ImportError::ChunkLength { .. }
    ));
    // Cut, with the header's total length patched to agree: the BIN chunk length now lies.
    let mut cut = bunny[..bunny.len() / 2].to_vec();
    let n = cut.len() as u32;
    cut[8..12].copy_from_slice(&n.to_le_bytes());
    let path = write(&dir, "half_patched.glb", &cut);
    assert!(matches!(
        import_err(&path),
        ImportError::ChunkLength { chunk: 1, .. }
    ));

    let path = write(&dir, "header.glb", &bunny[..10]);
    assert!(matches!(import_err(&path), ImportError::Truncated { .. }));

    let mut wrong = bunny.clone();
    wrong[..4].copy_from_slice(b"glTX");
    let path = write(&dir, "magic.glb", &wrong);
    assert!(matches!(import_err(&path), ImportError::NotGltf { .. }));

    let mut long = bunny.clone();
    long[12..16].copy_from_slice(&(bunny.len() as u32 + 100).to_le_bytes());
    let path = write(&dir, "chunk.glb", &long);
    match import_err(&path) {
        ImportError::ChunkLength {
            chunk,
            declared,
            available,
            ..
        } => {
            assert_eq!(chunk, 0);
            assert_eq!(declared, bunny.len() as u64 + 100);
            assert_eq!(available, bunny.len() as u64 - 20);
        }
        other => panic!("{other:?}"),
    }

    let mut v1 = bunny.clone();
    v1[4..8].copy_from_slice(&1u32.to_le_bytes());
    let path = write(&dir, "v1.glb", &v1);
    assert!(matches!(
        import_err(&path),
        ImportError::GlbVersion { version: 1, .. }
    ));

    let path = write(&dir, "empty.glb", &[]);
    assert!(matches!(import_err(&path), ImportError::NotGltf { .. }));
    let path = write(&dir, "text.gltf", b"hello");
    assert!(matches!(import_err(&path), ImportError::NotGltf { .. }));
    let path = write(&dir, "broken.gltf", b"{\"asset\": ");
    assert!(matches!(import_err(&path), ImportError::Json { .. }));
    let path = write(&dir, "noasset.gltf", b"{}");
    assert!(matches!(import_err(&path), ImportError::Json { .. }));
    let path = dir.join("does_not_exist.glb");
    assert!(matches!(scene::import(&path), Err(ImportError::Io { .. })));
}

// ---------------------------------------------------------------------------------------------
// Accessors, indices, structure

#[test]
fn index_out_of_range() {
    let dir = scratch("index");
    let (mut b, pos) = single_triangle();
    let idx = b.indices_u32(&[0, 1, 3]);
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"name": "tri", "primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]),
    );
    let path = write_glb(&dir, "index.glb", &doc, &b.bytes);
    match import_err(&path) {
        ImportError::IndexOutOfRange {
            mesh,
            index,
            vertices,
            ..
        } => {
            assert_eq!((mesh.as_str(), index, vertices), ("tri", 3, 3))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn triangles_need_a_multiple_of_three_indices() {
    let dir = scratch("mod3");
    let (mut b, pos) = single_triangle();
    let idx = b.indices_u16(&[0, 1, 2, 0]);
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]),
    );
    let path = write_glb(&dir, "mod3.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Accessor { accessor, .. } if accessor == idx));
}

#[test]
fn points_only_is_no_triangles_and_points_are_skipped() {
    let dir = scratch("points");
    let (b, pos) = single_triangle();
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}, "mode": 0}]}]),
    );
    let path = write_glb(&dir, "points.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::NoTriangles { .. }));

    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [
            {"attributes": {"POSITION": pos}, "mode": 0},
            {"attributes": {"POSITION": pos}, "mode": 1},
            {"attributes": {"POSITION": pos}}
        ]}]),
    );
    let s = import_ok(&write_glb(&dir, "mixed.glb", &doc, &b.bytes));
    assert_eq!(s.skipped_primitives, 2);
    assert_eq!(s.parts.len(), 1);
    assert_eq!(s.parts[0].primitive, 2);
    assert_eq!(s.mesh.positions.len(), 3);
}

/// A document with one triangle whose POSITION accessor is replaced by `accessor`.
fn with_position_accessor(b: &Bin, pos: usize, accessor: Value) -> Value {
    let mut doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
    );
    doc["accessors"][pos] = accessor;
    doc
}

#[test]
fn bad_accessors_are_refused() {
    let dir = scratch("accessors");
    let (b, pos) = single_triangle();
    let minmax = json!({"min": [0, 0, 0], "max": [1, 1, 0]});
    let acc = |extra: Value| {
        let mut a = json!({"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"});
        for (k, v) in minmax
            .as_object()
            .unwrap()
            .iter()
            .chain(extra.as_object().unwrap())
        {
            a[k] = v.clone();
        }
        a
    };
    let cases = [
        ("count0", acc(json!({"count": 0}))),
        ("count_big", acc(json!({"count": 4}))),
        ("count_huge", acc(json!({"count": 4_294_967_295u64}))),
        ("offset", acc(json!({"byteOffset": 4}))),
        (
            "offset_huge",
            acc(json!({"byteOffset": 18_446_744_073_709_551_000u64})),
        ),
        ("type", acc(json!({"type": "VEC2"}))),
        ("component", acc(json!({"componentType": 5123}))),
    ];
    for (name, a) in cases {
        let path = write_glb(
            &dir,
            &format!("{name}.glb"),
            &with_position_accessor(&b, pos, a),
            &b.bytes,
        );
        match import_err(&path) {
            ImportError::Accessor { accessor, .. } => assert_eq!(accessor, pos, "{name}"),
            other => panic!("{name}: {other:?}"),
        }
    }
    // A buffer view running past its buffer, and a stride smaller than the element.
    let mut doc = with_position_accessor(&b, pos, acc(json!({})));
    doc["bufferViews"][0]["byteOffset"] = json!(8);
    let path = write_glb(&dir, "view.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Accessor { .. }));
    let mut doc = with_position_accessor(&b, pos, acc(json!({"count": 2})));
    doc["bufferViews"][0]["byteStride"] = json!(8);
    let path = write_glb(&dir, "stride.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Accessor { .. }));
    // A POSITION attribute pointing at an accessor that does not exist.
    let mut doc = with_position_accessor(&b, pos, acc(json!({})));
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99);
    let path = write_glb(&dir, "noacc.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Validation { .. }));
}

#[test]
fn sparse_accessors() {
    let dir = scratch("sparse");
    let mut b = Bin::default();
    let pos = b.vec3(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let sidx = b.view(&[2u8, 0, 0, 0], None);
    let svals: Vec<u8> = [0.0f32, 2.0, 0.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let sval = b.view(&svals, None);
    let mut doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
    );
    doc["accessors"][pos]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": sidx, "componentType": 5121},
        "values": {"bufferView": sval}
    });
    doc["accessors"][pos]["max"] = json!([1, 2, 0]);
    let s = import_ok(&write_glb(&dir, "sparse.glb", &doc, &b.bytes));
    assert_eq!(s.mesh.positions[2], Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(s.mesh.positions[1], Vec3::X);

    // Sparse without a bufferView: zeros, then the override.
    let mut d2 = doc.clone();
    d2["accessors"][pos]
        .as_object_mut()
        .unwrap()
        .remove("bufferView");
    let s = import_ok(&write_glb(&dir, "sparse_only.glb", &d2, &b.bytes));
    assert_eq!(
        s.mesh.positions,
        vec![Vec3::ZERO, Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0)]
    );

    for (name, patch) in [
        (
            "sparse_index",
            json!({"count": 1, "indices": {"bufferView": sidx, "byteOffset": 0, "componentType": 5125}, "values": {"bufferView": sval}}),
        ),
        (
            "sparse_count",
            json!({"count": 4, "indices": {"bufferView": sidx, "componentType": 5121}, "values": {"bufferView": sval}}),
        ),
        (
            "sparse_values",
            json!({"count": 1, "indices": {"bufferView": sidx, "componentType": 5121}, "values": {"bufferView": sval, "byteOffset": 4}}),
        ),
        (
            "sparse_zero",
            json!({"count": 0, "indices": {"bufferView": sidx, "componentType": 5121}, "values": {"bufferView": sval}}),
        ),
    ] {
        let mut d = doc.clone();
        d["accessors"][pos]["sparse"] = patch;
        if name == "sparse_index" {
            // Index 0x00000002 read as u32 is fine; make it out of range instead.
            d["bufferViews"][sidx]["byteLength"] = json!(4);
        }
        let mut bytes = b.bytes.clone();
        if name == "sparse_index" {
            let off = d["bufferViews"][sidx]["byteOffset"].as_u64().unwrap() as usize;
            bytes[off..off + 4].copy_from_slice(&7u32.to_le_bytes());
        }
        let path = write_glb(&dir, &format!("{name}.glb"), &d, &bytes);
        assert!(
            matches!(import_err(&path), ImportError::Accessor { .. }),
            "{name}"
        );
    }
}

#[test]
fn bad_normals_are_replaced_and_counted() {
    let dir = scratch("bad_normals");
    let mut b = Bin::default();
    let pos = b.vec3(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let nrm = b.vec3(&[[0.0, 0.0, 1.0], [f32::NAN, 0.0, 0.0], [0.0, 0.0, 0.0]]);
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}}]}]),
    );
    let s = import_ok(&write_glb(&dir, "nan.glb", &doc, &b.bytes));
    assert_eq!(s.normal_fallbacks, 2);
    assert_eq!(s.parts[0].normals, AttributeSource::Present);
    assert!(s.mesh.normals.iter().all(|n| close(*n, Vec3::Z, 1e-6)));
}

#[test]
fn scene_structure_errors() {
    let dir = scratch("structure");
    let (b, pos) = single_triangle();
    let meshes = json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]);
    // A cycle in the node hierarchy.
    let doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0, "children": [1]}, {"children": [0]}]),
        meshes.clone(),
    );
    let path = write_glb(&dir, "cycle.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Validation { .. }));
    // No scene at all.
    let mut doc = b.doc(None, &[0], json!([{"mesh": 0}]), meshes.clone());
    doc.as_object_mut().unwrap().remove("scenes");
    doc.as_object_mut().unwrap().remove("scene");
    let path = write_glb(&dir, "noscene.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::NoScene { .. }));
    // No default scene: scene 0 is used.
    let mut doc = b.doc(None, &[0], json!([{"mesh": 0}]), meshes.clone());
    doc.as_object_mut().unwrap().remove("scene");
    assert_eq!(
        import_ok(&write_glb(&dir, "scene0.glb", &doc, &b.bytes))
            .mesh
            .triangles
            .len(),
        1
    );
    // An empty scene has no triangles.
    let doc = b.doc(None, &[], json!([{"mesh": 0}]), meshes.clone());
    let path = write_glb(&dir, "empty_scene.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::NoTriangles { .. }));
    // A perspective camera object missing: refused by validation or skipped, never a panic.
    let mut doc = b.doc(
        None,
        &[0, 1],
        json!([{"mesh": 0}, {"camera": 0}]),
        meshes.clone(),
    );
    doc["cameras"] = json!([{"type": "perspective", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 2}}]);
    let path = write_glb(&dir, "cam.glb", &doc, &b.bytes);
    if let Ok(s) = scene::import(&path) {
        assert!(s.cameras[0].is_default);
    }
    // glTF 1.0 is refused.
    let mut doc = b.doc(None, &[0], json!([{"mesh": 0}]), meshes);
    doc["asset"]["version"] = json!("1.0");
    let path = write_glb(&dir, "v1.glb", &doc, &b.bytes);
    assert!(matches!(import_err(&path), ImportError::Validation { .. }));
}

// ---------------------------------------------------------------------------------------------
// Robustness: corrupted inputs return errors (or import), never panic.

/// Replaces the `k`-th number (in document order) of `v` with `new`; returns whether it did.
fn replace_nth_number(v: &mut Value, k: &mut usize, new: &Value) -> bool {
    match v {
        Value::Number(_) => {
            if *k == 0 {
                *v = new.clone();
                return true;
            }
            *k -= 1;
            false
        }
        Value::Array(a) => a.iter_mut().any(|x| replace_nth_number(x, k, new)),
        Value::Object(o) => o.values_mut().any(|x| replace_nth_number(x, k, new)),
        _ => false,
    }
}

#[test]
fn corrupted_inputs_never_panic() {
    let dir = scratch("fuzz");
    // Template: indexed, interleaved normals, uvs, a camera, two nodes.
    let mut b = Bin::default();
    let pos = b.vec3(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ]);
    let nrm = b.vec3(&[[0.0, 0.0, 1.0]; 4]);
    let uv = b.floats(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]], "VEC2");
    let idx = b.indices_u16(&[0, 1, 2, 2, 1, 3]);
    let mut doc = b.doc(
        None,
        &[0],
        json!([{"mesh": 0, "children": [1], "translation": [0, 1, 0]}, {"camera": 0, "translation": [0, 0, 3]}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv}, "indices": idx, "mode": 4}]}]),
    );
    doc["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}]);
    import_ok(&write_glb(&dir, "template.glb", &doc, &b.bytes));

    let mut numbers = 0;
    while replace_nth_number(&mut doc.clone(), &mut { numbers }, &json!(0)) {
        numbers += 1;
    }
    assert!(numbers > 40, "{numbers}");
    let values = [
        json!(0),
        json!(1),
        json!(3),
        json!(5),
        json!(7),
        json!(255),
        json!(65_536),
        json!(4_294_967_295u64),
        json!(18_446_744_073_709_551_615u64),
        json!(-1),
        json!(1e30),
    ];
    let path = dir.join("mutant.glb");
    let mut outcomes = [0usize; 2];
    for k in 0..numbers {
        for v in &values {
            let mut d = doc.clone();
            assert!(replace_nth_number(&mut d, &mut { k }, v));
            std::fs::write(&path, pack_glb(&d, &b.bytes)).unwrap();
            outcomes[scene::import(&path).is_ok() as usize] += 1;
        }
    }
    // Byte-level corruption of the whole container (deterministic xorshift).
    let bytes = pack_glb(&doc, &b.bytes);
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for _ in 0..600 {
        let mut m = bytes.clone();
        for _ in 0..3 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let at = (state % m.len() as u64) as usize;
            m[at] = (state >> 32) as u8;
        }
        std::fs::write(&path, &m).unwrap();
        outcomes[scene::import(&path).is_ok() as usize] += 1;
    }
    // Every truncation length.
    for cut in 0..bytes.len() {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        assert!(scene::import(&path).is_err(), "cut at {cut}");
    }
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
}
