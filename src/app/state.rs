//! The app's document: strokes per view and every setting, the undo/redo history of it, and the
//! session file.
//!
//! Inputs: strokes the user paints (in full-resolution view pixels), settings from the side panel,
//! session JSON. Outputs: the stroke list in the `glint fit` stroke format
//! ([`crate::fit::strokes::ViewStrokes`]), [`crate::fit::run::FitSettings`]-like values, session
//! JSON. Invariants: pure (no IO, no GPU, no threads): unit-tested without a display; strokes
//! painted in the same view (equal [`ViewSpec`] and image size) go to the same view entry; the
//! history always holds the current document at `at`, and a new edit drops what could have been
//! redone.

use crate::fit::strokes::{self, Mode, Stroke, ViewSpec, ViewStrokes};
use crate::sphere::{LobeLayout, srbf};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What a left-drag does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BrushMode {
    /// Target = the brush colour (eq. 23 paint).
    Paint,
    /// Target = S × the value before the stroke.
    Scale,
    /// Target = the diffuse rendering (the stroke format's `erase`): no highlight there, even where
    /// an earlier stroke painted one.
    Erase,
}

/// The brush of eq. 23.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Brush {
    pub mode: BrushMode,
    /// Linear RGB colour in [0, 1]; the painted radiance is `color × intensity`.
    pub color: [f32; 3],
    /// HDR multiplier; negative values remove light.
    pub intensity: f32,
    /// Radius D in full-resolution view pixels.
    pub radius_px: f64,
    /// Falloff κ per pixel.
    pub kappa_per_px: f64,
    /// S of scale strokes.
    pub scale: f64,
}

impl Default for Brush {
    fn default() -> Self {
        Self {
            mode: BrushMode::Paint,
            color: [1.0, 0.96, 0.9],
            intensity: 2.5,
            radius_px: 22.0,
            kappa_per_px: 0.04,
            scale: 2.0,
        }
    }
}

impl Brush {
    /// The stroke this brush paints along `points`.
    pub fn stroke(&self, points: Vec<[f64; 2]>) -> Stroke {
        let (mode, scale) = match self.mode {
            BrushMode::Paint => (Mode::Paint, 1.0),
            BrushMode::Scale => (Mode::Scale, self.scale),
            BrushMode::Erase => (Mode::Erase, 1.0),
        };
        let color = self.color.map(|c| c as f64 * self.intensity as f64);
        Stroke {
            points,
            mode,
            color,
            scale,
            radius: self.radius_px,
            kappa: self.kappa_per_px,
        }
    }
}

/// Everything the fit and the preview depend on besides the strokes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub brush: Brush,
    pub rho_d: [f64; 3],
    pub f0: f64,
    /// Least-squares weight of unpainted pixels (the stroke file's `keep_weight`).
    pub keep_weight: f64,
    pub energy_limit: bool,
    /// Lobe width σ (radians).
    pub sigma: f64,
    /// Lobe count J: ring lobes for isotropic scenes; a hemicube of about J lobes otherwise.
    pub lobe_count: usize,
    /// Environment rotation about +Y (degrees).
    pub env_rotation_deg: f64,
    /// Exposure of the preview's tone mapping.
    pub exposure: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            brush: Brush::default(),
            rho_d: [0.5; 3],
            f0: 0.04,
            keep_weight: 0.1,
            energy_limit: true,
            sigma: srbf::PAPER_SIGMA,
            lobe_count: 24,
            env_rotation_deg: 0.0,
            exposure: 1.0,
        }
    }
}

impl Settings {
    /// The fit settings these app settings stand for (the lobe layout from J and the frame).
    pub fn fit_settings(&self, anisotropic: bool) -> crate::fit::run::FitSettings {
        crate::fit::run::FitSettings {
            rho_d: self.rho_d,
            f0: self.f0,
            energy_limit: self.energy_limit,
            layout: Some(self.layout(anisotropic)),
            sigma: self.sigma,
            fit_size: None,
            rotation_rad: self.env_rotation_deg.to_radians(),
        }
    }

    /// The lobe layout for a scene with or without a tangent field: `lobe_count` rings, or the
    /// hemicube n×n×3 nearest to `lobe_count` (n ≥ 2).
    pub fn layout(&self, anisotropic: bool) -> LobeLayout {
        if anisotropic {
            let n = ((self.lobe_count as f64 / 3.0).sqrt().round() as usize).max(2);
            LobeLayout::Hemicube { n }
        } else {
            LobeLayout::Isotropic {
                count: self.lobe_count.max(1),
            }
        }
    }

    /// One-line reason when a setting cannot be fitted.
    pub fn validate(&self) -> Result<(), String> {
        if self.rho_d.iter().any(|r| !(0.0..=1.0).contains(r)) || !(0.0..=1.0).contains(&self.f0) {
            return Err(format!(
                "ρd {:?} and F0 {} must lie in [0, 1]",
                self.rho_d, self.f0
            ));
        }
        if !(self.keep_weight.is_finite() && self.keep_weight >= 0.0) {
            return Err(format!(
                "keep weight {} must be finite and ≥ 0",
                self.keep_weight
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0 && self.sigma < 1.0) {
            return Err(format!("σ {} must lie in (0, 1) radians", self.sigma));
        }
        if !(1..=1024).contains(&self.lobe_count) {
            return Err(format!("J {} must lie in 1..=1024", self.lobe_count));
        }
        if !self.env_rotation_deg.is_finite() {
            return Err("the environment rotation must be finite".into());
        }
        Ok(())
    }
}

/// What one undo step restores: the strokes of every view and the settings.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Document {
    pub settings: Settings,
    /// Strokes per view, in the `glint fit` stroke format.
    pub views: Vec<ViewStrokes>,
}

impl Document {
    /// Appends a stroke to the view's entry (made if new).
    pub fn add_stroke(&mut self, view: ViewSpec, image_size: [u32; 2], stroke: Stroke) {
        let keep_weight = self.settings.keep_weight;
        match self
            .views
            .iter_mut()
            .find(|v| v.view == view && v.image_size == image_size)
        {
            Some(v) => v.strokes.push(stroke),
            None => self.views.push(ViewStrokes {
                view,
                image_size,
                keep_weight,
                strokes: vec![stroke],
            }),
        }
    }

    /// Number of strokes over all views.
    pub fn stroke_count(&self) -> usize {
        self.views.iter().map(|v| v.strokes.len()).sum()
    }

    /// The stroke list as `glint fit` reads it, with the current keep weight in every view.
    pub fn fit_views(&self) -> Vec<ViewStrokes> {
        self.views
            .iter()
            .map(|v| ViewStrokes {
                keep_weight: self.settings.keep_weight,
                ..v.clone()
            })
            .collect()
    }

    /// The stroke file (JSON list of views), as `glint fit --strokes` reads it.
    pub fn strokes_json(&self) -> String {
        serde_json::to_string_pretty(&self.fit_views()).unwrap_or_else(|_| "[]".into())
    }
}

/// Undo/redo over whole documents (they are small: strokes and settings).
#[derive(Debug, Clone)]
pub struct History {
    states: Vec<Document>,
    at: usize,
}

impl History {
    /// A history holding `doc` only.
    pub fn new(doc: Document) -> Self {
        Self {
            states: vec![doc],
            at: 0,
        }
    }

    /// The current document.
    pub fn current(&self) -> &Document {
        &self.states[self.at]
    }

    /// Records `doc` as the new current state (drops the redo branch); equal states are not
    /// recorded.
    pub fn push(&mut self, doc: Document) {
        if *self.current() == doc {
            return;
        }
        self.states.truncate(self.at + 1);
        self.states.push(doc);
        self.at += 1;
    }

    /// Steps back; `None` at the oldest state.
    pub fn undo(&mut self) -> Option<&Document> {
        if self.at == 0 {
            return None;
        }
        self.at -= 1;
        Some(self.current())
    }

    /// Steps forward; `None` at the newest state.
    pub fn redo(&mut self) -> Option<&Document> {
        if self.at + 1 >= self.states.len() {
            return None;
        }
        self.at += 1;
        Some(self.current())
    }

    pub fn can_undo(&self) -> bool {
        self.at > 0
    }

    pub fn can_redo(&self) -> bool {
        self.at + 1 < self.states.len()
    }
}

/// Version of the session file.
pub const SESSION_VERSION: u32 = 1;

/// A saved session: the inputs, the settings and the strokes (the `glint fit` stroke format).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Session {
    pub glint_session: u32,
    pub scene: PathBuf,
    pub env: PathBuf,
    pub settings: Settings,
    pub strokes: Vec<ViewStrokes>,
}

impl Session {
    /// The session of a document.
    pub fn new(scene: PathBuf, env: PathBuf, doc: &Document) -> Self {
        Self {
            glint_session: SESSION_VERSION,
            scene,
            env,
            settings: doc.settings.clone(),
            strokes: doc.fit_views(),
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "{}".into())
    }

    /// Parses and validates a session (strokes as strictly as `glint fit` reads them).
    pub fn parse(text: &str) -> Result<Self, String> {
        let session: Session =
            serde_json::from_str(text).map_err(|e| format!("not a glint session: {e}"))?;
        if session.glint_session != SESSION_VERSION {
            return Err(format!(
                "session version {} is not {SESSION_VERSION}",
                session.glint_session
            ));
        }
        session.settings.validate()?;
        let strokes = serde_json::to_string(&session.strokes).map_err(|e| e.to_string())?;
        strokes::parse(&strokes).map_err(|e| e.to_string())?;
        Ok(session)
    }

    /// The document it restores.
    pub fn document(&self) -> Document {
        Document {
            settings: self.settings.clone(),
            views: self.strokes.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(x: f64) -> Stroke {
        Brush::default().stroke(vec![[x, 10.0]])
    }

    #[test]
    fn strokes_of_one_view_share_an_entry_and_new_views_add_one() {
        let mut doc = Document::default();
        let named = ViewSpec::Name("default".into());
        let orbit = ViewSpec::Orbit {
            orbit: [30.0, 10.0, 3.0],
        };
        doc.add_stroke(named.clone(), [640, 480], dot(1.0));
        doc.add_stroke(named.clone(), [640, 480], dot(2.0));
        doc.add_stroke(orbit.clone(), [640, 480], dot(3.0));
        assert_eq!(doc.views.len(), 2);
        assert_eq!(doc.views[0].strokes.len(), 2);
        assert_eq!(doc.views[1].view, orbit);
        assert_eq!(doc.stroke_count(), 3);
        // The stroke file reads back with glint fit's parser.
        let parsed = strokes::parse(&doc.strokes_json()).unwrap();
        assert_eq!(parsed, doc.fit_views());
    }

    #[test]
    fn brush_modes_map_to_the_stroke_format() {
        let mut b = Brush {
            intensity: -2.0,
            ..Brush::default()
        };
        let s = b.stroke(vec![[0.0, 0.0]]);
        assert_eq!(s.mode, Mode::Paint);
        assert!(
            (s.color[0] + 2.0).abs() < 1e-6,
            "negative HDR paint is kept: {:?}",
            s.color
        );
        b.mode = BrushMode::Erase;
        let s = b.stroke(vec![[0.0, 0.0]]);
        assert_eq!(s.mode, Mode::Erase);
        b.mode = BrushMode::Scale;
        assert_eq!(b.stroke(vec![[0.0, 0.0]]).scale, b.scale);
    }

    #[test]
    fn undo_redo_walks_the_history_and_a_new_edit_drops_the_redo_branch() {
        let mut h = History::new(Document::default());
        assert!(h.undo().is_none());
        let mut a = Document::default();
        a.add_stroke(ViewSpec::Index(0), [64, 48], dot(1.0));
        let mut b = a.clone();
        b.add_stroke(ViewSpec::Index(0), [64, 48], dot(2.0));
        h.push(a.clone());
        h.push(b.clone());
        h.push(b.clone()); // unchanged: not recorded
        assert_eq!(h.undo(), Some(&a));
        assert_eq!(h.undo(), Some(&Document::default()));
        assert!(h.undo().is_none());
        assert_eq!(h.redo(), Some(&a));
        let mut c = a.clone();
        c.settings.f0 = 0.5;
        h.push(c.clone());
        assert!(!h.can_redo(), "a new edit drops the redo branch");
        assert_eq!(h.current(), &c);
        assert_eq!(h.undo(), Some(&a));
    }

    #[test]
    fn sessions_round_trip_and_bad_ones_are_refused() {
        let mut doc = Document::default();
        doc.settings.rho_d = [0.3, 0.4, 0.5];
        doc.add_stroke(ViewSpec::Name("default".into()), [640, 480], dot(5.0));
        let s = Session::new("a.glb".into(), "b.exr".into(), &doc);
        let back = Session::parse(&s.to_json()).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.document(), doc);
        assert!(Session::parse("{").is_err());
        let bad = s
            .to_json()
            .replace("\"glint_session\": 1", "\"glint_session\": 9");
        assert!(Session::parse(&bad).unwrap_err().contains("version"));
        let mut worse = s.clone();
        worse.strokes[0].strokes[0].radius = -1.0;
        assert!(
            Session::parse(&worse.to_json())
                .unwrap_err()
                .contains("radius")
        );
        let mut odd = s;
        odd.settings.f0 = 2.0;
        assert!(Session::parse(&odd.to_json()).is_err());
    }

    #[test]
    fn layouts_follow_the_lobe_count() {
        let s = Settings {
            lobe_count: 147,
            ..Settings::default()
        };
        assert_eq!(s.layout(true), LobeLayout::PAPER);
        assert_eq!(s.layout(false), LobeLayout::Isotropic { count: 147 });
    }
}
