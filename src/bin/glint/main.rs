//! The `glint` command line: parses arguments, calls the library's stage functions, prints. Errors
//! from the library are reported here once, as one line on stderr, with a non-zero exit code.

mod args;
mod demo;

use anyhow::{Context, Result};
use args::*;
use clap::Parser;
use glint::bake::{LoadedBake, file};
use glint::scene::view::{parse_size, pick_view, render_view};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

fn main() -> ExitCode {
    glint::fit::energy_cache::set_dir(energy_cache_dir());
    let result = match Cli::parse().command {
        Some(Command::Inspect { scene, env, json }) => inspect(&scene, env.as_deref(), json),
        None => default_job(),
        Some(Command::Bake(args)) => bake(&args),
        Some(Command::Fit(args)) => fit(&args),
        Some(Command::Render(args)) => render(&args),
        Some(Command::Export(args)) => export(&args),
        Some(Command::App(args)) => app(&args),
        Some(Command::Study(args)) => study(&args),
        Some(Command::Demo(args)) => demo::run(&samples_dir(), &args.out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("glint: error: {}", error_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each cause once: library errors already put their source's
/// message into their own (`"{path}: {source}"`), so a cause whose text the line already holds is
/// not repeated; line breaks inside a message (a decoder's, say) become spaces.
fn error_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

fn progress_bar(template: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

fn inspect(scene_path: &Path, env_path: Option<&Path>, json: bool) -> Result<()> {
    let scene = glint::scene::import(scene_path)?;
    let env = env_path.map(glint::env::load).transpose()?;
    let report = glint::inspect::report(&scene, env.as_ref());
    if json {
        println!(
            "{}",
            serde_json::to_string(&report).context("cannot serialise the report")?
        );
    } else {
        print!("{}", report.to_text());
    }
    Ok(())
}

fn bake(args: &BakeArgs) -> Result<()> {
    let settings = args.settings()?;
    // Every input and argument is checked before anything is baked: a bad view or fit size is
    // reported before minutes of baking, not after the bake was written.
    let scene = glint::scene::import(&args.scene)?;
    let env = glint::env::load(&args.env)?;
    let camera = pick_view(&scene, args.camera.as_deref(), args.orbit.as_deref())?;
    let fit_size = match &args.fit_size {
        Some(s) => parse_size(s)?,
        None => ((camera.width / 4).max(1), (camera.height / 4).max(1)),
    };
    let bar = progress_bar("baking {bar:40} {pos}/{len} vertices ({eta})");
    bar.set_length(scene.mesh.positions.len() as u64);
    let out = args.out_dir();
    let progress = |n: usize| bar.set_position(n as u64);
    let outcome = file::bake_or_reuse(
        &scene,
        &env,
        &args.scene,
        &args.env,
        &out,
        settings,
        args.force,
        &progress,
    )?;
    bar.finish_and_clear();
    if let Some(reason) = &outcome.rebuild_reason {
        eprintln!("glint bake: {reason}");
    }
    // What a fit in this view costs now (no ray tracing: only sums and transfers).
    let imported_vertices = scene.mesh.positions.len();
    let loaded = LoadedBake::with_inputs(&out, scene, env)?;
    let cost = glint::fit::cost::view_cost(&loaded, &camera, fit_size)?;
    let refined = loaded.scene.mesh.positions.len() != imported_vertices;
    let path = out.join("bake.glint");
    let (reused, header) = (outcome.reused, &outcome.header);
    let report = glint::fit::cost::BakeReport {
        path: &path,
        reused,
        header,
        refined,
        camera: &camera,
        fit_size,
        cost: &cost,
    };
    println!(
        "{}",
        if args.json {
            report.json().to_string()
        } else {
            report.text()
        }
    );
    Ok(())
}

fn fit(args: &FitArgs) -> Result<()> {
    use glint::fit::{dump, run, strokes};
    let loaded = LoadedBake::open(&args.bake)?;
    let &[r, g, b] = args.rho_d.as_slice() else {
        anyhow::bail!("--rho-d takes three numbers r,g,b")
    };
    let text = std::fs::read_to_string(&args.strokes)
        .with_context(|| format!("cannot read {}", args.strokes.display()))?;
    let views = strokes::parse(&text).with_context(|| args.strokes.display().to_string())?;
    let settings = run::FitSettings {
        rho_d: [r, g, b],
        f0: args.f0,
        energy_limit: !args.no_energy_limit,
        fit_size: args.fit_size.as_deref().map(parse_size).transpose()?,
        rotation_rad: args.rotate.to_radians(),
        ..run::FitSettings::default()
    };
    let outcome = run::fit(&(&loaded).into(), &views, &settings)?;
    let m = &outcome.material;
    glint_exporters::write_atomic(&args.out, m.to_json().as_bytes())?;
    if let Some(dir) = &args.dump_qp {
        dump::write_qp(dir, &outcome, &settings)?;
    }
    if args.json {
        let lobes = m.centres.len();
        println!(
            "{}",
            serde_json::json!({ "material": args.out, "layout": m.layout.name(), "lobes": lobes, "fit": m.fit })
        );
    } else {
        println!(
            "wrote {} ({} lobes, layout {})",
            args.out.display(),
            m.centres.len(),
            m.layout.name()
        );
        println!("{}", m.fit.summary());
    }
    Ok(())
}

/// `glint` with no subcommand (`cargo run --release`): the app on the bundled bunny under the
/// studio
/// map; where no window can be opened, the headless demo, saying why.
fn default_job() -> Result<()> {
    let samples = samples_dir();
    let (scene, env) = (samples.join("bunny.glb"), samples.join("studio_1k.exr"));
    let autosave = Some(PathBuf::from(".glint-autosave.json"));
    let opts = glint::app::AppOptions {
        scene,
        env,
        autosave,
        ..glint::app::AppOptions::default()
    };
    match glint::app::run_window(opts) {
        Err(e @ glint::app::AppError::NoDisplay(_)) => {
            eprintln!(
                "glint: cannot open the app ({e}); running the headless demo (glint demo --out demo-out) instead."
            );
            demo::run(&samples, Path::new("demo-out"))
        }
        r => Ok(r?),
    }
}

/// `glint app`: the window, or with --screenshot the app drawn offscreen after a replay.
fn app(args: &AppArgs) -> Result<()> {
    let samples = samples_dir();
    let scene = args
        .scene
        .clone()
        .unwrap_or_else(|| samples.join("bunny.glb"));
    let env = args
        .env
        .clone()
        .unwrap_or_else(|| samples.join("studio_1k.exr"));
    let autosave = (!args.no_autosave && args.screenshot.is_none()).then(|| args.autosave.clone());
    let opts = glint::app::AppOptions::from_files(
        scene,
        env,
        args.replay.as_deref(),
        args.session.clone(),
        autosave,
        args.preview,
    )?;
    let Some(out) = &args.screenshot else {
        return Ok(glint::app::run_window(opts)?);
    };
    let (w, h) = parse_size(&args.size)?;
    let r = glint::app::replay_screenshot(opts, out, [w as f32, h as f32], 600.0)?;
    println!("wrote {} {r}", out.display());
    Ok(())
}

/// `./samples` when run from the repository, else the samples folder of the source tree it was
/// built from.
fn samples_dir() -> PathBuf {
    let local = PathBuf::from("samples");
    if local.join("bunny.glb").is_file() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("samples")
    }
}

fn render(args: &RenderArgs) -> Result<()> {
    use glint::{material_file::read_fallback, render::frame};
    let bake = LoadedBake::open(&args.bake)?;
    let material = glint::material_file::read_material(&args.material)?;
    let (camera, w, h) = render_view(
        &bake.scene,
        args.view.camera.as_deref(),
        args.view.orbit.as_deref(),
        args.view.size.as_deref(),
    )?;
    let rotation = args.view.rotate.to_radians();
    let start = std::time::Instant::now();
    let fallback = args
        .fallback
        .then(|| read_fallback(&args.material))
        .transpose()?;
    let (c, size, r) = (&camera, (w, h), rotation);
    let traced = args
        .trace_visibility
        .then_some(glint::render::traced::Tracing {
            levels: args.trace_levels,
            budget: args.trace_budget,
        });
    let (mut image, what) = match (args.reference, &fallback) {
        (Some(n), Some(f)) => frame::reference_frame_standard(&bake, f, c, size, r, n)?,
        (None, Some(f)) => frame::prt_frame_standard(&bake, f, c, size, r, traced)?,
        (Some(spp), None) => frame::reference_frame(&bake, &material, c, size, r, spp)?,
        (None, None) if args.gpu => glint::gpu::preview_frame(&bake, &material, c, size, r)?,
        (None, None) => frame::prt_frame(&bake, &material, c, size, r, traced)?,
    };
    let seconds = start.elapsed().as_secs_f64();
    image.fill_background(&bake.env, rotation, &camera);
    image.write(&args.out, args.exposure)?;
    if args.json {
        let cam = glint::export::scene_camera(&camera, w, h).to_json();
        let offset = frame::ray_offset(&bake);
        println!(
            "{}",
            serde_json::json!({"image": args.out, "width": w, "height": h, "renderer": what, "seconds": seconds, "object_pixels": image.covered_count(), "camera": cam, "env_rotation_deg": args.view.rotate, "ray_offset": offset})
        );
    } else {
        println!(
            "wrote {} ({w}x{h}, {what}, {seconds:.2} s, {} object pixels)",
            args.out.display(),
            image.covered_count()
        );
    }
    Ok(())
}

fn export(args: &ExportArgs) -> Result<()> {
    if args.list {
        glint_exporters::registry()
            .iter()
            .for_each(|e| println!("{:<9} {}", e.name(), e.extensions().join(", ")));
        return Ok(());
    }
    let (Some(material_path), Some(to)) = (&args.material, &args.to) else {
        anyhow::bail!("glint export needs MATERIAL.json and --to DIR (or --list)");
    };
    let material = glint::material_file::read_material(material_path)?;
    let name = glint::export::material_name(material_path);
    let mut provenance = glint::export::Provenance::new(glint::export::Tool::Cli, &material);
    provenance.material_file(material_path)?;
    let scene = glint::export::export_scene(&args.scene_choice(), &mut provenance)?;
    let res = args.table_resolution as usize;
    let desc = glint::export::material_desc(&material, &name, res, provenance, scene.as_ref())?;
    std::fs::create_dir_all(to).with_context(|| format!("cannot create {}", to.display()))?;
    let formats: Vec<&str> = args.formats.iter().map(|s| s.as_str()).collect();
    for p in glint_exporters::export_all(&desc, scene.as_ref(), to, &formats)? {
        println!("wrote {}", p.display());
    }
    println!("{}", glint_exporters::fallback_summary::summary_text(&desc));
    Ok(())
}

fn study(args: &StudyArgs) -> Result<()> {
    let bar = progress_bar("study {bar:30} {pos}/{len} {msg}");
    let progress = |done: usize, total: usize, what: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(what.to_string());
    };
    let (written, summary) = if args.matrix {
        let study = glint::accuracy::run_study(
            &samples_dir(),
            &args.assets,
            args.quick,
            &args.only,
            &args.out,
            &progress,
        )?;
        (study.written.clone(), Some(study.summary()))
    } else {
        let (scene, env, strokes) = (&args.scene, &args.env, &args.strokes);
        let report =
            glint::study::run_study(scene, env, strokes, args.quick, &args.out, &progress)?;
        (report.written, report.summary)
    };
    bar.finish_and_clear();
    written
        .iter()
        .for_each(|p| println!("wrote {}", p.display()));
    summary.iter().for_each(|s| println!("{s}"));
    Ok(())
}
