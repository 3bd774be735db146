//! glint's file-format crate. It knows file formats and nothing of the pipeline: callers hand it
//! plain data — a [`MaterialDesc`] (the fitted lobe table, the tabulated p(h), a PBR fallback,
//! optionally a MERL table) and optionally a [`SceneMesh`] — never bake or fit state, so it cannot
//! form a dependency cycle with the root package.
//!
//! Formats ([`registry`], [`export_all`]):
//! - `exr` — `<name>_ph.exr`: the p(h) table, RGB f32, with `glint.*` header attributes ([`exr`]);
//! - `gltf` — `<name>.glb`: the mesh (or a preview sphere) with a metallic–roughness fallback
//!   material (plus `KHR_materials_anisotropy` when anisotropic) and the lobe table in
//!   `extras.glint` ([`gltf`]);
//! - `usd` — `<name>.usda`: a UsdShade Material with a UsdPreviewSurface and a `glint_dbrdf_srbf`
//!   shader carrying the lobe table, bound to the mesh or a preview sphere; the fallback's
//!   anisotropy, which UsdPreviewSurface cannot express, in the Material's `customData.glint`
//!   ([`usd`]);
//! - `merl` — `<name>.binary`: a MERL isotropic table sampled by the caller ([`merl`]).
//!
//! glTF and USD reference the table as `./<name>_ph.exr` and write it beside themselves.
//!
//! # The BRDF
//!
//! f_r(wi, wo) = ρd/π + p(h)·s(wi, wo), without the cosine, in the local frame (z = normal,
//! x = tangent); p(h) = Σ_j c_j exp(2λ(h·ξ_j − 1)) (isotropic layouts: ring lobes, p depends on h.z
//! only); s = F(wi·h) / (4(k1 + k2 − k1·k2)), F = f0 + (1 − f0)(1 − wi·h)^5, k1 = wi·n, k2 = wo·n,
//! h = normalize(wi + wo). [`eval_from_table`] and [`eval_lobes`] evaluate it.
//!
//! # The table parameterisation: "hemi-octahedral"
//!
//! Texel (x, y) of an R×R table sits at u = x/(R−1), v = y/(R−1) (corner-aligned: the outer texels
//! lie on the horizon); a = 2u−1, b = 2v−1, px = (a+b)/2, py = (a−b)/2, z = 1−|px|−|py| (always ≥
//! 0), h = normalize(px, py, z) is the local half-vector. Inverse: l1 = |hx|+|hy|+|hz|, px = hx/l1,
//! py = hy/l1, u = (px+py+1)/2, v = (px−py+1)/2. Lookup is bilinear between the four texels around
//! (u·(R−1), v·(R−1)); no clamping is needed. Row y = 0 is the first
//! (top) scan line of the EXR. One definition: [`hemi_oct_decode`], [`hemi_oct_encode`],
//! [`PhTable::lookup`]. Default resolution [`DEFAULT_TABLE_RESOLUTION`] (512).
//!
//! Also: [`atomic`] — every file goes through a temporary file in the destination folder and a
//! rename, so a crash or a full disk never leaves a half-written output; [`npy`] — NumPy arrays.
//!
//! Invariants: no dependency on the `glint` crate; every write is atomic; every exporter validates
//! and builds all its files in memory before writing; equal inputs give byte-identical files.

pub mod atomic;
pub mod bessel;
pub mod brdf;
pub mod error;
pub mod exporter;
pub mod exr;
pub mod fallback_summary;
pub mod gltf;
pub mod import;
pub mod material;
pub mod merl;
pub mod mitsuba;
pub mod mtlx;
pub mod npy;
pub mod sphere;
pub mod table;
pub mod usd;
pub mod view;

pub use atomic::{AtomicWriteError, write_atomic};
pub use brdf::{eval_from_table, eval_lobes};
pub use error::ExportError;
pub use exporter::{Exporter, OutputFile, export_all, find_exporter, registry};
pub use exr::{AttrValue, ExrExporter, read_ph_exr, read_ph_exr_attributes};
pub use fallback_summary::{FallbackExporter, fallback_summary};
pub use gltf::GltfExporter;
pub use material::{
    ClearcoatLayer, MODEL, MaterialDesc, PbrFallback, PreviewSurfaceFallback, SceneMesh,
    SheenLayer, SpecularLayer, Weighting,
};
pub use merl::{MerlExporter, MerlTable, merl_lookup, read_merl};
pub use mitsuba::MitsubaExporter;
pub use mtlx::MtlxExporter;
pub use table::{
    DEFAULT_TABLE_RESOLUTION, PARAMETERISATION, PhTable, hemi_oct_decode, hemi_oct_encode,
};
pub use usd::UsdExporter;
pub use view::{SceneCamera, SceneEnvironment};
