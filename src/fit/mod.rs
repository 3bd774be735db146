//! The fit (method.md §5-6): strokes become per-pixel targets and weights, and a constrained least
//! squares per colour channel finds the lobe coefficients.
//!
//! - [`strokes`]: the stroke file (JSON) and the brush of eq. 23.
//! - `qp` (the solver) comes next.
//!
//! Invariants: no IO except parsing stroke text handed in by the caller; knows no wgpu; f64.

pub mod strokes;
