//! The integration tests, one crate (one link of wgpu and eframe): a module per subject.
//! Shared helpers live in `common`; `tidy` enforces the house rules (tests/it/tidy.rs).

// Tests index parallel arrays (RGB channels, expected values) in one loop, as the checks are
// stated.
#![allow(clippy::needless_range_loop)]

#[macro_use]
mod common;

mod app_ui;
mod bad_input;
mod bake_file;
mod bake_visibility;
mod blender;
mod cli_export;
mod cli_fit;
mod cli_inspect;
mod cli_study;
mod determinism;
mod energy_table;
mod env_maps;
mod fit;
mod gltf_import;
mod gpu;
mod hard_cases;
mod properties;
mod qp;
mod render;
mod render_cases;
mod shadow_edges;
mod tidy;
mod transfer;
