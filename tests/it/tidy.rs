//! House rules that a reviewer would otherwise check by hand: every Rust module opens with a `//!`
//! doc (its inputs, outputs and invariants); the exporters crate depends on nothing of the
//! pipeline; library modules import only from earlier stages (the layers below); ARCHITECTURE.md's
//! code map names every module; the CLI's main.rs stays a thin shell; no test reads an environment
//! variable that could change what it asserts, and none writes outside the temporary folder; no
//! comment or document keeps dated history; every place where product code may panic says why it
//! cannot; README.md stays a user's page of at most 12 KiB (figures go to docs/benchmarks.md). (`cargo fmt --check` and clippy run in .ci/test.)

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
    for dir in [
        "src",
        "exporters/src",
        "tests",
        "benches",
        "examples",
        "fuzz/fuzz_targets",
    ] {
        rust_files(&root.join(dir), &mut files);
    }
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
                rel.starts_with("gpu") || rel.starts_with("app") || rel.starts_with("bin");
            !allowed && std::fs::read_to_string(f).unwrap().contains("wgpu::")
        })
        .collect();
    assert!(
        offenders.is_empty(),
        "wgpu outside src/gpu and src/app: {offenders:?}"
    );
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The library's layers in data-flow order: a module may import (`crate::…`) only from its own
/// layer or earlier ones. ARCHITECTURE.md explains each.
const LAYERS: &[&[&str]] = &[
    &["math"],
    &["sphere"],
    &["scene", "env"],
    &["raster"],
    &["brdf"],
    &["light"],
    &["bake"],
    &["transfer"],
    &["fit"],
    &["render", "material_file"],
    &["export", "gpu", "inspect"],
    &["study"],
    &["accuracy"],
    &["app"],
];

/// The lines of one file (numbered from 1) less its `#[cfg(test)]` items: the attribute, and the
/// item after it up to its closing brace (braces counted; a `;` before any `{` ends it).
fn non_test_lines(text: &str) -> Vec<(usize, &str)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim_start().starts_with("#[cfg(test)]") {
            let (mut depth, mut opened) = (0i64, false);
            i += 1;
            while i < lines.len() {
                let l = lines[i];
                depth += l.matches('{').count() as i64 - l.matches('}').count() as i64;
                opened |= l.contains('{');
                i += 1;
                if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                    break;
                }
            }
            continue;
        }
        out.push((i + 1, lines[i]));
        i += 1;
    }
    out
}

/// The library's non-test code of one file ([`non_test_lines`]), less its comment lines.
fn product_code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    non_test_lines(&text)
        .into_iter()
        .map(|(_, l)| l)
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Bad input is an error, never a panic (the project's standards): every place where the product
/// code (the library, the exporters, the binary) may panic by `unwrap`, `expect`, `unreachable!`
/// or `panic!` says why it cannot, in a comment on one of the three lines above it that says
/// "Cannot fail", "Cannot fire" or "Fires only" (and when).
#[test]
fn panics_in_product_code_say_why_they_cannot_fire() {
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    rust_files(&root().join("exporters/src"), &mut files);
    assert!(files.len() > 10);
    let mut unexplained = Vec::new();
    let mut explained = 0;
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (n, line) in non_test_lines(&text) {
            let code = line.split("//").next().unwrap_or("");
            let panics = [".unwrap()", ".expect(", "unreachable!(", "panic!("]
                .iter()
                .any(|p| code.contains(p));
            if !panics {
                continue;
            }
            let says_why = lines[n.saturating_sub(4)..n - 1].iter().any(|l| {
                let l = l.trim_start();
                l.starts_with("//")
                    && ["Cannot fail", "Cannot fire", "Fires only"]
                        .iter()
                        .any(|w| l.contains(w))
            });
            if says_why {
                explained += 1;
            } else {
                let rel = f.strip_prefix(root()).unwrap().display().to_string();
                unexplained.push(format!("{rel}:{n}: {}", line.trim()));
            }
        }
    }
    assert!(
        unexplained.is_empty(),
        "panics in product code with no comment saying why they cannot fire: {unexplained:#?}"
    );
    // The check sees the sites it should (a broken scan would pass on nothing).
    assert!(
        explained >= 5,
        "only {explained} explained panic sites found"
    );
}

#[test]
fn library_modules_import_only_from_earlier_stages() {
    let layer_of = |m: &str| LAYERS.iter().position(|l| l.contains(&m));
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    let mut offences = Vec::new();
    for f in files {
        let rel = f.strip_prefix(root().join("src")).unwrap();
        if rel.starts_with("bin") || rel == Path::new("lib.rs") {
            continue;
        }
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        let own =
            layer_of(&first).unwrap_or_else(|| panic!("src/{first} is in no layer of LAYERS"));
        let code = product_code(&f);
        for (i, _) in code.match_indices("crate::") {
            let name: String = code[i + 7..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if let Some(l) = layer_of(&name)
                && l > own
            {
                offences.push(format!("{} imports crate::{name}", rel.display()));
            }
        }
    }
    assert!(
        offences.is_empty(),
        "imports against the data flow: {offences:?}"
    );
}

#[test]
fn the_code_map_names_every_module() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    // Bullets of the code map: "- `path` — …" and their continuation lines.
    let mut bullets: Vec<String> = Vec::new();
    for line in map.lines() {
        if line.starts_with("- `") {
            bullets.push(line.to_string());
        } else if line.starts_with("  ") && !bullets.is_empty() {
            let last = bullets.last_mut().unwrap();
            last.push(' ');
            last.push_str(line.trim());
        }
    }
    let head = |b: &str| b[3..].split('`').next().unwrap_or("").to_string();
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    rust_files(&root().join("exporters/src"), &mut files);
    let mut missing = Vec::new();
    for f in files {
        let rel = f
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let (dir, name) = rel.rsplit_once('/').unwrap();
        let named = bullets.iter().any(|b| {
            let h = head(b);
            h == rel
                || (h == format!("{dir}/")
                    && (name == "mod.rs" || b.contains(&format!("`{name}`"))))
        });
        if !named {
            missing.push(rel);
        }
    }
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md's code map does not name: {missing:?}"
    );
}

#[test]
fn the_cli_main_is_a_thin_shell() {
    let lines = std::fs::read_to_string(root().join("src/bin/glint/main.rs"))
        .unwrap()
        .lines()
        .count();
    assert!(
        lines <= 350,
        "src/bin/glint/main.rs has {lines} lines (at most 350: logic belongs in the library)"
    );
}

#[test]
fn tests_read_no_knobs_and_write_only_to_temporary_folders() {
    // CI=true turns a missing tool into a failure (never a pass); PROPTEST_CASES is proptest's own
    // case count. No other variable may change what a test does.
    const ALLOWED: &[&str] = &["\"CI\"", "\"PROPTEST_CASES\""];
    let mut files = Vec::new();
    rust_files(&root().join("tests"), &mut files);
    let mut offences = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let rel = f.strip_prefix(root()).unwrap().display().to_string();
        for (i, _) in text.match_indices("env::var") {
            let call = &text[i..text[i..].find(')').map_or(text.len(), |e| i + e)];
            if !ALLOWED.iter().any(|a| call.contains(a)) && !rel.ends_with("tidy.rs") {
                offences.push(format!("{rel}: {call})"));
            }
        }
        if text.contains("\"/tmp") && !rel.ends_with("tidy.rs") {
            offences.push(format!("{rel}: writes to /tmp (use std::env::temp_dir)"));
        }
    }
    assert!(offences.is_empty(), "{offences:?}");
}

#[test]
fn no_dated_history_in_code_or_docs() {
    let mut files = Vec::new();
    for dir in [
        "src",
        "exporters/src",
        "tests",
        "benches",
        "examples",
        "shaders",
        "docs",
    ] {
        collect(&root().join(dir), &mut files);
    }
    files.push(root().join("README.md"));
    files.push(root().join("ARCHITECTURE.md"));
    let dated: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let text = std::fs::read_to_string(f).ok()?;
            let hit = text.lines().find(|l| {
                let b = l.as_bytes();
                (0..b.len().saturating_sub(9)).any(|i| {
                    b[i..i + 2] == *b"20"
                        && b[i + 2..i + 4].iter().all(u8::is_ascii_digit)
                        && b[i + 4] == b'-'
                        && b[i + 5..i + 7].iter().all(u8::is_ascii_digit)
                        && b[i + 7] == b'-'
                        && b[i + 8..i + 10].iter().all(u8::is_ascii_digit)
                })
            })?;
            Some(format!("{}: {hit}", f.display()))
        })
        .collect();
    assert!(dated.is_empty(), "dated history (git keeps it): {dated:?}");
}

/// Every file under `dir` (Rust, WGSL, Markdown).
fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect(&path, out);
        } else if path
            .extension()
            .is_some_and(|e| e == "rs" || e == "wgsl" || e == "md")
        {
            out.push(path);
        }
    }
}

/// README.md is for users: what glint is and how to use it, at most 12 KiB; measurements live in
/// docs/benchmarks.md.
#[test]
fn readme_stays_a_short_users_page() {
    let bytes = std::fs::metadata(root().join("README.md")).unwrap().len();
    assert!(bytes > 1000, "README.md is nearly empty ({bytes} bytes)");
    assert!(
        bytes <= 12 * 1024,
        "README.md is {bytes} bytes: keep it under 12 KiB, move figures to docs/benchmarks.md"
    );
}
