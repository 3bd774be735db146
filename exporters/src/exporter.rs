//! The exporter interface, the registry of formats and the export-several-at-once helper.
//!
//! Inputs: a [`MaterialDesc`], an optional [`SceneMesh`], an existing output folder and format
//! names. Outputs: the paths written. Invariants: every exporter validates the description and
//! builds every file in memory before writing any, so bad input never leaves a file; every write is
//! atomic (temp file + rename), so an IO failure never leaves a partial file (files already renamed
//! into place stay, each complete); equal inputs give byte-identical files.

use crate::atomic::write_atomic;
use crate::error::ExportError;
use crate::exr::ExrExporter;
use crate::fallback_summary::FallbackExporter;
use crate::gltf::GltfExporter;
use crate::material::{MaterialDesc, SceneMesh};
use crate::merl::MerlExporter;
use crate::mitsuba::MitsubaExporter;
use crate::mtlx::MtlxExporter;
use crate::usd::UsdExporter;
use std::path::{Path, PathBuf};

/// One file an exporter will write.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputFile {
    pub path: PathBuf,
    pub bytes: Vec<u8>,
}

/// A file format glint can write.
pub trait Exporter: Send + Sync {
    /// Short format name used on the command line: `exr`, `gltf`, `usd`, `mtlx`, `fallback`,
    /// `merl`, `mitsuba`.
    fn name(&self) -> &'static str;
    /// Extensions of the files it writes (without the dot); the first is the main file's.
    fn extensions(&self) -> &'static [&'static str];
    /// Whether the format needs a scene with a camera and an environment (a whole scene, not only a
    /// material); `export_all` with no format named leaves such formats out when the scene lacks
    /// them.
    fn needs_view(&self) -> bool {
        false
    }
    /// Builds every file in memory; writes nothing.
    fn build(
        &self,
        desc: &MaterialDesc,
        scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError>;
    /// Builds, then writes each file atomically into `dir` (which must exist). Returns the paths
    /// written.
    fn export(
        &self,
        desc: &MaterialDesc,
        scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<PathBuf>, ExportError> {
        check_dir(dir)?;
        let files = self.build(desc, scene, dir)?;
        write_all(&files)
    }
}

fn check_dir(dir: &Path) -> Result<(), ExportError> {
    if dir.is_dir() {
        Ok(())
    } else {
        Err(ExportError::NotADirectory {
            path: dir.to_path_buf(),
        })
    }
}

fn write_all(files: &[OutputFile]) -> Result<Vec<PathBuf>, ExportError> {
    let mut written = Vec::with_capacity(files.len());
    for f in files {
        write_atomic(&f.path, &f.bytes)?;
        written.push(f.path.clone());
    }
    Ok(written)
}

static REGISTRY: [&dyn Exporter; 7] = [
    &ExrExporter,
    &GltfExporter,
    &UsdExporter,
    &MtlxExporter,
    &FallbackExporter,
    &MerlExporter,
    &MitsubaExporter,
];

/// Every exporter, in a fixed order: exr, gltf, usd, mtlx, fallback, merl, mitsuba.
pub fn registry() -> &'static [&'static dyn Exporter] {
    &REGISTRY
}

/// The exporter named `name`.
pub fn find_exporter(name: &str) -> Option<&'static dyn Exporter> {
    registry().iter().copied().find(|e| e.name() == name)
}

/// Exports `desc` in each named format into `dir`. An empty list means every format, less those
/// that need a view (a camera and an environment) when `scene` has none.
///
/// All names are checked and all files built before the first write. Files several formats share
/// (the EXR table that glTF and USD reference) are written once. Returns the paths written, in
/// order.
pub fn export_all(
    desc: &MaterialDesc,
    scene: Option<&SceneMesh>,
    dir: &Path,
    formats: &[&str],
) -> Result<Vec<PathBuf>, ExportError> {
    let has_view = scene.is_some_and(|s| s.camera.is_some() && s.environment.is_some());
    let chosen: Vec<&dyn Exporter> = if formats.is_empty() {
        registry()
            .iter()
            .copied()
            .filter(|e| has_view || !e.needs_view())
            .collect()
    } else {
        let mut chosen: Vec<&dyn Exporter> = Vec::new();
        for f in formats {
            let e = find_exporter(f).ok_or_else(|| ExportError::UnknownFormat {
                format: f.escape_debug().to_string(),
                known: registry()
                    .iter()
                    .map(|e| e.name())
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
            if !chosen.iter().any(|c| c.name() == e.name()) {
                chosen.push(e);
            }
        }
        chosen
    };
    check_dir(dir)?;
    let mut files: Vec<OutputFile> = Vec::new();
    for e in chosen {
        for f in e.build(desc, scene, dir)? {
            if !files.iter().any(|g| g.path == f.path) {
                files.push(f);
            }
        }
    }
    write_all(&files)
}
