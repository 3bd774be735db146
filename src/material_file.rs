//! Reading a material from a file: glint's material JSON (`glint fit`), or the lobe table that a
//! glint export carries — a `.glb`/`.gltf` (`extras.glint`) or a `.usda` (the `GlintDbrdf` shader's
//! inputs), read by `glint_exporters::import`. Wherever glint takes a material (`render
//! --material`, `export`), any of these will do; a round trip JSON → export → glint gives the same
//! lobe table.
//!
//! Inputs: a path. Outputs: a validated [`Material`] or a one-line [`MaterialFileError`].
//! Invariants: only the named file is read (a USD layer is parsed alone, without composition, and
//! the table it names is not opened); every number is validated against the layout
//! ([`Material::parse`]).

use crate::fit::material::{Material, MaterialError};
use std::path::{Path, PathBuf};

/// Why a material file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MaterialFileError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Invalid {
        path: PathBuf,
        source: MaterialError,
    },
    #[error(transparent)]
    Export(#[from] glint_exporters::ExportError),
}

/// Reads a material by extension: `.glb`, `.gltf`, `.usda`, `.usd` are exports read back; anything
/// else is glint's material JSON.
pub fn read_material(path: &Path) -> Result<Material, MaterialFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let invalid = |source| MaterialFileError::Invalid {
        path: path.to_path_buf(),
        source,
    };
    match ext.as_str() {
        "glb" | "gltf" | "usda" | "usd" => {
            let table = glint_exporters::import::read_lobe_table(path)?;
            Material::from_lobe_table(&table).map_err(invalid)
        }
        _ => {
            let text = std::fs::read_to_string(path).map_err(|source| MaterialFileError::Read {
                path: path.to_path_buf(),
                source,
            })?;
            Material::parse(&text).map_err(invalid)
        }
    }
}
