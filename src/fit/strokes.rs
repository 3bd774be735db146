//! Strokes: the stroke file and the brush of eq. 23 (method.md §6).
//!
//! File (JSON; schema in `src/fit/strokes.schema.json`): one object, or a list of them (one per
//! view; multi-view fitting puts all their pixels into one solve): `{"view": <camera name | camera
//! index | {"orbit": [az°, el°, dist]}>, "image_size": [w, h],
//!   "keep_weight": 0.1, "strokes": [{"points": [[x, y], ...], "mode": "paint" | "scale" | "erase",
//!   "color": [r, g, b], "scale": S, "radius": D, "kappa": κ}]}`.
//! Points are pixels of the full-resolution view (`image_size`), origin top-left; `color` is linear
//! radiance and may be negative (it then removes a highlight).
//!
//! Brush: for a pixel at distance d (full-resolution pixels) from the stroke's polyline, w = exp(−κ
//! d) if d ≤ D else 0, and the target becomes B = w C + (1 − w) B' (paint), B = w S B' + (1 − w) B'
//! (scale) or B = w D + (1 − w) B' (erase: D is the diffuse rendering, so an erase stroke removes a
//! highlight painted by an earlier stroke too), B' the value before the stroke; strokes apply in
//! file order. The least-squares weight of a pixel is keep_weight + (1 − keep_weight) · max over
//! strokes of w: painted pixels count fully, unpainted ones keep their current value with the
//! user's keep weight (the paper's remedy for unpainted regions changing).
//!
//! Inputs: stroke text, fit-pixel positions, current radiance. Outputs: targets and weights.
//! Invariants: no IO (the caller reads the file); every number is validated finite; no panics.

use serde::{Deserialize, Serialize};

/// Which view a set of strokes was painted in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ViewSpec {
    /// A glTF camera by name.
    Name(String),
    /// A glTF camera by index (in the scene's camera list).
    Index(usize),
    /// An orbit around the bounds: azimuth°, elevation°, distance in bounding radii (0 = fit).
    Orbit { orbit: [f32; 3] },
}

/// Paint replaces, scale multiplies, erase returns to the diffuse rendering (no highlight).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Paint,
    Scale,
    Erase,
}

fn default_color() -> [f64; 3] {
    [1.0, 1.0, 1.0]
}
fn default_scale() -> f64 {
    1.0
}
fn default_keep() -> f64 {
    0.1
}

/// One stroke.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stroke {
    pub points: Vec<[f64; 2]>,
    pub mode: Mode,
    #[serde(default = "default_color")]
    pub color: [f64; 3],
    #[serde(default = "default_scale")]
    pub scale: f64,
    /// Brush radius D (full-resolution pixels).
    pub radius: f64,
    /// Falloff κ (per pixel).
    pub kappa: f64,
}

/// The strokes painted in one view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewStrokes {
    pub view: ViewSpec,
    pub image_size: [u32; 2],
    #[serde(default = "default_keep")]
    pub keep_weight: f64,
    pub strokes: Vec<Stroke>,
}

/// Why a stroke file cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StrokeError {
    #[error("stroke file is not valid JSON for glint strokes: {0}")]
    Json(String),
    #[error("stroke file: {0}")]
    Invalid(String),
}

#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    Many(Vec<ViewStrokes>),
    One(ViewStrokes),
}

/// Parses and validates a stroke file.
pub fn parse(text: &str) -> Result<Vec<ViewStrokes>, StrokeError> {
    // Parse once as a generic value for a precise error, then as our types.
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| StrokeError::Json(e.to_string()))?;
    let views = match serde_json::from_value::<OneOrMany>(value.clone()) {
        Ok(OneOrMany::Many(v)) => v,
        Ok(OneOrMany::One(v)) => vec![v],
        Err(_) => {
            // Re-run the single-object parse to get serde's message for the common case.
            let err = match &value {
                serde_json::Value::Array(items) => {
                    items.iter().enumerate().find_map(|(i, item)| {
                        serde_json::from_value::<ViewStrokes>(item.clone())
                            .err()
                            .map(|e| format!("view {i}: {e}"))
                    })
                }
                _ => serde_json::from_value::<ViewStrokes>(value.clone())
                    .err()
                    .map(|e| e.to_string()),
            };
            return Err(StrokeError::Json(
                err.unwrap_or_else(|| "unrecognised structure".into()),
            ));
        }
    };
    for (i, v) in views.iter().enumerate() {
        validate(v).map_err(|m| StrokeError::Invalid(format!("view {i}: {m}")))?;
    }
    Ok(views)
}

fn validate(v: &ViewStrokes) -> Result<(), String> {
    let [w, h] = v.image_size;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("image_size {w}x{h} is outside 1..16384"));
    }
    if !(v.keep_weight.is_finite() && v.keep_weight >= 0.0) {
        return Err(format!(
            "keep_weight {} must be finite and >= 0",
            v.keep_weight
        ));
    }
    if let ViewSpec::Orbit { orbit } = &v.view
        && orbit.iter().any(|x| !x.is_finite())
    {
        return Err("orbit values must be finite".into());
    }
    for (k, s) in v.strokes.iter().enumerate() {
        let bad = |m: String| Err(format!("stroke {k}: {m}"));
        if s.points.is_empty() {
            return bad("has no points".into());
        }
        if s.points.iter().flatten().any(|x| !x.is_finite()) {
            return bad("a point is not finite".into());
        }
        if s.color.iter().any(|x| !x.is_finite()) || !s.scale.is_finite() {
            return bad("color and scale must be finite".into());
        }
        if !(s.radius.is_finite() && s.radius > 0.0) {
            return bad(format!("radius {} must be finite and > 0", s.radius));
        }
        if !(s.kappa.is_finite() && s.kappa >= 0.0) {
            return bad(format!("kappa {} must be finite and >= 0", s.kappa));
        }
    }
    Ok(())
}

/// Distance from p to the segment [a, b].
pub fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (cx, cy) = (a[0] + t * dx, a[1] + t * dy);
    ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt()
}

/// Distance from p to a polyline (a single point is a dot).
pub fn polyline_distance(p: [f64; 2], points: &[[f64; 2]]) -> f64 {
    match points {
        [] => f64::INFINITY,
        [a] => segment_distance(p, *a, *a),
        _ => points
            .windows(2)
            .map(|w| segment_distance(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

impl Stroke {
    /// The brush weight w at full-resolution pixel position p (eq. 23).
    pub fn weight(&self, p: [f64; 2]) -> f64 {
        let d = polyline_distance(p, &self.points);
        if d <= self.radius {
            (-self.kappa * d).exp()
        } else {
            0.0
        }
    }

    /// Applies the stroke to the value before it, B', at weight w; `diffuse` is the pixel's diffuse
    /// rendering (what an erase stroke returns to).
    pub fn apply(&self, w: f64, before: [f64; 3], diffuse: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|c| match self.mode {
            Mode::Paint => w * self.color[c] + (1.0 - w) * before[c],
            Mode::Scale => w * self.scale * before[c] + (1.0 - w) * before[c],
            Mode::Erase => w * diffuse[c] + (1.0 - w) * before[c],
        })
    }
}

/// Targets and least-squares weights of the fit pixels of one view.
#[derive(Debug, Clone, PartialEq)]
pub struct Targets {
    /// Target radiance per pixel.
    pub target: Vec<[f64; 3]>,
    /// Least-squares weight per pixel.
    pub weight: Vec<f64>,
    /// Pixels that at least one stroke touched (w > 0).
    pub touched: usize,
    /// Indices of strokes that touched no pixel of the object (ignored).
    pub off_object: Vec<usize>,
}

/// Targets for `pixels` (fit-resolution pixel coordinates, of a fit image of `fit_size`) whose
/// current radiance is `current` (the diffuse rendering, c = 0: what strokes paint over and erase
/// returns to), under the strokes of `view`.
pub fn targets(
    view: &ViewStrokes,
    pixels: &[(u32, u32)],
    fit_size: (u32, u32),
    current: &[[f64; 3]],
) -> Targets {
    let sx = view.image_size[0] as f64 / fit_size.0.max(1) as f64;
    let sy = view.image_size[1] as f64 / fit_size.1.max(1) as f64;
    let mut target: Vec<[f64; 3]> = current.to_vec();
    let mut max_w = vec![0.0f64; pixels.len()];
    let mut hits = vec![0usize; view.strokes.len()];
    for (i, &(x, y)) in pixels.iter().enumerate() {
        let p = [(x as f64 + 0.5) * sx, (y as f64 + 0.5) * sy];
        for (k, s) in view.strokes.iter().enumerate() {
            let w = s.weight(p);
            if w > 0.0 {
                if let Some(t) = target.get_mut(i) {
                    *t = s.apply(w, *t, current[i]);
                }
                max_w[i] = max_w[i].max(w);
                hits[k] += 1;
            }
        }
    }
    let keep = view.keep_weight;
    Targets {
        weight: max_w.iter().map(|w| keep + (1.0 - keep) * w).collect(),
        touched: max_w.iter().filter(|w| **w > 0.0).count(),
        off_object: hits
            .iter()
            .enumerate()
            .filter(|(_, h)| **h == 0)
            .map(|(k, _)| k)
            .collect(),
        target,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: &str = r#"{"view": "default", "image_size": [640, 480], "strokes": [
        {"points": [[100, 100], [200, 100]], "mode": "paint", "color": [2, 2, 2], "radius": 10, "kappa": 0.1}]}"#;

    #[test]
    fn parses_one_view_many_views_and_orbits() {
        let v = parse(ONE).unwrap();
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].keep_weight, 0.1);
        assert_eq!(v[0].view, ViewSpec::Name("default".into()));
        let many = format!(
            "[{ONE}, {}]",
            ONE.replace("\"default\"", "{\"orbit\": [30, 20, 0]}")
                .replace("\"paint\"", "\"scale\"")
        );
        let v = parse(&many).unwrap();
        assert_eq!(v.len(), 2);
        assert_eq!(
            v[1].view,
            ViewSpec::Orbit {
                orbit: [30.0, 20.0, 0.0]
            }
        );
        assert_eq!(v[1].strokes[0].mode, Mode::Scale);
        assert_eq!(
            parse(&ONE.replace("\"default\"", "2")).unwrap()[0].view,
            ViewSpec::Index(2)
        );
    }

    #[test]
    fn malformed_files_give_one_line_errors() {
        for (bad, needle) in [
            ("{", "JSON"),
            (
                r#"{"view": "a", "image_size": [0, 10], "strokes": []}"#,
                "image_size",
            ),
            (&ONE.replace("\"radius\": 10", "\"radius\": -1"), "radius"),
            (&ONE.replace("\"paint\"", "\"smudge\""), "JSON"),
            (&ONE.replace("[[100, 100], [200, 100]]", "[]"), "no points"),
            (
                &ONE.replace("\"kappa\": 0.1", "\"kappa\": 0.1, \"extra\": 1"),
                "JSON",
            ),
        ] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains(needle) && !e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn brush_follows_eq_23() {
        let s = &parse(ONE).unwrap()[0].strokes[0];
        // On the segment: d = 0, w = 1, B = C.
        assert_eq!(
            s.apply(s.weight([150.0, 100.0]), [0.5; 3], [0.5; 3]),
            [2.0; 3]
        );
        // 5 px away: w = exp(-0.5).
        let w = s.weight([150.0, 105.0]);
        assert!((w - (-0.5f64).exp()).abs() < 1e-15);
        let b = s.apply(w, [0.5; 3], [0.5; 3]);
        assert!((b[0] - (w * 2.0 + (1.0 - w) * 0.5)).abs() < 1e-15);
        // Past the end cap, distance to the end point; beyond D, untouched.
        assert!((s.weight([203.0, 104.0]) - (-0.5f64).exp()).abs() < 1e-12);
        assert_eq!(s.weight([150.0, 111.0]), 0.0);
        // Scale mode multiplies.
        let mut sc = s.clone();
        sc.mode = Mode::Scale;
        sc.scale = 3.0;
        assert_eq!(
            sc.apply(1.0, [0.5, 1.0, 0.0], [0.5, 1.0, 0.0]),
            [1.5, 3.0, 0.0]
        );
        // Negative colour removes a highlight (the target goes below the current value).
        let mut neg = s.clone();
        neg.color = [-1.0; 3];
        assert!(neg.apply(0.5, [0.5; 3], [0.5; 3])[0] < 0.0);
    }

    #[test]
    fn erase_returns_to_the_diffuse_rendering_even_over_an_earlier_highlight() {
        // A paint stroke, then an erase stroke over the same segment: at full weight the target is
        // the diffuse value again (a scale stroke with S = 1 would have kept the painted
        // highlight).
        let text = r#"{"view": "default", "image_size": [100, 100], "keep_weight": 0.1, "strokes": [
            {"points": [[10, 10], [90, 10]], "mode": "paint", "color": [3, 3, 3], "radius": 8, "kappa": 0},
            {"points": [[50, 10]], "mode": "erase", "radius": 4, "kappa": 0.1}]}"#;
        let view = parse(text).unwrap().remove(0);
        assert_eq!(view.strokes[1].mode, Mode::Erase);
        // Fit size = image size, so pixel (x, y) samples (x + ½, y + ½): (49, 9) and (51, 9) lie
        // under both strokes (erase weights exp(−0.1·√0.5) and exp(−0.1·√2.5)), (19, 9) under the
        // paint only.
        let pixels = [(49u32, 9u32), (19, 9), (51, 9)];
        let diffuse = [[0.2, 0.3, 0.4]; 3];
        let t = targets(&view, &pixels, (100, 100), &diffuse);
        for (i, d) in [(0, 0.5f64.sqrt()), (2, 2.5f64.sqrt())] {
            let w = (-0.1 * d).exp();
            for c in 0..3 {
                let want = w * diffuse[i][c] + (1.0 - w) * 3.0;
                assert!(
                    (t.target[i][c] - want).abs() < 1e-12,
                    "{:?} vs {want}",
                    t.target[i]
                );
            }
        }
        assert_eq!(t.target[1], [3.0; 3]);
        assert_eq!(t.touched, 3);
    }

    #[test]
    fn targets_map_fit_pixels_to_the_full_view_and_count_off_object_strokes() {
        let mut view = parse(ONE).unwrap().remove(0);
        view.strokes.push(Stroke {
            points: vec![[600.0, 470.0]],
            mode: Mode::Paint,
            color: [1.0; 3],
            scale: 1.0,
            radius: 2.0,
            kappa: 0.0,
        });
        // Fit at 160x120: fit pixel (37, 24) has its centre at full-res (150, 98).
        let pixels = vec![(37, 24), (0, 0)];
        let t = targets(&view, &pixels, (160, 120), &[[0.1; 3], [0.2; 3]]);
        let w = (-0.2f64).exp();
        assert!((t.target[0][0] - (w * 2.0 + (1.0 - w) * 0.1)).abs() < 1e-12);
        assert_eq!(t.target[1], [0.2; 3]);
        assert!((t.weight[0] - (0.1 + 0.9 * w)).abs() < 1e-12);
        assert_eq!(t.weight[1], 0.1);
        assert_eq!(t.touched, 1);
        assert_eq!(t.off_object, vec![1]);
    }
}

#[cfg(test)]
mod schema_tests {
    /// The schema names exactly the fields the parser accepts (a change to one must change the
    /// other).
    #[test]
    fn schema_matches_the_types() {
        let schema: serde_json::Value =
            serde_json::from_str(include_str!("strokes.schema.json")).unwrap();
        let keys = |def: &str| -> Vec<String> {
            let mut k: Vec<String> = schema["$defs"][def]["properties"]
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect();
            k.sort();
            k
        };
        assert_eq!(
            keys("view"),
            ["image_size", "keep_weight", "strokes", "view"]
        );
        assert_eq!(
            keys("stroke"),
            ["color", "kappa", "mode", "points", "radius", "scale"]
        );
    }
}
