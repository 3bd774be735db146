//! The material: the fitted lobe table (what `glint fit` writes and the renderers and exporters
//! read).
//!
//! JSON, documented by `src/fit/material.schema.json`. It carries everything needed to evaluate the
//! BRDF without glint: the model, λ and σ, the layout and the J centres (local frame: z = normal, x
//! = tangent), the 3 × J coefficients, ρd and F0, the frame and BRDF conventions, and fit
//! statistics.
//!
//! Inputs: fit results. Outputs: JSON text; parsing validates model, version, sizes and finiteness.
//! Invariants: no IO (callers read and write files, atomically).

use crate::sphere::{LobeLayout, LobeSet, SphereError};
use serde::{Deserialize, Serialize};

/// The model name written into every material.
pub const MODEL: &str = "dbrdf-srbf";
/// Current version of the material format.
pub const MATERIAL_VERSION: u32 = 1;
/// The BRDF and frame conventions repeated in every file: one definition, in the exporters crate
/// (the exact statement is docs/conventions.md).
pub use glint_exporters::material::{FRAME_CONVENTION, brdf_convention};

/// Statistics of the fit that made the material.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FitStats {
    /// Weighted RMS residual per channel.
    pub residual_rms: [f64; 3],
    /// Energy rows at their bound, per channel.
    pub active_energy_rows: [usize; 3],
    /// Active constraints (bounds and rows) per channel.
    pub active_constraints: [usize; 3],
    pub iterations: [usize; 3],
    pub solve_seconds: f64,
    pub pixels: usize,
    pub views: usize,
    pub energy_limit: bool,
    /// Strokes that touched no pixel of the object (ignored).
    pub strokes_off_object: usize,
    /// Free-text notes (e.g. "no strokes: the current material is returned unchanged").
    pub notes: Vec<String>,
}

impl FitStats {
    /// Lines for people: pixels and views, residuals, active energy rows, iterations, solve time
    /// and the notes (as `glint fit` prints them).
    pub fn summary(&self) -> String {
        let r = self.residual_rms;
        let mut lines = vec![format!(
            "{} pixels in {} view(s); residual (weighted RMS) R {:.4e} G {:.4e} B {:.4e}; active energy rows {:?}; \
             iterations {:?}; solve {:.2} ms",
            self.pixels,
            self.views,
            r[0],
            r[1],
            r[2],
            self.active_energy_rows,
            self.iterations,
            self.solve_seconds * 1e3
        )];
        lines.extend(self.notes.iter().map(|n| format!("note: {n}")));
        lines.join("\n")
    }
}

/// A fitted material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub model: String,
    pub version: u32,
    pub lambda: f64,
    pub sigma: f64,
    pub layout: LobeLayout,
    pub centres: Vec<[f64; 3]>,
    /// 3 × J, per channel (R, G, B).
    pub coefficients: [Vec<f64>; 3],
    pub rho_d: [f64; 3],
    pub f0: f64,
    pub frame: String,
    pub brdf_convention: String,
    pub fit: FitStats,
}

/// Why a material file cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MaterialError {
    #[error("material is not valid JSON: {0}")]
    Json(String),
    #[error("material model '{found}' is not '{MODEL}'")]
    Model { found: String },
    #[error("material format version {found}; this glint reads version {MATERIAL_VERSION}")]
    Version { found: u32 },
    #[error("material: {0}")]
    Invalid(String),
}

impl Material {
    /// A material with the given coefficients for a lobe set.
    pub fn new(
        lobes: &LobeSet,
        sigma: f64,
        coefficients: [Vec<f64>; 3],
        rho_d: [f64; 3],
        f0: f64,
        fit: FitStats,
    ) -> Self {
        Self {
            model: MODEL.into(),
            version: MATERIAL_VERSION,
            lambda: lobes.lambda(),
            sigma,
            layout: lobes.layout(),
            centres: lobes.centres().iter().map(|c| c.to_array()).collect(),
            coefficients,
            rho_d,
            f0,
            frame: FRAME_CONVENTION.into(),
            brdf_convention: brdf_convention(lobes.layout().is_isotropic()).into(),
            fit,
        }
    }

    /// The lobe set this material's coefficients refer to.
    pub fn lobes(&self) -> Result<LobeSet, SphereError> {
        LobeSet::new(self.layout, self.lambda)
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// A material from the lobe table of a glint export (the glTF extras' or the USD shader's
    /// object, `layout` by name, no fit statistics), validated as [`Material::parse`] validates.
    pub fn from_lobe_table(table: &serde_json::Value) -> Result<Self, MaterialError> {
        let mut value = table.clone();
        let name = value
            .get("layout")
            .and_then(|l| l.as_str())
            .ok_or_else(|| MaterialError::Invalid("the lobe table has no layout name".into()))?;
        let layout = LobeLayout::from_name(name).ok_or_else(|| {
            MaterialError::Invalid(format!("unknown lobe layout '{}'", name.escape_debug()))
        })?;
        let isotropic = value.get("isotropic").and_then(|b| b.as_bool());
        if isotropic.is_some_and(|i| i != layout.is_isotropic()) {
            return Err(MaterialError::Invalid(format!(
                "'isotropic' contradicts the layout {name}"
            )));
        }
        value["layout"] =
            serde_json::to_value(layout).map_err(|e| MaterialError::Json(e.to_string()))?;
        if let Some(object) = value.as_object_mut() {
            object.remove("isotropic");
            object.insert("frame".into(), FRAME_CONVENTION.into());
            object.insert(
                "brdf_convention".into(),
                brdf_convention(layout.is_isotropic()).into(),
            );
            object.insert(
                "fit".into(),
                serde_json::to_value(FitStats {
                    notes: vec![
                        "read back from an export: the fit statistics are not carried".into(),
                    ],
                    ..FitStats::default()
                })
                .map_err(|e| MaterialError::Json(e.to_string()))?,
            );
        }
        Self::parse(&value.to_string())
    }

    /// Parses and validates a material.
    pub fn parse(text: &str) -> Result<Self, MaterialError> {
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| MaterialError::Json(e.to_string()))?;
        if let Some(model) = value.get("model").and_then(|m| m.as_str())
            && model != MODEL
        {
            return Err(MaterialError::Model {
                found: model.into(),
            });
        }
        if let Some(version) = value.get("version").and_then(|v| v.as_u64())
            && version != MATERIAL_VERSION as u64
        {
            return Err(MaterialError::Version {
                found: version.min(u32::MAX as u64) as u32,
            });
        }
        let mut m: Material =
            serde_json::from_value(value).map_err(|e| MaterialError::Json(e.to_string()))?;
        let j = m.layout.count();
        if m.centres.len() != j || m.coefficients.iter().any(|c| c.len() != j) {
            return Err(MaterialError::Invalid(format!(
                "layout {} needs {j} centres and 3 x {j} coefficients",
                m.layout.name()
            )));
        }
        let numbers = m
            .coefficients
            .iter()
            .flatten()
            .chain(m.centres.iter().flatten())
            .chain(&m.rho_d)
            .chain([&m.f0, &m.lambda, &m.sigma]);
        if numbers.into_iter().any(|x| !x.is_finite()) {
            return Err(MaterialError::Invalid("a number is not finite".into()));
        }
        if m.coefficients.iter().flatten().any(|&c| c < 0.0) {
            return Err(MaterialError::Invalid(
                "a coefficient is negative (p(h) must be >= 0)".into(),
            ));
        }
        let lobes = m
            .lobes()
            .map_err(|e| MaterialError::Invalid(e.to_string()))?;
        if lobes
            .centres()
            .iter()
            .zip(&m.centres)
            .any(|(a, b)| (a.x - b[0]).abs() + (a.y - b[1]).abs() + (a.z - b[2]).abs() > 1e-9)
        {
            return Err(MaterialError::Invalid(
                "the centres do not match the layout".into(),
            ));
        }
        // The convention strings are descriptive: a material written by an older glint (whose
        // string named point lobes for every layout) is read with the exact statement for its
        // layout.
        m.brdf_convention = brdf_convention(m.layout.is_isotropic()).into();
        m.frame = FRAME_CONVENTION.into();
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_other_versions() {
        let lobes = LobeSet::new(LobeLayout::PAPER, 81.06).unwrap();
        let c: Vec<f64> = (0..147).map(|j| j as f64 * 0.01).collect();
        let m = Material::new(
            &lobes,
            std::f64::consts::PI / 40.0,
            [c.clone(), c.clone(), c],
            [0.5, 0.4, 0.3],
            0.04,
            FitStats::default(),
        );
        let text = m.to_json();
        assert_eq!(Material::parse(&text).unwrap(), m);
        let other = text.replace("\"version\": 1", "\"version\": 2");
        assert_eq!(
            Material::parse(&other).unwrap_err(),
            MaterialError::Version { found: 2 }
        );
        assert!(matches!(
            Material::parse(&text.replace("dbrdf-srbf", "ggx")),
            Err(MaterialError::Model { .. })
        ));
        assert!(matches!(Material::parse("{"), Err(MaterialError::Json(_))));
        let negative = text.replacen("0.01,", "-0.01,", 1);
        assert!(matches!(
            Material::parse(&negative),
            Err(MaterialError::Invalid(_))
        ));
    }
}

#[cfg(test)]
mod schema_tests {
    use super::*;

    /// The schema names exactly the fields a material serialises.
    #[test]
    fn schema_matches_the_type() {
        let schema: serde_json::Value =
            serde_json::from_str(include_str!("material.schema.json")).unwrap();
        let lobes = LobeSet::new(LobeLayout::Isotropic { count: 4 }, 10.0).unwrap();
        let m = Material::new(
            &lobes,
            0.3,
            [vec![0.0; 4], vec![0.0; 4], vec![0.0; 4]],
            [0.5; 3],
            0.04,
            FitStats::default(),
        );
        let value = serde_json::to_value(&m).unwrap();
        let mut have: Vec<&String> = value.as_object().unwrap().keys().collect();
        let mut want: Vec<&String> = schema["properties"].as_object().unwrap().keys().collect();
        have.sort();
        want.sort();
        assert_eq!(have, want);
        let mut fit_have: Vec<&String> = value["fit"].as_object().unwrap().keys().collect();
        let mut fit_want: Vec<&String> = schema["properties"]["fit"]["properties"]
            .as_object()
            .unwrap()
            .keys()
            .collect();
        fit_have.sort();
        fit_want.sort();
        assert_eq!(fit_have, fit_want);
    }
}
