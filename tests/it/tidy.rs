//! House rules that a reviewer would otherwise check by hand: every Rust module of the product
//! opens with a `//!` doc (its inputs, outputs and invariants), and the exporters crate depends on
//! nothing of the pipeline.

use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn every_module_opens_with_a_module_doc() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    rust_files(&root.join("exporters/src"), &mut files);
    assert!(files.len() > 10);
    let missing: Vec<_> = files
        .iter()
        .filter(|f| {
            let text = std::fs::read_to_string(f).unwrap();
            !text.trim_start().starts_with("//!")
        })
        .collect();
    assert!(missing.is_empty(), "modules without a //! doc: {missing:?}");
}

#[test]
fn exporters_know_nothing_of_the_pipeline() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("exporters/Cargo.toml")).unwrap();
    // No dependency line in any [*dependencies] table names the root package or points at it.
    let mut in_deps = false;
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line.contains("dependencies");
            continue;
        }
        if in_deps {
            let key = line.split('=').next().unwrap_or("").trim();
            assert!(
                key != "glint" && !line.contains("path = \"..\""),
                "exporters must not depend on glint: {line}"
            );
        }
    }
    let mut files = Vec::new();
    rust_files(&root.join("exporters/src"), &mut files);
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        assert!(!text.contains("glint::"), "{f:?} names the pipeline crate");
    }
}

#[test]
fn only_the_gpu_and_app_modules_know_wgpu() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    let offenders: Vec<_> = files
        .iter()
        .filter(|f| {
            let rel = f.strip_prefix(root.join("src")).unwrap();
            let allowed =
                rel.starts_with("gpu") || rel.starts_with("app") || rel == Path::new("main.rs");
            !allowed && std::fs::read_to_string(f).unwrap().contains("wgpu::")
        })
        .collect();
    assert!(
        offenders.is_empty(),
        "wgpu outside src/gpu and src/app: {offenders:?}"
    );
}
