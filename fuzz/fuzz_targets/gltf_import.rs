//! Fuzz target: arbitrary bytes as a glTF/GLB file → `glint::scene::import`. glint has no in-memory
//! entry point (import resolves buffers relative to the file), so the bytes are written to a file
//! in a private, otherwise empty folder per process; any URI the input names resolves there or is
//! refused.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("glint-fuzz-gltf-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        // The harness's own scratch folder, not the code under test: without it nothing can be
        // fuzzed.
        std::fs::create_dir_all(&dir).expect("scratch folder");
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    // The content decides the container, not the name; alternate the extension anyway.
    let name = if data.starts_with(b"glTF") { "scene.glb" } else { "scene.gltf" };
    let path = scratch().join(name);
    // Writing the input to the harness's scratch folder (not the code under test) must work.
    std::fs::write(&path, data).expect("write the input");
    if let Ok(scene) = glint::scene::import(&path) {
        // What every later stage relies on: indices in range, finite unit normals, finite
        // positions.
        let n = scene.mesh.positions.len();
        assert_eq!(scene.mesh.normals.len(), n);
        for t in &scene.mesh.triangles {
            assert!(t.iter().all(|&i| (i as usize) < n), "index out of range");
        }
        for (p, nrm) in scene.mesh.positions.iter().zip(&scene.mesh.normals) {
            assert!(p.is_finite(), "position {p}");
            assert!(nrm.is_finite() && (nrm.length() - 1.0).abs() < 1e-3, "normal {nrm}");
        }
        assert!(!scene.cameras.is_empty());
        let _ = glint::inspect::report(&scene, None).to_text();
    }
});
