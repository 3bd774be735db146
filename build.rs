//! Finds Intel Embree 3 (Debian's `libembree-dev`) for the bake's rays (`src/bake/embree.rs`).
//!
//! Where `libembree3.so` is found, the crate is built with `cfg(embree)` and links it; elsewhere it
//! builds without it and the rays go through obvhs (`src/bake/tracer.rs`), the same answers more
//! slowly. Its headers' configuration must match what `src/bake/embree.rs` declares.
//! `GLINT_EMBREE=0` builds without Embree even where it is installed; `EMBREE_DIR` names a folder
//! to look in first (its `lib/`). After installing or removing Embree, `cargo clean -p
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
    let Some(dir) = found else {
        println!(
            "cargo:warning=Embree 3 not found (apt-get install libembree-dev): the bake's rays \
             go through obvhs, 2-3x slower"
        );
        return;
    };
    // src/bake/embree.rs declares RTCIntersectContext as Embree 3 lays it out with one instance
    // level and no minimum width (Debian's and Intel's default builds): check the installed
    // configuration before linking.
    let config = ["/usr/include", "/usr/local/include"]
        .iter()
        .map(PathBuf::from)
        .chain(
            std::env::var("EMBREE_DIR")
                .ok()
                .map(|r| PathBuf::from(r).join("include")),
        )
        .map(|d| d.join("embree3/rtcore_config.h"))
        .find_map(|p| std::fs::read_to_string(p).ok());
    let defines = |text: &str, name: &str, value: &str| {
        text.lines().any(|l| {
            let mut words = l.split_whitespace();
            words.next() == Some("#define")
                && words.next() == Some(name)
                && words.next() == Some(value)
        })
    };
    match config {
        Some(text)
            if defines(&text, "RTC_VERSION_MAJOR", "3")
                && defines(&text, "RTC_MAX_INSTANCE_LEVEL_COUNT", "1")
                && defines(&text, "EMBREE_MIN_WIDTH", "0") =>
        {
            println!("cargo:rustc-link-search=native={}", dir.display());
            println!("cargo:rustc-cfg=embree");
        }
        _ => println!(
            "cargo:warning=Embree 3 found without the headers glint was written against \
             (embree3/rtcore_config.h: one instance level, no minimum width): the bake's rays go \
             through obvhs"
        ),
    }
}
