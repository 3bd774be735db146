//! The command line's arguments (clap): what each subcommand takes, with its help text.

use std::path::PathBuf;

#[derive(clap::Parser)]
#[command(
    name = "glint",
    version,
    about = "Paint highlights on a glTF object under an HDR environment; glint solves for the physically valid BRDF that renders them."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(clap::Subcommand)]
pub enum Command {
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
    /// Accuracy against time: sweep each accuracy knob from the defaults; write study.csv,
    /// study.svg
    /// (error against time, Pareto front) and study.md.
    Study(StudyArgs),
    /// The headless main job on the bundled sample: bake, fit the sample strokes, render, export.
    Demo(DemoArgs),
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The bake made by `glint bake` (its folder or its bake.glint).
    pub bake: PathBuf,
    /// The material made by `glint fit`.
    #[arg(long)]
    pub material: PathBuf,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Render the Monte Carlo reference with this many samples per pixel instead of the PRT frame.
    #[arg(long, conflicts_with = "gpu")]
    pub reference: Option<u32>,
    /// Render the PRT frame with the wgpu preview (vertex shading, on the first GPU adapter; Mesa's
    /// lavapipe where there is no GPU) instead of the CPU.
    #[arg(long)]
    pub gpu: bool,
    /// Render the fallback the --material export carries instead of glint's BRDF (the glTF
    /// material of a .glb, the UsdPreviewSurface of a .usda), as other tools show it: with the PRT,
    /// or with --reference the Monte Carlo reference.
    #[arg(long, conflicts_with = "gpu")]
    pub fallback: bool,
    /// PRT frame: trace each pixel's own visibility where its triangle's corners disagree (shadow
    /// edges inside triangles), with the bake's visibility cells; slower, a still's accuracy.
    #[arg(long, conflicts_with_all = ["gpu", "reference"])]
    pub trace_visibility: bool,
    /// With --trace-visibility: refine the pixels' visibility cells at shadow edges at least this
    /// many times (each level halves a cell's width; 4 reaches single directions at every size
    /// the bake decides).
    #[arg(long, requires = "trace_visibility", default_value_t = glint::render::traced::TRACED_BOUNDARY_LEVELS)]
    pub trace_levels: u32,
    /// With --trace-visibility: the light budget of that refinement (default: the bake's, 0.0015):
    /// shadow edges of lights carrying less than this share of the light are left unrefined; 0
    /// refines every shadow edge, for a sharp lobe that takes its light from a dim one.
    #[arg(long, requires = "trace_visibility", value_parser = budget_share)]
    pub trace_budget: Option<f64>,
    /// Exposure applied before tone mapping (PNG only).
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Output image: .exr (linear) or .png (tone-mapped).
    #[arg(long)]
    pub out: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// The view and light of a render or a scene export (docs/conventions.md §4–5).
#[derive(clap::Args)]
pub struct ViewArgs {
    /// A camera of the scene, by name (default: the first camera, or the default camera).
    #[arg(long, conflicts_with = "orbit")]
    pub camera: Option<String>,
    /// An orbit view around the bounds: azimuth°, elevation°, distance (in bounding radii; 0 =
    /// fit).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub orbit: Option<Vec<f32>>,
    /// Environment rotation about +Y in degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rotate: f64,
    /// Image size WxH (default: the camera's).
    #[arg(long)]
    pub size: Option<String>,
}

#[derive(clap::Args)]
pub struct AppArgs {
    /// The scene: .glb or .gltf (default: the bundled bunny).
    pub scene: Option<PathBuf>,
    /// Equirectangular environment map: .exr or .hdr (default: the bundled studio map).
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Replay a stroke file (the `glint fit --strokes` format) once the first view is baked.
    #[arg(long)]
    pub replay: Option<PathBuf>,
    /// Draw the app offscreen (no window, no display needed) after the replay's fit, write this PNG
    /// and
    /// exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Window size in points for --screenshot, WxH.
    #[arg(long, default_value = "1280x760")]
    pub size: String,
    /// Load this session (saved by the app) once the first view is baked.
    #[arg(long)]
    pub session: Option<PathBuf>,
    /// Where the session is saved after every edit.
    #[arg(long, default_value = ".glint-autosave.json")]
    pub autosave: PathBuf,
    /// Do not autosave.
    #[arg(long)]
    pub no_autosave: bool,
    /// What draws the preview: auto (the wgpu preview on a hardware adapter, the CPU PRT frame
    /// where
    /// the only adapter is a software rasteriser such as llvmpipe), cpu or gpu.
    #[arg(long, default_value = "auto")]
    pub preview: glint::app::PreviewChoice,
}

#[derive(clap::Args)]
pub struct ExportArgs {
    /// The material made by `glint fit`.
    pub material: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub to: Option<PathBuf>,
    /// Formats, comma-separated (default: all; see --list).
    #[arg(long, value_delimiter = ',')]
    pub formats: Vec<String>,
    /// Put the material on this scene's mesh in the glTF, USD and Mitsuba files (default: a preview
    /// sphere), with the view as a camera.
    #[arg(long, conflicts_with = "bake")]
    pub scene: Option<PathBuf>,
    /// Take the scene, its environment and tangent frames from this bake (what `glint render`
    /// renders:
    /// the refined mesh), instead of --scene and --env.
    #[arg(long)]
    pub bake: Option<PathBuf>,
    /// The environment map that lights the Mitsuba scene (.exr or .hdr).
    #[arg(long, conflicts_with = "bake")]
    pub env: Option<PathBuf>,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Resolution of the p(h) table (16 to 4096).
    #[arg(long, default_value_t = glint::export::EXPORT_TABLE_RESOLUTION as u16,
          value_parser = clap::value_parser!(u16).range(16..=4096))]
    pub table_resolution: u16,
    /// List the formats and exit.
    #[arg(long)]
    pub list: bool,
}

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct BakeArgs {
    /// The scene: .glb or .gltf.
    pub scene: PathBuf,
    /// Equirectangular environment map (.exr or .hdr); decides how fine the direction set must be.
    #[arg(long)]
    pub env: PathBuf,
    /// Output folder (default: ./<scene name>.bake).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Direction-set resolution per cube face (default: decided from the environment).
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Cut error bound ε (mean |Ṽ error| per cut node).
    #[arg(long, default_value_t = glint::bake::CutSettings::default().epsilon)]
    pub epsilon: f64,
    /// Visibility cell size in degrees (one ray per cell; 0 traces every direction of the set).
    /// Default: decided from the scene and the environment (11.25, or 5.625 where 11.25° cells
    /// cannot find the shadow edges; printed with the reason).
    #[arg(long)]
    pub cell_deg: Option<f64>,
    /// Times a visibility cell beside a cell of the other visibility (a shadow edge) is traced
    /// again as cells half as wide (0: off). Default: decided with the cell size (3 from 11.25°, 2
    /// from 5.625°, where small bright lights cast sharp shadows; else 0).
    #[arg(long)]
    pub boundary_levels: Option<u32>,
    /// Boundary refinement's light budget: per level, the shadow-edge cells that gate the least
    /// light (under any rotation of the map about +Y) are left coarse while their light sums to at
    /// most this fraction of a vertex's irradiance (0: refine every shadow-edge cell).
    #[arg(long, default_value_t = glint::bake::CutSettings::default().boundary_budget)]
    pub boundary_budget: f64,
    /// Nodes with at most this many leaves are traced cell by cell instead of cone-tested (0: half
    /// the direction set's leaves).
    #[arg(long, default_value_t = glint::bake::CutSettings::default().trace_leaves)]
    pub trace_leaves: usize,
    /// Rounds of adaptive refinement: edges whose ends' visibility differs are split and the new
    /// vertices traced (0: bake the mesh as it is).
    #[arg(long, default_value_t = glint::bake::RefineSettings::default().rounds)]
    pub refine_rounds: u32,
    /// Split an edge when its ends' visibility differs by more than this fraction of the
    /// irradiance.
    #[arg(long, default_value_t = glint::bake::RefineSettings::default().threshold)]
    pub refine_threshold: f64,
    /// Trace every vertex (no vertex sampling: by default a vertex of a dense mesh whose traced
    /// neighbours agree within the refine threshold is interpolated from them).
    #[arg(long)]
    pub trace_every_vertex: bool,
    /// Cap on the nodes of one vertex's cut.
    #[arg(long, default_value_t = glint::bake::CutSettings::default().max_cut)]
    pub max_cut: usize,
    /// A camera of the scene, by name (default: the first camera, or the default camera).
    #[arg(long, conflicts_with = "orbit")]
    pub camera: Option<String>,
    /// An orbit view around the bounds: azimuth°, elevation°, distance (in bounding radii; 0 =
    /// fit).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub orbit: Option<Vec<f32>>,
    /// Fit resolution WxH (default: a quarter of the view in each axis, 160x120 for 640x480).
    #[arg(long)]
    pub fit_size: Option<String>,
    /// Rebuild even if a matching bake exists.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args)]
pub struct FitArgs {
    /// The bake made by `glint bake` (its folder or its bake.glint).
    pub bake: PathBuf,
    /// The stroke file (JSON; schema in src/fit/strokes.schema.json).
    #[arg(long)]
    pub strokes: PathBuf,
    /// Where to write the material (lobe table JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the problem and its solution as .npy files (T, B, w, E, energy rows, bounds, c)
    /// and
    /// meta.json into this folder.
    #[arg(long)]
    pub dump_qp: Option<PathBuf>,
    /// Diffuse albedo r,g,b (not fitted).
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.5,0.5")]
    pub rho_d: Vec<f64>,
    /// Schlick F0.
    #[arg(long, default_value_t = 0.04)]
    pub f0: f64,
    /// Drop the energy rows: a physically impossible BRDF on purpose (c ≥ 0 still holds).
    #[arg(long)]
    pub no_energy_limit: bool,
    /// Fit resolution WxH (default: a quarter of each stroke view's image size).
    #[arg(long)]
    pub fit_size: Option<String>,
    /// Environment rotation about +Y in degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rotate: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `glint study`.
#[derive(clap::Args)]
pub struct StudyArgs {
    /// The scene (default: the bundled bunny).
    #[arg(long, default_value = "samples/bunny.glb")]
    pub scene: PathBuf,
    /// The environment (default: the bundled studio).
    #[arg(long, default_value = "samples/studio_1k.exr")]
    pub env: PathBuf,
    /// The fixed stroke set every setting is fitted to.
    #[arg(long, default_value = "samples/strokes/bunny-highlight.json")]
    pub strokes: PathBuf,
    /// Fewer settings, an 80×60 frame and a 256-spp truth: minutes → well under 2 minutes (for CI).
    /// With --matrix: the bunny and the brushed sphere under the studio map, at 64×48 and 1024 spp.
    #[arg(long)]
    pub quick: bool,
    /// The accuracy matrix instead: the PRT frame against the Monte Carlo reference over meshes
    /// (bunny, teapot, suzanne, a patch of dragon_100k, the brushed sphere) × maps (studio,
    /// courtyard, interior) × views (default, orbit, grazing) × rotations (0°, 90°) × materials
    /// (sharp, broad, anisotropic where the mesh has tangents); writes matrix.md and matrix.csv.
    #[arg(long)]
    pub matrix: bool,
    /// Where the matrix finds dragon_100k.glb (glb/) and interior_1k.exr (hdr/).
    #[arg(long, default_value = "../shared/assets")]
    pub assets: PathBuf,
    /// With --matrix: only the meshes and maps whose names contain one of these words (e.g.
    /// `--only teapot --only interior`); meshes or maps that no word names are all kept.
    #[arg(long, requires = "matrix")]
    pub only: Vec<String>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

impl BakeArgs {
    /// The bake settings these arguments ask for.
    pub fn settings(&self) -> anyhow::Result<glint::bake::BakeSettings> {
        use glint::bake::{BakeSettings, CutSettings, RefineSettings};
        if !(self.refine_threshold >= 0.0 && self.refine_threshold.is_finite()) {
            anyhow::bail!(
                "--refine-threshold must be finite and >= 0, not {}",
                self.refine_threshold
            );
        }
        if !(self.boundary_budget >= 0.0 && self.boundary_budget.is_finite()) {
            anyhow::bail!(
                "--boundary-budget must be finite and >= 0, not {}",
                self.boundary_budget
            );
        }
        let cut = CutSettings {
            epsilon: self.epsilon,
            boundary_budget: self.boundary_budget,
            max_cut: self.max_cut,
            trace_leaves: self.trace_leaves,
            cell_leaves: 1,
            ..CutSettings::default()
        };
        let refine = RefineSettings {
            rounds: self.refine_rounds,
            threshold: self.refine_threshold,
            interpolate: !self.trace_every_vertex,
            ..RefineSettings::default()
        };
        let (resolution, cell_deg, boundary_levels) =
            (self.resolution, self.cell_deg, self.boundary_levels);
        Ok(BakeSettings {
            resolution,
            cut,
            cell_deg,
            boundary_levels,
            refine,
            ..BakeSettings::default()
        })
    }

    /// The output folder: --out, else `<scene name>.bake` here.
    pub fn out_dir(&self) -> PathBuf {
        let stem = self
            .scene
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().to_string());
        self.out
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{stem}.bake")))
    }
}

impl ExportArgs {
    /// The scene the export carries, as the library takes it.
    pub fn scene_choice(&self) -> glint::export::SceneChoice<'_> {
        glint::export::SceneChoice {
            bake: self.bake.as_deref(),
            scene: self.scene.as_deref(),
            env: self.env.as_deref(),
            camera: self.view.camera.as_deref(),
            orbit: self.view.orbit.as_deref(),
            size: self.view.size.as_deref(),
            rotate_deg: self.view.rotate,
        }
    }
}

/// The energy tables' disk cache ([`glint::fit::energy_cache`]): `GLINT_CACHE_DIR` (empty turns
/// the cache off), else `$XDG_CACHE_HOME/glint`, else `$HOME/.cache/glint`.
pub fn energy_cache_dir() -> Option<PathBuf> {
    let var = |name| std::env::var_os(name).filter(|v| !v.is_empty());
    match std::env::var_os("GLINT_CACHE_DIR") {
        Some(dir) if dir.is_empty() => None,
        Some(dir) => Some(PathBuf::from(dir)),
        None => var("XDG_CACHE_HOME")
            .map(|d| PathBuf::from(d).join("glint"))
            .or_else(|| var("HOME").map(|h| PathBuf::from(h).join(".cache").join("glint"))),
    }
}

/// `--trace-budget`: a share of the light, in [0, 1].
fn budget_share(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(x),
        _ => Err(format!("{s} is not a share of the light in [0, 1]")),
    }
}
