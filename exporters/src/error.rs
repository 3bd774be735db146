//! The one error type of the exporters and readers.
//!
//! Inputs: none (a type). Outputs: [`ExportError`], a `thiserror` enum with structured fields.
//! Invariants: every message is one line (no embedded newlines from our side) and names what was
//! wrong and where; bad input is reported, never panicked on.

use crate::atomic::AtomicWriteError;
use std::path::PathBuf;

/// Why an export (or a reader used by the tests) failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A field of the material description is unusable (wrong length, not finite, out of range).
    #[error("material '{material}': {field} {reason}")]
    InvalidMaterial {
        material: String,
        field: &'static str,
        reason: String,
    },
    /// The material name cannot be used as a file name.
    #[error("material name '{name}' cannot name files: {reason}")]
    InvalidName { name: String, reason: &'static str },
    /// The scene mesh is unusable.
    #[error("scene mesh: {reason}")]
    InvalidMesh { reason: String },
    /// The camera or environment of a scene export is unusable.
    #[error("scene view: {reason}")]
    InvalidView { reason: String },
    /// A format needs what the export was not given (a mesh, a camera, an environment).
    #[error("format '{format}' needs {what}")]
    NeedsScene {
        format: &'static str,
        what: &'static str,
    },
    /// A material file read back (`.glb`, `.usda`) is malformed or holds no glint material.
    #[error("{path}: {reason}")]
    Import { path: PathBuf, reason: String },
    /// A format name that no exporter answers to.
    #[error("unknown export format '{format}' (known: {known})")]
    UnknownFormat { format: String, known: String },
    /// The MERL exporter was asked for but the description carries no MERL table.
    #[error(
        "material '{material}' has no MERL table: sample one with MerlTable::sample before exporting 'merl'"
    )]
    NoMerlTable { material: String },
    /// The output folder is missing or not a folder.
    #[error("cannot export into {path}: not an existing directory")]
    NotADirectory { path: PathBuf },
    /// An atomic write failed (the destination is untouched).
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An EXR table file is malformed or is not a glint table.
    #[error("EXR table {path}: {reason}")]
    Exr { path: PathBuf, reason: String },
    /// MERL bytes are malformed.
    #[error("MERL table: {reason}")]
    Merl { reason: String },
}
