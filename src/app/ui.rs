//! The egui app: the preview in a viewport (left-drag paints, right-drag orbits, the wheel zooms)
//! and a side panel with the brush, the material settings, the environment, the fit statistics, a
//! view of p(h), undo/redo, sessions and export.
//!
//! Inputs: egui input, [`super::worker::Event`]s. Outputs: [`super::worker::Command`]s, autosaved
//! sessions, what egui draws. Invariants: the UI thread only sends commands and uploads finished
//! images (never bakes, fits or shades); painting starts once the first view is drawn (in clay,
//! before the bake; a stroke's fit waits for the first view's vertices to be baked); a stroke's points are pixels of the view's full-resolution image (origin top-left),
//! mapped from the widget rectangle the image is drawn in; every settled edit (stroke released,
//! slider let go, undo, redo, session loaded) is one history step and one fit.

use super::engine::{FitResult, PreviewChoice};
use super::state::{BrushMode, Document, History, Session};
use super::worker::{Command, Event, Worker};
use crate::fit::strokes::{ViewSpec, ViewStrokes};
use crate::render::Image;
use egui::{Color32, Pos2, Rect, Sense, Stroke as LineStroke, TextureHandle, TextureOptions, Vec2};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// How the app is started.
#[derive(Debug, Clone, Default)]
pub struct AppOptions {
    pub scene: PathBuf,
    pub env: PathBuf,
    /// Where the session is written after every settled edit (`None`: nowhere).
    pub autosave: Option<PathBuf>,
    /// A session to load once the first view is ready.
    pub session: Option<PathBuf>,
    /// Strokes to replay (and fit) once the first view's fit is prepared (`--replay`).
    pub replay: Vec<ViewStrokes>,
    /// Which renderer draws the preview (`--preview`).
    pub preview: PreviewChoice,
}

impl AppOptions {
    /// Options from files, checked before a window opens: the scene and the map must exist, a
    /// replay must parse as strokes and a session as a session.
    pub fn from_files(
        scene: PathBuf,
        env: PathBuf,
        replay: Option<&std::path::Path>,
        session: Option<PathBuf>,
        autosave: Option<PathBuf>,
        preview: PreviewChoice,
    ) -> Result<Self, super::AppError> {
        for (what, p) in [("scene", &scene), ("environment map", &env)] {
            if !p.is_file() {
                return Err(super::AppError::Io {
                    path: p.clone(),
                    reason: format!("the {what} does not exist"),
                });
            }
        }
        let read = |p: &std::path::Path| {
            std::fs::read_to_string(p).map_err(|e| super::AppError::Io {
                path: p.to_path_buf(),
                reason: format!("cannot read it: {e}"),
            })
        };
        let replay = match replay {
            Some(p) => crate::fit::strokes::parse(&read(p)?).map_err(|e| super::AppError::Io {
                path: p.to_path_buf(),
                reason: e.to_string(),
            })?,
            None => Vec::new(),
        };
        if let Some(s) = &session {
            super::state::Session::parse(&read(s)?).map_err(|e| super::AppError::Io {
                path: s.clone(),
                reason: e.to_string(),
            })?;
        }
        Ok(Self {
            scene,
            env,
            autosave,
            session,
            replay,
            preview,
        })
    }
}

/// What the worker said about the inputs.
#[derive(Debug, Clone)]
struct Loaded {
    size: [u32; 2],
    vertices: usize,
    triangles: usize,
    device: String,
    anisotropic: bool,
}

/// The last fit as the side panel shows it.
#[derive(Debug, Clone)]
pub struct FitReport {
    pub result: FitResult,
    /// From the stroke's release (or the settled edit) to the new preview on screen.
    pub release_to_preview_secs: f64,
}

/// The app (see the module docs).
pub struct GlintApp {
    opts: AppOptions,
    worker: Worker,
    history: History,
    doc: Document,
    loaded: Option<Loaded>,
    view: Option<ViewSpec>,
    orbit: [f32; 3],
    ready: bool,
    /// The first view is drawn (in clay before the bake): painting works.
    paintable: bool,
    painting_possible_secs: Option<f64>,
    bake_complete: Option<f64>,
    first_fit_possible_secs: Option<f64>,
    first_fit_ready_secs: Option<f64>,
    progress: (usize, usize, &'static str),
    preview: Option<TextureHandle>,
    preview_image: Option<Arc<Image>>,
    brdf: Option<TextureHandle>,
    stroke: Option<Vec<[f64; 2]>>,
    fit_id: u64,
    pending_fit: Option<(u64, Instant)>,
    fits_done: u64,
    last_fit: Option<FitReport>,
    messages: Vec<String>,
    session_path: String,
    export_dir: String,
    env_path: String,
    settings_dirty: bool,
    show_strokes: bool,
    image_rect: Option<Rect>,
    pending_session: Option<Session>,
}

/// The environment maps (.exr, .hdr, any case) in a folder, sorted by name; empty when it cannot be
/// read.
pub fn env_maps_in(folder: &std::path::Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return Vec::new();
    };
    let mut maps: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("hdr"))
        })
        .collect();
    maps.sort();
    maps
}

/// Linear radiance → sRGB8 as the PNG writer does ([`crate::render::image::tone_map`]).
pub fn tone_map(image: &Image, exposure: f32) -> egui::ColorImage {
    let rgb: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.map(|x| crate::render::image::tone_map(x, exposure)))
        .collect();
    egui::ColorImage::from_rgb([image.width as usize, image.height as usize], &rgb)
}

impl GlintApp {
    /// Starts the worker (load, bake) and returns at once.
    pub fn new(opts: AppOptions, ctx: &egui::Context) -> Self {
        let repaint = ctx.clone();
        let worker = Worker::start(
            opts.scene.clone(),
            opts.env.clone(),
            opts.preview,
            Arc::new(move || repaint.request_repaint()),
        );
        let pending_session = opts.session.as_ref().and_then(|p| {
            match std::fs::read_to_string(p)
                .map_err(|e| e.to_string())
                .and_then(|t| Session::parse(&t))
            {
                Ok(s) => Some(s),
                Err(e) => {
                    eprintln!("glint app: session {}: {e}", p.display());
                    None
                }
            }
        });
        Self {
            env_path: opts.env.display().to_string(),
            session_path: "glint-session.json".into(),
            export_dir: "glint-export".into(),
            opts,
            worker,
            history: History::new(Document::default()),
            doc: Document::default(),
            loaded: None,
            view: None,
            orbit: [0.0, 0.0, 3.0],
            ready: false,
            bake_complete: None,
            paintable: false,
            painting_possible_secs: None,
            first_fit_possible_secs: None,
            first_fit_ready_secs: None,
            progress: (0, 0, ""),
            preview: None,
            preview_image: None,
            brdf: None,
            stroke: None,
            fit_id: 0,
            pending_fit: None,
            fits_done: 0,
            last_fit: None,
            messages: Vec::new(),
            settings_dirty: false,
            show_strokes: true,
            image_rect: None,
            pending_session,
        }
    }

    /// True once the first view's vertices are baked (fitting works).
    pub fn ready(&self) -> bool {
        self.ready
    }

    /// True once the first view is drawn, in clay before the bake (painting works).
    pub fn paintable(&self) -> bool {
        self.paintable
    }

    /// Seconds from launch to painting being possible.
    pub fn painting_possible_secs(&self) -> Option<f64> {
        self.painting_possible_secs
    }

    /// True once every vertex is baked.
    pub fn bake_complete(&self) -> bool {
        self.bake_complete.is_some()
    }

    /// Fits finished and shown.
    pub fn fits_done(&self) -> u64 {
        self.fits_done
    }

    /// True while a fit is under way.
    pub fn fit_pending(&self) -> bool {
        self.pending_fit.is_some()
    }

    /// The preview's linear frame now shown.
    pub fn preview_image(&self) -> Option<&Arc<Image>> {
        self.preview_image.as_ref()
    }

    /// The last fit.
    pub fn last_fit(&self) -> Option<&FitReport> {
        self.last_fit.as_ref()
    }

    /// Seconds from launch to the first fit being possible.
    pub fn first_fit_possible_secs(&self) -> Option<f64> {
        self.first_fit_possible_secs
    }

    /// Seconds from launch to the first view's transfer and energy rows being ready.
    pub fn first_fit_ready_secs(&self) -> Option<f64> {
        self.first_fit_ready_secs
    }

    /// Messages (errors, notes), oldest first.
    pub fn messages(&self) -> &[String] {
        &self.messages
    }

    /// The current document.
    pub fn document(&self) -> &Document {
        &self.doc
    }

    /// Where a full-resolution view pixel is on screen (`None` before the first frame is drawn).
    pub fn view_to_screen(&self, p: [f64; 2]) -> Option<Pos2> {
        let (rect, size) = (self.image_rect?, self.loaded.as_ref()?.size);
        Some(Pos2::new(
            rect.min.x + (p[0] / size[0] as f64) as f32 * rect.width(),
            rect.min.y + (p[1] / size[1] as f64) as f32 * rect.height(),
        ))
    }

    fn screen_to_view(&self, p: Pos2) -> Option<[f64; 2]> {
        let (rect, size) = (self.image_rect?, self.loaded.as_ref()?.size);
        Some([
            ((p.x - rect.min.x) / rect.width()) as f64 * size[0] as f64,
            ((p.y - rect.min.y) / rect.height()) as f64 * size[1] as f64,
        ])
    }

    /// Replaces the settings (as the side panel would) and refits: one history step.
    pub fn set_settings(&mut self, settings: super::state::Settings) {
        self.doc.settings = settings;
        self.commit();
    }

    /// Replaces the strokes with `views` (a stroke file), shows the first of them and fits.
    pub fn replay(&mut self, views: Vec<ViewStrokes>) {
        if let Some(first) = views.first() {
            self.set_view(first.view.clone());
            if let Some(keep) = views.first().map(|v| v.keep_weight) {
                self.doc.settings.keep_weight = keep;
            }
        }
        self.doc.views = views;
        self.commit();
    }

    fn set_view(&mut self, view: ViewSpec) {
        if let ViewSpec::Orbit { orbit } = &view {
            self.orbit = *orbit;
        }
        self.view = Some(view);
    }

    fn note(&mut self, m: String) {
        eprintln!("glint app: {m}");
        self.messages.push(m);
        if self.messages.len() > 50 {
            self.messages.remove(0);
        }
    }

    fn size(&self) -> [u32; 2] {
        self.loaded.as_ref().map_or([640, 480], |l| l.size)
    }

    fn request_frame(&self) {
        if let Some(view) = &self.view {
            self.worker.send(Command::Render {
                view: view.clone(),
                size: self.size(),
                rotation_deg: self.doc.settings.env_rotation_deg,
            });
        }
    }

    /// Records the document as one history step, fits it and autosaves.
    fn commit(&mut self) {
        self.history.push(self.doc.clone());
        self.request_fit();
        self.autosave();
    }

    fn request_fit(&mut self) {
        let Some(view) = self.view.clone() else {
            return;
        };
        self.fit_id += 1;
        self.pending_fit = Some((self.fit_id, Instant::now()));
        self.worker.send(Command::Fit {
            id: self.fit_id,
            doc: Box::new(self.doc.clone()),
            view,
            size: self.size(),
        });
    }

    fn session(&self) -> Session {
        Session::new(
            self.opts.scene.clone(),
            PathBuf::from(&self.env_path),
            &self.doc,
        )
    }

    fn autosave(&mut self) {
        if let Some(path) = self.opts.autosave.clone()
            && let Err(e) =
                glint_exporters::write_atomic(&path, self.session().to_json().as_bytes())
        {
            self.note(format!("autosave {}: {e}", path.display()));
        }
    }

    fn undo(&mut self) {
        if let Some(doc) = self.history.undo().cloned() {
            self.doc = doc;
            self.request_fit();
            self.autosave();
        }
    }

    fn redo(&mut self) {
        if let Some(doc) = self.history.redo().cloned() {
            self.doc = doc;
            self.request_fit();
            self.autosave();
        }
    }

    fn load_session(&mut self, session: Session) {
        if std::path::absolute(&session.scene).ok() != std::path::absolute(&self.opts.scene).ok() {
            self.note(format!(
                "the session is for {}, not {}: start `glint app {} --session FILE`",
                session.scene.display(),
                self.opts.scene.display(),
                session.scene.display()
            ));
            return;
        }
        if session.env.display().to_string() != self.env_path {
            self.env_path = session.env.display().to_string();
            self.worker.send(Command::SetEnv(session.env.clone()));
        }
        self.doc = session.document();
        if let Some(v) = self.doc.views.last() {
            let view = v.view.clone();
            self.set_view(view);
        }
        self.commit();
        self.request_frame();
    }

    fn handle_events(&mut self, ctx: &egui::Context) {
        for event in self.worker.poll() {
            match event {
                Event::Loaded {
                    view,
                    size,
                    orbit,
                    vertices,
                    triangles,
                    device,
                    anisotropic,
                } => {
                    self.orbit = orbit;
                    if self.view.is_none() {
                        self.view = Some(view.clone());
                    }
                    self.loaded = Some(Loaded {
                        size,
                        vertices,
                        triangles,
                        device,
                        anisotropic,
                    });
                }
                Event::Progress { done, total, phase } => self.progress = (done, total, phase),
                Event::Paintable { secs_since_start } => {
                    self.paintable = true;
                    self.painting_possible_secs = Some(secs_since_start);
                    self.note(format!("painting possible {secs_since_start:.2} s after launch (the view in clay until its vertices are baked)"));
                }
                Event::Note(text) => self.note(text),
                Event::FirstViewReady {
                    secs_since_start,
                    vertices,
                } => {
                    self.ready = true;
                    self.paintable = true;
                    self.painting_possible_secs.get_or_insert(secs_since_start);
                    self.first_fit_possible_secs = Some(secs_since_start);
                    self.note(format!("first fit possible {secs_since_start:.2} s after launch ({vertices} vertices of the first view baked)"));
                    self.request_frame();
                    if let Some(s) = self.pending_session.take() {
                        self.load_session(s);
                    }
                }
                Event::FitPrepared {
                    secs_since_start,
                    prepare_secs,
                } => {
                    self.first_fit_ready_secs = Some(secs_since_start);
                    self.note(format!("first view's transfer and energy rows ready {secs_since_start:.2} s after launch ({prepare_secs:.2} s): a stroke there now costs a solve"));
                    if !self.opts.replay.is_empty() {
                        let views = std::mem::take(&mut self.opts.replay);
                        self.replay(views);
                    }
                }
                Event::BakeComplete {
                    bake_secs,
                    vertices,
                } => {
                    self.bake_complete = Some(bake_secs);
                    self.note(format!("bake complete {bake_secs:.2} s after launch ({vertices} vertices after refinement)"));
                    self.request_frame();
                }
                Event::Frame { view, image } => {
                    // While a fit is under way its own frame replaces this one; before the bake a
                    // fit only waits, so the clay frames of a new view are shown.
                    if Some(&view) == self.view.as_ref()
                        && (self.pending_fit.is_none() || !self.ready)
                    {
                        self.show_frame(ctx, image);
                    }
                }
                Event::Fitted {
                    id,
                    result,
                    image,
                    view,
                } => {
                    if Some(&view) == self.view.as_ref() {
                        self.show_frame(ctx, image);
                    }
                    self.brdf = result.table_image.as_ref().map(|t| {
                        ctx.load_texture("p(h)", tone_map(t, 0.05), TextureOptions::LINEAR)
                    });
                    if let Some((pending, since)) = self.pending_fit
                        && pending == id
                    {
                        self.pending_fit = None;
                        let secs = since.elapsed().as_secs_f64();
                        let t = result.timings;
                        let f = &result.material.fit;
                        self.note(format!(
                            "fit {id}: release -> preview {:.3} s (transfer {:.3}, solve {:.4}, table {:.3}, frame {:.3}); residual {:.3e} {:.3e} {:.3e}; active energy rows {:?}",
                            secs, t.transfer_secs, t.solve_secs, t.table_secs, t.render_secs, f.residual_rms[0], f.residual_rms[1], f.residual_rms[2], f.active_energy_rows
                        ));
                        self.last_fit = Some(FitReport {
                            result: *result,
                            release_to_preview_secs: secs,
                        });
                        self.fits_done += 1;
                    }
                }
                Event::Exported(files) => {
                    let list: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
                    self.note(format!("exported {}", list.join(", ")));
                }
                Event::EnvChanged(path) => {
                    self.note(format!("environment {}", path.display()));
                    self.request_fit();
                }
                Event::Error(e) => {
                    if e.starts_with("the fit waits") {
                        self.note(e);
                    } else {
                        self.pending_fit = None;
                        self.note(format!("error: {e}"));
                    }
                }
            }
        }
    }

    fn show_frame(&mut self, ctx: &egui::Context, image: Arc<Image>) {
        let colour = tone_map(&image, self.doc.settings.exposure);
        match &mut self.preview {
            Some(t) => t.set(colour, TextureOptions::LINEAR),
            None => {
                self.preview = Some(ctx.load_texture("preview", colour, TextureOptions::LINEAR))
            }
        }
        self.preview_image = Some(image);
    }

    /// One frame of the UI.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.handle_events(&ctx);
        let (redo, undo) = ui.input_mut(|i| {
            let redo = i.consume_shortcut(&egui::KeyboardShortcut::new(
                egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
                egui::Key::Z,
            ));
            let undo = i.consume_shortcut(&egui::KeyboardShortcut::new(
                egui::Modifiers::COMMAND,
                egui::Key::Z,
            ));
            (redo, undo)
        });
        if redo {
            self.redo();
        } else if undo {
            self.undo();
        }
        egui::Panel::right("glint side panel")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                // The panel is taller than the default window once the p(h) image is shown: it
                // scrolls with the wheel, and its bar is always drawn so that one sees it can
                // (tests/it/app_ui.rs). (egui's default floating bar is invisible until hovered: a
                // solid one instead.)
                ui.spacing_mut().scroll = egui::style::ScrollStyle::solid();
                egui::ScrollArea::vertical()
                    .scroll_bar_visibility(egui::scroll_area::ScrollBarVisibility::AlwaysVisible)
                    .show(ui, |ui| self.side_panel(ui));
            });
        egui::CentralPanel::no_frame().show(ui, |ui| self.viewport(ui));
        // Settled settings (no button held): one history step and one fit.
        if self.settings_dirty && !ui.input(|i| i.pointer.any_down()) && self.ready {
            self.settings_dirty = false;
            self.commit();
        }
        if self.pending_fit.is_some() || !self.bake_complete() {
            ctx.request_repaint_after(std::time::Duration::from_millis(100));
        }
    }

    fn viewport(&mut self, ui: &mut egui::Ui) {
        let (rect, response) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(24));
        let size = self.size();
        let scale = (rect.width() / size[0] as f32).min(rect.height() / size[1] as f32);
        let image_rect = Rect::from_center_size(
            rect.center(),
            Vec2::new(size[0] as f32, size[1] as f32) * scale,
        );
        self.image_rect = Some(image_rect);
        if let Some(t) = &self.preview {
            painter.image(
                t.id(),
                image_rect,
                Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
                Color32::WHITE,
            );
        }
        if !self.ready {
            let (done, total, phase) = self.progress;
            let text = if self.loaded.is_none() {
                "loading the scene and the environment…".to_string()
            } else {
                format!(
                    "baking the {phase}: {done} / {total} vertices — paint now, the fit follows"
                )
            };
            // Centred while there is nothing to see; at the top once the clay view is drawn.
            let (at, align) = if self.preview.is_some() {
                (
                    rect.center_top() + Vec2::new(0.0, 12.0),
                    egui::Align2::CENTER_TOP,
                )
            } else {
                (rect.center(), egui::Align2::CENTER_CENTER)
            };
            painter.text(
                at,
                align,
                text,
                egui::FontId::proportional(16.0),
                Color32::WHITE,
            );
        }
        // Strokes of this view, and the one being painted.
        let px = image_rect.width() / size[0] as f32;
        if self.show_strokes
            && let Some(view) = &self.view
        {
            for v in self
                .doc
                .views
                .iter()
                .filter(|v| &v.view == view && v.image_size == size)
            {
                for s in &v.strokes {
                    let pts: Vec<Pos2> = s
                        .points
                        .iter()
                        .filter_map(|p| self.view_to_screen(*p))
                        .collect();
                    painter.add(egui::Shape::line(
                        pts,
                        LineStroke::new(1.5, Color32::from_rgba_unmultiplied(255, 200, 80, 160)),
                    ));
                }
            }
        }
        if let Some(points) = &self.stroke {
            let pts: Vec<Pos2> = points
                .iter()
                .filter_map(|p| self.view_to_screen(*p))
                .collect();
            let radius = self.doc.settings.brush.radius_px as f32 * px;
            for p in &pts {
                painter.circle_filled(
                    *p,
                    radius,
                    Color32::from_rgba_unmultiplied(255, 255, 255, 12),
                );
            }
            painter.add(egui::Shape::line(pts, LineStroke::new(2.0, Color32::WHITE)));
        }
        if let Some(hover) = response.hover_pos() {
            painter.circle_stroke(
                hover,
                self.doc.settings.brush.radius_px as f32 * px,
                LineStroke::new(1.0, Color32::from_white_alpha(120)),
            );
        }
        // Left-drag paints.
        if self.paintable {
            if response.drag_started_by(egui::PointerButton::Primary) {
                self.stroke = Some(Vec::new());
            }
            if (response.dragged_by(egui::PointerButton::Primary)
                || response.drag_started_by(egui::PointerButton::Primary))
                && let Some(p) = response
                    .interact_pointer_pos()
                    .and_then(|p| self.screen_to_view(p))
                && let Some(points) = &mut self.stroke
                && points
                    .last()
                    .is_none_or(|q: &[f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]) >= 1.0)
            {
                points.push(p);
            }
            if response.drag_stopped_by(egui::PointerButton::Primary)
                && let Some(points) = self.stroke.take()
                && !points.is_empty()
                && let Some(view) = self.view.clone()
            {
                let stroke = self.doc.settings.brush.stroke(points);
                self.doc.add_stroke(view, size, stroke);
                self.commit();
            }
        }
        // Right-drag orbits, the wheel zooms: a new view.
        let mut moved = false;
        if response.dragged_by(egui::PointerButton::Secondary) {
            let d = response.drag_delta();
            self.orbit[0] -= d.x * 0.4;
            self.orbit[1] = (self.orbit[1] + d.y * 0.4).clamp(-89.0, 89.0);
            moved = d != Vec2::ZERO;
        }
        if response.hovered() {
            let dy = ui.input(|i| i.smooth_scroll_delta.y);
            if dy != 0.0 {
                self.orbit[2] = (self.orbit[2] * (-dy * 0.002).exp()).clamp(1.05, 50.0);
                moved = true;
            }
        }
        if moved {
            self.view = Some(ViewSpec::Orbit { orbit: self.orbit });
            self.request_frame();
        }
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        let mut changed = false;
        ui.heading("glint");
        if let Some(l) = &self.loaded {
            ui.label(format!(
                "{} — {} vertices, {} triangles",
                self.opts.scene.display(),
                l.vertices,
                l.triangles
            ));
            ui.label(format!(
                "{} lobes; preview on {}",
                if l.anisotropic {
                    "anisotropic"
                } else {
                    "isotropic"
                },
                l.device
            ));
        }
        let (done, total, phase) = self.progress;
        if self.bake_complete.is_none() && total > 0 && done < total {
            ui.add(
                egui::ProgressBar::new(done as f32 / total as f32)
                    .text(format!("bake ({phase}) {done}/{total}")),
            );
        }
        ui.horizontal(|ui| {
            if ui
                .add_enabled(self.history.can_undo(), egui::Button::new("Undo"))
                .clicked()
            {
                self.undo();
            }
            if ui
                .add_enabled(self.history.can_redo(), egui::Button::new("Redo"))
                .clicked()
            {
                self.redo();
            }
            ui.label(format!(
                "{} strokes in {} views",
                self.doc.stroke_count(),
                self.doc.views.len()
            ));
        });
        ui.separator();
        ui.strong("Brush");
        let b = &mut self.doc.settings.brush;
        ui.horizontal(|ui| {
            ui.radio_value(&mut b.mode, BrushMode::Paint, "paint");
            ui.radio_value(&mut b.mode, BrushMode::Scale, "scale");
            ui.radio_value(&mut b.mode, BrushMode::Erase, "erase highlight");
        });
        ui.horizontal(|ui| {
            ui.label("colour");
            ui.color_edit_button_rgb(&mut b.color);
            ui.add(
                egui::DragValue::new(&mut b.intensity)
                    .speed(0.05)
                    .range(-20.0..=100.0)
                    .prefix("× "),
            );
        });
        ui.add(egui::Slider::new(&mut b.radius_px, 1.0..=200.0).text("radius D (px)"));
        ui.add(
            egui::Slider::new(&mut b.kappa_per_px, 0.0..=1.0)
                .logarithmic(true)
                .text("falloff κ (1/px)"),
        );
        ui.add(egui::Slider::new(&mut b.scale, 0.0..=10.0).text("scale S"));
        ui.checkbox(&mut self.show_strokes, "show strokes");
        ui.separator();
        ui.strong("Material");
        let s = &mut self.doc.settings;
        ui.horizontal(|ui| {
            let label = ui.label("ρd (R, G, B)");
            for c in 0..3 {
                changed |= ui
                    .add(
                        egui::DragValue::new(&mut s.rho_d[c])
                            .speed(0.005)
                            .range(0.0..=1.0),
                    )
                    .labelled_by(label.id)
                    .changed();
            }
        });
        changed |= ui
            .add(egui::Slider::new(&mut s.f0, 0.0..=1.0).text("F0"))
            .changed();
        changed |= ui
            .add(egui::Slider::new(&mut s.keep_weight, 0.0..=1.0).text("keep weight"))
            .changed();
        changed |= ui
            .checkbox(&mut s.energy_limit, "energy limit (physical)")
            .changed();
        changed |= ui
            .add(
                egui::Slider::new(&mut s.sigma, 0.01..=0.5)
                    .logarithmic(true)
                    .text("σ (rad)"),
            )
            .changed();
        changed |= ui
            .add(egui::Slider::new(&mut s.lobe_count, 4..=300).text("J (lobes)"))
            .changed();
        if ui
            .add(
                egui::Slider::new(&mut s.exposure, 0.05..=8.0)
                    .logarithmic(true)
                    .text("exposure"),
            )
            .changed()
            && let (Some(img), Some(tex)) = (&self.preview_image, &mut self.preview)
        {
            tex.set(tone_map(img, s.exposure), TextureOptions::LINEAR);
        }
        ui.separator();
        ui.strong("Environment");
        ui.horizontal(|ui| {
            let label = ui.label("file");
            ui.text_edit_singleline(&mut self.env_path)
                .labelled_by(label.id);
            if ui.button("Load").clicked() {
                self.worker
                    .send(Command::SetEnv(PathBuf::from(&self.env_path)));
            }
        });
        // A picker over the maps beside the current one (listed only while the list is open).
        let current = PathBuf::from(&self.env_path);
        let folder = current
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    std::path::Path::new(".")
                } else {
                    p
                }
            })
            .unwrap_or(std::path::Path::new("."))
            .to_path_buf();
        let mut picked = None;
        egui::ComboBox::from_label("maps in this folder")
            .selected_text(
                current
                    .file_name()
                    .map(|f| f.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            )
            .show_ui(ui, |ui| {
                let maps = env_maps_in(&folder);
                if maps.is_empty() {
                    ui.label("no .exr or .hdr here");
                }
                for map in maps {
                    let name = map
                        .file_name()
                        .map(|f| f.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    if ui
                        .selectable_label(map.file_name() == current.file_name(), name)
                        .clicked()
                    {
                        picked = Some(map);
                    }
                }
            });
        if let Some(map) = picked {
            self.env_path = map.display().to_string();
            self.worker.send(Command::SetEnv(map));
        }
        let rot = ui.add(
            egui::Slider::new(&mut self.doc.settings.env_rotation_deg, -180.0..=180.0)
                .text("rotation (°)"),
        );
        if rot.changed() {
            self.request_frame();
            changed = true;
        }
        if changed {
            self.settings_dirty = true;
        }
        ui.separator();
        ui.strong("Fit");
        if self.pending_fit.is_some() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("fitting…");
            });
        }
        if let Some(secs) = self.painting_possible_secs {
            ui.label(format!("painting possible {secs:.2} s after launch"));
        }
        if let Some(secs) = self.first_fit_possible_secs {
            ui.label(format!("first view baked {secs:.2} s after launch"));
        }
        if let Some(secs) = self.first_fit_ready_secs {
            ui.label(format!("first fit prepared {secs:.2} s after launch"));
        }
        if let Some(r) = &self.last_fit {
            let f = &r.result.material.fit;
            let t = r.result.timings;
            ui.label(format!(
                "solve {:.2} ms, {} pixels in {} view(s)",
                f.solve_seconds * 1e3,
                f.pixels,
                f.views
            ));
            ui.label(format!(
                "residual (weighted RMS) {:.3e} / {:.3e} / {:.3e}",
                f.residual_rms[0], f.residual_rms[1], f.residual_rms[2]
            ));
            ui.label(format!(
                "active energy rows {:?} (limit {})",
                f.active_energy_rows,
                if f.energy_limit { "on" } else { "off" }
            ));
            ui.label(format!(
                "release -> preview {:.3} s (transfer {:.3} s, frame {:.3} s)",
                r.release_to_preview_secs, t.transfer_secs, t.render_secs
            ));
            for n in &f.notes {
                ui.label(format!("note: {n}"));
            }
        }
        if let Some(t) = &self.brdf {
            ui.label("p(h), hemi-octahedral (centre: h = n)");
            ui.image((t.id(), Vec2::splat(128.0)));
        }
        ui.separator();
        ui.strong("Session");
        ui.horizontal(|ui| {
            let label = ui.label("file");
            ui.text_edit_singleline(&mut self.session_path)
                .labelled_by(label.id);
        });
        ui.horizontal(|ui| {
            if ui.button("Save").clicked() {
                let path = PathBuf::from(&self.session_path);
                match glint_exporters::write_atomic(&path, self.session().to_json().as_bytes()) {
                    Ok(()) => self.note(format!("saved {}", path.display())),
                    Err(e) => self.note(format!("error: {e}")),
                }
            }
            if ui.button("Load").clicked() {
                match std::fs::read_to_string(&self.session_path)
                    .map_err(|e| e.to_string())
                    .and_then(|t| Session::parse(&t))
                {
                    Ok(s) => self.load_session(s),
                    Err(e) => self.note(format!("error: {}: {e}", self.session_path)),
                }
            }
            if ui.button("Save strokes").clicked() {
                let path = PathBuf::from(&self.session_path).with_extension("strokes.json");
                match glint_exporters::write_atomic(&path, self.doc.strokes_json().as_bytes()) {
                    Ok(()) => self.note(format!("saved {} (glint fit --strokes)", path.display())),
                    Err(e) => self.note(format!("error: {e}")),
                }
            }
        });
        if let Some(p) = &self.opts.autosave {
            ui.label(format!("autosave: {}", p.display()));
        }
        ui.separator();
        ui.strong("Export (EXR table, glTF, USD, MERL)");
        ui.horizontal(|ui| {
            let label = ui.label("folder");
            ui.text_edit_singleline(&mut self.export_dir)
                .labelled_by(label.id);
            if ui
                .add_enabled(self.last_fit.is_some(), egui::Button::new("Export"))
                .clicked()
            {
                let name = self
                    .opts
                    .scene
                    .file_stem()
                    .map_or("material".into(), |s| s.to_string_lossy().into_owned());
                self.worker.send(Command::Export {
                    dir: PathBuf::from(&self.export_dir),
                    name,
                });
            }
        });
        ui.separator();
        for m in self.messages.iter().rev().take(6) {
            ui.small(m);
        }
    }
}

impl eframe::App for GlintApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_maps_in_lists_exr_and_hdr_files_sorted() {
        let dir = std::env::temp_dir().join(format!("glint-env-maps-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub.exr")).unwrap();
        for f in ["b.hdr", "a.EXR", "c.png", "notes.txt"] {
            std::fs::write(dir.join(f), b"x").unwrap();
        }
        let names: Vec<String> = env_maps_in(&dir)
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            ["a.EXR", "b.hdr"],
            "files only (not the folder named sub.exr), .exr/.hdr in any case"
        );
        assert!(env_maps_in(&dir.join("missing")).is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
