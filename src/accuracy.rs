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
        let ok = self
            .rows
            .iter()
            .filter(|r| {
                r.rel_rmse <= 0.02 && (r.silhouette_pixels == 0 || r.silhouette_rel_rmse <= 0.04)
            })
            .count();
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
        format!(
            "{ok} of {} cases within 2 % (object pixels) and 4 % (silhouette pixels){}",
            self.rows.len(),
            worst.unwrap_or_default()
        )
    }
}

/// `glint study --matrix`: loads the meshes and maps (the bundled samples; dragon_100k and the
/// interior map from `assets`; `quick`: the bunny and the brushed sphere under the studio map),
/// runs the matrix and writes matrix.md and matrix.csv into `out`.
pub fn run_study(
    samples: &std::path::Path,
    assets: &std::path::Path,
    quick: bool,
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
        "glint accuracy matrix: PRT frame vs Monte Carlo reference, {}x{}, {} spp{} — {} cases, {:.0} s on {} threads",
        options.size.0,
        options.size.1,
        options.spp,
        if quick { " (quick)" } else { "" },
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
    /// The reference's own noise: relative RMSE over object pixels between it and a second
    /// reference with another seed, divided by √2.
    pub reference_noise: f64,
    pub prt_secs: f64,
    pub reference_secs: f64,
    /// The knob for visibility that changes inside triangles: the same frame with each pixel's
    /// own traced cut where its corners disagree ([`render_traced`]).
    pub traced: TracedCase,
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

impl MatrixRow {
    /// The PRT's own error: the RMSE with the reference's noise taken out in quadrature.
    pub fn error_less_noise(&self) -> f64 {
        less_noise(self.rel_rmse, self.reference_noise)
    }

    /// The traced frame's error with the reference's noise taken out.
    pub fn traced_error_less_noise(&self) -> f64 {
        less_noise(self.traced.rel_rmse, self.reference_noise)
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
            // The knob `--trace-visibility`: pixels traced as `glint render` traces them.
            let pixel_baker = Baker::new(
                &refined,
                env,
                crate::render::traced::tracing_settings(bake.settings, &bake.decisions),
            )?;
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
                        let t0 = Instant::now();
                        let (traced_img, traced_stats) = render_traced(
                            &pixel_baker,
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
                        let traced_secs = t0.elapsed().as_secs_f64();
                        let t0 = Instant::now();
                        let exact = ExactMaterial {
                            lobes: &lobes,
                            coefficients,
                            rho_d: m.rho_d,
                            f0: m.f0,
                        };
                        let truth = render_reference(
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
                            options.spp,
                            1,
                        );
                        let reference_secs = t0.elapsed().as_secs_f64();
                        let second = render_reference(
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
                            options.spp,
                            2,
                        );
                        let all = vec![true; truth.pixels.len()];
                        let reference_noise =
                            masked_rel_rmse(&second, &truth, &all).0 / std::f64::consts::SQRT_2;
                        let (rel_rmse, object_pixels) = masked_rel_rmse(&img, &truth, &all);
                        let silhouette = silhouette_mask(&truth);
                        let (silhouette_rel_rmse, silhouette_pixels) =
                            masked_rel_rmse(&img, &truth, &silhouette);
                        let traced = TracedCase {
                            rel_rmse: masked_rel_rmse(&traced_img, &truth, &all).0,
                            silhouette_rel_rmse: masked_rel_rmse(&traced_img, &truth, &silhouette)
                                .0,
                            secs: traced_secs,
                            traced_pixels: traced_stats.traced,
                            rays: traced_stats.rays,
                        };
                        rows.push(MatrixRow {
                            mesh: mesh_name.clone(),
                            map: map_name.clone(),
                            view: view_name.clone(),
                            rotation_deg,
                            material: material_name,
                            rel_rmse,
                            silhouette_rel_rmse,
                            object_pixels,
                            silhouette_pixels,
                            reference_noise,
                            prt_secs,
                            reference_secs,
                            traced,
                        });
                    }
                }
            }
        }
    }
    progress(total, total, "done");
    Ok(rows)
}

/// The matrix as CSV (one row per case).
pub fn csv(rows: &[MatrixRow]) -> String {
    let mut out = String::from(
        "mesh,map,view,rotation_deg,material,rel_rmse,silhouette_rel_rmse,object_pixels,silhouette_pixels,reference_noise,prt_secs,reference_secs,traced_rel_rmse,traced_silhouette_rel_rmse,traced_secs,traced_pixels,traced_rays\n",
    );
    for r in rows {
        out.push_str(&format!(
            "{},{},{},{},{},{:.5},{:.5},{},{},{:.5},{:.4},{:.3},{:.5},{:.5},{:.4},{},{}\n",
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
            r.prt_secs,
            r.reference_secs,
            r.traced.rel_rmse,
            r.traced.silhouette_rel_rmse,
            r.traced.secs,
            r.traced.traced_pixels,
            r.traced.rays
        ));
    }
    out
}

/// The goals with the reference's noise taken out: 2 % over object pixels and 4 % over silhouette
/// pixels, for the default frame and for the traced one.
fn within_less_noise(r: &MatrixRow, traced: bool) -> bool {
    let (object, silhouette) = if traced {
        (r.traced_error_less_noise(), r.traced.silhouette_rel_rmse)
    } else {
        (r.error_less_noise(), r.silhouette_rel_rmse)
    };
    object <= 0.02
        && (r.silhouette_pixels == 0 || less_noise(silhouette, r.reference_noise) <= 0.04)
}

/// The matrix as Markdown: a summary against the goals (2 % over object pixels, 4 % over silhouette
/// pixels), as measured and with the reference's noise taken out, for the default frame and with
/// the knob that traces visibility per pixel; then every case, worst first.
pub fn markdown(rows: &[MatrixRow], title: &str) -> String {
    let within = |r: &MatrixRow| {
        r.rel_rmse <= 0.02 && (r.silhouette_pixels == 0 || r.silhouette_rel_rmse <= 0.04)
    };
    let ok = rows.iter().filter(|r| within(r)).count();
    let ok_less_noise = rows.iter().filter(|r| within_less_noise(r, false)).count();
    let failing: Vec<&MatrixRow> = rows
        .iter()
        .filter(|r| !within_less_noise(r, false))
        .collect();
    let fixed = failing
        .iter()
        .filter(|r| within_less_noise(r, true))
        .count();
    let ok_traced = rows.iter().filter(|r| within_less_noise(r, true)).count();
    let secs = |f: &dyn Fn(&MatrixRow) -> f64| -> f64 { rows.iter().map(f).sum() };
    let mut out = format!(
        "# {title}\n\n{ok} of {} cases within 2 % over object pixels and 4 % over silhouette pixels as measured; {ok_less_noise} with the reference's noise taken out.\n\n",
        rows.len()
    );
    out.push_str(&format!(
        "The knob for the rest: `glint render --trace-visibility` (each pixel whose triangle's corners disagree traced on its own, its cells refined at shadow edges). With it {ok_traced} of {} cases are within both goals with the noise taken out; of the {} that are not at the defaults, {fixed} are. Cost over the whole matrix: {:.1} s of frames at the defaults, {:.1} s traced ({:.1} M rays).\n\n",
        rows.len(),
        failing.len(),
        secs(&|r| r.prt_secs),
        secs(&|r| r.traced.secs),
        rows.iter().map(|r| r.traced.rays).sum::<u64>() as f64 / 1e6,
    ));
    let mut worst: Vec<&MatrixRow> = rows.iter().collect();
    worst.sort_by(|a, b| b.rel_rmse.total_cmp(&a.rel_rmse));
    out.push_str("Relative RMSE of the PRT frame against the reference over object pixels and over silhouette pixels (count in brackets); the reference's own noise beside it, and the PRT's error with that noise taken out (√(RMSE² − noise²)); then the same frame with visibility traced per pixel (`--trace-visibility`): its error less noise over object and silhouette pixels, and its time.\n\n");
    out.push_str("| mesh | map | view | rotation | material | object pixels | silhouette pixels | reference noise | PRT error less noise | PRT s | reference s | traced: less noise | traced: silhouette less noise | traced s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in worst {
        out.push_str(&format!(
            "| {} | {} | {} | {}° | {} | {:.2} % ({}) | {:.2} % ({}) | {:.2} % | {:.2} % | {:.3} | {:.2} | {:.2} % | {:.2} % | {:.3} |\n",
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
            100.0 * r.error_less_noise(),
            r.prt_secs,
            r.reference_secs,
            100.0 * r.traced_error_less_noise(),
            100.0 * less_noise(r.traced.silhouette_rel_rmse, r.reference_noise),
            r.traced.secs
        ));
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
}
