//! The painting app (`glint app`): a thin egui shell over the library's stage functions.
//!
//! - [`state`]: the document (strokes per view in the `glint fit` format, settings), undo/redo, the
//!   session file — pure, tested without a display;
//! - [`engine`]: scene, environment, growing bake, cached transfers, warm-started fits, the wgpu
//!   preview, exports;
//! - [`worker`]: the thread that runs the engine (and the bake, first view first) and reports
//!   events;
//! - [`ui`]: the egui app — viewport with the preview, painting, orbit and zoom, the side panel;
//! - [`screenshot`]: `--replay STROKES --screenshot OUT.png`: the app drawn offscreen with
//!   egui-wgpu after replaying strokes (no display needed).
//!
//! Inputs: a glTF scene and an environment map (paths), user input. Outputs: preview frames, fitted
//! materials, sessions, exports, screenshots. Invariants: only this module and `gpu` use wgpu; the
//! UI thread never bakes, fits or renders the PRT frame itself; failures are [`AppError`]s (one
//! line).

pub mod engine;
pub mod screenshot;
pub mod state;
pub mod ui;
pub mod worker;

pub use engine::PreviewChoice;
pub use screenshot::{ReplayReport, replay_screenshot};
pub use ui::{AppOptions, GlintApp};

use std::path::PathBuf;

/// What can go wrong in the app.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    #[error("{0}")]
    Stage(String),
    #[error("settings: {0}")]
    Settings(String),
    #[error("not ready: {0}")]
    NotReady(&'static str),
    #[error("{path}: {reason}")]
    Io { path: PathBuf, reason: String },
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("no display: {0}")]
    NoDisplay(String),
    #[error("timed out after {secs} s waiting for {what}")]
    Timeout { what: &'static str, secs: f64 },
}

/// Opens the app in a window (eframe on wgpu). Fails when no display can be opened.
pub fn run_window(opts: AppOptions) -> Result<(), AppError> {
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        return Err(AppError::NoDisplay(
            "neither DISPLAY nor WAYLAND_DISPLAY is set".into(),
        ));
    }
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("glint")
            .with_inner_size([1280.0, 760.0]),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    eframe::run_native(
        "glint",
        native,
        Box::new(move |cc| Ok(Box::new(ui::GlintApp::new(opts, &cc.egui_ctx)))),
    )
    .map_err(|e| AppError::NoDisplay(e.to_string()))
}
