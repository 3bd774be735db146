//! Where an export came from, written into every file it makes (glTF extras, USD customData, the
//! EXR header, the Mitsuba scene): one set of keys for the CLI and the app.
//!
//! Keys: `tool` (glint and its version; "app" when the app exported), `fit_residual_rms`,
//! `fit_pixels`, and where known `material_file` with `material_hash_fnv1a64`, `bake`,
//! `scene_file`, `env_file`, `env_rotation_deg` (only when not 0), and what the fallback fit adds
//! (`fallback_isotropic_relative_error`). File names only, never folders. Invariants: hashing the
//! material file is the only IO.

use crate::bake::file::{BakeFileError, hash_file};
use crate::fit::material::Material;
use std::collections::BTreeMap;
use std::path::Path;

/// Which program made an export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    Cli,
    App,
}

/// The provenance of one export (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Provenance {
    entries: BTreeMap<String, String>,
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default()
}

impl Provenance {
    /// The tool and the fit's figures.
    pub fn new(tool: Tool, material: &Material) -> Self {
        let mut p = Self::default();
        let suffix = if tool == Tool::App { " app" } else { "" };
        p.set(
            "tool",
            format!("glint {}{suffix}", env!("CARGO_PKG_VERSION")),
        );
        p.set(
            "fit_residual_rms",
            format!("{:?}", material.fit.residual_rms),
        );
        p.set("fit_pixels", material.fit.pixels.to_string());
        p
    }

    /// The material file the export read, by name and content hash.
    pub fn material_file(&mut self, path: &Path) -> Result<&mut Self, BakeFileError> {
        self.set("material_file", file_name(path));
        self.set("material_hash_fnv1a64", hash_file(path)?);
        Ok(self)
    }

    /// The bake the scene came from.
    pub fn bake(&mut self, path: &Path) -> &mut Self {
        self.set("bake", file_name(path))
    }

    pub fn scene_file(&mut self, path: &Path) -> &mut Self {
        self.set("scene_file", file_name(path))
    }

    pub fn env_file(&mut self, path: &Path) -> &mut Self {
        self.set("env_file", file_name(path))
    }

    /// The environment's rotation about +Y, recorded when it is not 0.
    pub fn env_rotation_deg(&mut self, degrees: f64) -> &mut Self {
        if degrees != 0.0 {
            self.set("env_rotation_deg", format!("{degrees:?}"));
        }
        self
    }

    /// Sets one entry.
    pub fn set(&mut self, key: &str, value: String) -> &mut Self {
        self.entries.insert(key.to_string(), value);
        self
    }

    pub fn get(&self, key: &str) -> Option<&str> {
        self.entries.get(key).map(String::as_str)
    }

    /// The entries, as the exporters write them.
    pub fn into_map(self) -> BTreeMap<String, String> {
        self.entries
    }
}
