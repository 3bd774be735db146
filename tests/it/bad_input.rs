//! The bad-input corpus (`tests/bad_input/`, one case per file, see its README.md) run through the
//! real `glint` binary. For every case the binary must fail cleanly: exit code 1 (an error: not 0,
//! not 101, not killed by a signal), exactly one non-empty line on stderr that starts with `glint:
//! error:` and holds the case's keywords (the cause), nothing on stdout, and no output file or
//! directory (`--out` / `--to` point into a fresh, empty temporary folder that must stay empty).
//! Every run is made under an address-space limit (`ulimit -v`, [`MEMORY_LIMIT_KIB`]), so a loader
//! that allocated for an enormous declared image size before refusing it would abort instead of
//! passing.
//!
//! The corpus files are committed; [`corpus`] is the script that made them (run `cargo test --test
//! bad_input -- --ignored write_corpus` to rewrite them) and `corpus_matches_its_generator` checks
//! that the committed bytes are still what it makes. Each file is an unbroken base ([`base_glb`],
//! [`base_exr`], …) with one defect; `unbroken_bases_are_accepted` checks that the bases themselves
//! pass, so a case fails because of its defect only.

use crate::common;

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use base64::Engine as _;
use common::pack_glb;
use serde_json::{Value, json};

/// Address-space limit for every run of a bad case: far below the tens of gigabytes an enormous
/// declared image would need, far above what glint needs to refuse a file.
const MEMORY_LIMIT_KIB: u64 = 3 * 1024 * 1024;

/// The environment map used with scene cases, and the scene used with environment cases.
const GOOD_ENV: &str = "hdr/small/studio_512.exr";
const GOOD_SCENE: &str = "glb/teapot.glb";

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_input")
}

/// One corpus file and the words its error line must contain. What the binary is asked to do with
/// it follows from the file name's prefix (see [`Kind`]).
struct Case {
    file: &'static str,
    keywords: &'static [&'static str],
}

const fn case(file: &'static str, keywords: &'static [&'static str]) -> Case {
    Case { file, keywords }
}

/// Every file of the corpus. A test fails if a file has no entry here or an entry has no file.
const CASES: &[Case] = &[
    // glTF scenes: `glint bake CASE --env GOOD_ENV --out OUT/bake`.
    case("scene_empty.glb", &["scene_empty.glb", "not a glTF file"]),
    case("scene_truncated.glb", &["truncated", "GLB container"]),
    case("scene_wrong_magic.glb", &["no GLB magic"]),
    case("scene_glb_version_1.glb", &["GLB container version 1"]),
    case(
        "scene_json_chunk_length_lies.glb",
        &["GLB chunk 0 declares 4294967280 bytes"],
    ),
    case(
        "scene_bin_chunk_length_lies.glb",
        &["GLB chunk 1 declares", "remain in the container"],
    ),
    case("scene_trailing_data.glb", &["trailing data"]),
    case(
        "scene_not_json.gltf",
        &["scene_not_json.gltf", "not a glTF file"],
    ),
    case("scene_broken_json.gltf", &["invalid glTF JSON", "EOF"]),
    case("scene_gltf_1_0.gltf", &["asset.version", "2.x only"]),
    case(
        "scene_buffer_uri_parent.gltf",
        &["../it/bad_input.rs", "outside the scene file's folder"],
    ),
    case(
        "scene_buffer_uri_absolute.gltf",
        &["/etc/passwd", "absolute path"],
    ),
    case(
        "scene_buffer_uri_file_scheme.gltf",
        &["file:///etc/passwd", "scheme"],
    ),
    case(
        "scene_buffer_missing.gltf",
        &["scene_buffer_missing.bin", "not found"],
    ),
    case(
        "scene_required_draco.gltf",
        &["requires glTF extension KHR_draco_mesh_compression"],
    ),
    case(
        "scene_required_meshopt.gltf",
        &["requires glTF extension EXT_meshopt_compression"],
    ),
    case("scene_no_vertices.gltf", &["POSITION accessor has count 0"]),
    case(
        "scene_accessor_count_lies.gltf",
        &["1000 elements", "do not fit in buffer view 0"],
    ),
    case("scene_node_cycle.gltf", &["node hierarchy has a cycle"]),
    case(
        "scene_instancing_bomb.gltf",
        &["scene too large", "node instances"],
    ),
    case("scene_points_only.gltf", &["contains no triangles"]),
    case("scene_lines_only.gltf", &["contains no triangles"]),
    case(
        "scene_index_out_of_range.gltf",
        &["vertex index 9 is out of range", "3 vertices"],
    ),
    // Environment maps: `glint bake GOOD_SCENE --env CASE --out OUT/bake`.
    case(
        "env_empty.exr",
        &["env_empty.exr", "invalid OpenEXR header"],
    ),
    case("env_empty.hdr", &["env_empty.hdr", "signature"]),
    case("env_not_exr.exr", &["invalid OpenEXR header"]),
    case(
        "env_no_rgb.exr",
        &["no layer with R, G, B", "channels found: [Z]"],
    ),
    case("env_truncated.exr", &["invalid OpenEXR pixel data"]),
    case("env_truncated.hdr", &["invalid Radiance pixel data"]),
    case("env_huge_side.exr", &["too large", "100000x100000"]),
    case("env_huge_texels.exr", &["too large", "32768x16384"]),
    case("env_huge_side.hdr", &["too large", "100000x100000"]),
    case("env_huge_texels.hdr", &["too large", "32768x16384"]),
    // Stroke files: `glint fit BAKE --strokes CASE --out OUT/material.json` (BAKE: the teapot).
    case(
        "strokes_empty.json",
        &["strokes_empty.json", "not valid JSON", "EOF"],
    ),
    case("strokes_malformed.json", &["not valid JSON", "EOF"]),
    case(
        "strokes_wrong_type.json",
        &["invalid type", "expected a sequence"],
    ),
    case("strokes_unknown_field.json", &["unknown field `colour`"]),
    case(
        "strokes_unknown_camera.json",
        &["'no-such-camera'", "no such camera"],
    ),
    case(
        "strokes_camera_index_out_of_range.json",
        &["#7", "no such camera"],
    ),
    case("strokes_zero_image_size.json", &["image_size 0x480"]),
    case(
        "strokes_huge_image_size.json",
        &["image_size 100000x100000", "outside"],
    ),
    // Materials: `glint export CASE --to OUT/export` and `glint render BAKE --material CASE --out
    // OUT/image.png`.
    case(
        "material_version_2.json",
        &["material_version_2.json", "material format version 2"],
    ),
    case(
        "material_malformed.json",
        &["material is not valid JSON", "EOF"],
    ),
    case("material_wrong_model.json", &["material model 'ggx'"]),
    case(
        "material_negative_coefficient.json",
        &["coefficient is negative"],
    ),
    case("material_coefficient_count.json", &["needs 24 centres"]),
];

/// What the binary is asked to do with a case, from the file name's prefix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Scene,
    Env,
    Strokes,
    Material,
}

fn kind_of(file: &str) -> Kind {
    match file.split('_').next() {
        Some("scene") => Kind::Scene,
        Some("env") => Kind::Env,
        Some("strokes") => Kind::Strokes,
        Some("material") => Kind::Material,
        _ => panic!(
            "corpus file {file}: the name must start with scene_, env_, strokes_ or material_"
        ),
    }
}

// ---------------------------------------------------------------------------------------------
// The generator: unbroken bases, and one defect per case

/// A glTF document with one mesh of one primitive over a buffer of `bin` (its `uri`, if any):
/// POSITION (`positions`), optional u16 indices, `mode`.
fn mesh_doc(
    positions: &[[f32; 3]],
    indices: Option<&[u16]>,
    mode: u32,
    uri: Option<String>,
) -> (Value, Vec<u8>) {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let pos_len = bin.len();
    let mut views = vec![json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_len})];
    let lo: Vec<f32> = (0..3)
        .map(|k| positions.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min))
        .collect();
    let hi: Vec<f32> = (0..3)
        .map(|k| {
            positions
                .iter()
                .map(|p| p[k])
                .fold(f32::NEG_INFINITY, f32::max)
        })
        .collect();
    let position = json!({"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi});
    let mut accessors = vec![position];
    let mut primitive = json!({"attributes": {"POSITION": 0}, "mode": mode});
    if let Some(idx) = indices {
        let data: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        views.push(json!({"buffer": 0, "byteOffset": pos_len, "byteLength": data.len()}));
        accessors.push(
            json!({"bufferView": 1, "componentType": 5123, "count": idx.len(), "type": "SCALAR"}),
        );
        primitive["indices"] = json!(1);
        bin.extend_from_slice(&data);
    }
    let mut buffer = json!({"byteLength": bin.len()});
    if let Some(uri) = uri {
        buffer["uri"] = json!(uri);
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": "glint tests/bad_input.rs"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "tetrahedron"}],
        "meshes": [{"name": "tetrahedron", "primitives": [primitive]}],
        "buffers": [buffer],
        "bufferViews": views,
        "accessors": accessors,
    });
    (doc, bin)
}

const TETRA: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
const TETRA_INDICES: [u16; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

fn data_uri(bin: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bin)
    )
}

/// The unbroken GLB base: a tetrahedron, positions and indices in the BIN chunk.
fn base_glb() -> Vec<u8> {
    let (doc, bin) = mesh_doc(&TETRA, Some(&TETRA_INDICES), 4, None);
    pack_glb(&doc, &bin)
}

/// The unbroken .gltf base: the tetrahedron with its buffer in a `data:` URI.
fn base_gltf_doc() -> Value {
    serde_json::from_slice(&gltf_from_mesh(&TETRA, Some(&TETRA_INDICES), 4)).unwrap()
}

fn gltf_text(doc: &Value) -> Vec<u8> {
    let mut text = serde_json::to_vec_pretty(doc).unwrap();
    text.push(b'\n');
    text
}

/// The tetrahedron's GLB with its buffer in a file at `uri` instead of a BIN chunk (as .gltf text).
fn gltf_with_uri(uri: &str) -> Vec<u8> {
    let (doc, _) = mesh_doc(&TETRA, Some(&TETRA_INDICES), 4, Some(uri.to_string()));
    gltf_text(&doc)
}

fn gltf_from_mesh(positions: &[[f32; 3]], indices: Option<&[u16]>, mode: u32) -> Vec<u8> {
    let (mut doc, bin) = mesh_doc(positions, indices, mode, None);
    doc["buffers"][0]["uri"] = json!(data_uri(&bin));
    gltf_text(&doc)
}

/// An RGB f32 EXR of w × h (uncompressed, so a cut file is cut in its pixel data).
fn exr_rgb(w: usize, h: usize) -> Vec<u8> {
    use exr::prelude::*;
    let px = SpecificChannels::rgb(|pos: Vec2<usize>| {
        (pos.x() as f32 / 8.0, pos.y() as f32 / 8.0, 0.5f32)
    });
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("main"),
        Encoding::UNCOMPRESSED,
        px,
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .unwrap();
    out.into_inner()
}

/// The unbroken EXR base: 64 × 32 RGB.
fn base_exr() -> Vec<u8> {
    exr_rgb(64, 32)
}

/// An EXR whose only channel is `Z` (a depth image).
fn exr_depth_only() -> Vec<u8> {
    use exr::prelude::*;
    let (w, h) = (8, 4);
    let channel = AnyChannel::new(
        "Z",
        FlatSamples::F32((0..w * h).map(|i| i as f32).collect()),
    );
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("depth"),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .unwrap();
    out.into_inner()
}

/// A 4 × 4 EXR whose header's dataWindow is patched to declare `w` × `h` (the pixel data stays 4 ×
/// 4).
fn exr_declaring(w: i32, h: i32) -> Vec<u8> {
    let mut bytes = exr_rgb(4, 4);
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|k| k == key)
        .expect("dataWindow attribute")
        + key.len();
    assert_eq!(&bytes[at..at + 4], &16i32.to_le_bytes()); // attribute size
    let bx = at + 4; // xMin, yMin, xMax, yMax
    bytes[bx + 8..bx + 12].copy_from_slice(&(w - 1).to_le_bytes());
    bytes[bx + 12..bx + 16].copy_from_slice(&(h - 1).to_le_bytes());
    bytes
}

fn hdr_header(w: u32, h: u32) -> Vec<u8> {
    format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes()
}

/// The unbroken Radiance base: 64 × 32, flat (not run-length encoded) RGBE scanlines.
fn base_hdr() -> Vec<u8> {
    let (w, h) = (64u32, 32u32);
    let mut out = hdr_header(w, h);
    for y in 0..h {
        for x in 0..w {
            // Mantissas below 128 are legal; exponent 128 means a scale of 2^0 / 256.
            out.extend_from_slice(&[(x * 2) as u8 + 1, (y * 4) as u8 + 1, 100, 129]);
        }
    }
    out
}

/// The unbroken stroke file: a highlight painted in the default view of the teapot.
fn base_strokes() -> Value {
    json!({"view": "default", "image_size": [640, 480], "keep_weight": 0.1, "strokes": [
        {"points": [[300, 200], [340, 220]], "mode": "paint", "color": [2, 2, 2], "radius": 20, "kappa": 0.05}]})
}

/// The unbroken material: isotropic, 24 lobes.
fn base_material() -> Value {
    use glint::sphere::{LobeLayout, LobeSet, srbf};
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
    )
    .unwrap();
    let c: Vec<f64> = (0..lobes.len())
        .map(|j| if j % 5 == 0 { 0.25 } else { 0.0 })
        .collect();
    let m = glint::fit::material::Material::new(
        &lobes,
        srbf::PAPER_SIGMA,
        [c.clone(), c.clone(), c],
        [0.5; 3],
        0.04,
        Default::default(),
    );
    serde_json::from_str(&m.to_json()).unwrap()
}

fn json_text(v: &Value) -> Vec<u8> {
    let mut text = serde_json::to_vec_pretty(v).unwrap();
    text.push(b'\n');
    text
}

/// The corpus: (file name, bytes), one case per file.
fn corpus() -> Vec<(&'static str, Vec<u8>)> {
    let mut files: Vec<(&'static str, Vec<u8>)> = Vec::new();
    let mut add = |name: &'static str, bytes: Vec<u8>| files.push((name, bytes));

    // --- scenes
    let glb = base_glb();
    add("scene_empty.glb", Vec::new());
    add("scene_truncated.glb", glb[..glb.len() / 2].to_vec());
    let mut b = glb.clone();
    b[..4].copy_from_slice(b"glTX");
    add("scene_wrong_magic.glb", b);
    let mut b = glb.clone();
    b[4..8].copy_from_slice(&1u32.to_le_bytes());
    add("scene_glb_version_1.glb", b);
    let mut b = glb.clone();
    b[12..16].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    add("scene_json_chunk_length_lies.glb", b);
    let mut b = glb.clone();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let bin_header = 20 + json_len;
    let bin_len = u32::from_le_bytes(glb[bin_header..bin_header + 4].try_into().unwrap());
    b[bin_header..bin_header + 4].copy_from_slice(&(bin_len + 64).to_le_bytes());
    add("scene_bin_chunk_length_lies.glb", b);
    let mut b = glb.clone();
    b.extend_from_slice(&[0; 8]);
    add("scene_trailing_data.glb", b);
    add(
        "scene_not_json.gltf",
        b"This is not JSON, let alone glTF.\n".to_vec(),
    );
    let text = gltf_text(&base_gltf_doc());
    add(
        "scene_broken_json.gltf",
        text[..text.len() * 2 / 3].to_vec(),
    );
    let mut doc = base_gltf_doc();
    doc["asset"]["version"] = json!("1.0");
    add("scene_gltf_1_0.gltf", gltf_text(&doc));
    // A file that exists outside the scene's folder (tests/it/bad_input.rs): refused before it is
    // opened.
    add(
        "scene_buffer_uri_parent.gltf",
        gltf_with_uri("../it/bad_input.rs"),
    );
    add(
        "scene_buffer_uri_absolute.gltf",
        gltf_with_uri("/etc/passwd"),
    );
    add(
        "scene_buffer_uri_file_scheme.gltf",
        gltf_with_uri("file:///etc/passwd"),
    );
    add(
        "scene_buffer_missing.gltf",
        gltf_with_uri("scene_buffer_missing.bin"),
    );
    for (name, ext) in [
        ("scene_required_draco.gltf", "KHR_draco_mesh_compression"),
        ("scene_required_meshopt.gltf", "EXT_meshopt_compression"),
    ] {
        let mut doc = base_gltf_doc();
        doc["extensionsUsed"] = json!([ext]);
        doc["extensionsRequired"] = json!([ext]);
        add(name, gltf_text(&doc));
    }
    // A mesh with no vertices: its POSITION accessor declares a count of 0.
    let (mut doc, bin) = mesh_doc(&TETRA, None, 4, None);
    doc["buffers"][0]["uri"] = json!(data_uri(&bin));
    doc["accessors"][0]["count"] = json!(0);
    add("scene_no_vertices.gltf", gltf_text(&doc));
    // An accessor that declares far more vertices than its buffer view holds.
    let mut doc = base_gltf_doc();
    doc["accessors"][0]["count"] = json!(1000);
    add("scene_accessor_count_lies.gltf", gltf_text(&doc));
    // A node that is its own child, and a node graph that expands to 2^40 instances.
    let mut doc = base_gltf_doc();
    doc["nodes"][0]["children"] = json!([0]);
    add("scene_node_cycle.gltf", gltf_text(&doc));
    let mut doc = base_gltf_doc();
    let mut nodes: Vec<Value> = (0..40)
        .map(|i| json!({"children": [i + 1, i + 1]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    doc["nodes"] = json!(nodes);
    add("scene_instancing_bomb.gltf", gltf_text(&doc));
    add("scene_points_only.gltf", gltf_from_mesh(&TETRA, None, 0));
    add(
        "scene_lines_only.gltf",
        gltf_from_mesh(&TETRA, Some(&[0, 1, 1, 2, 2, 3]), 1),
    );
    add(
        "scene_index_out_of_range.gltf",
        gltf_from_mesh(&TETRA[..3], Some(&[0, 1, 9]), 4),
    );

    // --- environment maps
    add("env_empty.exr", Vec::new());
    add("env_empty.hdr", Vec::new());
    add("env_not_exr.exr", base_hdr());
    add("env_no_rgb.exr", exr_depth_only());
    let exr = base_exr();
    add("env_truncated.exr", exr[..exr.len() * 3 / 5].to_vec());
    let hdr = base_hdr();
    add("env_truncated.hdr", hdr[..hdr.len() * 3 / 5].to_vec());
    add("env_huge_side.exr", exr_declaring(100_000, 100_000));
    add("env_huge_texels.exr", exr_declaring(32768, 16384));
    add("env_huge_side.hdr", hdr_header(100_000, 100_000));
    add("env_huge_texels.hdr", hdr_header(32768, 16384));

    // --- strokes
    add("strokes_empty.json", Vec::new());
    let text = json_text(&base_strokes());
    add("strokes_malformed.json", text[..text.len() / 2].to_vec());
    let mut s = base_strokes();
    s["strokes"] = json!("paint a highlight here");
    add("strokes_wrong_type.json", json_text(&s));
    let mut s = base_strokes();
    s["strokes"][0]["colour"] = s["strokes"][0]["color"].take();
    s["strokes"][0].as_object_mut().unwrap().remove("color");
    add("strokes_unknown_field.json", json_text(&s));
    let mut s = base_strokes();
    s["view"] = json!("no-such-camera");
    add("strokes_unknown_camera.json", json_text(&s));
    let mut s = base_strokes();
    s["view"] = json!(7);
    add("strokes_camera_index_out_of_range.json", json_text(&s));
    let mut s = base_strokes();
    s["image_size"] = json!([0, 480]);
    add("strokes_zero_image_size.json", json_text(&s));
    let mut s = base_strokes();
    s["image_size"] = json!([100_000, 100_000]);
    add("strokes_huge_image_size.json", json_text(&s));

    // --- materials
    let mut m = base_material();
    m["version"] = json!(2);
    add("material_version_2.json", json_text(&m));
    let text = json_text(&base_material());
    add("material_malformed.json", text[..text.len() / 2].to_vec());
    let mut m = base_material();
    m["model"] = json!("ggx");
    add("material_wrong_model.json", json_text(&m));
    let mut m = base_material();
    m["coefficients"][1][3] = json!(-0.5);
    add("material_negative_coefficient.json", json_text(&m));
    let mut m = base_material();
    m["coefficients"][2].as_array_mut().unwrap().pop();
    add("material_coefficient_count.json", json_text(&m));
    files
}

/// Writes the corpus from [`corpus`] into a temporary folder and prints the command that copies it
/// over the committed one (run it after changing the generator; tests write nowhere else).
#[test]
#[ignore = "run by hand: cargo test --test it bad_input:: -- --ignored --nocapture write_corpus"]
fn write_corpus() {
    let dir = common::temp_dir("bad-input-corpus");
    for (name, bytes) in corpus() {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    println!("cp {}/* {}/", dir.display(), corpus_dir().display());
}

#[test]
fn corpus_matches_its_generator() {
    let dir = corpus_dir();
    let generated = corpus();
    for (name, bytes) in &generated {
        let on_disk = std::fs::read(dir.join(name))
            .unwrap_or_else(|e| panic!("{name}: {e} (run the write_corpus generator)"));
        assert!(
            &on_disk == bytes,
            "{name}: the committed file differs from what the generator makes (run write_corpus)"
        );
    }
    // Every file has a case, every case has a file, one case per file.
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "README.md")
        .collect();
    files.sort();
    let mut listed: Vec<String> = CASES.iter().map(|c| c.file.to_string()).collect();
    listed.sort();
    let before = listed.len();
    listed.dedup();
    assert_eq!(listed.len(), before, "a file is listed twice in CASES");
    assert_eq!(
        files, listed,
        "the files of tests/bad_input/ and CASES disagree"
    );
    for c in CASES {
        kind_of(c.file);
        assert!(
            !c.keywords.is_empty() && c.keywords.iter().all(|k| !k.trim().is_empty()),
            "{}: no keyword",
            c.file
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Running the binary

/// Runs `glint args` under the address-space limit.
fn glint_limited(args: &[&std::ffi::OsStr]) -> Output {
    let exe = env!("CARGO_BIN_EXE_glint");
    let mut cmd = if cfg!(unix) {
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg(format!(
                "ulimit -v {MEMORY_LIMIT_KIB} && exec \"$0\" \"$@\""
            ))
            .arg(exe)
            .env("GLINT_CACHE_DIR", crate::common::energy_cache_dir());
        c
    } else {
        Command::new(exe)
    };
    cmd.args(args).output().expect("run glint")
}

fn glint(args: &[&str]) -> Output {
    run_glint!(args)
}

fn os<S: AsRef<std::ffi::OsStr> + ?Sized>(s: &S) -> &std::ffi::OsStr {
    s.as_ref()
}

/// A bake of the teapot (for stroke and material cases), made once per test process.
fn teapot_bake() -> &'static Path {
    static BAKE: OnceLock<PathBuf> = OnceLock::new();
    BAKE.get_or_init(|| {
        let dir = common::temp_dir("bad-input-bake");
        let out = dir.join("teapot.bake");
        let scene = common::assets().join(GOOD_SCENE);
        let env = common::assets().join("hdr/small/courtyard_512.exr");
        let o = glint(&[
            "bake",
            scene.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--resolution",
            "32",
            "--fit-size",
            "40x30",
        ]);
        assert!(
            o.status.success(),
            "bake of the teapot failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out
    })
}

/// Checks one run of a bad case; returns what is wrong with it (empty: nothing).
fn check_run(label: &str, o: &Output, keywords: &[&str], out_root: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let stdout = String::from_utf8_lossy(&o.stdout);
    if o.status.code() != Some(1) {
        problems.push(format!(
            "{label}: exit status {:?}, expected code 1 (stderr: {stderr:?})",
            o.status
        ));
    }
    let lines: Vec<&str> = stderr.lines().collect();
    if lines.len() != 1
        || !stderr.ends_with('\n')
        || !lines[0].starts_with("glint: error: ")
        || lines[0].trim() == "glint: error:"
    {
        problems.push(format!(
            "{label}: stderr is not one `glint: error: …` line: {stderr:?}"
        ));
    }
    for k in keywords {
        if !stderr.contains(k) {
            problems.push(format!("{label}: error line lacks {k:?}: {stderr:?}"));
        }
    }
    if !stdout.is_empty() {
        problems.push(format!("{label}: printed on stdout: {stdout:?}"));
    }
    let left: Vec<_> = std::fs::read_dir(out_root)
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    if !left.is_empty() {
        problems.push(format!("{label}: left output behind: {left:?}"));
    }
    problems
}

/// Runs every case of one kind; returns the problems and the error lines (for the report).
fn run_cases(kind: Kind) -> (Vec<String>, Vec<String>) {
    let dir = corpus_dir();
    let scratch = common::temp_dir(&format!("bad-input-{kind:?}"));
    let (mut problems, mut lines) = (Vec::new(), Vec::new());
    for c in CASES.iter().filter(|c| kind_of(c.file) == kind) {
        let input = dir.join(c.file);
        let mut runs: Vec<(String, Vec<PathBuf>, PathBuf)> = Vec::new(); // (label, argv, out root)
        let root = |what: &str| {
            let r = scratch.join(format!("{}-{what}", c.file));
            std::fs::create_dir_all(&r).unwrap();
            r
        };
        match kind {
            Kind::Scene => {
                let r = root("bake");
                let argv = vec![
                    "bake".into(),
                    input.clone(),
                    "--env".into(),
                    common::assets().join(GOOD_ENV),
                    "--out".into(),
                    r.join("bake"),
                ];
                runs.push((format!("{} (bake)", c.file), argv, r));
            }
            Kind::Env => {
                let r = root("bake");
                let argv = vec![
                    "bake".into(),
                    common::assets().join(GOOD_SCENE),
                    "--env".into(),
                    input.clone(),
                    "--out".into(),
                    r.join("bake"),
                ];
                runs.push((format!("{} (bake)", c.file), argv, r));
            }
            Kind::Strokes => {
                let r = root("fit");
                let argv = vec![
                    "fit".into(),
                    teapot_bake().to_path_buf(),
                    "--strokes".into(),
                    input.clone(),
                    "--out".into(),
                    r.join("material.json"),
                ];
                runs.push((format!("{} (fit)", c.file), argv, r));
            }
            Kind::Material => {
                let r = root("export");
                let argv = vec![
                    "export".into(),
                    input.clone(),
                    "--to".into(),
                    r.join("export"),
                ];
                runs.push((format!("{} (export)", c.file), argv, r));
                let r = root("render");
                let argv = vec![
                    "render".into(),
                    teapot_bake().to_path_buf(),
                    "--material".into(),
                    input.clone(),
                    "--size".into(),
                    "8x6".into(),
                    "--out".into(),
                    r.join("image.png"),
                ];
                runs.push((format!("{} (render)", c.file), argv, r));
            }
        }
        for (label, argv, r) in runs {
            let args: Vec<&std::ffi::OsStr> = argv.iter().map(os).collect();
            let o = glint_limited(&args);
            lines.push(format!(
                "{label}: exit {:?}: {}",
                o.status.code(),
                String::from_utf8_lossy(&o.stderr).trim_end()
            ));
            problems.extend(check_run(&label, &o, c.keywords, &r));
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
    (problems, lines)
}

fn assert_all_clean(kind: Kind) {
    let (problems, lines) = run_cases(kind);
    for l in &lines {
        println!("{l}");
    }
    assert!(
        problems.is_empty(),
        "{} problem(s):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn scene_cases_fail_cleanly() {
    assert_all_clean(Kind::Scene);
}

#[test]
fn env_cases_fail_cleanly() {
    assert_all_clean(Kind::Env);
}

#[test]
fn stroke_cases_fail_cleanly() {
    assert_all_clean(Kind::Strokes);
}

#[test]
fn material_cases_fail_cleanly() {
    assert_all_clean(Kind::Material);
}

/// The bases the cases are made from pass, so each case fails because of its one defect.
#[test]
fn unbroken_bases_are_accepted() {
    let dir = common::temp_dir("bad-input-bases");
    let ok = |label: &str, o: Output| {
        assert!(
            o.status.success(),
            "{label}: {}",
            String::from_utf8_lossy(&o.stderr)
        )
    };
    let teapot = common::assets().join(GOOD_SCENE);
    let env = common::assets().join(GOOD_ENV);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    for (name, bytes) in [
        ("base.glb", base_glb()),
        ("base.gltf", gltf_text(&base_gltf_doc())),
    ] {
        let p = write(name, &bytes);
        ok(name, glint(&["inspect", &s(&p), "--env", &s(&env)]));
    }
    // The missing-buffer case itself, with its buffer present beside it.
    let (_, bin) = mesh_doc(&TETRA, Some(&TETRA_INDICES), 4, None);
    write("scene_buffer_missing.bin", &bin);
    let p = write(
        "scene_buffer_missing.gltf",
        &std::fs::read(corpus_dir().join("scene_buffer_missing.gltf")).unwrap(),
    );
    ok(
        "scene_buffer_missing.gltf with its buffer",
        glint(&["inspect", &s(&p)]),
    );
    for (name, bytes) in [("base.exr", base_exr()), ("base.hdr", base_hdr())] {
        let p = write(name, &bytes);
        ok(name, glint(&["inspect", &s(&teapot), "--env", &s(&p)]));
    }
    let bake = teapot_bake();
    let strokes = write("strokes.json", &json_text(&base_strokes()));
    ok(
        "base strokes",
        glint(&[
            "fit",
            &s(bake),
            "--strokes",
            &s(&strokes),
            "--out",
            &s(&dir.join("fitted.json")),
        ]),
    );
    let material = write("material.json", &json_text(&base_material()));
    ok(
        "base material (export)",
        glint(&[
            "export",
            &s(&material),
            "--to",
            &s(&dir.join("export")),
            "--formats",
            "exr",
            "--table-resolution",
            "16",
        ]),
    );
    ok(
        "base material (render)",
        glint(&[
            "render",
            &s(bake),
            "--material",
            &s(&material),
            "--size",
            "8x6",
            "--out",
            &s(&dir.join("image.png")),
        ]),
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Bad arguments rather than bad files, checked the same way: files that do not exist (each error
/// reported once: the OS error must not be repeated), and a bake view that does not exist (refused
/// before baking, so no bake folder is left behind).
#[test]
fn bad_arguments_fail_cleanly() {
    let scratch = common::temp_dir("bad-input-args");
    let teapot = common::assets().join(GOOD_SCENE);
    let env = common::assets().join(GOOD_ENV);
    let material = corpus_dir().join("material_version_2.json"); // never read: the bake is missing
    let missing = scratch.join("missing");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let bake = teapot_bake();
    let cases: Vec<(&str, Vec<String>, &[&str])> = vec![
        (
            "missing scene",
            vec![
                "bake".into(),
                s(&missing.join("nowhere.glb")),
                "--env".into(),
                s(&env),
            ],
            &["nowhere.glb", "No such file"],
        ),
        (
            "missing env",
            vec![
                "bake".into(),
                s(&teapot),
                "--env".into(),
                s(&missing.join("nowhere.exr")),
            ],
            &["nowhere.exr", "No such file"],
        ),
        (
            "missing bake",
            vec![
                "fit".into(),
                s(&missing.join("nowhere.bake")),
                "--strokes".into(),
                s(&material),
            ],
            &["nowhere.bake", "No such file"],
        ),
        (
            "missing strokes",
            vec![
                "fit".into(),
                s(bake),
                "--strokes".into(),
                s(&missing.join("nowhere.json")),
            ],
            &["nowhere.json", "No such file"],
        ),
        (
            "missing material",
            vec!["export".into(), s(&missing.join("nowhere.json"))],
            &["nowhere.json", "No such file"],
        ),
        (
            "unknown bake camera",
            vec![
                "bake".into(),
                s(&teapot),
                "--env".into(),
                s(&env),
                "--camera".into(),
                "no-such-camera".into(),
            ],
            &["no camera named 'no-such-camera'"],
        ),
        (
            "bad fit size",
            vec![
                "bake".into(),
                s(&teapot),
                "--env".into(),
                s(&env),
                "--fit-size".into(),
                "0x0".into(),
            ],
            &["size 0x0 is outside"],
        ),
    ];
    let mut problems = Vec::new();
    for (label, mut argv, keywords) in cases {
        let root = scratch.join(label.replace(' ', "-"));
        std::fs::create_dir_all(&root).unwrap();
        argv.extend(match argv[0].as_str() {
            "bake" => vec!["--out".to_string(), s(&root.join("bake"))],
            "fit" => vec!["--out".to_string(), s(&root.join("material.json"))],
            _ => vec!["--to".to_string(), s(&root.join("export"))],
        });
        let args: Vec<&std::ffi::OsStr> = argv.iter().map(os).collect();
        let o = glint_limited(&args);
        let stderr = String::from_utf8_lossy(&o.stderr).to_string();
        println!("{label}: exit {:?}: {}", o.status.code(), stderr.trim_end());
        problems.extend(check_run(label, &o, keywords, &root));
        if stderr.matches("No such file").count() > 1 {
            problems.push(format!(
                "{label}: the cause is reported more than once: {stderr:?}"
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
    assert!(
        problems.is_empty(),
        "{} problem(s):\n{}",
        problems.len(),
        problems.join("\n")
    );
}
