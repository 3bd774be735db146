//! The `glint` command line: parses arguments, calls the library's stage functions, prints. Errors
//! from the library are reported here once, as one line on stderr, with a non-zero exit code.

mod args;

use anyhow::{Context, Result};
use args::*;
use clap::Parser;
use glint::bake::{LoadedBake, file};
use glint::scene::view::{parse_size, pick_view, render_view};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Some(Command::Inspect { scene, env, json }) => inspect(&scene, env.as_deref(), json),
        None => default_job(),
        Some(Command::Bake(args)) => bake(&args),
        Some(Command::Fit(args)) => fit(&args),
        Some(Command::Render(args)) => render(&args),
        Some(Command::Export(args)) => export(&args),
        Some(Command::App(args)) => app(&args),
        Some(Command::Study(args)) => study(&args),
        Some(Command::Demo(args)) => demo(&args),
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
/// message into their own (`"{path}: {source}"`), so a cause whose text the line already holds is not
/// repeated; line breaks inside a message (a decoder's, say) become spaces.
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
    line.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(" ")
}

fn progress_bar(template: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(indicatif::ProgressStyle::with_template(template).unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()));
    bar
}

fn inspect(scene_path: &Path, env_path: Option<&Path>, json: bool) -> Result<()> {
    let scene = glint::scene::import(scene_path)?;
    let env = env_path.map(glint::env::load).transpose()?;
    let report = glint::inspect::report(&scene, env.as_ref());
    if json {
        println!("{}", serde_json::to_string(&report).context("cannot serialise the report")?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(())
}

fn bake(args: &BakeArgs) -> Result<()> {
    use glint::bake::{BakeSettings, CutSettings, RefineSettings};
    let stem = args.scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().to_string());
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("{stem}.bake")));
    if !(args.refine_threshold >= 0.0 && args.refine_threshold.is_finite()) {
        anyhow::bail!("--refine-threshold must be finite and >= 0, not {}", args.refine_threshold);
    }
    let settings = BakeSettings {
        resolution: args.resolution,
        cut: CutSettings { epsilon: args.epsilon, max_cut: args.max_cut, trace_leaves: args.trace_leaves, cell_leaves: 1, ..CutSettings::default() },
        cell_deg: args.cell_deg,
        boundary_levels: args.boundary_levels,
        refine: RefineSettings { rounds: args.refine_rounds, threshold: args.refine_threshold, interpolate: !args.trace_every_vertex, ..RefineSettings::default() },
        ..BakeSettings::default()
    };
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
    let outcome = file::bake_or_reuse(&scene, &env, &args.scene, &args.env, &out, settings, args.force, &|n| bar.set_position(n as u64))?;
    bar.finish_and_clear();
    if let Some(reason) = &outcome.rebuild_reason {
        eprintln!("glint bake: {reason}");
    }
    // What a fit in this view costs now (no ray tracing: only sums and transfers).
    let loaded = LoadedBake::open(&out)?;
    let cost = glint::fit::cost::view_cost(&loaded, &camera, fit_size)?;
    let (s, d, path) = (&outcome.header.stats, &outcome.header.decisions, out.join("bake.glint"));
    if args.json {
        let mut json = serde_json::json!({
            "bake": path, "reused": outcome.reused, "vertices": s.vertices, "triangles": s.triangles, "rays_traced": s.rays_traced,
            "mean_cut_size": s.mean_cut_size, "max_cut_size": s.max_cut_size, "capped_vertices": s.capped_vertices,
            "seconds": s.seconds, "decision_seconds": s.decision_seconds,
            "rays_per_second": s.rays_traced as f64 / (s.seconds - s.decision_seconds).max(1e-9), "bytes_per_vertex": s.bytes_per_vertex,
            "decisions": d,
            "view": { "camera": camera.name, "fit_width": fit_size.0, "fit_height": fit_size.1, "pixels": cost.pixels, "lobes": cost.lobes },
        });
        json.as_object_mut().context("a JSON object")?.extend(serde_json::to_value(&cost)?.as_object().cloned().unwrap_or_default().into_iter().filter(|(k, _)| k.ends_with("seconds")));
        println!("{json}");
        return Ok(());
    }
    println!("{} {}", if outcome.reused { "reused" } else { "wrote" }, path.display());
    for (what, why) in d.summary(loaded.scene.mesh.positions.len() != scene.mesh.positions.len()) {
        println!("decision: {what} — {why}");
    }
    println!(
        "{} vertices, {} rays, mean cut {:.1} nodes (max {}, {} capped), {:.0} bytes/vertex, {:.2} s ({:.2} s deciding)",
        s.vertices, s.rays_traced, s.mean_cut_size, s.max_cut_size, s.capped_vertices, s.bytes_per_vertex, s.seconds, s.decision_seconds
    );
    println!(
        "view '{}' at {}x{}: {} pixels, J = {}; light sums {:.3} s, transfer {:.3} s; a rotated environment: {:.3} s (sums + transfer, no rays)",
        camera.name, fit_size.0, fit_size.1, cost.pixels, cost.lobes, cost.light_seconds, cost.transfer_seconds, cost.rotation_seconds
    );
    Ok(())
}

fn fit(args: &FitArgs) -> Result<()> {
    use glint::fit::{dump, run, strokes};
    let loaded = LoadedBake::open(&args.bake)?;
    let &[r, g, b] = args.rho_d.as_slice() else { anyhow::bail!("--rho-d takes three numbers r,g,b") };
    let text = std::fs::read_to_string(&args.strokes).with_context(|| format!("cannot read {}", args.strokes.display()))?;
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
    let f = &m.fit;
    if args.json {
        println!("{}", serde_json::json!({ "material": args.out, "layout": m.layout.name(), "lobes": m.centres.len(), "fit": f }));
        return Ok(());
    }
    println!("wrote {} ({} lobes, layout {})", args.out.display(), m.centres.len(), m.layout.name());
    println!(
        "{} pixels in {} view(s); residual (weighted RMS) R {:.4e} G {:.4e} B {:.4e}; active energy rows {:?}; iterations {:?}; solve {:.2} ms",
        f.pixels, f.views, f.residual_rms[0], f.residual_rms[1], f.residual_rms[2], f.active_energy_rows, f.iterations, f.solve_seconds * 1e3
    );
    f.notes.iter().for_each(|note| println!("note: {note}"));
    Ok(())
}

/// `glint` with no subcommand (`cargo run --release`): the app on the bundled bunny under the studio
/// map; where no window can be opened, the headless demo, saying why.
fn default_job() -> Result<()> {
    let samples = samples_dir();
    let opts = glint::app::AppOptions {
        scene: samples.join("bunny.glb"),
        env: samples.join("studio_1k.exr"),
        autosave: Some(PathBuf::from(".glint-autosave.json")),
        session: None,
        replay: Vec::new(),
        preview: glint::app::PreviewChoice::Auto,
    };
    match glint::app::run_window(opts) {
        Err(e @ glint::app::AppError::NoDisplay(_)) => {
            eprintln!("glint: cannot open the app ({e}); running the headless demo (glint demo --out demo-out) instead.");
            demo(&DemoArgs { out: PathBuf::from("demo-out") })
        }
        r => Ok(r?),
    }
}

/// `glint app`: the window, or with --screenshot the app drawn offscreen after a replay.
fn app(args: &AppArgs) -> Result<()> {
    let samples = samples_dir();
    let scene = args.scene.clone().unwrap_or_else(|| samples.join("bunny.glb"));
    let env = args.env.clone().unwrap_or_else(|| samples.join("studio_1k.exr"));
    for (what, p) in [("scene", &scene), ("environment map", &env)] {
        if !p.is_file() {
            anyhow::bail!("the {what} {} does not exist", p.display());
        }
    }
    let read = |p: &Path| std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()));
    let replay = match &args.replay {
        Some(p) => glint::fit::strokes::parse(&read(p)?).with_context(|| p.display().to_string())?,
        None => Vec::new(),
    };
    if let Some(s) = &args.session {
        glint::app::state::Session::parse(&read(s)?).map_err(|e| anyhow::anyhow!("{}: {e}", s.display()))?;
    }
    let autosave = (!args.no_autosave && args.screenshot.is_none()).then(|| args.autosave.clone());
    let opts = glint::app::AppOptions { scene, env, autosave, session: args.session.clone(), replay, preview: args.preview };
    let Some(out) = &args.screenshot else { return Ok(glint::app::run_window(opts)?) };
    let (w, h) = parse_size(&args.size)?;
    let r = glint::app::replay_screenshot(opts, out, [w as f32, h as f32], 600.0)?;
    println!(
        "wrote {} ({}x{} px); painting possible {:.2} s and first fit prepared {:.2} s after launch; stroke release → preview {:.3} s",
        out.display(), r.width_px, r.height_px, r.first_fit_possible_secs, r.first_fit_ready_secs, r.release_to_preview_secs
    );
    Ok(())
}

/// `./samples` when run from the repository, else the samples folder of the source tree it was built from.
fn samples_dir() -> PathBuf {
    let local = PathBuf::from("samples");
    if local.join("bunny.glb").is_file() { local } else { Path::new(env!("CARGO_MANIFEST_DIR")).join("samples") }
}

fn render(args: &RenderArgs) -> Result<()> {
    use glint::render::frame;
    let bake = LoadedBake::open(&args.bake)?;
    let material = glint::material_file::read_material(&args.material)?;
    let (camera, w, h) = render_view(&bake.scene, args.view.camera.as_deref(), args.view.orbit.as_deref(), args.view.size.as_deref())?;
    let rotation = args.view.rotate.to_radians();
    let start = std::time::Instant::now();
    let (mut image, what) = match args.reference {
        Some(spp) => frame::reference_frame(&bake, &material, &camera, (w, h), rotation, spp)?,
        None if args.gpu => glint::gpu::preview_frame(&bake, &material, &camera, (w, h), rotation)?,
        None => frame::prt_frame(&bake, &material, &camera, (w, h), rotation)?,
    };
    let seconds = start.elapsed().as_secs_f64();
    image.fill_background(&bake.env, rotation, &camera);
    image.write(&args.out, args.exposure)?;
    if args.json {
        let cam = glint::export::scene_camera(&camera, w, h).to_json();
        let offset = frame::ray_offset(&bake);
        println!("{}", serde_json::json!({"image": args.out, "width": w, "height": h, "renderer": what, "seconds": seconds, "object_pixels": image.covered_count(), "camera": cam, "env_rotation_deg": args.view.rotate, "ray_offset": offset}));
    } else {
        println!("wrote {} ({w}x{h}, {what}, {seconds:.2} s, {} object pixels)", args.out.display(), image.covered_count());
    }
    Ok(())
}

fn export(args: &ExportArgs) -> Result<()> {
    if args.list {
        glint_exporters::registry().iter().for_each(|e| println!("{:<6} {}", e.name(), e.extensions().join(", ")));
        return Ok(());
    }
    let (Some(material_path), Some(to)) = (&args.material, &args.to) else {
        anyhow::bail!("glint export needs MATERIAL.json and --to DIR (or --list)");
    };
    let material = glint::material_file::read_material(material_path)?;
    let name = material_path.file_stem().and_then(|s| s.to_str()).unwrap_or("material").replace(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-'), "_");
    let mut provenance = glint::export::Provenance::new(glint::export::Tool::Cli, &material);
    provenance.material_file(material_path)?;
    let scene = export_scene(args, &mut provenance)?;
    if !(16..=4096).contains(&args.table_resolution) {
        anyhow::bail!("--table-resolution {} is outside 16..=4096", args.table_resolution);
    }
    let desc = glint::export::material_desc(&material, &name, args.table_resolution, provenance)?;
    std::fs::create_dir_all(to).with_context(|| format!("cannot create {}", to.display()))?;
    let formats: Vec<&str> = args.formats.iter().map(|s| s.as_str()).collect();
    for p in glint_exporters::export_all(&desc, scene.as_ref(), to, &formats)? {
        println!("wrote {}", p.display());
    }
    println!("{}", desc.fallback.summary(desc.isotropic));
    Ok(())
}

/// The scene an export carries: the mesh (a bake's refined mesh, or an imported scene's), its tangent
/// frames, the view as a camera and, when given, the environment; `None` without --scene or --bake.
fn export_scene(args: &ExportArgs, provenance: &mut glint::export::Provenance) -> Result<Option<glint_exporters::SceneMesh>> {
    let (scene, tangents, env) = match (&args.bake, &args.scene) {
        (Some(b), _) => {
            let loaded = LoadedBake::open(b)?;
            provenance.bake(b).scene_file(&loaded.header.scene_file).env_file(&loaded.header.env_file);
            (loaded.scene, loaded.tangents, Some(loaded.env))
        }
        (None, Some(p)) => {
            let scene = glint::scene::import(p)?;
            let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
            provenance.scene_file(p);
            args.env.as_deref().map(|e| provenance.env_file(e));
            (scene, tangents, args.env.as_deref().map(glint::env::load).transpose()?)
        }
        (None, None) if args.env.is_some() || args.view.camera.is_some() || args.view.orbit.is_some() || args.view.size.is_some() => {
            anyhow::bail!("--env, --camera, --orbit and --size describe a scene: give --scene or --bake too")
        }
        (None, None) => return Ok(None),
    };
    let (camera, w, h) = render_view(&scene, args.view.camera.as_deref(), args.view.orbit.as_deref(), args.view.size.as_deref())?;
    let mut mesh = glint::export::scene_mesh(&scene.mesh, tangents.as_deref());
    mesh.camera = Some(glint::export::scene_camera(&camera, w, h));
    mesh.environment = env.map(|e| glint::export::scene_environment(&e, args.view.rotate.to_radians()));
    provenance.env_rotation_deg(args.view.rotate);
    Ok(Some(mesh))
}

fn study(args: &StudyArgs) -> Result<()> {
    let bar = progress_bar("study {bar:30} {pos}/{len} {msg}");
    let progress = |done: usize, total: usize, what: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(what.to_string());
    };
    if args.matrix {
        let study = glint::accuracy::run_study(&samples_dir(), &args.assets, args.quick, &args.out, &progress)?;
        bar.finish_and_clear();
        study.written.iter().for_each(|p| println!("wrote {}", p.display()));
        println!("{}", study.summary());
        return Ok(());
    }
    let scene = glint::scene::import(&args.scene)?;
    let env = glint::env::load(&args.env)?;
    let text = std::fs::read_to_string(&args.strokes).with_context(|| format!("reading {}", args.strokes.display()))?;
    let strokes = glint::fit::strokes::parse(&text)?;
    let start = std::time::Instant::now();
    let rows = glint::study::run(&scene, &env, &strokes, &glint::study::StudyOptions { quick: args.quick }, &progress)?;
    bar.finish_and_clear();
    let name = |p: &Path| p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let quick = if args.quick { " (quick)" } else { "" };
    let secs = start.elapsed().as_secs_f64();
    let title = format!("glint study: {} under {}{quick} — {} settings, {secs:.0} s on {} threads", name(&args.scene), name(&args.env), rows.len(), rayon::current_num_threads());
    for p in glint::study::write_report(&args.out, &rows, &title)? {
        println!("wrote {}", p.display());
    }
    let front = glint::study::pareto_front(&rows);
    if let Some((r, _)) = rows.iter().zip(&front).find(|(r, _)| r.is_default) {
        let on_front = front.iter().filter(|p| **p).count();
        println!("defaults: {:.2} s, {:.2} % against Monte Carlo; {on_front} of {} settings on the Pareto front", r.total_secs(), 100.0 * r.rel_rmse, rows.len());
    }
    Ok(())
}

/// `glint demo`: the headless main job on the bundled sample, each step a `glint` subcommand.
fn demo(args: &DemoArgs) -> Result<()> {
    let (samples, out) = (samples_dir(), &args.out);
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let exe = std::env::current_exe().context("cannot find the glint executable")?;
    let run = |what: &str, argv: &[&std::ffi::OsStr]| -> Result<()> {
        eprintln!("glint demo: {what}");
        let status = std::process::Command::new(&exe).args(argv).status().with_context(|| format!("cannot run {what}"))?;
        if !status.success() {
            anyhow::bail!("{what} failed ({status})");
        }
        Ok(())
    };
    let (bake_dir, zero, material) = (out.join("bunny.bake"), out.join("diffuse.json"), out.join("bunny-highlight.json"));
    let (bunny, studio, strokes) = (samples.join("bunny.glb"), samples.join("studio_1k.exr"), samples.join("strokes/bunny-highlight.json"));
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    run("bake the bunny under the studio", &[os("bake"), bunny.as_os_str(), os("--env"), studio.as_os_str(), os("--out"), bake_dir.as_os_str()])?;
    run("fit the sample strokes", &[os("fit"), bake_dir.as_os_str(), os("--strokes"), strokes.as_os_str(), os("--out"), material.as_os_str()])?;
    // "Before": the same material with its lobes off (the rendering the strokes painted over).
    let mut before = glint::material_file::read_material(&material)?;
    before.coefficients.iter_mut().for_each(|c| c.fill(0.0));
    glint_exporters::write_atomic(&zero, before.to_json().as_bytes())?;
    for (what, m, rotate, name) in [("render before", &zero, "0", "before.png"), ("render after", &material, "0", "after.png"), ("render after, light rotated 90°", &material, "90", "after-rotated.png")] {
        let image = out.join(name);
        let argv = [os("render"), bake_dir.as_os_str(), os("--material"), m.as_os_str(), os("--out"), image.as_os_str(), os("--rotate"), os(rotate)];
        run(what, &argv)?;
    }
    let export = out.join("export");
    run("export every format", &[os("export"), material.as_os_str(), os("--to"), export.as_os_str(), os("--scene"), bunny.as_os_str()])?;
    println!("demo written to {}: before.png, after.png, after-rotated.png, bunny-highlight.json, export/", out.display());
    Ok(())
}
