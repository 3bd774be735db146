//! glint: paint highlights on a glTF object under an HDR environment map and solve for the
//! physically valid BRDF whose rendering matches the paint (Iwasaki, Dobashi, Nishita 2009, as
//! restated in `../shared/spec/method.md`).
//!
//! The data flows one way: [`scene`] (glTF import) and [`env`](mod@env) (environment maps) feed the bake
//! (visibility cuts over the [`sphere`] light tree), the light sums, the transfer, the fit, the
//! tabulation, the renderers and the exporters. [`brdf`] holds the reflectance model every stage
//! shares. Stages are free functions over plain data; IO lives only in the importers and at the CLI
//! edge. See `ARCHITECTURE.md` for the code map and the invariants.

// Numeric code indexes parallel arrays (RGB channels, per-vertex buffers) in one loop, as the
// formulas are written; iterator zips of three or four slices read worse.
#![allow(clippy::needless_range_loop)]
// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these tests must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accuracy;
#[cfg(feature = "gui")]
pub mod app;
pub mod bake;
pub mod brdf;
pub mod env;
pub mod export;
pub mod fit;
#[cfg(feature = "gui")]
pub mod gpu;
pub mod inspect;
pub mod light;
pub mod material_file;
pub mod math;
pub mod raster;
pub mod render;
pub mod scene;
pub mod sphere;
pub mod study;
pub mod transfer;
