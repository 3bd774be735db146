//! `glint app --replay STROKES.json --screenshot OUT.png`: runs the app without a window, replays a
//! stroke file, waits for the fit, and draws the whole app offscreen with egui-wgpu into a PNG.
//!
//! Inputs: [`AppOptions`], the strokes (the `glint fit` format), a window size in points. Outputs:
//! the PNG (written atomically) and a [`ReplayReport`] with the measured times. Invariants: the
//! same [`GlintApp`] code the window runs, fed the same events; no display is needed (the headless
//! wgpu device of [`crate::gpu::GpuContext`]); a fit that fails or does not finish in
//! `timeout_secs` is an error, so a screenshot always shows a finished fit.

use super::{AppError, AppOptions, GlintApp};
use crate::gpu::GpuContext;
use std::path::Path;
use std::time::{Duration, Instant};

/// What a replay measured.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    pub painting_possible_secs: f64,
    pub first_fit_possible_secs: f64,
    pub first_fit_ready_secs: f64,
    pub release_to_preview_secs: f64,
    pub width_px: u32,
    pub height_px: u32,
}

impl std::fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "({}x{} px); after launch: painting possible {:.2} s, first view baked {:.2} s, first fit prepared {:.2} s; stroke release → preview {:.3} s",
            self.width_px,
            self.height_px,
            self.painting_possible_secs,
            self.first_fit_possible_secs,
            self.first_fit_ready_secs,
            self.release_to_preview_secs
        )
    }
}

/// egui drawn into an offscreen texture.
struct Offscreen {
    ctx: GpuContext,
    renderer: eframe::egui_wgpu::Renderer,
}

const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

impl Offscreen {
    fn new() -> Result<Self, AppError> {
        let ctx = GpuContext::headless()?;
        let renderer = eframe::egui_wgpu::Renderer::new(
            &ctx.device,
            FORMAT,
            eframe::egui_wgpu::RendererOptions::default(),
        );
        Ok(Self { ctx, renderer })
    }

    /// Applies (and so consumes) a frame's texture changes.
    fn textures(&mut self, delta: &mut egui::TexturesDelta) {
        for (id, images) in delta.set.drain() {
            for image in &images {
                self.renderer
                    .update_texture(&self.ctx.device, &self.ctx.queue, id, image);
            }
        }
        for id in delta.free.drain() {
            self.renderer.free_texture(&id);
        }
    }

    /// RGBA8 pixels of one frame.
    fn draw(
        &mut self,
        egui_ctx: &egui::Context,
        mut output: egui::FullOutput,
    ) -> Result<(u32, u32, Vec<u8>), AppError> {
        self.textures(&mut output.textures_delta);
        let ppp = output.pixels_per_point;
        let size = egui_ctx.content_rect().size() * ppp;
        let (w, h) = (
            size.x.round().max(1.0) as u32,
            size.y.round().max(1.0) as u32,
        );
        let screen = eframe::egui_wgpu::ScreenDescriptor {
            size_in_pixels: [w, h],
            pixels_per_point: ppp,
        };
        let jobs = egui_ctx.tessellate(std::mem::take(&mut output.shapes), ppp);
        let device = &self.ctx.device;
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("egui screenshot"),
        });
        let user =
            self.renderer
                .update_buffers(device, &self.ctx.queue, &mut encoder, &jobs, &screen);
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("egui screenshot"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("egui screenshot"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                })
                .forget_lifetime();
            self.renderer.render(&mut pass, &jobs, &screen);
        }
        let row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("egui screenshot readback"),
            size: row as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.ctx
            .queue
            .submit(user.into_iter().chain(std::iter::once(encoder.finish())));
        let mapped = crate::gpu::preview::read_buffer(&self.ctx, &buffer)
            .map_err(|e| AppError::Stage(format!("screenshot readback: {e}")))?;
        let mut rgba = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h as usize {
            rgba.extend_from_slice(&mapped[y * row as usize..y * row as usize + w as usize * 4]);
        }
        Ok((w, h, rgba))
    }
}

/// Runs `app` for one frame of `size_pt` points; returns egui's output.
fn frame(egui_ctx: &egui::Context, app: &mut GlintApp, size_pt: [f32; 2]) -> egui::FullOutput {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(size_pt[0], size_pt[1]),
        )),
        ..Default::default()
    };
    egui_ctx.run_ui(input, |ui| app.show(ui))
}

/// Runs the app windowless until `opts.replay` (if any) is fitted and writes its screenshot to
/// `out` (PNG).
pub fn replay_screenshot(
    opts: AppOptions,
    out: &Path,
    size_pt: [f32; 2],
    timeout_secs: f64,
) -> Result<ReplayReport, AppError> {
    let expect_fit = !opts.replay.is_empty();
    let mut offscreen = Offscreen::new()?;
    let egui_ctx = egui::Context::default();
    let mut app = GlintApp::new(opts, &egui_ctx);
    let start = Instant::now();
    let deadline = |what: &'static str| -> Result<(), AppError> {
        if start.elapsed().as_secs_f64() > timeout_secs {
            Err(AppError::Timeout {
                what,
                secs: timeout_secs,
            })
        } else {
            Ok(())
        }
    };
    let step = |app: &mut GlintApp, offscreen: &mut Offscreen| {
        let mut output = frame(&egui_ctx, app, size_pt);
        offscreen.textures(&mut output.textures_delta);
        std::thread::sleep(Duration::from_millis(15));
    };
    while !app.ready() {
        deadline("the first view's bake")?;
        if let Some(e) = app.messages().iter().find(|m| m.starts_with("error")) {
            return Err(AppError::Stage(e.clone()));
        }
        step(&mut app, &mut offscreen);
    }
    while app.fit_pending() || (expect_fit && app.fits_done() == 0) {
        deadline("the fit")?;
        if let Some(e) = app.messages().iter().rev().find(|m| m.starts_with("error")) {
            return Err(AppError::Stage(e.clone()));
        }
        step(&mut app, &mut offscreen);
    }
    step(&mut app, &mut offscreen);
    let output = frame(&egui_ctx, &mut app, size_pt);
    let (w, h, rgba) = offscreen.draw(&egui_ctx, output)?;
    let image = image::RgbaImage::from_raw(w, h, rgba)
        .ok_or_else(|| AppError::Stage("screenshot size mismatch".into()))?;
    let mut png = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| AppError::Stage(e.to_string()))?;
    glint_exporters::write_atomic(out, png.get_ref()).map_err(|e| AppError::Io {
        path: out.to_path_buf(),
        reason: e.to_string(),
    })?;
    Ok(ReplayReport {
        painting_possible_secs: app.painting_possible_secs().unwrap_or(f64::NAN),
        first_fit_possible_secs: app.first_fit_possible_secs().unwrap_or(f64::NAN),
        first_fit_ready_secs: app.first_fit_ready_secs().unwrap_or(f64::NAN),
        release_to_preview_secs: app
            .last_fit()
            .map_or(f64::NAN, |r| r.release_to_preview_secs),
        width_px: w,
        height_px: h,
    })
}
