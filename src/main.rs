//! The `glint` command line: a thin shell over the library's public stage functions. Errors from the
//! library are reported here once, as one line on stderr, with a non-zero exit code.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "glint", version, about = "Paint highlights on a glTF object under an HDR environment; glint solves for the physically valid BRDF that renders them.")]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Report what a glTF scene (and optionally an environment map) imports as.
    Inspect {
        /// The scene: .glb or .gltf.
        scene: PathBuf,
        /// An equirectangular environment map: .exr or .hdr.
        #[arg(long)]
        env: Option<PathBuf>,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Bake per-vertex visibility cuts (reused when the inputs and settings are unchanged).
    Bake(BakeArgs),
    /// Fit the BRDF to painted strokes.
    Fit(FitArgs),
    /// Render a fitted material: the PRT frame (tabulated p), or the Monte Carlo reference.
    Render(RenderArgs),
    /// Export a fitted material: p(h) EXR table, glTF (.glb), USD (.usda), MERL (.binary), and a
    /// Mitsuba 3 scene (with --scene and --env, or --bake).
    Export(ExportArgs),
    /// The painting app: paint highlights on the object, glint fits the BRDF on release.
    App(AppArgs),
    /// Accuracy against time: sweep each accuracy knob from the defaults; write study.csv, study.svg
    /// (error against time, Pareto front) and study.md.
    Study(StudyArgs),
    /// The headless main job on the bundled sample: bake, fit the sample strokes, render, export.
    Demo(DemoArgs),
}

#[derive(clap::Args)]
struct RenderArgs {
    /// The bake made by `glint bake` (its folder or its bake.glint).
    bake: PathBuf,
    /// The material made by `glint fit`.
    #[arg(long)]
    material: PathBuf,
    #[command(flatten)]
    view: ViewArgs,
    /// Render the Monte Carlo reference with this many samples per pixel instead of the PRT frame.
    #[arg(long, conflicts_with = "gpu")]
    reference: Option<u32>,
    /// Render the PRT frame with the wgpu preview (vertex shading, on the first GPU adapter; Mesa's
    /// lavapipe where there is no GPU) instead of the CPU.
    #[arg(long)]
    gpu: bool,
    /// Exposure applied before tone mapping (PNG only).
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Output image: .exr (linear) or .png (tone-mapped).
    #[arg(long)]
    out: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// The view and light of a render or a scene export (docs/conventions.md §4–5).
#[derive(clap::Args)]
struct ViewArgs {
    /// A camera of the scene, by name (default: the first camera, or the default camera).
    #[arg(long, conflicts_with = "orbit")]
    camera: Option<String>,
    /// An orbit view around the bounds: azimuth°, elevation°, distance (in bounding radii; 0 = fit).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    orbit: Option<Vec<f32>>,
    /// Environment rotation about +Y in degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotate: f64,
    /// Image size WxH (default: the camera's).
    #[arg(long)]
    size: Option<String>,
}

#[derive(clap::Args)]
struct AppArgs {
    /// The scene: .glb or .gltf (default: the bundled bunny).
    scene: Option<PathBuf>,
    /// Equirectangular environment map: .exr or .hdr (default: the bundled studio map).
    #[arg(long)]
    env: Option<PathBuf>,
    /// Replay a stroke file (the `glint fit --strokes` format) once the first view is baked.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Draw the app offscreen (no window, no display needed) after the replay's fit, write this PNG and
    /// exit.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Window size in points for --screenshot, WxH.
    #[arg(long, default_value = "1280x760")]
    size: String,
    /// Load this session (saved by the app) once the first view is baked.
    #[arg(long)]
    session: Option<PathBuf>,
    /// Where the session is saved after every edit.
    #[arg(long, default_value = ".glint-autosave.json")]
    autosave: PathBuf,
    /// Do not autosave.
    #[arg(long)]
    no_autosave: bool,
    /// What draws the preview: auto (the wgpu preview on a hardware adapter, the CPU PRT frame where
    /// the only adapter is a software rasteriser such as llvmpipe), cpu or gpu.
    #[arg(long, default_value = "auto")]
    preview: glint::app::PreviewChoice,
}

#[derive(clap::Args)]
struct ExportArgs {
    /// The material made by `glint fit`.
    material: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    to: Option<PathBuf>,
    /// Formats, comma-separated (default: all; see --list).
    #[arg(long, value_delimiter = ',')]
    formats: Vec<String>,
    /// Put the material on this scene's mesh in the glTF, USD and Mitsuba files (default: a preview
    /// sphere), with the view as a camera.
    #[arg(long, conflicts_with = "bake")]
    scene: Option<PathBuf>,
    /// Take the scene, its environment and tangent frames from this bake (what `glint render` renders:
    /// the refined mesh), instead of --scene and --env.
    #[arg(long)]
    bake: Option<PathBuf>,
    /// The environment map that lights the Mitsuba scene (.exr or .hdr).
    #[arg(long, conflicts_with = "bake")]
    env: Option<PathBuf>,
    #[command(flatten)]
    view: ViewArgs,
    /// Resolution of the p(h) table.
    #[arg(long, default_value_t = glint::export::EXPORT_TABLE_RESOLUTION)]
    table_resolution: usize,
    /// List the formats and exit.
    #[arg(long)]
    list: bool,
}

#[derive(clap::Args)]
struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
}

#[derive(clap::Args)]
struct BakeArgs {
    /// The scene: .glb or .gltf.
    scene: PathBuf,
    /// Equirectangular environment map (.exr or .hdr); decides how fine the direction set must be.
    #[arg(long)]
    env: PathBuf,
    /// Output folder (default: ./<scene name>.bake).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Direction-set resolution per cube face (default: decided from the environment).
    #[arg(long)]
    resolution: Option<usize>,
    /// Cut error bound ε (mean |Ṽ error| per cut node).
    #[arg(long, default_value_t = glint::bake::CutSettings::default().epsilon)]
    epsilon: f64,
    /// Visibility cell size in degrees (one ray per cell; 0 traces every direction of the set).
    /// Default: decided from the scene and the environment (11.25 or 5.625, printed with the reason).
    #[arg(long)]
    cell_deg: Option<f64>,
    /// Times a visibility cell beside a cell of the other visibility (a shadow edge) is traced again as
    /// cells half as wide (0: off). Default: decided with the cell size (2 where small bright lights
    /// cast sharp shadows, else 0).
    #[arg(long)]
    boundary_levels: Option<u32>,
    /// Nodes with at most this many leaves are traced cell by cell instead of cone-tested.
    #[arg(long, default_value_t = glint::bake::CutSettings::default().trace_leaves)]
    trace_leaves: usize,
    /// Rounds of adaptive refinement: edges whose ends' visibility differs are split and the new
    /// vertices traced (0: bake the mesh as it is).
    #[arg(long, default_value_t = glint::bake::RefineSettings::default().rounds)]
    refine_rounds: u32,
    /// Split an edge when its ends' visibility differs by more than this fraction of the irradiance.
    #[arg(long, default_value_t = glint::bake::RefineSettings::default().threshold)]
    refine_threshold: f64,
    /// Trace every vertex (no vertex sampling: by default a vertex of a dense mesh whose traced
    /// neighbours agree within the refine threshold is interpolated from them).
    #[arg(long)]
    trace_every_vertex: bool,
    /// Cap on the nodes of one vertex's cut.
    #[arg(long, default_value_t = glint::bake::CutSettings::default().max_cut)]
    max_cut: usize,
    /// A camera of the scene, by name (default: the first camera, or the default camera).
    #[arg(long, conflicts_with = "orbit")]
    camera: Option<String>,
    /// An orbit view around the bounds: azimuth°, elevation°, distance (in bounding radii; 0 = fit).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    orbit: Option<Vec<f32>>,
    /// Fit resolution WxH (default: a quarter of the view in each axis, 160x120 for 640x480).
    #[arg(long)]
    fit_size: Option<String>,
    /// Rebuild even if a matching bake exists.
    #[arg(long)]
    force: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct FitArgs {
    /// The bake made by `glint bake` (its folder or its bake.glint).
    bake: PathBuf,
    /// The stroke file (JSON; schema in src/fit/strokes.schema.json).
    #[arg(long)]
    strokes: PathBuf,
    /// Where to write the material (lobe table JSON).
    #[arg(long)]
    out: PathBuf,
    /// Also write the problem and its solution as .npy files (T, B, w, E, energy rows, bounds, c) and
    /// meta.json into this folder.
    #[arg(long)]
    dump_qp: Option<PathBuf>,
    /// Diffuse albedo r,g,b (not fitted).
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.5,0.5")]
    rho_d: Vec<f64>,
    /// Schlick F0.
    #[arg(long, default_value_t = 0.04)]
    f0: f64,
    /// Drop the energy rows: a physically impossible BRDF on purpose (c ≥ 0 still holds).
    #[arg(long)]
    no_energy_limit: bool,
    /// Fit resolution WxH (default: a quarter of each stroke view's image size).
    #[arg(long)]
    fit_size: Option<String>,
    /// Environment rotation about +Y in degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotate: f64,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Arguments of a subcommand that this build does not have yet: accepted, then refused clearly.
#[derive(clap::Args)]
struct StudyArgs {
    /// The scene (default: the bundled bunny).
    #[arg(long, default_value = "samples/bunny.glb")]
    scene: PathBuf,
    /// The environment (default: the bundled studio).
    #[arg(long, default_value = "samples/studio_1k.exr")]
    env: PathBuf,
    /// The fixed stroke set every setting is fitted to.
    #[arg(long, default_value = "samples/strokes/bunny-highlight.json")]
    strokes: PathBuf,
    /// Fewer settings, an 80×60 frame and a 256-spp truth: minutes → well under 2 minutes (for CI).
    /// With --matrix: the bunny and the brushed sphere under the studio map, at 64×48 and 1024 spp.
    #[arg(long)]
    quick: bool,
    /// The accuracy matrix instead: the PRT frame against the Monte Carlo reference over meshes
    /// (bunny, teapot, suzanne, a patch of dragon_100k, the brushed sphere) × maps (studio,
    /// courtyard, interior) × views (default, orbit, grazing) × rotations (0°, 90°) × materials
    /// (sharp, broad, anisotropic where the mesh has tangents); writes matrix.md and matrix.csv.
    #[arg(long)]
    matrix: bool,
    /// Where the matrix finds dragon_100k.glb (glb/) and interior_1k.exr (hdr/).
    #[arg(long, default_value = "../shared/assets")]
    assets: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}


fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
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
    use glint::bake::{BakeSettings, CutSettings, file};
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args.scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().to_string());
        PathBuf::from(format!("{stem}.bake"))
    });
    let settings = BakeSettings {
        resolution: args.resolution,
        cut: CutSettings { epsilon: args.epsilon, max_cut: args.max_cut, trace_leaves: args.trace_leaves, cell_leaves: 1, ..CutSettings::default() },
        cell_deg: args.cell_deg,
        boundary_levels: args.boundary_levels,
        refine: glint::bake::RefineSettings { rounds: args.refine_rounds, threshold: args.refine_threshold, interpolate: !args.trace_every_vertex, ..glint::bake::RefineSettings::default() },
        ..BakeSettings::default()
    };
    if !(args.refine_threshold >= 0.0 && args.refine_threshold.is_finite()) {
        anyhow::bail!("--refine-threshold must be finite and >= 0, not {}", args.refine_threshold);
    }
    // Every input and argument is checked before anything is baked or written: the loaders refuse
    // bad files (and oversized ones) before the whole file is read for its hash, and a bad view or
    // fit size is reported before minutes of baking, not after the bake was written.
    let scene = glint::scene::import(&args.scene)?;
    let env = glint::env::load(&args.env)?;
    let camera = pick_view(&scene, args.camera.as_deref(), args.orbit.as_deref())?;
    let (fit_w, fit_h) = match &args.fit_size {
        Some(s) => parse_size(s)?,
        None => ((camera.width / 4).max(1), (camera.height / 4).max(1)),
    };
    let scene_hash = file::hash_file(&args.scene)?;
    let env_hash = file::hash_file(&args.env)?;
    let existing = out.join("bake.glint");
    let mut reused = None;
    if existing.exists() && !args.force {
        match file::read(&existing) {
            Ok((header, _, _)) if header.scene_hash == scene_hash && header.env_hash == env_hash && header.settings == settings => {
                reused = Some(header);
            }
            Ok(_) => eprintln!("glint bake: {} was made from other inputs or settings; rebuilding", existing.display()),
            Err(e) => eprintln!("glint bake: {e}; rebuilding"),
        }
    }
    let (header, reused_flag) = match reused {
        Some(h) => (h, true),
        None => {
            let baker = glint::bake::Baker::new(&scene, &env, settings)?;
            let bar = indicatif::ProgressBar::new(scene.mesh.positions.len() as u64);
            bar.set_style(
                indicatif::ProgressStyle::with_template("baking {bar:40} {pos}/{len} vertices ({eta})")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            let bake = baker.bake_refined(None, &|n| bar.set_position(n as u64));
            bar.finish_and_clear();
            let header = file::BakeHeader {
                format_version: file::FORMAT_VERSION,
                glint_version: env!("CARGO_PKG_VERSION").into(),
                scene_file: std::path::absolute(&args.scene).unwrap_or_else(|_| args.scene.clone()),
                env_file: std::path::absolute(&args.env).unwrap_or_else(|_| args.env.clone()),
                scene_hash,
                env_hash,
                settings,
                decisions: bake.decisions.clone(),
                stats: bake.stats.clone(),
                vertex_count: bake.cuts.vertex_count(),
            };
            file::write(&out, &header, &bake.cuts, &bake.refinement)?;
            (header, false)
        }
    };
    // The view: transfer for it and for a rotated environment (no ray tracing: only new sums).
    let (_, cuts, refinement) = file::read(&out.join("bake.glint"))?;
    let mut scene = scene;
    scene.mesh = refinement.apply(&scene.mesh)?;
    let set = glint::sphere::DirectionSet::cube(header.decisions.resolution)?;
    let tree = glint::sphere::LightTree::build(&set);
    let lambda = glint::sphere::srbf::lambda_from_sigma(header.settings.sigma)?;
    let layout = if header.decisions.anisotropic { glint::sphere::LobeLayout::PAPER } else { glint::sphere::LobeLayout::Isotropic { count: 24 } };
    let lobes = glint::sphere::LobeSet::new(layout, lambda)?;
    let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
    let ctx = glint::transfer::TransferContext::new(&scene.mesh, &cuts, &tree, &lobes, tangents.as_deref(), None);
    let t0 = std::time::Instant::now();
    let light = glint::light::LightSums::new(&env, &set, &tree, 0.0);
    let light_seconds = t0.elapsed().as_secs_f64();
    let transfer = ctx.compute(&light, &camera, fit_w, fit_h, 0.04);
    let source = glint::light::LightSource::new(&env);
    let t1 = std::time::Instant::now();
    let rotated = glint::light::LightSums::from_source(&source, &set, &tree, 0.5);
    let rotated_transfer = ctx.compute(&rotated, &camera, fit_w, fit_h, 0.04);
    let rotation_seconds = t1.elapsed().as_secs_f64();
    let s = &header.stats;
    let d = &header.decisions;
    if args.json {
        let json = serde_json::json!({
            "bake": out.join("bake.glint"),
            "reused": reused_flag,
            "vertices": s.vertices,
            "triangles": s.triangles,
            "rays_traced": s.rays_traced,
            "mean_cut_size": s.mean_cut_size,
            "max_cut_size": s.max_cut_size,
            "capped_vertices": s.capped_vertices,
            "seconds": s.seconds,
            "decision_seconds": s.decision_seconds,
            "rays_per_second": s.rays_traced as f64 / (s.seconds - s.decision_seconds).max(1e-9),
            "bytes_per_vertex": s.bytes_per_vertex,
            "decisions": d,
            "view": { "camera": camera.name, "fit_width": fit_w, "fit_height": fit_h, "pixels": transfer.pixels.len(), "lobes": lobes.len() },
            "light_seconds": light_seconds,
            "transfer_seconds": transfer.seconds,
            "rotation_seconds": rotation_seconds,
            "rotated_transfer_seconds": rotated_transfer.seconds,
        });
        println!("{json}");
    } else {
        println!("{} {}", if reused_flag { "reused" } else { "wrote" }, out.join("bake.glint").display());
        println!("decision: {} — {}", if d.trace_visibility { "trace visibility" } else { "no ray tracing" }, d.trace_reason);
        println!("decision: {} — {}", if d.anisotropic { "anisotropic frame" } else { "isotropic fit" }, d.frame_reason);
        println!("decision: {} directions ({} per face) — {}", 6 * d.resolution * d.resolution, d.resolution, d.resolution_reason);
        println!("decision: visibility cells of {}° — {}", d.cell_deg, d.cell_reason);
        println!("decision: {} — {}", if d.boundary_levels > 0 { format!("{} boundary level(s)", d.boundary_levels) } else { "no boundary refinement".into() }, d.boundary_reason);
        println!("decision: {} — {}", if !refinement.is_empty() { "refined mesh" } else { "mesh as it is" }, d.refine_reason);
        println!("decision: {} — {}", if d.interpolated_vertices > 0 { "vertex sampling" } else { "every vertex traced" }, d.sampling_reason);
        println!(
            "{} vertices, {} rays, mean cut {:.1} nodes (max {}, {} capped), {:.0} bytes/vertex, {:.2} s ({:.2} s deciding)",
            s.vertices, s.rays_traced, s.mean_cut_size, s.max_cut_size, s.capped_vertices, s.bytes_per_vertex, s.seconds, s.decision_seconds
        );
        println!(
            "view '{}' at {fit_w}x{fit_h}: {} pixels, J = {}; light sums {:.3} s, transfer {:.3} s; a rotated environment: {:.3} s (sums + transfer, no rays)",
            camera.name,
            transfer.pixels.len(),
            lobes.len(),
            light_seconds,
            transfer.seconds,
            rotation_seconds
        );
    }
    Ok(())
}

/// A bake read back with the inputs it was made from (checked unchanged).
struct LoadedBake {
    header: glint::bake::file::BakeHeader,
    cuts: glint::bake::Cuts,
    scene: glint::scene::Scene,
    env: glint::env::EnvMap,
    tangents: Option<Vec<glam::Vec4>>,
}

fn load_bake(path: &Path) -> Result<LoadedBake> {
    use glint::bake::file;
    let (header, cuts, refinement) = file::read(path)?;
    for (path, hash, what) in [(&header.scene_file, &header.scene_hash, "scene"), (&header.env_file, &header.env_hash, "environment")] {
        if &file::hash_file(path)? != hash {
            anyhow::bail!("the {what} {} changed since the bake; run glint bake again", path.display());
        }
    }
    let mut scene = glint::scene::import(&header.scene_file)?;
    // The cuts belong to the baked (refined) mesh; the surface is the same.
    scene.mesh = refinement.apply(&scene.mesh).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if scene.mesh.positions.len() != cuts.vertex_count() {
        anyhow::bail!("{}: the bake has {} cuts for a mesh of {} vertices; run glint bake again", path.display(), cuts.vertex_count(), scene.mesh.positions.len());
    }
    let env = glint::env::load(&header.env_file)?;
    let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
    Ok(LoadedBake { header, cuts, scene, env, tangents })
}

fn fit(args: &FitArgs) -> Result<()> {
    use glint::fit::{run, strokes};
    let LoadedBake { header, cuts, scene, env, tangents } = load_bake(&args.bake)?;
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
    let outcome = run::fit(&scene, &env, &cuts, header.decisions.resolution, tangents.as_deref(), header.decisions.anisotropic, &views, &settings)?;
    let m = &outcome.material;
    glint_exporters::write_atomic(&args.out, m.to_json().as_bytes())?;
    if let Some(dir) = &args.dump_qp {
        dump_qp(dir, &outcome, &settings)?;
    }
    let f = &m.fit;
    if args.json {
        println!("{}", serde_json::json!({ "material": args.out, "layout": m.layout.name(), "lobes": m.centres.len(), "fit": f }));
    } else {
        println!("wrote {} ({} lobes, layout {})", args.out.display(), m.centres.len(), m.layout.name());
        println!(
            "{} pixels in {} view(s); residual (weighted RMS) R {:.4e} G {:.4e} B {:.4e}; active energy rows {:?}; iterations {:?}; solve {:.2} ms",
            f.pixels, f.views, f.residual_rms[0], f.residual_rms[1], f.residual_rms[2], f.active_energy_rows, f.iterations, f.solve_seconds * 1e3
        );
        for note in &f.notes {
            println!("note: {note}");
        }
    }
    Ok(())
}

/// `--dump-qp`: the problem and its solution as .npy files anyone can re-solve, plus meta.json.
fn dump_qp(dir: &Path, outcome: &glint::fit::run::FitOutcome, settings: &glint::fit::run::FitSettings) -> Result<()> {
    use glint_exporters::npy::write_f64;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let j = outcome.material.centres.len();
    let (mut t, mut b, mut w, mut e) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for v in &outcome.views {
        for p in 0..v.transfer.pixels.len() {
            for c in 0..3 {
                t.extend(v.transfer.t_row(p, c).iter().map(|x| *x as f64));
            }
            b.extend_from_slice(&v.target[p]);
            w.push(v.weight[p]);
            e.extend_from_slice(&v.transfer.irradiance[p]);
        }
    }
    let n = w.len();
    write_f64(&dir.join("T.npy"), &[n, 3, j], &t)?;
    write_f64(&dir.join("B.npy"), &[n, 3], &b)?;
    write_f64(&dir.join("w.npy"), &[n], &w)?;
    write_f64(&dir.join("E.npy"), &[n, 3], &e)?;
    let rows = outcome.energy.as_ref().map(|table| (table.rows(), table.matrix(settings.f0)));
    if let Some((l, g)) = &rows {
        write_f64(&dir.join("energy_rows.npy"), &[*l, j], g)?;
    }
    write_f64(&dir.join("bounds.npy"), &[3], &settings.rho_d.map(|r| 1.0 - r))?;
    let c: Vec<f64> = outcome.material.coefficients.iter().flatten().copied().collect();
    write_f64(&dir.join("c.npy"), &[3, j], &c)?;
    let meta = serde_json::json!({
        "problem": "per channel k: minimise sum_i w_i (B[i,k] - rho_d[k]/pi E[i,k] - sum_j T[i,k,j] c[k,j])^2 subject to c[k] >= 0 and energy_rows @ c[k] <= bounds[k] (energy rows absent when the limit is off)",
        "rho_d": settings.rho_d,
        "f0": settings.f0,
        "energy_limit": settings.energy_limit,
        "pixels": n,
        "lobes": j,
        "energy_rows": rows.as_ref().map_or(0, |r| r.0),
        "files": ["T.npy", "B.npy", "w.npy", "E.npy", "energy_rows.npy", "bounds.npy", "c.npy"],
    });
    glint_exporters::write_atomic(&dir.join("meta.json"), serde_json::to_string_pretty(&meta)?.as_bytes())?;
    Ok(())
}

/// The view named on the command line: a camera by name, an orbit, or the scene's first camera.
fn pick_view(scene: &glint::scene::Scene, name: Option<&str>, orbit: Option<&[f32]>) -> Result<glint::scene::Camera> {
    if let Some(o) = orbit {
        let &[az, el, dist] = o else { anyhow::bail!("--orbit takes three numbers: azimuth°,elevation°,distance") };
        let first = scene.cameras.first();
        let (w, h) = first.map_or((640, 480), |c| (c.width, c.height));
        return Ok(glint::scene::orbit_camera(&scene.bounds, az, el, dist, w, h));
    }
    match name {
        Some(n) => scene.cameras.iter().find(|c| c.name == n).cloned().ok_or_else(|| {
            let names: Vec<&str> = scene.cameras.iter().map(|c| c.name.as_str()).collect();
            anyhow::anyhow!("the scene has no camera named '{n}' (it has: {})", names.join(", "))
        }),
        None => scene.cameras.first().cloned().ok_or_else(|| anyhow::anyhow!("the scene has no camera")),
    }
}

/// "WxH" → (W, H), both ≥ 1 and ≤ 8192.
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| anyhow::anyhow!("size '{s}' is not WxH"))?;
    let (w, h): (u32, u32) = (w.trim().parse()?, h.trim().parse()?);
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        anyhow::bail!("size {w}x{h} is outside 1..8192");
    }
    Ok((w, h))
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
        Ok(()) => Ok(()),
        Err(e @ glint::app::AppError::NoDisplay(_)) => {
            eprintln!("glint: cannot open the app ({e}); running the headless demo (glint demo --out demo-out) instead.");
            demo(&DemoArgs { out: PathBuf::from("demo-out") })
        }
        Err(e) => Err(e.into()),
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
    let replay = match &args.replay {
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
            glint::fit::strokes::parse(&text).with_context(|| p.display().to_string())?
        }
        None => Vec::new(),
    };
    if let Some(s) = &args.session {
        let text = std::fs::read_to_string(s).with_context(|| format!("cannot read {}", s.display()))?;
        glint::app::state::Session::parse(&text).map_err(|e| anyhow::anyhow!("{}: {e}", s.display()))?;
    }
    let opts = glint::app::AppOptions {
        scene,
        env,
        autosave: (!args.no_autosave && args.screenshot.is_none()).then(|| args.autosave.clone()),
        session: args.session.clone(),
        replay,
        preview: args.preview,
    };
    match &args.screenshot {
        Some(out) => {
            let (w, h) = parse_size(&args.size)?;
            let r = glint::app::replay_screenshot(opts, out, [w as f32, h as f32], 600.0)?;
            println!(
                "wrote {} ({}x{} px); painting possible {:.2} s and first fit prepared {:.2} s after launch; stroke release → preview {:.3} s",
                out.display(), r.width_px, r.height_px, r.first_fit_possible_secs, r.first_fit_ready_secs, r.release_to_preview_secs
            );
            Ok(())
        }
        None => Ok(glint::app::run_window(opts)?),
    }
}

/// `./samples` when run from the repository, else the samples folder of the source tree it was built from.
fn samples_dir() -> PathBuf {
    let local = PathBuf::from("samples");
    if local.join("bunny.glb").is_file() { local } else { Path::new(env!("CARGO_MANIFEST_DIR")).join("samples") }
}

/// A material: glint's material JSON, or the lobe table of glint's own `.glb`/`.gltf`/`.usda` export.
fn read_material(path: &Path) -> Result<glint::fit::material::Material> {
    Ok(glint::material_file::read_material(path)?)
}

fn render(args: &RenderArgs) -> Result<()> {
    use glint::render::{Prt, PrtSettings, Shading, Specular, table};
    let loaded = load_bake(&args.bake)?;
    let material = read_material(&args.material)?;
    if !material.layout.is_isotropic() && loaded.tangents.is_none() {
        anyhow::bail!("the material's layout {} is anisotropic but the scene has no tangent field", material.layout.name());
    }
    let lobes = material.lobes()?;
    let (camera, w, h) = render_view(&loaded.scene, args.view.camera.as_deref(), args.view.orbit.as_deref(), args.view.size.as_deref())?;
    let rotation = args.view.rotate.to_radians();
    let set = glint::sphere::DirectionSet::cube(loaded.header.decisions.resolution)?;
    let tree = glint::sphere::LightTree::build(&set);
    let coefficients = [material.coefficients[0].as_slice(), material.coefficients[1].as_slice(), material.coefficients[2].as_slice()];
    let start = std::time::Instant::now();
    let (mut image, what) = match args.reference {
        Some(spp) => {
            if spp == 0 {
                anyhow::bail!("--reference needs at least 1 sample per pixel");
            }
            let tracer = glint::bake::Tracer::new(&loaded.scene.mesh);
            let offset = 1e-4 * loaded.scene.bounds.diagonal() as f64;
            let m = glint::render::ExactMaterial { lobes: &lobes, coefficients, rho_d: material.rho_d, f0: material.f0 };
            let img = glint::render::render_reference(&loaded.scene.mesh, loaded.tangents.as_deref(), &tracer, offset, &loaded.env, rotation, m, &camera, w, h, spp, 1);
            (img, format!("Monte Carlo reference, {spp} spp"))
        }
        None if args.gpu => {
            let ctx = glint::gpu::GpuContext::headless()?;
            let settings = PrtSettings { max_edge_px: 0.0, per_pixel: false, ..PrtSettings::default() };
            let mut preview = glint::gpu::GpuPreview::new(&ctx, &loaded.scene.mesh, &loaded.cuts, &tree, loaded.tangents.as_deref(), settings)?;
            let t = table::PhTable::build(&lobes, coefficients, table::default_resolution(lobes.lambda()));
            preview.set_light(&glint::light::LightSums::new(&loaded.env, &set, &tree, rotation), &tree)?;
            preview.set_material(material.rho_d, material.f0, Some(&t))?;
            let img = preview.render(&camera, w, h)?;
            (img, format!("wgpu PRT preview on {}, p(h) table {}²", ctx.describe(), t.resolution()))
        }
        None => {
            let light = glint::light::LightSums::new(&loaded.env, &set, &tree, rotation);
            let prt = Prt::new(&loaded.scene.mesh, &loaded.cuts, &tree, loaded.tangents.as_deref(), PrtSettings::default());
            let t = table::PhTable::build(&lobes, coefficients, table::default_resolution(lobes.lambda()));
            let img = prt.render(&light, &camera, w, h, &Shading { rho_d: material.rho_d, f0: material.f0, specular: Specular::Table(&t) });
            (img, format!("PRT, p(h) table {}²", t.resolution()))
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    image.fill_background(&loaded.env, rotation, &camera);
    image.write(&args.out, args.exposure)?;
    if args.json {
        let cam = camera_json(&glint::export::scene_camera(&camera, w, h));
        println!("{}", serde_json::json!({"image": args.out, "width": w, "height": h, "renderer": what, "seconds": seconds, "object_pixels": image.covered_count(), "camera": cam, "env_rotation_deg": args.view.rotate, "ray_offset": 1e-4 * loaded.scene.bounds.diagonal() as f64}));
    } else {
        println!("wrote {} ({w}x{h}, {what}, {seconds:.2} s, {} object pixels)", args.out.display(), image.covered_count());
    }
    Ok(())
}

fn export(args: &ExportArgs) -> Result<()> {
    if args.list {
        for e in glint_exporters::registry() {
            println!("{:<6} {}", e.name(), e.extensions().join(", "));
        }
        return Ok(());
    }
    let (Some(material_path), Some(to)) = (&args.material, &args.to) else {
        anyhow::bail!("glint export needs MATERIAL.json and --to DIR (or --list)");
    };
    let material = read_material(material_path)?;
    let name = material_path.file_stem().and_then(|s| s.to_str()).unwrap_or("material").replace(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-'), "_");
    let mut provenance = std::collections::BTreeMap::new();
    provenance.insert("tool".into(), format!("glint {}", env!("CARGO_PKG_VERSION")));
    provenance.insert("material_file".into(), material_path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default());
    provenance.insert("material_hash_fnv1a64".into(), glint::bake::file::hash_file(material_path)?);
    provenance.insert("fit_residual_rms".into(), format!("{:?}", material.fit.residual_rms));
    provenance.insert("fit_pixels".into(), material.fit.pixels.to_string());
    let scene = export_scene(args, &mut provenance)?;
    if !(16..=4096).contains(&args.table_resolution) {
        anyhow::bail!("--table-resolution {} is outside 16..=4096", args.table_resolution);
    }
    let desc = glint::export::material_desc(&material, &name, args.table_resolution, provenance)?;
    std::fs::create_dir_all(to).with_context(|| format!("cannot create {}", to.display()))?;
    let formats: Vec<&str> = args.formats.iter().map(|s| s.as_str()).collect();
    let written = glint_exporters::export_all(&desc, scene.as_ref(), to, &formats)?;
    for p in &written {
        println!("wrote {}", p.display());
    }
    let f = &desc.fallback;
    println!(
        "glTF/USD fallback (pbrMetallicRoughness): base colour [{:.3}, {:.3}, {:.3}], metallic {:.2}, roughness {:.3}; relative RMS error against the fitted BRDF {:.1} %{}",
        f.base_color[0], f.base_color[1], f.base_color[2], f.metallic, f.roughness, f.relative_error * 100.0,
        match f.anisotropy {
            Some((strength, rotation)) => format!("; KHR_materials_anisotropy strength {strength:.3}, rotation {rotation:.3} rad"),
            None if desc.isotropic => String::new(),
            None => " (isotropic fallback: an anisotropic one fitted no better)".to_string(),
        }
    );
    Ok(())
}

/// The scene an export carries: the mesh (a bake's refined mesh, or an imported scene's), its tangent
/// frames, the view as a camera and, when given, the environment; `None` without --scene or --bake.
fn export_scene(args: &ExportArgs, provenance: &mut std::collections::BTreeMap<String, String>) -> Result<Option<glint_exporters::SceneMesh>> {
    let file_name = |p: &Path| p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let (scene, tangents, env) = match (&args.bake, &args.scene) {
        (Some(b), _) => {
            let loaded = load_bake(b)?;
            provenance.insert("bake".into(), file_name(b));
            provenance.insert("scene_file".into(), file_name(&loaded.header.scene_file));
            provenance.insert("env_file".into(), file_name(&loaded.header.env_file));
            (loaded.scene, loaded.tangents, Some(loaded.env))
        }
        (None, Some(p)) => {
            let scene = glint::scene::import(p)?;
            let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
            provenance.insert("scene_file".into(), file_name(p));
            let env = match &args.env {
                Some(e) => {
                    provenance.insert("env_file".into(), file_name(e));
                    Some(glint::env::load(e)?)
                }
                None => None,
            };
            (scene, tangents, env)
        }
        (None, None) => {
            if args.env.is_some() || args.view.camera.is_some() || args.view.orbit.is_some() || args.view.size.is_some() {
                anyhow::bail!("--env, --camera, --orbit and --size describe a scene: give --scene or --bake too");
            }
            return Ok(None);
        }
    };
    let (camera, w, h) = render_view(&scene, args.view.camera.as_deref(), args.view.orbit.as_deref(), args.view.size.as_deref())?;
    let mut mesh = glint::export::scene_mesh(&scene.mesh, tangents.as_deref());
    mesh.camera = Some(glint::export::scene_camera(&camera, w, h));
    mesh.environment = env.map(|e| glint::export::scene_environment(&e, args.view.rotate.to_radians()));
    if args.view.rotate != 0.0 {
        provenance.insert("env_rotation_deg".into(), format!("{:?}", args.view.rotate));
    }
    Ok(Some(mesh))
}

/// The camera `glint render` uses for these options, with its image size: a named camera, an orbit,
/// or the scene's first camera, else the default camera; the aspect follows the image.
fn render_view(scene: &glint::scene::Scene, camera: Option<&str>, orbit: Option<&[f32]>, size: Option<&str>) -> Result<(glint::scene::Camera, u32, u32)> {
    let mut cam = pick_view(scene, camera, orbit).or_else(|e| if camera.is_none() && orbit.is_none() { Ok(glint::scene::default_camera(&scene.bounds)) } else { Err(e) })?;
    let (w, h) = match size {
        Some(s) => parse_size(s)?,
        None => (cam.width.max(1), cam.height.max(1)),
    };
    cam.aspect = w as f32 / h as f32;
    Ok((cam, w, h))
}

/// The camera as `glint render --json` prints it (docs/conventions.md §4).
fn camera_json(c: &glint_exporters::SceneCamera) -> serde_json::Value {
    serde_json::json!({
        "name": c.name, "eye": c.eye, "forward": c.forward, "up": c.up, "right": c.right(),
        "yfov_deg": c.yfov_rad.to_degrees(), "width": c.width, "height": c.height,
        "znear": c.znear, "zfar": c.zfar, "pixel_centres": true,
    })
}

/// `glint study --matrix`: the accuracy matrix (src/accuracy.rs), written as matrix.md and matrix.csv.
fn study_matrix(args: &StudyArgs) -> Result<()> {
    use glint::accuracy::{self, MatrixOptions};
    let samples = samples_dir();
    let need = |p: PathBuf| -> Result<PathBuf> {
        if p.is_file() { Ok(p) } else { anyhow::bail!("the accuracy matrix needs {} (see --assets)", p.display()) }
    };
    let mut meshes: Vec<(String, PathBuf, Option<f32>)> = vec![("bunny".into(), need(samples.join("bunny.glb"))?, None)];
    if !args.quick {
        meshes.push(("teapot".into(), need(samples.join("teapot.glb"))?, None));
        meshes.push(("suzanne".into(), need(samples.join("suzanne.glb"))?, None));
        meshes.push(("dragon_100k patch".into(), need(args.assets.join("glb/dragon_100k.glb"))?, Some(0.3)));
    }
    meshes.push(("brushed sphere".into(), need(samples.join("brushed_sphere.glb"))?, None));
    let mut maps = vec![("studio".to_string(), need(samples.join("studio_1k.exr"))?)];
    if !args.quick {
        maps.push(("courtyard".into(), need(samples.join("courtyard_1k.exr"))?));
        maps.push(("interior".into(), need(args.assets.join("hdr/interior_1k.exr"))?));
    }
    let mut scenes = Vec::new();
    for (name, path, fraction) in meshes {
        let mut scene = glint::scene::import(&path)?;
        if let Some(f) = fraction {
            scene.mesh = glint::accuracy::patch(&scene.mesh, f);
            scene.bounds = glint::scene::Bounds::from_points(&scene.mesh.positions).ok_or_else(|| anyhow::anyhow!("{}: the patch is empty", path.display()))?;
        }
        scenes.push((name, scene));
    }
    let envs = maps.into_iter().map(|(n, p)| Ok((n, glint::env::load(&p)?))).collect::<Result<Vec<_>>>()?;
    let options = if args.quick { MatrixOptions::QUICK } else { MatrixOptions::FULL };
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(indicatif::ProgressStyle::with_template("matrix {bar:30} {pos}/{len} {msg}").unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()));
    let start = std::time::Instant::now();
    let rows = accuracy::run(&scenes, &envs, options, &|done, total, what| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(what.to_string());
    })?;
    bar.finish_and_clear();
    let title = format!(
        "glint accuracy matrix: PRT frame vs Monte Carlo reference, {}x{}, {} spp{} — {} cases, {:.0} s on {} threads",
        options.size.0, options.size.1, options.spp, if args.quick { " (quick)" } else { "" }, rows.len(), start.elapsed().as_secs_f64(), rayon::current_num_threads()
    );
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    for (name, text) in [("matrix.md", accuracy::markdown(&rows, &title)), ("matrix.csv", accuracy::csv(&rows))] {
        let p = args.out.join(name);
        glint_exporters::write_atomic(&p, text.as_bytes())?;
        println!("wrote {}", p.display());
    }
    let ok = rows.iter().filter(|r| r.rel_rmse <= 0.02 && (r.silhouette_pixels == 0 || r.silhouette_rel_rmse <= 0.04)).count();
    let worst = rows.iter().max_by(|a, b| a.rel_rmse.total_cmp(&b.rel_rmse));
    println!("{ok} of {} cases within 2 % (object pixels) and 4 % (silhouette pixels){}", rows.len(), worst.map(|r| format!("; worst {:.2} %: {} under {}, {}, {}°, {}", 100.0 * r.rel_rmse, r.mesh, r.map, r.view, r.rotation_deg, r.material)).unwrap_or_default());
    Ok(())
}

/// `glint demo`: the headless main job on the bundled sample.
fn study(args: &StudyArgs) -> Result<()> {
    if args.matrix {
        return study_matrix(args);
    }
    let scene = glint::scene::import(&args.scene)?;
    let env = glint::env::load(&args.env)?;
    let text = std::fs::read_to_string(&args.strokes).with_context(|| format!("reading {}", args.strokes.display()))?;
    let strokes = glint::fit::strokes::parse(&text)?;
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(indicatif::ProgressStyle::with_template("study {bar:30} {pos}/{len} {msg}").unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()));
    let start = std::time::Instant::now();
    let rows = glint::study::run(&scene, &env, &strokes, &glint::study::StudyOptions { quick: args.quick }, &|done, total, what| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(what.to_string());
    })?;
    bar.finish_and_clear();
    let name = |p: &std::path::Path| p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let title = format!(
        "glint study: {} under {}{} — {} settings, {:.0} s on {} threads",
        name(&args.scene),
        name(&args.env),
        if args.quick { " (quick)" } else { "" },
        rows.len(),
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    for p in glint::study::write_report(&args.out, &rows, &title)? {
        println!("wrote {}", p.display());
    }
    let front = glint::study::pareto_front(&rows);
    if let Some((r, _)) = rows.iter().zip(&front).find(|(r, _)| r.is_default) {
        println!("defaults: {:.2} s, {:.2} % against Monte Carlo; {} of {} settings on the Pareto front", r.total_secs(), 100.0 * r.rel_rmse, front.iter().filter(|p| **p).count(), rows.len());
    }
    Ok(())
}

fn demo(args: &DemoArgs) -> Result<()> {
    let samples = samples_dir();
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let exe = std::env::current_exe().context("cannot find the glint executable")?;
    let run = |what: &str, argv: Vec<std::ffi::OsString>| -> Result<()> {
        eprintln!("glint demo: {what}");
        let status = std::process::Command::new(&exe).args(&argv).status().with_context(|| format!("cannot run {what}"))?;
        if !status.success() {
            anyhow::bail!("{what} failed ({status})");
        }
        Ok(())
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let p = |p: PathBuf| p.into_os_string();
    let bake_dir = out.join("bunny.bake");
    run("bake the bunny under the studio", vec![os("bake"), p(samples.join("bunny.glb")), os("--env"), p(samples.join("studio_1k.exr")), os("--out"), p(bake_dir.clone())])?;
    let zero = out.join("diffuse.json");
    let material = out.join("bunny-highlight.json");
    let strokes = samples.join("strokes/bunny-highlight.json");
    run("fit the sample strokes", vec![os("fit"), p(bake_dir.clone()), os("--strokes"), p(strokes), os("--out"), p(material.clone())])?;
    // "Before": the same material with its lobes off (the rendering the strokes painted over).
    let mut before = read_material(&material)?;
    for c in before.coefficients.iter_mut() {
        c.iter_mut().for_each(|x| *x = 0.0);
    }
    glint_exporters::write_atomic(&zero, before.to_json().as_bytes())?;
    for (what, m, extra, name) in [
        ("render before", &zero, vec![], "before.png"),
        ("render after", &material, vec![], "after.png"),
        ("render after, light rotated 90°", &material, vec![os("--rotate"), os("90")], "after-rotated.png"),
    ] {
        let mut argv = vec![os("render"), p(bake_dir.clone()), os("--material"), p(m.clone()), os("--out"), p(out.join(name))];
        argv.extend(extra);
        run(what, argv)?;
    }
    run("export every format", vec![os("export"), p(material.clone()), os("--to"), p(out.join("export")), os("--scene"), p(samples.join("bunny.glb"))])?;
    println!("demo written to {}: before.png, after.png, after-rotated.png, bunny-highlight.json, export/", out.display());
    Ok(())
}

