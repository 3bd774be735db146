//! `glint demo`: the headless main job on the bundled sample, each step a `glint` subcommand run as
//! a child process (bake, fit, render before/after/rotated, export), so the demo shows exactly what
//! a user's commands do.

use anyhow::{Context, Result};
use std::path::Path;

/// `glint demo`: the headless main job on the bundled sample, each step a `glint` subcommand.
pub fn run(samples: &Path, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let exe = std::env::current_exe().context("cannot find the glint executable")?;
    let run = |what: &str, argv: &[&std::ffi::OsStr]| -> Result<()> {
        eprintln!("glint demo: {what}");
        let status = std::process::Command::new(&exe)
            .args(argv)
            .status()
            .with_context(|| format!("cannot run {what}"))?;
        if !status.success() {
            anyhow::bail!("{what} failed ({status})");
        }
        Ok(())
    };
    let (bake_dir, zero, material) = (
        out.join("bunny.bake"),
        out.join("diffuse.json"),
        out.join("bunny-highlight.json"),
    );
    let (bunny, studio, strokes) = (
        samples.join("bunny.glb"),
        samples.join("studio_1k.exr"),
        samples.join("strokes/bunny-highlight.json"),
    );
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    run(
        "bake the bunny under the studio",
        &[
            os("bake"),
            bunny.as_os_str(),
            os("--env"),
            studio.as_os_str(),
            os("--out"),
            bake_dir.as_os_str(),
        ],
    )?;
    run(
        "fit the sample strokes",
        &[
            os("fit"),
            bake_dir.as_os_str(),
            os("--strokes"),
            strokes.as_os_str(),
            os("--out"),
            material.as_os_str(),
        ],
    )?;
    // "Before": the same material with its lobes off (the rendering the strokes painted over).
    let mut before = glint::material_file::read_material(&material)?;
    before.coefficients.iter_mut().for_each(|c| c.fill(0.0));
    glint_exporters::write_atomic(&zero, before.to_json().as_bytes())?;
    for (what, m, rotate, name) in [
        ("render before", &zero, "0", "before.png"),
        ("render after", &material, "0", "after.png"),
        (
            "render after, light rotated 90°",
            &material,
            "90",
            "after-rotated.png",
        ),
    ] {
        let image = out.join(name);
        let argv = [
            os("render"),
            bake_dir.as_os_str(),
            os("--material"),
            m.as_os_str(),
            os("--out"),
            image.as_os_str(),
            os("--rotate"),
            os(rotate),
        ];
        run(what, &argv)?;
    }
    let export = out.join("export");
    run(
        "export every format",
        &[
            os("export"),
            material.as_os_str(),
            os("--to"),
            export.as_os_str(),
            os("--scene"),
            bunny.as_os_str(),
        ],
    )?;
    println!(
        "demo written to {}: before.png, after.png, after-rotated.png, bunny-highlight.json, export/",
        out.display()
    );
    Ok(())
}
