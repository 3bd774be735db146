//! Rendering a fitted material (method.md §7): the tabulated p(h), the CPU PRT renderer (per vertex
//! over its cut, interpolated), the Monte Carlo reference (ground truth), and images.
//!
//! - [`table`]: p(h) on the hemi-octahedral map, with pre-filtered levels.
//! - [`prt`]: eq. 22 per vertex, then raster interpolation — what every frame costs.
//! - [`reference`](mod@reference): exact visibility by ray casting, exact lobes, the environment map itself, MIS.
//! - [`traced`]: the PRT frame with visibility traced per pixel where a triangle's corners disagree
//!   (the knob for shadow edges inside triangles).
//! - [`frame`]: a material on a bake as `glint render` renders it (the PRT frame or the reference).
//! - [`image`]: linear images, relative RMSE, EXR and tone-mapped PNG output (atomic).
//!
//! Inputs: the bake (cuts, light tree, tangents), light sums or the environment, a material, a
//! camera. Outputs: images. Invariants: the BRDF convention is the one in [`crate::brdf`] (f_r
//! without the cosine; s with the 4); renderers do no IO except [`image::Image::write`]; results do
//! not depend on the thread count.

pub mod frame;
pub mod image;
pub mod prt;
pub mod reference;
pub mod table;
pub mod traced;

pub use image::{Image, ImageError};
pub use prt::{Prt, PrtSettings, Shading, Specular, VertexLight};
pub use reference::{ExactMaterial, ReferenceScene, render_reference, render_reference_standard};
pub use table::PhPyramid;
pub use traced::{TracedStats, render_traced};
