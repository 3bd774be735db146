//! The accuracy matrix: the PRT frame (what `glint render` and the fit see) against the Monte Carlo
//! reference over meshes × environment maps × views × environment rotations × materials, with the
//! silhouette pixels (object pixels with a background 4-neighbour) reported apart.
//!
//! Materials: `sharp` — one ring lobe at the normal, λ = 81 (σ = π/40), little diffuse; `broad` —
//! ring lobes of λ = 10 spread over the polar angles, a diffuse base; `anisotropic` — a hemicube-5
//! lobe stretched along the tangent (λ = 40), on meshes with a tangent field only. Views: the
//! default camera, an orbit (20°, 15°, 2.5 radii) and a grazing orbit (200°, 3°, 2.5 radii).
//! Rotations 0° and 90°. Each (mesh, map) is baked once with the default settings (and its
//! decisions); each case's reference is rendered on the imported mesh, as `glint render
//! --reference` does.
//!
//! Inputs: scenes and maps ([`run`]: the caller loads them; [`run_study`]: the bundled samples and
//! the shared assets, read here), [`MatrixOptions`]. Outputs: [`MatrixRow`]s and their Markdown/CSV
//! ([`markdown`], [`csv`]; [`run_study`] writes them). Invariants: references are seeded, so two
//! runs give the same errors.

use crate::bake::{BakeSettings, Baker, Tracer};
use crate::env::EnvMap;
use crate::fit::material::{FitStats, Material};
use crate::light::LightSums;
use crate::render::traced::{TRACED_BOUNDARY_LEVELS, Tracing};
use crate::render::{
    ExactMaterial, Image, PhPyramid, Prt, PrtSettings, Shading, Specular, render_reference,
    render_traced, table,
};
use crate::scene::{Bounds, Camera, Mesh, Scene, default_camera, orbit_camera};
use crate::sphere::{LobeLayout, LobeSet, srbf};
use crate::study::StudyError;
use std::time::Instant;

/// How big a matrix to run.
#[derive(Debug, Clone, Copy)]
pub struct MatrixOptions {
    /// Image width and height.
    pub size: (u32, u32),
    /// Samples per pixel of each reference.
    pub spp: u32,
}

impl MatrixOptions {
    /// The documented matrix: 128×96, 1024 spp.
    pub const FULL: MatrixOptions = MatrixOptions {
        size: (128, 96),
        spp: 1024,
    };
    /// A small one (CI): 64×48, 1024 spp.
    pub const QUICK: MatrixOptions = MatrixOptions {
        size: (64, 48),
        spp: 1024,
    };
}

/// What `glint study --matrix` did: the rows, the report's title and the files written.
pub struct MatrixStudy {
    pub rows: Vec<MatrixRow>,
    pub title: String,
    pub written: Vec<std::path::PathBuf>,
}

impl MatrixStudy {
    /// One line: how many cases meet 2 % (object pixels) and 4 % (silhouette pixels), and the
    /// worst.
    pub fn summary(&self) -> String {
        let ok = self.rows.iter().filter(|r| r.within_as_measured()).count();
        let worst = self
            .rows
            .iter()
            .max_by(|a, b| a.rel_rmse.total_cmp(&b.rel_rmse));
        let worst = worst.map(|r| {
            format!(
                "; worst {:.2} %: {} under {}, {}, {}°, {}",
                100.0 * r.rel_rmse,
                r.mesh,
                r.map,
                r.view,
                r.rotation_deg,
                r.material
            )
        });
        let knobs: Vec<Knob> = self.rows.iter().map(MatrixRow::knob).collect();
        let n = |f: &dyn Fn(Knob) -> bool| knobs.iter().filter(|&&k| f(k)).count();
        format!(
            "{ok} of {} cases within 2 % (object pixels) and 4 % (silhouette pixels){}; with the reference's noise taken out, {} at the defaults, {} more with --trace-visibility, {} with --trace-budget 0, {} with --trace-levels {FINER_LEVELS} as well, {} within only against {FINER_SPP}x the reference's samples, {} with no knob tried",
            self.rows.len(),
            worst.unwrap_or_default(),
            n(&|k| k == Knob::Defaults),
            n(&|k| k == Knob::TraceVisibility),
            n(&|k| k == Knob::TraceAllEdges),
            n(&|k| k == Knob::TraceLevels),
            n(&|k| matches!(k, Knob::FinerReference(_))),
            n(&|k| k == Knob::None),
        )
    }
}

/// `glint study --matrix`: loads the meshes and maps (the bundled samples; dragon_100k and the
/// interior map from `assets`; `quick`: the bunny and the brushed sphere under the studio map),
/// runs the matrix and writes matrix.md and matrix.csv into `out`. `only`: words that narrow the
/// meshes and the maps to those whose names contain one (a kind no word names is kept whole).
pub fn run_study(
    samples: &std::path::Path,
    assets: &std::path::Path,
    quick: bool,
    only: &[String],
    out: &std::path::Path,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<MatrixStudy, StudyError> {
    let need = |p: std::path::PathBuf| {
        if p.is_file() {
            Ok(p)
        } else {
            Err(StudyError::Input(format!(
                "the accuracy matrix needs {} (see --assets)",
                p.display()
            )))
        }
    };
    let mut meshes = vec![("bunny", need(samples.join("bunny.glb"))?, None)];
    if !quick {
        meshes.push(("teapot", need(samples.join("teapot.glb"))?, None));
        meshes.push(("suzanne", need(samples.join("suzanne.glb"))?, None));
        meshes.push((
            "dragon_100k patch",
            need(assets.join("glb/dragon_100k.glb"))?,
            Some(0.3),
        ));
    }
    meshes.push((
        "brushed sphere",
        need(samples.join("brushed_sphere.glb"))?,
        None,
    ));
    let mut maps = vec![("studio", need(samples.join("studio_1k.exr"))?)];
    if !quick {
        maps.push(("courtyard", need(samples.join("courtyard_1k.exr"))?));
        maps.push(("interior", need(assets.join("hdr/interior_1k.exr"))?));
    }
    let named = |names: &[&str]| {
        let words: Vec<&String> = only
            .iter()
            .filter(|w| names.iter().any(|n| n.contains(w.as_str())))
            .collect();
        move |name: &str| words.is_empty() || words.iter().any(|w| name.contains(w.as_str()))
    };
    let keep_mesh = named(&meshes.iter().map(|m| m.0).collect::<Vec<_>>());
    let keep_map = named(&maps.iter().map(|m| m.0).collect::<Vec<_>>());
    if let Some(w) = only.iter().find(|w| {
        !meshes.iter().any(|m| m.0.contains(w.as_str()))
            && !maps.iter().any(|m| m.0.contains(w.as_str()))
    }) {
        return Err(StudyError::Input(format!(
            "--only {w}: no mesh or map of the matrix is named so"
        )));
    }
    meshes.retain(|m| keep_mesh(m.0));
    maps.retain(|m| keep_map(m.0));
    let mut scenes = Vec::new();
    for (name, path, fraction) in meshes {
        let mut scene = crate::scene::import(&path)?;
        if let Some(f) = fraction {
            scene.mesh = patch(&scene.mesh, f);
            scene.bounds = Bounds::from_points(&scene.mesh.positions).ok_or_else(|| {
                StudyError::Input(format!("{}: the patch is empty", path.display()))
            })?;
        }
        scenes.push((name.to_string(), scene));
    }
    let envs = maps
        .into_iter()
        .map(|(n, p)| Ok((n.to_string(), crate::env::load(&p)?)))
        .collect::<Result<Vec<_>, StudyError>>()?;
    let options = if quick {
        MatrixOptions::QUICK
    } else {
        MatrixOptions::FULL
    };
    let start = Instant::now();
    let rows = run(&scenes, &envs, options, progress)?;
    let title = format!(
        "glint accuracy matrix: PRT frame vs Monte Carlo reference, {}x{}, {} spp{}{} — {} cases, {:.0} s on {} threads",
        options.size.0,
        options.size.1,
        options.spp,
        if quick { " (quick)" } else { "" },
        if only.is_empty() {
            String::new()
        } else {
            format!(" (only {})", only.join(", "))
        },
        rows.len(),
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    std::fs::create_dir_all(out).map_err(|e| StudyError::Write {
        path: out.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut written = Vec::new();
    for (name, text) in [
        ("matrix.md", markdown(&rows, &title)),
        ("matrix.csv", csv(&rows)),
    ] {
        let p = out.join(name);
        glint_exporters::write_atomic(&p, text.as_bytes()).map_err(|e| StudyError::Write {
            path: p.display().to_string(),
            reason: e.to_string(),
        })?;
        written.push(p);
    }
    Ok(MatrixStudy {
        rows,
        title,
        written,
    })
}

/// One case of the matrix.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MatrixRow {
    pub mesh: String,
    pub map: String,
    pub view: String,
    pub rotation_deg: f64,
    pub material: String,
    /// Relative RMSE of the PRT frame against the reference over object pixels.
    pub rel_rmse: f64,
    /// The same over silhouette pixels only (object pixels with a background 4-neighbour).
    pub silhouette_rel_rmse: f64,
    pub object_pixels: usize,
    pub silhouette_pixels: usize,
    /// The reference's own noise over object pixels: it is the mean of two seeds' images, whose
    /// difference gives its noise (relative RMSE between them over 2).
    pub reference_noise: f64,
    /// The same over silhouette pixels, where a grazing view makes the reference noisier.
    pub silhouette_noise: f64,
    pub prt_secs: f64,
    /// Seconds for the reference (both seeds).
    pub reference_secs: f64,
    /// The knob for visibility that changes inside triangles: the same frame with each pixel's
    /// own traced cut where its corners disagree ([`render_traced`]).
    pub traced: TracedCase,
    /// Where the traced frame misses: what was tried next ([`Finer`]).
    pub finer: Option<Finer>,
}

/// A case rendered with per-pixel traced visibility ([`render_traced`], `glint render
/// --trace-visibility`).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct TracedCase {
    /// Relative RMSE against the reference over object pixels, and over silhouette pixels.
    pub rel_rmse: f64,
    pub silhouette_rel_rmse: f64,
    /// Seconds for the frame (tracing and shading; the p(h) table is the default frame's).
    pub secs: f64,
    /// Pixels traced (their triangle's corners disagree) and the rays cast for them.
    pub traced_pixels: usize,
    pub rays: u64,
}

/// The steps after `--trace-visibility` for a case it leaves outside the goals: the traced frame
/// with every shadow edge refined (`--trace-budget 0`); where that misses, its cells refined down
/// to single directions at those edges as well (`--trace-levels` [`FINER_LEVELS`]); and where
/// that misses too, every frame against a reference of [`FINER_SPP`] times the samples (a miss
/// that goes away there was the reference's noise).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Finer {
    pub all_edges: TracedCase,
    pub levels: Option<TracedCase>,
    pub reference: Option<FinerReference>,
}

/// The case's frames against a reference with [`FINER_SPP`] times the samples per seed.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct FinerReference {
    pub spp: u32,
    pub noise: f64,
    pub silhouette_noise: f64,
    /// (object, silhouette) relative RMSE of the default frame, the traced frame, the traced
    /// frame at budget 0 and (where rendered) at [`FINER_LEVELS`] as well.
    pub default: (f64, f64),
    pub traced: (f64, f64),
    pub all_edges: (f64, f64),
    pub levels: Option<(f64, f64)>,
    pub secs: f64,
}

/// The traced frame of the matrix's third knob: every shadow edge refined (`--trace-budget 0`).
pub const ALL_EDGES: Tracing = Tracing {
    levels: TRACED_BOUNDARY_LEVELS,
    budget: Some(0.0),
};

/// `--trace-levels` of the matrix's fourth knob (with `--trace-budget 0`): 4 levels take the
/// decided cells (at most 16 directions a side) down to single directions at shadow edges.
pub const FINER_LEVELS: u32 = 4;

/// How many times the samples the finer reference takes.
pub const FINER_SPP: u32 = 4;

/// What brings a case within the goals, cheapest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Knob {
    Defaults,
    TraceVisibility,
    /// `--trace-visibility --trace-budget 0`.
    TraceAllEdges,
    /// `--trace-visibility --trace-budget 0 --trace-levels` [`FINER_LEVELS`].
    TraceLevels,
    /// Within only against the finer reference, with the frame named.
    FinerReference(Frame),
    /// Not within with any knob tried.
    None,
}

/// One of a case's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Frame {
    Default,
    Traced,
    AllEdges,
    Levels,
}

impl Knob {
    /// The CSV's word for it.
    pub fn code(self) -> &'static str {
        match self {
            Knob::Defaults => "defaults",
            Knob::TraceVisibility => "traced",
            Knob::TraceAllEdges => "all-edges",
            Knob::TraceLevels => "levels",
            Knob::FinerReference(Frame::Default) => "finer-reference-default",
            Knob::FinerReference(Frame::Traced) => "finer-reference-traced",
            Knob::FinerReference(Frame::AllEdges) => "finer-reference-all-edges",
            Knob::FinerReference(Frame::Levels) => "finer-reference-levels",
            Knob::None => "none",
        }
    }

    /// In words, with the command-line flags.
    pub fn describe(self) -> String {
        let frame = |f: Frame| match f {
            Frame::Default => "defaults".to_string(),
            Frame::Traced => "--trace-visibility".to_string(),
            Frame::AllEdges => "--trace-visibility --trace-budget 0".to_string(),
            Frame::Levels => {
                format!("--trace-visibility --trace-budget 0 --trace-levels {FINER_LEVELS}")
            }
        };
        match self {
            Knob::Defaults => frame(Frame::Default),
            Knob::TraceVisibility => frame(Frame::Traced),
            Knob::TraceAllEdges => frame(Frame::AllEdges),
            Knob::TraceLevels => frame(Frame::Levels),
            Knob::FinerReference(f) => {
                format!(
                    "{} (within against {FINER_SPP}× the reference's samples)",
                    frame(f)
                )
            }
            Knob::None => "none tried".to_string(),
        }
    }
}

impl MatrixRow {
    /// Within 2 % over object pixels and 4 % over silhouette pixels as measured (noise included).
    pub fn within_as_measured(&self) -> bool {
        self.rel_rmse <= 0.02 && (self.silhouette_pixels == 0 || self.silhouette_rel_rmse <= 0.04)
    }

    /// The PRT's own error: the RMSE with the reference's noise taken out in quadrature.
    pub fn error_less_noise(&self) -> f64 {
        less_noise(self.rel_rmse, self.reference_noise)
    }

    /// The traced frame's error with the reference's noise taken out.
    pub fn traced_error_less_noise(&self) -> f64 {
        less_noise(self.traced.rel_rmse, self.reference_noise)
    }

    /// Whether (object, silhouette) errors meet the goals with the noise taken out.
    fn meets(&self, errors: (f64, f64), noise: (f64, f64)) -> bool {
        less_noise(errors.0, noise.0) <= 0.02
            && (self.silhouette_pixels == 0 || less_noise(errors.1, noise.1) <= 0.04)
    }

    /// The cheapest knob that brings the case within both goals with the reference's noise taken
    /// out ([`Knob`]).
    pub fn knob(&self) -> Knob {
        let noise = (self.reference_noise, self.silhouette_noise);
        if self.meets((self.rel_rmse, self.silhouette_rel_rmse), noise) {
            return Knob::Defaults;
        }
        let traced = (self.traced.rel_rmse, self.traced.silhouette_rel_rmse);
        if self.meets(traced, noise) {
            return Knob::TraceVisibility;
        }
        let Some(finer) = &self.finer else {
            return Knob::None;
        };
        let errors = |c: &TracedCase| (c.rel_rmse, c.silhouette_rel_rmse);
        if self.meets(errors(&finer.all_edges), noise) {
            return Knob::TraceAllEdges;
        }
        if finer.levels.is_some_and(|l| self.meets(errors(&l), noise)) {
            return Knob::TraceLevels;
        }
        let Some(r) = &finer.reference else {
            return Knob::None;
        };
        let noise = (r.noise, r.silhouette_noise);
        [
            (Frame::Default, Some(r.default)),
            (Frame::Traced, Some(r.traced)),
            (Frame::AllEdges, Some(r.all_edges)),
            (Frame::Levels, r.levels),
        ]
        .into_iter()
        .find(|&(_, e)| e.is_some_and(|e| self.meets(e, noise)))
        .map_or(Knob::None, |(f, _)| Knob::FinerReference(f))
    }
}

/// √(rmse² − noise²), 0 where the noise is larger.
fn less_noise(rmse: f64, noise: f64) -> f64 {
    (rmse.powi(2) - noise.powi(2)).max(0.0).sqrt()
}

/// The views of the matrix: (name, camera) for a mesh's bounds at `size`.
pub fn views(bounds: &Bounds, (w, h): (u32, u32)) -> Vec<(String, Camera)> {
    let mut default = default_camera(bounds);
    default.aspect = w as f32 / h as f32;
    vec![
        ("default".into(), default),
        (
            "orbit 20°/15°/2.5".into(),
            orbit_camera(bounds, 20.0, 15.0, 2.5, w, h),
        ),
        (
            "grazing 200°/3°/2.5".into(),
            orbit_camera(bounds, 200.0, 3.0, 2.5, w, h),
        ),
    ]
}

/// The matrix's materials; `anisotropic` only when `tangents` (the mesh has a tangent field).
pub fn materials(tangents: bool) -> Vec<(String, Material)> {
    let iso = |lambda: f64, rho_d: f64, c: &dyn Fn(f64) -> f64| -> Material {
        // Cannot fail: a fixed, valid layout (24 lobes) and λ ∈ {10, 81.06} > 0.
        let lobes =
            LobeSet::new(LobeLayout::Isotropic { count: 24 }, lambda).expect("isotropic-24");
        let coefficients: [Vec<f64>; 3] = std::array::from_fn(|ch| {
            lobes
                .centres()
                .iter()
                .map(|x| [1.0, 0.9, 0.8][ch] * c(x.z.clamp(-1.0, 1.0).acos()))
                .collect()
        });
        let sigma = srbf::sigma_from_lambda(lambda).unwrap_or(0.0);
        Material::new(
            &lobes,
            sigma,
            coefficients,
            [rho_d; 3],
            0.04,
            FitStats::default(),
        )
    };
    let mut out = vec![
        (
            "sharp".to_string(),
            iso(
                srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap_or(81.06),
                0.05,
                &|theta| if theta == 0.0 { 20.0 } else { 0.0 },
            ),
        ),
        (
            "broad".to_string(),
            iso(10.0, 0.3, &|theta| 0.6 * (-(theta / 0.6).powi(2)).exp()),
        ),
    ];
    if tangents {
        // Cannot fail: a fixed, valid layout (75 lobes) and λ = 40.
        let lobes = LobeSet::new(LobeLayout::Hemicube { n: 5 }, 40.0).expect("hemicube-5");
        let coefficients: [Vec<f64>; 3] = std::array::from_fn(|ch| {
            lobes
                .centres()
                .iter()
                .map(|x| [1.2, 1.0, 0.8][ch] * (-(x.x / 0.6).powi(2) - (x.y / 0.15).powi(2)).exp())
                .collect()
        });
        let sigma = srbf::sigma_from_lambda(40.0).unwrap_or(0.0);
        out.push((
            "anisotropic".into(),
            Material::new(
                &lobes,
                sigma,
                coefficients,
                [0.15, 0.12, 0.1],
                0.3,
                FitStats::default(),
            ),
        ));
    }
    out
}

/// Object pixels of `img` with a background 4-neighbour (or on the image border).
pub fn silhouette_mask(img: &Image) -> Vec<bool> {
    let (w, h) = (img.width as usize, img.height as usize);
    let covered = |x: isize, y: isize| {
        x >= 0
            && y >= 0
            && (x as usize) < w
            && (y as usize) < h
            && img.covered[y as usize * w + x as usize]
    };
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as isize, (k / w) as isize);
            img.covered[k]
                && !(covered(x - 1, y)
                    && covered(x + 1, y)
                    && covered(x, y - 1)
                    && covered(x, y + 1))
        })
        .collect()
}

/// ‖a − b‖ / ‖b‖ over the pixels `mask` selects that both images cover; `(NaN, 0)` when none.
pub fn masked_rel_rmse(a: &Image, b: &Image, mask: &[bool]) -> (f64, usize) {
    let (mut num, mut den, mut n) = (0f64, 0f64, 0usize);
    for k in 0..b.pixels.len() {
        if mask[k] && a.covered[k] && b.covered[k] {
            for c in 0..3 {
                num += (a.pixels[k][c] as f64 - b.pixels[k][c] as f64).powi(2);
                den += (b.pixels[k][c] as f64).powi(2);
            }
            n += 1;
        }
    }
    if n == 0 || den == 0.0 {
        (f64::NAN, 0)
    } else {
        ((num / den).sqrt(), n)
    }
}

/// A patch of a mesh: the triangles whose centroid lies within `fraction` of the bounding box's x
/// extent from its +x end (re-indexed; normals and tangents kept).
pub fn patch(mesh: &Mesh, fraction: f32) -> Mesh {
    let Some(bounds) = Bounds::from_points(&mesh.positions) else {
        return mesh.clone();
    };
    let cut = bounds.max.x - fraction * bounds.size().x;
    let mut map = vec![u32::MAX; mesh.positions.len()];
    let mut out = Mesh {
        positions: Vec::new(),
        normals: Vec::new(),
        tangents: mesh.tangents.as_ref().map(|_| Vec::new()),
        uvs: mesh.uvs.as_ref().map(|_| Vec::new()),
        triangles: Vec::new(),
    };
    for tri in &mesh.triangles {
        let c = (mesh.positions[tri[0] as usize]
            + mesh.positions[tri[1] as usize]
            + mesh.positions[tri[2] as usize])
            / 3.0;
        if c.x < cut {
            continue;
        }
        let mut t = [0u32; 3];
        for (k, &v) in tri.iter().enumerate() {
            if map[v as usize] == u32::MAX {
                map[v as usize] = out.positions.len() as u32;
                out.positions.push(mesh.positions[v as usize]);
                out.normals.push(mesh.normals[v as usize]);
                if let (Some(dst), Some(src)) = (out.tangents.as_mut(), mesh.tangents.as_ref()) {
                    dst.push(src[v as usize]);
                }
                if let (Some(dst), Some(src)) = (out.uvs.as_mut(), mesh.uvs.as_ref()) {
                    dst.push(src[v as usize]);
                }
            }
            t[k] = map[v as usize];
        }
        out.triangles.push(t);
    }
    out
}

/// Runs the matrix over every (scene, map) pair; `progress(done, total, what)`.
pub fn run(
    scenes: &[(String, Scene)],
    maps: &[(String, EnvMap)],
    options: MatrixOptions,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<Vec<MatrixRow>, StudyError> {
    let (w, h) = options.size;
    let mut rows = Vec::new();
    let total = scenes.len() * maps.len();
    for (i, (mesh_name, scene)) in scenes.iter().enumerate() {
        let tracer = Tracer::new(&scene.mesh);
        let (_, ref_tangents, _) = crate::bake::decisions::decide_frames(&scene.mesh);
        for (j, (map_name, env)) in maps.iter().enumerate() {
            progress(
                i * maps.len() + j,
                total,
                &format!("{mesh_name} under {map_name}: baking"),
            );
            let baker = Baker::new(scene, env, BakeSettings::default())?;
            let bake = baker.bake_refined(None, &|_| {});
            let refined = bake.scene(scene)?;
            let (_, tangents, _) = crate::bake::decisions::decide_frames(&refined.mesh);
            let prt = Prt::new(
                &refined.mesh,
                &bake.cuts,
                &baker.tree,
                tangents.as_deref(),
                PrtSettings::default(),
            );
            // The knob `--trace-visibility`: pixels traced as `glint render` traces them; then,
            // for the cases that miss with it, with `--trace-budget 0` and with
            // `--trace-levels` FINER_LEVELS as well.
            let tracing = |t| {
                let settings =
                    crate::render::traced::tracing_settings(bake.settings, &bake.decisions, t);
                Baker::new(&refined, env, settings)
            };
            let pixel_baker = tracing(Tracing::default())?;
            let all_edges_baker = tracing(ALL_EDGES)?;
            let finer_baker = tracing(Tracing {
                levels: FINER_LEVELS,
                ..ALL_EDGES
            })?;
            progress(
                i * maps.len() + j,
                total,
                &format!("{mesh_name} under {map_name}: rendering"),
            );
            // The light sums depend on the rotation only: once per rotation, not per view.
            for rotation_deg in [0.0, 90.0] {
                let rotation = f64::to_radians(rotation_deg);
                let light = LightSums::new(env, &baker.set, &baker.tree, rotation);
                for (view_name, camera) in views(&scene.bounds, options.size) {
                    for (material_name, m) in
                        materials(tangents.is_some() && ref_tangents.is_some())
                    {
                        let lobes = m.lobes()?;
                        let coefficients = [
                            m.coefficients[0].as_slice(),
                            m.coefficients[1].as_slice(),
                            m.coefficients[2].as_slice(),
                        ];
                        let t0 = Instant::now();
                        let tab = PhPyramid::build(
                            &lobes,
                            coefficients,
                            table::default_resolution(lobes.lambda()),
                        );
                        let shading = Shading {
                            rho_d: m.rho_d,
                            f0: m.f0,
                            specular: Specular::Table(&tab),
                        };
                        let img = prt.render(&light, &camera, w, h, &shading);
                        let prt_secs = t0.elapsed().as_secs_f64();
                        let traced_frame = |baker: &Baker| {
                            let t0 = Instant::now();
                            let (img, stats) = render_traced(
                                baker,
                                &refined.mesh,
                                &bake.cuts,
                                &bake.refinement.parents,
                                tangents.as_deref(),
                                &light,
                                &camera,
                                (w, h),
                                &shading,
                                PrtSettings::default(),
                            );
                            (img, stats, t0.elapsed().as_secs_f64())
                        };
                        let (traced_img, traced_stats, traced_secs) = traced_frame(&pixel_baker);
                        let exact = ExactMaterial {
                            lobes: &lobes,
                            coefficients,
                            rho_d: m.rho_d,
                            f0: m.f0,
                        };
                        let reference = |spp: u32| {
                            let t0 = Instant::now();
                            let seeds = [1, 2].map(|seed| {
                                render_reference(
                                    &scene.mesh,
                                    ref_tangents.as_deref(),
                                    &tracer,
                                    baker.ray_offset(),
                                    env,
                                    rotation,
                                    exact,
                                    &camera,
                                    w,
                                    h,
                                    spp,
                                    seed,
                                )
                            });
                            Reference::of_seeds(seeds, t0.elapsed().as_secs_f64())
                        };
                        let truth = reference(options.spp);
                        let all = vec![true; truth.image.pixels.len()];
                        let silhouette = silhouette_mask(&truth.image);
                        let errors = |img: &Image, truth: &Reference| {
                            (
                                masked_rel_rmse(img, &truth.image, &all).0,
                                masked_rel_rmse(img, &truth.image, &silhouette).0,
                            )
                        };
                        let (rel_rmse, object_pixels) = masked_rel_rmse(&img, &truth.image, &all);
                        let (silhouette_rel_rmse, silhouette_pixels) =
                            masked_rel_rmse(&img, &truth.image, &silhouette);
                        let (noise, silhouette_noise) = truth.noise(&all, &silhouette);
                        let traced_errors = errors(&traced_img, &truth);
                        let traced = TracedCase {
                            rel_rmse: traced_errors.0,
                            silhouette_rel_rmse: traced_errors.1,
                            secs: traced_secs,
                            traced_pixels: traced_stats.traced,
                            rays: traced_stats.rays,
                        };
                        let mut row = MatrixRow {
                            mesh: mesh_name.clone(),
                            map: map_name.clone(),
                            view: view_name.clone(),
                            rotation_deg,
                            material: material_name,
                            rel_rmse,
                            silhouette_rel_rmse,
                            object_pixels,
                            silhouette_pixels,
                            reference_noise: noise,
                            silhouette_noise,
                            prt_secs,
                            reference_secs: truth.secs,
                            traced,
                            finer: None,
                        };
                        // The next knobs, only where the traced frame misses.
                        let case = |baker: &Baker| {
                            let (img, stats, secs) = traced_frame(baker);
                            let e = errors(&img, &truth);
                            let case = TracedCase {
                                rel_rmse: e.0,
                                silhouette_rel_rmse: e.1,
                                secs,
                                traced_pixels: stats.traced,
                                rays: stats.rays,
                            };
                            (img, case)
                        };
                        if row.knob() == Knob::None {
                            let (all_edges_img, all_edges) = case(&all_edges_baker);
                            row.finer = Some(Finer {
                                all_edges,
                                levels: None,
                                reference: None,
                            });
                            let levels = (row.knob() == Knob::None).then(|| case(&finer_baker));
                            if let Some(f) = row.finer.as_mut() {
                                f.levels = levels.as_ref().map(|l| l.1);
                            }
                            if row.knob() == Knob::None {
                                let spp = options.spp * FINER_SPP;
                                let fine = reference(spp);
                                let (noise, silhouette_noise) = fine.noise(&all, &silhouette);
                                let reference = FinerReference {
                                    spp,
                                    noise,
                                    silhouette_noise,
                                    default: errors(&img, &fine),
                                    traced: errors(&traced_img, &fine),
                                    all_edges: errors(&all_edges_img, &fine),
                                    levels: levels.as_ref().map(|l| errors(&l.0, &fine)),
                                    secs: fine.secs,
                                };
                                if let Some(f) = row.finer.as_mut() {
                                    f.reference = Some(reference);
                                }
                            }
                        }
                        rows.push(row);
                    }
                }
            }
        }
    }
    progress(total, total, "done");
    Ok(rows)
}

/// A case's Monte Carlo reference: the mean of two seeds' images, which also give its noise.
struct Reference {
    image: Image,
    seeds: [Image; 2],
    secs: f64,
}

impl Reference {
    fn of_seeds(seeds: [Image; 2], secs: f64) -> Self {
        let mut image = seeds[0].clone();
        for ((p, q), c) in image
            .pixels
            .iter_mut()
            .zip(&seeds[1].pixels)
            .zip(&seeds[1].covered)
        {
            if *c {
                *p = std::array::from_fn(|k| 0.5 * (p[k] + q[k]));
            }
        }
        Self { image, seeds, secs }
    }

    /// The mean's noise over the two masks: half the seeds' relative RMS difference (each seed's
    /// noise is that difference over √2, the mean's a further √2 less).
    fn noise(&self, all: &[bool], silhouette: &[bool]) -> (f64, f64) {
        let half = |mask: &[bool]| 0.5 * masked_rel_rmse(&self.seeds[0], &self.seeds[1], mask).0;
        (half(all), half(silhouette))
    }
}

/// The matrix as CSV (one row per case; the finer knobs' columns empty where not tried).
pub fn csv(rows: &[MatrixRow]) -> String {
    let mut out = String::from(
        "mesh,map,view,rotation_deg,material,rel_rmse,silhouette_rel_rmse,object_pixels,silhouette_pixels,reference_noise,silhouette_noise,prt_secs,reference_secs,traced_rel_rmse,traced_silhouette_rel_rmse,traced_secs,traced_pixels,traced_rays,all_edges_rel_rmse,all_edges_silhouette_rel_rmse,all_edges_secs,all_edges_rays,levels_rel_rmse,levels_silhouette_rel_rmse,levels_secs,levels_rays,finer_spp,finer_noise,finer_silhouette_noise,finer_default_rel_rmse,finer_default_silhouette_rel_rmse,finer_traced_rel_rmse,finer_traced_silhouette_rel_rmse,finer_all_edges_rel_rmse,finer_all_edges_silhouette_rel_rmse,finer_levels_rel_rmse,finer_levels_silhouette_rel_rmse,finer_secs,knob\n",
    );
    for r in rows {
        out.push_str(&format!(
            "{},{},{},{},{},{:.5},{:.5},{},{},{:.5},{:.5},{:.4},{:.3},{:.5},{:.5},{:.4},{},{}",
            r.mesh,
            r.map,
            r.view,
            r.rotation_deg,
            r.material,
            r.rel_rmse,
            r.silhouette_rel_rmse,
            r.object_pixels,
            r.silhouette_pixels,
            r.reference_noise,
            r.silhouette_noise,
            r.prt_secs,
            r.reference_secs,
            r.traced.rel_rmse,
            r.traced.silhouette_rel_rmse,
            r.traced.secs,
            r.traced.traced_pixels,
            r.traced.rays
        ));
        let case = |c: Option<&TracedCase>| {
            c.map_or(",,,,".to_string(), |c| {
                format!(
                    ",{:.5},{:.5},{:.4},{}",
                    c.rel_rmse, c.silhouette_rel_rmse, c.secs, c.rays
                )
            })
        };
        out.push_str(&case(r.finer.as_ref().map(|f| &f.all_edges)));
        out.push_str(&case(r.finer.as_ref().and_then(|f| f.levels.as_ref())));
        let pair = |e: Option<(f64, f64)>| {
            e.map_or(",,".to_string(), |e| format!(",{:.5},{:.5}", e.0, e.1))
        };
        match r.finer.as_ref().and_then(|f| f.reference.as_ref()) {
            Some(x) => {
                out.push_str(&format!(
                    ",{},{:.5},{:.5}",
                    x.spp, x.noise, x.silhouette_noise
                ));
                for e in [Some(x.default), Some(x.traced), Some(x.all_edges), x.levels] {
                    out.push_str(&pair(e));
                }
                out.push_str(&format!(",{:.3}", x.secs));
            }
            None => out.push_str(",,,,,,,,,,,,"),
        }
        out.push_str(&format!(",{}\n", r.knob().code()));
    }
    out
}

/// The matrix as Markdown: a summary against the goals (2 % over object pixels, 4 % over silhouette
/// pixels), as measured and with the reference's noise taken out, and the cheapest knob that brings
/// each case within; then every case, worst first; then the cases past `--trace-visibility`.
pub fn markdown(rows: &[MatrixRow], title: &str) -> String {
    let ok = rows.iter().filter(|r| r.within_as_measured()).count();
    let count = |k: &dyn Fn(Knob) -> bool| rows.iter().filter(|r| k(r.knob())).count();
    let secs = |f: &dyn Fn(&MatrixRow) -> f64| -> f64 { rows.iter().map(f).sum() };
    let mut out = format!(
        "# {title}\n\n{ok} of {} cases within 2 % over object pixels and 4 % over silhouette pixels as measured. The reference is the mean of two seeds, whose difference gives its noise, over object pixels and over silhouette pixels apart; with that noise taken out in quadrature, the cheapest knob that brings each case within both goals:\n\n",
        rows.len()
    );
    out.push_str("| knob | cases |\n|---|---|\n");
    let order = [
        Knob::Defaults,
        Knob::TraceVisibility,
        Knob::TraceAllEdges,
        Knob::TraceLevels,
        Knob::FinerReference(Frame::Default),
        Knob::FinerReference(Frame::Traced),
        Knob::FinerReference(Frame::AllEdges),
        Knob::FinerReference(Frame::Levels),
        Knob::None,
    ];
    for k in order {
        let n = count(&|x| x == k);
        if n > 0 {
            out.push_str(&format!("| {} | {n} |\n", k.describe()));
        }
    }
    out.push_str(&format!(
        "\nCost over the whole matrix: {:.1} s of frames at the defaults, {:.1} s with `--trace-visibility` ({:.1} M rays); `--trace-budget 0` was rendered for {} cases ({:.1} s, against {:.1} s for the same cases with `--trace-visibility` alone), `--trace-levels {FINER_LEVELS}` as well for {} ({:.1} s) and the reference at {FINER_SPP}× the samples for {} ({:.1} s).\n\n",
        secs(&|r| r.prt_secs),
        secs(&|r| r.traced.secs),
        rows.iter().map(|r| r.traced.rays).sum::<u64>() as f64 / 1e6,
        rows.iter().filter(|r| r.finer.is_some()).count(),
        secs(&|r| r.finer.map_or(0.0, |f| f.all_edges.secs)),
        secs(&|r| r.finer.map_or(0.0, |_| r.traced.secs)),
        rows.iter().filter(|r| r.finer.is_some_and(|f| f.levels.is_some())).count(),
        secs(&|r| r.finer.and_then(|f| f.levels).map_or(0.0, |l| l.secs)),
        rows.iter().filter(|r| r.finer.is_some_and(|f| f.reference.is_some())).count(),
        secs(&|r| r.finer.and_then(|f| f.reference).map_or(0.0, |x| x.secs)),
    ));
    let mut worst: Vec<&MatrixRow> = rows.iter().collect();
    worst.sort_by(|a, b| b.rel_rmse.total_cmp(&a.rel_rmse));
    out.push_str("Relative RMSE of the PRT frame against the reference over object pixels and over silhouette pixels (count in brackets); the reference's own noise over each, and the PRT's error with that noise taken out (√(RMSE² − noise²)); then the same frame with visibility traced per pixel (`--trace-visibility`): its error less noise over object and silhouette pixels, and its time; and the cheapest knob that brings the case within.\n\n");
    out.push_str("| mesh | map | view | rotation | material | object pixels | silhouette pixels | reference noise (silhouette) | PRT error less noise (silhouette) | PRT s | reference s | traced: less noise | traced: silhouette less noise | traced s | knob |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in worst {
        out.push_str(&format!(
            "| {} | {} | {} | {}° | {} | {:.2} % ({}) | {:.2} % ({}) | {:.2} % ({:.2} %) | {:.2} % ({:.2} %) | {:.3} | {:.2} | {:.2} % | {:.2} % | {:.3} | {} |\n",
            r.mesh,
            r.map,
            r.view,
            r.rotation_deg,
            r.material,
            100.0 * r.rel_rmse,
            r.object_pixels,
            100.0 * r.silhouette_rel_rmse,
            r.silhouette_pixels,
            100.0 * r.reference_noise,
            100.0 * r.silhouette_noise,
            100.0 * r.error_less_noise(),
            100.0 * less_noise(r.silhouette_rel_rmse, r.silhouette_noise),
            r.prt_secs,
            r.reference_secs,
            100.0 * r.traced_error_less_noise(),
            100.0 * less_noise(r.traced.silhouette_rel_rmse, r.silhouette_noise),
            r.traced.secs,
            r.knob().describe()
        ));
    }
    let past: Vec<&MatrixRow> = rows.iter().filter(|r| r.finer.is_some()).collect();
    if !past.is_empty() {
        out.push_str(&format!("\n## Past `--trace-visibility`\n\nThe cases the traced frame leaves outside the goals: the traced frame with every shadow edge refined (`--trace-budget 0`), then where that misses at `--trace-levels {FINER_LEVELS}` as well (errors less noise, object / silhouette, and their times), and where both miss, every frame against the reference at {FINER_SPP}× the samples (its noise, then each frame's errors less that noise).\n\n"));
        out.push_str("| mesh | map | view | rotation | material | budget 0: less noise | budget 0 s | levels: less noise | levels s | finer reference: noise (silhouette) | default | traced | budget 0 | levels | knob |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for r in past {
            let Some(f) = r.finer else { continue };
            let pair = |e: (f64, f64), n: (f64, f64)| {
                format!(
                    "{:.2} % / {:.2} %",
                    100.0 * less_noise(e.0, n.0),
                    100.0 * less_noise(e.1, n.1)
                )
            };
            let noise = (r.reference_noise, r.silhouette_noise);
            let errors = |c: &TracedCase| (c.rel_rmse, c.silhouette_rel_rmse);
            let (levels, levels_secs) = f.levels.map_or(Default::default(), |l| {
                (pair(errors(&l), noise), format!("{:.3}", l.secs))
            });
            let fine: [String; 5] = match f.reference {
                Some(x) => {
                    let n = (x.noise, x.silhouette_noise);
                    [
                        format!(
                            "{:.2} % ({:.2} %)",
                            100.0 * x.noise,
                            100.0 * x.silhouette_noise
                        ),
                        pair(x.default, n),
                        pair(x.traced, n),
                        pair(x.all_edges, n),
                        x.levels.map_or(String::new(), |e| pair(e, n)),
                    ]
                }
                None => Default::default(),
            };
            out.push_str(&format!(
                "| {} | {} | {} | {}° | {} | {} | {:.3} | {} | {} | {} | {} |\n",
                r.mesh,
                r.map,
                r.view,
                r.rotation_deg,
                r.material,
                pair(errors(&f.all_edges), noise),
                f.all_edges.secs,
                levels,
                levels_secs,
                fine.join(" | "),
                r.knob().describe()
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn silhouette_pixels_have_a_background_neighbour() {
        let mut img = Image::new(5, 4);
        for y in 1..4 {
            for x in 1..4 {
                img.set(x, y, [1.0; 3]);
            }
        }
        let m = silhouette_mask(&img);
        // The 3×3 block touching the bottom edge: only its centre column's upper-middle pixel (2,
        // 2) has four covered neighbours.
        let count = m.iter().filter(|&&b| b).count();
        assert_eq!(count, 8);
        assert!(!m[2 * 5 + 2]);
        let (e, n) = masked_rel_rmse(&img, &img, &m);
        assert_eq!((e, n), (0.0, 8));
    }

    #[test]
    fn a_patch_keeps_the_triangles_at_one_end() {
        let mut mesh = Mesh::default();
        for k in 0..10 {
            let x = k as f32;
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([
                glam::Vec3::new(x, 0.0, 0.0),
                glam::Vec3::new(x + 0.5, 1.0, 0.0),
                glam::Vec3::new(x + 1.0, 0.0, 0.0),
            ]);
            mesh.normals.extend([glam::Vec3::Z; 3]);
            mesh.triangles.push([base, base + 2, base + 1]);
        }
        let p = patch(&mesh, 0.3);
        assert_eq!(p.triangles.len(), 3);
        assert_eq!(p.positions.len(), 9);
        assert!(
            p.triangles
                .iter()
                .flatten()
                .all(|&i| (i as usize) < p.positions.len())
        );
    }

    /// The ladder: each rung is named only where every cheaper one misses, errors judged less
    /// the noise of the reference they were measured against.
    #[test]
    fn the_knob_is_the_first_rung_within() {
        let case = |e: f64| TracedCase {
            rel_rmse: e,
            silhouette_rel_rmse: e,
            secs: 1.0,
            traced_pixels: 1,
            rays: 1,
        };
        let mut row = MatrixRow {
            mesh: "m".into(),
            map: "e".into(),
            view: "v".into(),
            rotation_deg: 0.0,
            material: "sharp".into(),
            rel_rmse: 0.05,
            silhouette_rel_rmse: 0.05,
            object_pixels: 100,
            silhouette_pixels: 10,
            reference_noise: 0.012,
            silhouette_noise: 0.012,
            prt_secs: 1.0,
            reference_secs: 1.0,
            traced: case(0.03),
            finer: None,
        };
        assert_eq!(row.knob(), Knob::None);
        // 2.3 % with 1.2 % of noise is 1.96 % less noise: within.
        row.traced = case(0.023);
        assert_eq!(row.knob(), Knob::TraceVisibility);
        row.traced = case(0.03);
        let mut finer = Finer {
            all_edges: case(0.023),
            levels: None,
            reference: None,
        };
        row.finer = Some(finer);
        assert_eq!(row.knob(), Knob::TraceAllEdges);
        finer.all_edges = case(0.025);
        finer.levels = Some(case(0.02));
        row.finer = Some(finer);
        assert_eq!(row.knob(), Knob::TraceLevels);
        finer.levels = Some(case(0.025));
        let mut reference = FinerReference {
            spp: 4096,
            noise: 0.006,
            silhouette_noise: 0.006,
            default: (0.05, 0.05),
            traced: (0.022, 0.022),
            all_edges: (0.02, 0.02),
            levels: Some((0.019, 0.019)),
            secs: 1.0,
        };
        finer.reference = Some(reference);
        row.finer = Some(finer);
        assert_eq!(row.knob(), Knob::FinerReference(Frame::AllEdges));
        reference.all_edges = (0.022, 0.022);
        finer.reference = Some(reference);
        row.finer = Some(finer);
        assert_eq!(row.knob(), Knob::FinerReference(Frame::Levels));
        // A silhouette over 4 % less noise misses, whatever the object pixels read.
        reference.levels = Some((0.019, 0.05));
        finer.reference = Some(reference);
        row.finer = Some(finer);
        assert_eq!(row.knob(), Knob::None);
        assert_eq!(Knob::TraceAllEdges.code(), "all-edges");
        assert!(
            Knob::TraceLevels
                .describe()
                .contains("--trace-budget 0 --trace-levels 4")
        );
    }
}
