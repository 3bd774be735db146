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
    /// Bake per-vertex visibility cuts and the transfer for a view (issue #3).
    Bake(Pending),
    /// Fit the BRDF to painted strokes (issue #4).
    Fit(Pending),
    /// Render a fitted material: PRT, Monte Carlo reference (issue #5).
    Render(Pending),
    /// Export a fitted material: EXR table, glTF, USD, MERL (issue #6).
    Export(Pending),
    /// The interactive painting app (issue #7).
    App(Pending),
    /// Accuracy-against-time study (issue #8).
    Study(Pending),
    /// The headless main job on the bundled sample (issue #5).
    Demo(Pending),
}

/// Arguments of a subcommand that this build does not have yet: accepted, then refused clearly.
#[derive(clap::Args)]
struct Pending {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    args: Vec<String>,
}

/// Exit code for a subcommand this build does not implement yet (distinct from errors, 1, and usage, 2).
const EXIT_NOT_AVAILABLE: u8 = 3;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Inspect { scene, env, json }) => inspect(&scene, env.as_deref(), json),
        None => default_job(),
        Some(Command::Bake(_)) => return not_available("bake", 3),
        Some(Command::Fit(_)) => return not_available("fit", 4),
        Some(Command::Render(_)) => return not_available("render", 5),
        Some(Command::Export(_)) => return not_available("export", 6),
        Some(Command::App(_)) => return not_available("app", 7),
        Some(Command::Study(_)) => return not_available("study", 8),
        Some(Command::Demo(_)) => return not_available("demo", 5),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("glint: error: {e:#}");
            ExitCode::FAILURE
        }
    }
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

/// `glint` with no subcommand (`cargo run --release`): the main job that exists in this build. Until the
/// app lands (issue #7) that is inspecting the bundled sample, with a note saying so.
fn default_job() -> Result<()> {
    let samples = samples_dir();
    let scene = samples.join("bunny.glb");
    let env = samples.join("studio_1k.exr");
    eprintln!("glint: the painting app comes with issue #7 and the headless demo with issue #5; inspecting the bundled sample instead.");
    inspect(&scene, Some(&env), false)
}

/// `./samples` when run from the repository, else the samples folder of the source tree it was built from.
fn samples_dir() -> PathBuf {
    let local = PathBuf::from("samples");
    if local.join("bunny.glb").is_file() { local } else { Path::new(env!("CARGO_MANIFEST_DIR")).join("samples") }
}

fn not_available(name: &str, issue: u32) -> ExitCode {
    eprintln!("glint {name}: not available in this build; it comes with issue #{issue}. Nothing was done.");
    ExitCode::from(EXIT_NOT_AVAILABLE)
}
