//! Finds Intel Embree 3 (Debian's `libembree-dev`) for the bake's rays (`src/bake/embree.rs`).
//!
//! Where `libembree3.so` is found, the crate is built with `cfg(embree)` and links it; elsewhere it
//! builds without it and the rays go through obvhs (`src/bake/tracer.rs`), the same answers more
//! slowly. `GLINT_EMBREE=0` builds without Embree even where it is installed; `EMBREE_DIR` names a
//! folder to look in first (its `lib/`). After installing or removing Embree, `cargo clean -p
//! glint` makes the next build look again.

use std::path::PathBuf;

fn main() {
    println!("cargo:rustc-check-cfg=cfg(embree)");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=GLINT_EMBREE");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    if std::env::var("GLINT_EMBREE").is_ok_and(|v| v == "0") {
        return;
    }
    let mut dirs: Vec<PathBuf> = Vec::new();
    if let Ok(root) = std::env::var("EMBREE_DIR") {
        dirs.push(PathBuf::from(&root).join("lib"));
        dirs.push(PathBuf::from(root));
    }
    let multiarch = match std::env::var("CARGO_CFG_TARGET_ARCH").as_deref() {
        Ok("x86_64") => "x86_64-linux-gnu",
        Ok("aarch64") => "aarch64-linux-gnu",
        _ => "",
    };
    for d in ["/usr/lib", "/usr/local/lib", "/usr/lib64"] {
        if !multiarch.is_empty() {
            dirs.push(PathBuf::from(d).join(multiarch));
        }
        dirs.push(PathBuf::from(d));
    }
    let found = dirs.iter().find(|d| d.join("libembree3.so").exists());
    match found {
        Some(dir) => {
            println!("cargo:rustc-link-search=native={}", dir.display());
            println!("cargo:rustc-cfg=embree");
        }
        None => println!(
            "cargo:warning=Embree 3 not found (apt-get install libembree-dev): the bake's rays \
             go through obvhs, 2-3x slower"
        ),
    }
}
