//! The fit (method.md §5-6): strokes become per-pixel targets and weights, and a constrained least
//! squares per colour channel finds the lobe coefficients.
//!
//! - [`strokes`]: the stroke file (JSON) and the brush of eq. 23.
//! - [`problem`]: the weighted normal equations per channel and the per-channel system kept across
//!   strokes.
//! - [`material`]: the lobe table that a fit writes.
//! - [`session`]: the fitting context (cached lobes, transfers and warm start) the CLI and the app
//!   share.
//! - [`run`]: a whole fit from a bake and a stroke file, in a fresh session.
//! - [`energy_cache`]: the energy rows a fit needs, kept in memory and in a disk cache under a
//!   content hash.
//! - [`cost`]: what a fit in one view costs after the bake (`glint bake` reports it).
//! - [`dump`]: a fit's problem and solution as `.npy` files (`glint fit --dump-qp`).
//! - [`qp`]: an exact, warm-started dual active-set solver (Goldfarb–Idnani) for
//!   min ½cᵀHc + qᵀc subject to c ≥ 0 and Gc ≤ u.
//!
//! Invariants: no IO except parsing stroke text handed in by the caller, [`dump`]'s files and
//! [`energy_cache`]'s folder; knows
//! no wgpu; f64.

pub mod cost;
pub mod dump;
pub mod energy_cache;
pub mod material;
pub mod problem;
pub mod qp;
pub mod run;
pub mod session;
pub mod strokes;
