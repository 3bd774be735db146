//! The app's engine: one scene under one environment, its (growing) bake, the wgpu preview, and
//! fits that reuse everything a stroke does not change.
//!
//! Inputs: the scene, the environment, cuts as the bake delivers them (first the vertices the first
//! view sees, then all), a [`Document`] per fit, a view per frame, and which renderer draws the
//! preview ([`PreviewChoice`]: the wgpu preview on a hardware adapter, the CPU PRT frame where the
//! only adapter is a software rasteriser, which is 40-60× slower than the CPU frame for the same
//! picture). Outputs: preview frames (linear [`Image`]s with the environment behind the object),
//! fitted [`Material`]s with their p(h) table and timings, exported files. Invariants: calls only
//! the library's public stage functions (the fitting context, tabulation, the GPU preview, the
//! exporters); fits run in one [`FitSession`], the type `glint fit` uses, so a view's transfer is
//! computed once per (view, rotation, σ, layout, F0) and kept, each solve is warm-started from the
//! previous fit's active sets, and the same strokes give the same material as `glint fit`.

use super::AppError;
use super::state::Document;
use crate::bake::Cuts;
use crate::env::EnvMap;
use crate::export::{Provenance, Tool};
use crate::fit::material::Material;
use crate::fit::run::camera_for;
use crate::fit::session::{FitInputs, FitSession};
use crate::fit::strokes::ViewSpec;
use crate::gpu::{GpuContext, GpuPreview};
use crate::light::LightSums;
use crate::render::prt::ShadingMesh;
use crate::render::{Image, PhPyramid, Prt, PrtSettings, Shading, Specular, VertexLight, table};
use crate::scene::{Camera, Scene};
use crate::sphere::{DirectionSet, LightTree};
use glam::Vec4;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Where the time of one fit went (seconds).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FitTimings {
    /// Transfers of views not seen before and energy rows of new lobes (≈ 0 when all were cached).
    pub transfer_secs: f64,
    /// Normal equations and the three QP solves.
    pub solve_secs: f64,
    /// The p(h) table and its upload.
    pub table_secs: f64,
    /// The preview frame (wgpu: shade, raster, readback; or the CPU PRT frame), background
    /// included.
    pub render_secs: f64,
}

/// Which renderer draws the preview frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PreviewChoice {
    /// The wgpu preview on a hardware adapter; the CPU frame where the adapter is a software one
    /// (wgpu's `DeviceType::Cpu`, e.g. Mesa's llvmpipe).
    #[default]
    Auto,
    /// The CPU PRT frame (`render::Prt`, vertex shading, every core).
    Cpu,
    /// The wgpu preview, whatever the adapter.
    Gpu,
}

impl std::str::FromStr for PreviewChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "cpu" => Ok(Self::Cpu),
            "gpu" => Ok(Self::Gpu),
            _ => Err(format!("the preview is auto, cpu or gpu, not {s:?}")),
        }
    }
}

/// The settings the preview renderers use: the mesh's own vertices are shaded (the wgpu preview's
/// compute pass shades vertices; the CPU frame does the same so that the two show the same picture,
/// `tests/it/gpu.rs`). The wgpu preview takes the default partition (8°); the CPU preview uses 16°
/// nodes, which halve its frame time for ≤ 0.2 points against Monte Carlo (`cargo test --test
/// render diagnose`, PDS=8,16: bunny 3.65 / 3.68 %, teapot 12.83 / 12.99 %; dragon_100k at 640×480:
/// 0.30 s / 0.15 s, `cargo bench --bench render`) and clips nodes of up to 64 leaves astride a
/// horizon whole ([`CPU_PREVIEW_HORIZON_LEAVES`]).
pub fn preview_settings(gpu: bool) -> PrtSettings {
    if gpu {
        return PrtSettings {
            max_edge_px: 0.0,
            per_pixel: false,
            ..PrtSettings::default()
        };
    }
    PrtSettings {
        max_edge_px: 0.0,
        per_pixel: false,
        partition_deg: CPU_PREVIEW_PARTITION_DEG,
        horizon_leaves: CPU_PREVIEW_HORIZON_LEAVES,
        ..PrtSettings::default()
    }
}

/// The CPU preview's horizon clip ([`PrtSettings::horizon_leaves`]): nodes of ≤ 64 leaves (~11°)
/// astride a vertex's horizon are clipped whole by the disc model. dragon_100k at 640×480 under
/// courtyard, vertex shading at 16°: the first frame after a light rotation 0.131 → 0.099 s, 2.6e-3
/// relative RMSE against clipping leaf by leaf (4.9e-4 at the default 16 leaves).
pub const CPU_PREVIEW_HORIZON_LEAVES: u32 = 64;

/// The CPU preview's render partition (degrees), see [`preview_settings`].
pub const CPU_PREVIEW_PARTITION_DEG: f64 = 16.0;

/// A finished fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    pub material: Material,
    pub timings: FitTimings,
    /// The p(h) table as an image (resolution², hemi-octahedral), `None` without specular lobes.
    pub table_image: Option<Image>,
}

/// The refined mesh and its tangents, the cuts' mesh (taken field by field, so that a caller can
/// hold it while it mutates the engine's other fields).
type Refined = Option<(Arc<crate::scene::Mesh>, Option<Vec<Vec4>>)>;
fn baked_mesh<'a>(
    scene: &'a Scene,
    tangents: &'a Option<Vec<Vec4>>,
    refined: &'a Refined,
) -> (&'a crate::scene::Mesh, Option<&'a [Vec4]>) {
    match refined {
        Some((m, t)) => (m, t.as_deref()),
        None => (&scene.mesh, tangents.as_deref()),
    }
}

/// The engine (see the module docs).
pub struct Engine {
    scene: Arc<Scene>,
    env: EnvMap,
    env_path: PathBuf,
    tangents: Option<Vec<Vec4>>,
    /// The bake's refined mesh and its tangents, once the bake has refined it (decision (e)); the
    /// cuts then belong to it. Frames and transfers use it; exports write the scene's own mesh.
    refined: Refined,
    anisotropic: bool,
    set: DirectionSet,
    tree: LightTree,
    cuts: Option<Cuts>,
    ctx: GpuContext,
    /// Whether frames come from the wgpu preview (else from the CPU PRT frame).
    use_gpu: bool,
    /// Why, in words (shown in the side panel).
    preview_reason: String,
    gpu: Option<GpuPreview>,
    /// The CPU preview's per-vertex light for the current rotation and cuts (frames after a new
    /// view or a new fit evaluate only the BRDF); emptied when the light or the cuts change.
    vertex_light: VertexLight,
    /// CPU frames drawn with the current light (and cuts): the first is shaded directly, later ones
    /// fill and read `vertex_light`.
    frames_with_light: u32,
    /// The CPU preview's shading mesh of the last view (camera and size): kept while only the light
    /// or the material changes; dropped with the cuts.
    view_mesh: Option<(Camera, [u32; 2], ShadingMesh)>,
    light: Option<(f64, LightSums)>,
    /// The environment prepared for light sums (kept across rotations; dropped with the
    /// environment).
    light_source: Option<crate::light::LightSource>,
    /// Lobes, energy rows, transfers and the warm start, kept across fits.
    session: FitSession,
    /// ρd, F0 and the table on the GPU now (re-uploaded when the preview is rebuilt).
    shown: Option<([f64; 3], f64, Option<PhPyramid>)>,
    material: Option<Material>,
}

impl Engine {
    /// An engine for a scene whose bake decided `resolution` and `anisotropic`; no cuts yet.
    pub fn new(
        scene: Arc<Scene>,
        env: EnvMap,
        env_path: PathBuf,
        tangents: Option<Vec<Vec4>>,
        anisotropic: bool,
        resolution: usize,
        preview: PreviewChoice,
    ) -> Result<Self, AppError> {
        let set = DirectionSet::cube(resolution).map_err(|e| AppError::Stage(e.to_string()))?;
        let tree = LightTree::build(&set);
        let ctx = GpuContext::headless()?;
        let software = ctx.info.device_type == wgpu::DeviceType::Cpu;
        let threads = rayon::current_num_threads();
        let (use_gpu, preview_reason) = match preview {
            PreviewChoice::Gpu => (
                true,
                format!("wgpu on {} (chosen with --preview gpu)", ctx.describe()),
            ),
            PreviewChoice::Cpu => (
                false,
                format!("the CPU PRT frame on {threads} threads (chosen with --preview cpu)"),
            ),
            PreviewChoice::Auto if software => (
                false,
                format!(
                    "the CPU PRT frame on {threads} threads: the only adapter, {}, is a software rasteriser",
                    ctx.describe()
                ),
            ),
            PreviewChoice::Auto => (true, format!("wgpu on {}", ctx.describe())),
        };
        Ok(Self {
            scene,
            env,
            env_path,
            tangents,
            refined: None,
            anisotropic,
            set,
            tree,
            cuts: None,
            ctx,
            use_gpu,
            preview_reason,
            gpu: None,
            vertex_light: VertexLight::default(),
            frames_with_light: 0,
            view_mesh: None,
            light: None,
            light_source: None,
            session: FitSession::default(),
            shown: None,
            material: None,
        })
    }

    /// What draws the preview and why, in words.
    pub fn device(&self) -> String {
        self.preview_reason.clone()
    }

    /// Whether preview frames come from the wgpu preview (else from the CPU PRT frame).
    pub fn uses_gpu(&self) -> bool {
        self.use_gpu
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn env_path(&self) -> &Path {
        &self.env_path
    }

    /// The last fitted material.
    pub fn material(&self) -> Option<&Material> {
        self.material.as_ref()
    }

    /// New cuts from the bake (partial: unbaked vertices have empty cuts and render black).
    /// Rebuilds the GPU buffers (when the GPU draws the preview) and keeps the cached transfers (a
    /// baked vertex's cut never changes) — unless `refined` brings the refined mesh (and its
    /// tangents) the cuts now belong to: then the transfers are dropped and recomputed on it.
    pub fn set_bake(&mut self, cuts: Cuts, refined: Refined) -> Result<(), AppError> {
        if let Some(r) = refined {
            self.refined = Some(r);
            self.session.forget_transfers();
        }
        let (mesh, tangents) = baked_mesh(&self.scene, &self.tangents, &self.refined);
        if cuts.vertex_count() != mesh.positions.len() {
            return Err(AppError::Stage(format!(
                "the bake delivered {} cuts for a mesh of {} vertices",
                cuts.vertex_count(),
                mesh.positions.len()
            )));
        }
        if self.use_gpu {
            match GpuPreview::new(
                &self.ctx,
                mesh,
                &cuts,
                &self.tree,
                tangents,
                preview_settings(true),
            ) {
                Ok(mut gpu) => {
                    if let Some((_, light)) = &self.light {
                        gpu.set_light(light, &self.tree)?;
                    }
                    if let Some((rho_d, f0, t)) = &self.shown {
                        gpu.set_material(*rho_d, *f0, t.as_ref())?;
                    }
                    self.gpu = Some(gpu);
                }
                // A bake this adapter cannot shade (its limits): the CPU frame draws it, and says
                // why.
                Err(e @ crate::gpu::GpuError::Limit { .. }) => {
                    let threads = rayon::current_num_threads();
                    self.use_gpu = false;
                    self.gpu = None;
                    self.preview_reason = format!("the CPU PRT frame on {threads} threads: {e}");
                }
                Err(e) => return Err(e.into()),
            }
        }
        self.cuts = Some(cuts);
        self.vertex_light = VertexLight::default();
        self.frames_with_light = 0;
        self.view_mesh = None;
        Ok(())
    }

    /// Vertices of the mesh the cuts belong to (the refined mesh once the bake has refined it).
    pub fn baked_vertices(&self) -> usize {
        baked_mesh(&self.scene, &self.tangents, &self.refined)
            .0
            .positions
            .len()
    }

    /// Replaces the environment (the bake stays: visibility does not depend on the light).
    pub fn set_env(&mut self, path: &Path) -> Result<(), AppError> {
        self.env = crate::env::load(path)
            .map_err(|e| AppError::Stage(format!("{}: {e}", path.display())))?;
        self.env_path = path.to_path_buf();
        self.light = None;
        self.light_source = None;
        self.session.forget_transfers();
        Ok(())
    }

    fn ensure_light(&mut self, rotation_deg: f64) -> Result<(), AppError> {
        let rotation = rotation_deg.to_radians();
        if self.light.as_ref().is_some_and(|(r, _)| *r == rotation) {
            return Ok(());
        }
        let source = self
            .light_source
            .get_or_insert_with(|| crate::light::LightSource::new(&self.env));
        let light = LightSums::from_source(source, &self.set, &self.tree, rotation);
        if let Some(gpu) = &mut self.gpu {
            gpu.set_light(&light, &self.tree)?;
        }
        self.vertex_light = VertexLight::default();
        self.frames_with_light = 0;
        self.light = Some((rotation, light));
        Ok(())
    }

    /// The camera of a view at an image size.
    pub fn camera(&self, view: &ViewSpec, size: [u32; 2]) -> Result<Camera, AppError> {
        camera_for(&self.scene, view, size).map_err(|e| AppError::Stage(e.to_string()))
    }

    /// The fitting context and what a fit reads (the cuts' mesh, the cuts, the light at the current
    /// rotation), borrowed together.
    fn session_and_inputs(&mut self) -> Result<(&mut FitSession, FitInputs<'_>), AppError> {
        let cuts = self.cuts.as_ref().ok_or(AppError::NotReady(
            "the bake has not delivered any cuts yet",
        ))?;
        let (_, light) = self
            .light
            .as_ref()
            .ok_or(AppError::NotReady("the light comes before a fit"))?;
        let (mesh, tangents) = baked_mesh(&self.scene, &self.tangents, &self.refined);
        let inputs = FitInputs {
            scene: &self.scene,
            mesh,
            tangents,
            anisotropic: self.anisotropic,
            cuts,
            tree: &self.tree,
            light,
        };
        Ok((&mut self.session, inputs))
    }

    /// Everything a first stroke in `view` needs besides the solve: light, lobes, energy rows and
    /// the view's transfer. Returns the seconds it took.
    pub fn prepare(
        &mut self,
        doc: &Document,
        view: &ViewSpec,
        size: [u32; 2],
    ) -> Result<f64, AppError> {
        let start = Instant::now();
        self.ensure_light(doc.settings.env_rotation_deg)?;
        let settings = doc.settings.fit_settings(self.anisotropic);
        let (session, inputs) = self.session_and_inputs()?;
        session
            .prepare(&inputs, view, size, &settings)
            .map_err(|e| AppError::Stage(e.to_string()))?;
        Ok(start.elapsed().as_secs_f64())
    }

    /// The view in clay — grey, lit from the eye, 0.1 + 0.4·|n·v| — from the mesh alone: what the
    /// viewport shows, and what can be painted on, before the first view's vertices are baked.
    pub fn render_clay(&self, view: &ViewSpec, size: [u32; 2]) -> Result<Image, AppError> {
        let camera = self.camera(view, size)?;
        let mesh = &self.scene.mesh;
        let eye = camera.eye();
        let mut image = Image::new(size[0], size[1]);
        for f in crate::raster::rasterize(mesh, &camera, size[0], size[1]) {
            let corners = mesh.triangles[f.triangle as usize].map(|v| v as usize);
            let (mut p, mut n) = (glam::Vec3::ZERO, glam::Vec3::ZERO);
            for (&v, &b) in corners.iter().zip(&f.bary) {
                p += mesh.positions[v] * b;
                n += mesh.normals[v] * b;
            }
            let shade = 0.1
                + 0.4
                    * n.normalize_or_zero()
                        .dot((eye - p).normalize_or_zero())
                        .abs();
            let i = f.y as usize * size[0] as usize + f.x as usize;
            image.pixels[i] = [shade; 3];
            image.covered[i] = true;
        }
        Ok(image)
    }

    /// A preview frame of the current material in a view (the wgpu preview or the CPU PRT frame,
    /// see [`PreviewChoice`]; both shade the mesh's vertices and interpolate).
    pub fn render(
        &mut self,
        view: &ViewSpec,
        size: [u32; 2],
        rotation_deg: f64,
    ) -> Result<Image, AppError> {
        self.ensure_light(rotation_deg)?;
        let camera = self.camera(view, size)?;
        let mut image = if self.use_gpu {
            let gpu = self.gpu.as_mut().ok_or(AppError::NotReady(
                "the bake has not delivered any cuts yet",
            ))?;
            if self.shown.is_none() {
                gpu.set_material([0.5; 3], 0.04, None)?;
                self.shown = Some(([0.5; 3], 0.04, None));
            }
            gpu.render(&camera, size[0], size[1])?
        } else {
            let cuts = self.cuts.as_ref().ok_or(AppError::NotReady(
                "the bake has not delivered any cuts yet",
            ))?;
            let (_, light) = self
                .light
                .as_ref()
                .ok_or(AppError::NotReady("the light comes before a frame"))?;
            let (rho_d, f0, table) = self.shown.get_or_insert(([0.5; 3], 0.04, None));
            let specular = match table.as_ref() {
                Some(t) => Specular::Table(t),
                None => Specular::None,
            };
            let (mesh, tangents) = baked_mesh(&self.scene, &self.tangents, &self.refined);
            let prt = Prt::new(mesh, cuts, &self.tree, tangents, preview_settings(false));
            let shading = Shading {
                rho_d: *rho_d,
                f0: *f0,
                specular,
            };
            if !self
                .view_mesh
                .as_ref()
                .is_some_and(|(c, s, _)| *c == camera && *s == size)
            {
                self.view_mesh = None;
            }
            let (_, _, sm) = self.view_mesh.get_or_insert_with(|| {
                (
                    camera.clone(),
                    size,
                    prt.shading_mesh(&camera, size[0], size[1]),
                )
            });
            let image = if self.frames_with_light == 0 {
                // The first frame with a new light (a rotation being dragged) is shaded directly:
                // filling the per-vertex light cache on the way costs more than it saves on one
                // frame (dragon_100k at 640×480: 0.10 s against 0.13 s, light sums included). The
                // next frame with this light fills it, for the views and fits that follow.
                prt.render_mesh(sm, light, &camera, size[0], size[1], &shading)
            } else {
                prt.render_cached_mesh(
                    &mut self.vertex_light,
                    sm,
                    light,
                    &camera,
                    size[0],
                    size[1],
                    &shading,
                )
            };
            self.frames_with_light += 1;
            image
        };
        image.fill_background(&self.env, rotation_deg.to_radians(), &camera);
        Ok(image)
    }

    /// The still frame of a view that stopped moving: what `glint render` draws — the PRT frame
    /// with its default settings (shaded per pixel, finer partitions at grazing views) and the
    /// table the preview shows — where a preview frame shades the mesh's vertices (the wgpu
    /// preview, or the CPU frame at [`CPU_PREVIEW_PARTITION_DEG`]) and interpolates. The worker
    /// draws it once the view, the light and the material have rested for
    /// [`super::worker::STILL_DELAY`].
    pub fn render_still(
        &mut self,
        view: &ViewSpec,
        size: [u32; 2],
        rotation_deg: f64,
    ) -> Result<Image, AppError> {
        self.ensure_light(rotation_deg)?;
        let camera = self.camera(view, size)?;
        let cuts = self.cuts.as_ref().ok_or(AppError::NotReady(
            "the bake has not delivered any cuts yet",
        ))?;
        let (_, light) = self
            .light
            .as_ref()
            .ok_or(AppError::NotReady("the light comes before a frame"))?;
        let (rho_d, f0, table) = match &self.shown {
            Some((rho_d, f0, table)) => (*rho_d, *f0, table.as_ref()),
            None => ([0.5; 3], 0.04, None),
        };
        let specular = table.map_or(Specular::None, Specular::Table);
        let (mesh, tangents) = baked_mesh(&self.scene, &self.tangents, &self.refined);
        let prt = Prt::new(mesh, cuts, &self.tree, tangents, PrtSettings::default());
        let shading = Shading {
            rho_d,
            f0,
            specular,
        };
        let mut image = prt.render(light, &camera, size[0], size[1], &shading);
        image.fill_background(&self.env, rotation_deg.to_radians(), &camera);
        Ok(image)
    }

    /// Fits the document's strokes (all views in one solve) and shows the material in the preview.
    pub fn fit(&mut self, doc: &Document) -> Result<FitResult, AppError> {
        let s = &doc.settings;
        s.validate().map_err(AppError::Settings)?;
        self.ensure_light(s.env_rotation_deg)?;
        let settings = s.fit_settings(self.anisotropic);
        let (session, inputs) = self.session_and_inputs()?;
        let outcome = session
            .fit(&inputs, &doc.fit_views(), &settings)
            .map_err(|e| AppError::Stage(e.to_string()))?;
        let material = outcome.material;
        let mut timings = FitTimings {
            transfer_secs: outcome.transfer_seconds,
            solve_secs: material.fit.solve_seconds,
            ..FitTimings::default()
        };
        let lobes = material
            .lobes()
            .map_err(|e| AppError::Stage(e.to_string()))?;
        let table_start = Instant::now();
        let specular = material.coefficients.iter().flatten().any(|c| *c > 0.0);
        let table = specular.then(|| {
            let c = &material.coefficients;
            PhPyramid::build(
                &lobes,
                [&c[0], &c[1], &c[2]],
                table::default_resolution(lobes.lambda()),
            )
        });
        if let Some(gpu) = &mut self.gpu {
            gpu.set_material(s.rho_d, s.f0, table.as_ref())?;
        }
        let table_image = table.as_ref().map(|t| {
            let n = t.resolution() as u32;
            let mut img = Image::new(n, n);
            for (k, texel) in t.texels().iter().enumerate() {
                img.set(k as u32 % n, k as u32 / n, *texel);
            }
            img
        });
        self.shown = Some((s.rho_d, s.f0, table));
        timings.table_secs = table_start.elapsed().as_secs_f64();
        self.material = Some(material.clone());
        Ok(FitResult {
            material,
            timings,
            table_image,
        })
    }

    /// Writes every export format of the last material into `dir` (the scene's mesh in glTF and
    /// USD).
    pub fn export(&self, dir: &Path, name: &str) -> Result<Vec<PathBuf>, AppError> {
        let material = self
            .material
            .as_ref()
            .ok_or(AppError::NotReady("nothing is fitted yet"))?;
        let mut provenance = Provenance::new(Tool::App, material);
        provenance
            .scene_file(&self.scene.source)
            .env_file(&self.env_path)
            .env_rotation_deg(self.light.as_ref().map_or(0.0, |(r, _)| r.to_degrees()));
        let mesh = crate::export::scene_mesh(&self.scene.mesh, self.tangents.as_deref());
        // The fallbacks are fitted where the scene's first camera looks, under the current light.
        let mut seen = mesh.clone();
        seen.camera = self
            .scene
            .cameras
            .first()
            .map(|c| crate::export::scene_camera(c, 640, 480));
        seen.environment = Some(crate::export::scene_environment(
            &self.env,
            self.light.as_ref().map_or(0.0, |(r, _)| *r),
        ));
        let desc = crate::export::material_desc(
            material,
            name,
            crate::export::EXPORT_TABLE_RESOLUTION,
            provenance,
            Some(&seen),
        )
        .map_err(|e| AppError::Stage(e.to_string()))?;
        std::fs::create_dir_all(dir).map_err(|e| AppError::Io {
            path: dir.to_path_buf(),
            reason: e.to_string(),
        })?;
        glint_exporters::export_all(&desc, Some(&mesh), dir, &[])
            .map_err(|e| AppError::Stage(e.to_string()))
    }
}
