//! Render studies: the PRT frame against the Monte Carlo reference and the transfer render, one
//! ingredient or setting at a time, printed as tables (developer tools behind the accuracy figures
//! in docs/benchmarks.md; tests/it/render.rs holds the assertions). Run one by name with KEY=VALUE
//! settings, e.g. `cargo run --release --features studies --example render_studies -- diagnose
//! MESH=teapot`.

// Studies index parallel arrays (RGB channels, texels) in one loop, as the quadratures are written;
// the bake settings are built field by field as each study varies them.
#![allow(clippy::needless_range_loop, clippy::field_reassign_with_default)]

#[path = "../tests/it/common.rs"]
mod common;
#[path = "../tests/it/render_cases.rs"]
mod render_cases;

use anyhow::{Context, anyhow, bail};
use glint::bake::{BakeSettings, Baker};
use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, Specular};
use glint::render::reference::{ExactMaterial, render_reference};
use glint::render::table::{PhPyramid, default_resolution};
use render_cases::*;
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// A study's setting: `KEY=VALUE` on the command line (in place of an environment variable);
/// `None` when absent, an error when its value is not UTF-8.
fn arg(key: &str) -> anyhow::Result<Option<String>> {
    let prefix = format!("{key}=");
    for a in std::env::args_os().skip(2) {
        match a.into_string() {
            Ok(a) => {
                if let Some(value) = a.strip_prefix(&prefix) {
                    return Ok(Some(value.to_owned()));
                }
            }
            Err(a) => {
                if a.as_encoded_bytes().starts_with(prefix.as_bytes()) {
                    bail!("setting {}: not valid UTF-8", a.to_string_lossy());
                }
            }
        }
    }
    Ok(None)
}

/// Whether the setting `key` is given (whatever its value).
fn flag(key: &str) -> anyhow::Result<bool> {
    Ok(arg(key)?.is_some())
}

/// `value`, the value of setting `key`, parsed as a `T`.
fn parse_setting<T: FromStr>(key: &str, value: &str) -> anyhow::Result<T>
where
    T::Err: Display,
{
    value
        .parse()
        .map_err(|e| anyhow!("setting {key}={value}: {e}"))
}

/// Setting `key` parsed as a `T`, else `default` parsed.
fn setting<T: FromStr>(key: &str, default: &str) -> anyhow::Result<T>
where
    T::Err: Display,
{
    parse_setting(key, arg(key)?.as_deref().unwrap_or(default))
}

/// Setting `key` parsed as a `T`, `None` when absent.
fn optional_setting<T: FromStr>(key: &str) -> anyhow::Result<Option<T>>
where
    T::Err: Display,
{
    arg(key)?
        .map(|value| parse_setting(key, &value))
        .transpose()
}

/// `value`, the value of setting `key`, as a comma-separated list of `T`.
fn parse_list<T: FromStr>(key: &str, value: &str) -> anyhow::Result<Vec<T>>
where
    T::Err: Display,
{
    value
        .split(',')
        .map(|x| {
            x.parse()
                .map_err(|e| anyhow!("setting {key}={value}: item {x:?}: {e}"))
        })
        .collect()
}

/// Setting `key` (else `default`) as a comma-separated list of `T`.
fn list_setting<T: FromStr>(key: &str, default: &str) -> anyhow::Result<Vec<T>>
where
    T::Err: Display,
{
    parse_list(key, arg(key)?.as_deref().unwrap_or(default))
}

/// The `:`-separated fields of `item`, an entry of setting `key` written as `form`: at least
/// `required` and at most `N` of them, the missing optional ones empty.
fn fields<'a, const N: usize>(
    key: &str,
    item: &'a str,
    form: &str,
    required: usize,
) -> anyhow::Result<[&'a str; N]> {
    let parts: Vec<&str> = item.split(':').collect();
    if parts.len() < required || parts.len() > N {
        let expected = if required == N {
            format!("{N}")
        } else {
            format!("{required} to {N}")
        };
        bail!(
            "setting {key}: item {item:?} has {} fields, expected {expected} ({form})",
            parts.len()
        );
    }
    let mut out = [""; N];
    out[..parts.len()].copy_from_slice(&parts);
    Ok(out)
}

/// `value`, the field `name` of `item` (an entry of setting `key`), parsed as a `T`.
fn field<T: FromStr>(key: &str, item: &str, name: &str, value: &str) -> anyhow::Result<T>
where
    T::Err: Display,
{
    value
        .parse()
        .map_err(|e| anyhow!("setting {key}: item {item:?}: {name} {value:?}: {e}"))
}

/// A glint error as its message alone: glint's messages are one line that already ends with the
/// cause, which `{:#}` would print a second time from the error's source chain.
fn flat(e: impl Display) -> anyhow::Error {
    anyhow!("{e}")
}

/// Where studies write images: `OUT`, else glint-studies in the system temp folder.
fn out_dir() -> anyhow::Result<PathBuf> {
    Ok(arg("OUT")?
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("glint-studies")))
}

/// `path`, which must be an existing file: the shared render cases panic on a missing one.
fn existing(path: &Path) -> anyhow::Result<&Path> {
    if !path.is_file() {
        bail!("{}: no such file", path.display());
    }
    Ok(path)
}

/// [`case`] with its inputs checked first.
fn checked_case(mesh: &str, env: &str) -> anyhow::Result<Case> {
    existing(&common::assets().join(format!("glb/{mesh}.glb")))?;
    existing(&common::assets().join(format!("hdr/small/{env}.exr")))?;
    Ok(case(mesh, env))
}

/// [`case_at`] with its inputs checked first.
fn checked_case_at(mesh: &Path, env: &Path, refined: bool) -> anyhow::Result<Case> {
    Ok(case_at(existing(mesh)?, existing(env)?, refined))
}

/// The scene's first camera (an imported scene always has one).
fn first_camera(scene: &glint::scene::Scene) -> anyhow::Result<&glint::scene::Camera> {
    scene.cameras.first().context("the scene has no camera")
}

/// [`glint::render::Image::relative_rmse`] of `a` against `b`, named `what` in the error.
fn relative_rmse(
    a: &glint::render::Image,
    b: &glint::render::Image,
    what: &str,
) -> anyhow::Result<f64> {
    a.relative_rmse(b).with_context(|| {
        format!("relative RMSE of {what}: no covered pixel in common, or a black reference")
    })
}

/// Writes `img` to `path` at exposure 1.
fn write(img: &glint::render::Image, path: &Path) -> anyhow::Result<()> {
    img.write(path, 1.0).map_err(flat)
}

/// A study: runs with its settings from the command line.
type Study = fn() -> anyhow::Result<()>;

fn main() {
    let studies: &[(&str, Study)] = &[
        ("diagnose", diagnose),
        ("subdivision_study", subdivision_study),
        ("profile_frame", profile_frame),
        ("refine_study", refine_study),
        ("sharp_lobe_diagnose", sharp_lobe_diagnose),
        ("sharp_lobe_quadrature", sharp_lobe_quadrature),
        ("bake_error", bake_error),
    ];
    let name = std::env::args_os()
        .nth(1)
        .and_then(|n| n.into_string().ok())
        .unwrap_or_default();
    match studies.iter().find(|(n, _)| *n == name) {
        Some((_, run)) => {
            if let Err(e) = run() {
                eprintln!("render_studies {name}: {e:#}");
                std::process::exit(1);
            }
        }
        None => {
            let names: Vec<_> = studies.iter().map(|(n, _)| *n).collect();
            eprintln!(
                "usage: render_studies STUDY [KEY=VALUE ...]; STUDY is one of {}",
                names.join(", ")
            );
            std::process::exit(2);
        }
    }
}

/// Study: `cargo run --release --features studies --example render_studies -- diagnose MESH=teapot`
/// prints PRT, transfer and Monte Carlo errors for a grid of PRT settings (ES: shading-triangle
/// edges in pixels; a negative value shades per pixel) and writes images to `OUT` (default: the
/// system temp folder's glint-studies).
fn diagnose() -> anyhow::Result<()> {
    let mesh: String = setting("MESH", "bunny")?;
    let pds: Vec<f64> = list_setting("PDS", "1,2,4")?;
    let es: Vec<f64> = list_setting("ES", "0,1,2,4")?;
    let out = &out_dir()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let (w, h) = (160, 120);
    let c = checked_case(&mesh, "studio_512")?;
    let m = fitted(&c);
    println!("coefficients R: {:?}", m.coefficients[0]);
    let lobes = m.lobes().map_err(flat)?;
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let zero = vec![0.0; lobes.len()];
    let zc = [zero.as_slice(), zero.as_slice(), zero.as_slice()];
    let camera = first_camera(&c.scene)?;
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let tracer = glint::bake::Tracer::new(&c.scene.mesh);
    for (name, coef) in [("diffuse", zc), ("full", coefficients)] {
        let material = ExactMaterial {
            lobes: &lobes,
            coefficients: coef,
            rho_d: m.rho_d,
            f0: m.f0,
        };
        let mc = render_reference(
            &c.scene.mesh,
            c.tangents.as_deref(),
            &tracer,
            c.baker_offset,
            &c.env,
            0.0,
            material,
            camera,
            w,
            h,
            1024,
            7,
        );
        let mc2 = render_reference(
            &c.scene.mesh,
            c.tangents.as_deref(),
            &tracer,
            c.baker_offset,
            &c.env,
            0.0,
            material,
            camera,
            w,
            h,
            1024,
            8,
        );
        // Transfer (per pixel) render.
        let ctx = glint::transfer::TransferContext::new(
            &c.scene.mesh,
            &c.bake.cuts,
            &c.tree,
            &lobes,
            c.tangents.as_deref(),
            None,
        );
        let t = ctx.compute(&light, camera, w, h, m.f0);
        let tr = t.render(m.rho_d, coef);
        let mut timg = glint::render::Image::new(w, h);
        for (p, v) in t.pixels.iter().zip(&tr) {
            timg.set(p.x, p.y, v.map(|x| x as f32));
        }
        let mut variants = vec![("default".to_string(), PrtSettings::default())];
        for &pd in &pds {
            for &e in &es {
                variants.push((
                    format!("p{pd}e{e}"),
                    PrtSettings {
                        partition_deg: pd,
                        prefilter: true,
                        max_edge_px: e,
                        per_pixel: e < 0.0,
                        ..PrtSettings::default()
                    },
                ));
            }
        }
        for (label, settings) in variants {
            let prt = Prt::new(
                &c.scene.mesh,
                &c.bake.cuts,
                &c.tree,
                c.tangents.as_deref(),
                settings,
            );
            let table = PhPyramid::build(&lobes, coef, default_resolution(lobes.lambda()));
            let t0 = std::time::Instant::now();
            let img = prt.render(
                &light,
                camera,
                w,
                h,
                &Shading {
                    rho_d: m.rho_d,
                    f0: m.f0,
                    specular: Specular::Table(&table),
                },
            );
            let secs = t0.elapsed().as_secs_f64();
            println!(
                "{name} {label}: PRT vs MC {:.4}, PRT vs transfer {:.4}, frame {secs:.3} s, partition nodes {}",
                relative_rmse(&img, &mc, "PRT vs MC")?,
                relative_rmse(&img, &timg, "PRT vs transfer")?,
                prt.partition_nodes()
            );
            write(&img, &out.join(format!("{mesh}_{name}_{label}.exr")))?;
        }
        println!(
            "{name}: transfer vs MC {:.4}, MC noise {:.4}",
            relative_rmse(&timg, &mc, "transfer vs MC")?,
            relative_rmse(&mc2, &mc, "MC noise")?
        );
        let mut diff = glint::render::Image::new(w, h);
        let mut signed = 0.0f64;
        for k in 0..diff.pixels.len() {
            if mc.covered[k] && timg.covered[k] {
                let (a, b) = (
                    timg.pixels[k][1],
                    (mc.pixels[k][1] + mc2.pixels[k][1]) * 0.5,
                );
                signed += (a - b) as f64;
                diff.pixels[k] = if a > b {
                    [(a - b) * 10.0, 0.0, 0.0]
                } else {
                    [0.0, 0.0, (b - a) * 10.0]
                };
            }
        }
        println!(
            "{name}: mean signed (transfer - MC) {:.4e} per pixel, mean MC {:.4e}",
            signed / mc.covered_count() as f64,
            mc.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / mc.covered_count() as f64
        );
        write(&diff, &out.join(format!("{mesh}_{name}_diff.png")))?;
        write(&mc, &out.join(format!("{mesh}_{name}_mc.exr")))?;
        write(&mc2, &out.join(format!("{mesh}_{name}_mc2.exr")))?;
        write(&timg, &out.join(format!("{mesh}_{name}_transfer.exr")))?;
        write(&mc, &out.join(format!("{mesh}_{name}_mc.png")))?;
        write(&timg, &out.join(format!("{mesh}_{name}_transfer.png")))?;
    }
    Ok(())
}

/// Study: transfer and PRT vs Monte Carlo as visibility is baked on a midpoint-subdivided
/// mesh (`cargo run --release --features studies --example render_studies -- subdivision_study`).
fn subdivision_study() -> anyhow::Result<()> {
    const KEY: &str = "GLINT_STUDY";
    let spec: String = setting(KEY, "teapot:0:11.25:0.02,teapot:1:11.25:0.02")?;
    // Every item is read before the first bake, so that a bad one fails at once.
    let items = spec
        .split(',')
        .map(|item| {
            let [mesh, levels, cell_deg, epsilon] =
                fields(KEY, item, "mesh:levels:cell_deg:epsilon", 4)?;
            let (levels, cell_deg, epsilon): (usize, f64, f64) = (
                field(KEY, item, "levels", levels)?,
                field(KEY, item, "cell_deg", cell_deg)?,
                field(KEY, item, "epsilon", epsilon)?,
            );
            Ok((mesh, levels, cell_deg, epsilon))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    for (mesh, levels, cell_deg, epsilon) in items {
        {
            let mut scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))
                .map_err(flat)?;
            for _ in 0..levels {
                scene.mesh = glint::scene::subdivide_midpoint(&scene.mesh);
            }
            let env = glint::env::load(&common::assets().join("hdr/small/studio_512.exr"))
                .map_err(flat)?;
            let t0 = std::time::Instant::now();
            let mut settings = BakeSettings {
                cell_deg: Some(cell_deg),
                ..BakeSettings::default()
            };
            settings.cut.epsilon = epsilon;
            let baker = Baker::new(&scene, &env, settings).map_err(flat)?;
            let bake = baker.bake_all(None, &|_| {});
            let bake_secs = t0.elapsed().as_secs_f64();
            let (baker_offset, tangents, set, tree) = (
                baker.ray_offset(),
                baker.tangents.clone(),
                baker.set.clone(),
                baker.tree.clone(),
            );
            drop(baker);
            let c = Case {
                scene,
                env,
                baker_offset,
                tangents,
                set,
                tree,
                bake,
            };
            let m = fitted(&c);
            let lobes = m.lobes().map_err(flat)?;
            let coefficients = [
                m.coefficients[0].as_slice(),
                m.coefficients[1].as_slice(),
                m.coefficients[2].as_slice(),
            ];
            let camera = first_camera(&c.scene)?;
            let (w, h) = (160, 120);
            let (prt, prt_v, transfer) = prt_and_transfer(&c, &m, w, h);
            let material = ExactMaterial {
                lobes: &lobes,
                coefficients,
                rho_d: m.rho_d,
                f0: m.f0,
            };
            let tracer = glint::bake::Tracer::new(&c.scene.mesh);
            let mc = render_reference(
                &c.scene.mesh,
                c.tangents.as_deref(),
                &tracer,
                c.baker_offset,
                &c.env,
                0.0,
                material,
                camera,
                w,
                h,
                4096,
                7,
            );
            println!(
                "{mesh} levels {levels} cell {cell_deg}° ε {epsilon}: {} vertices, mean cut {:.0}, bake {bake_secs:.2} s; vs MC: transfer {:.4}, PRT {:.4}, PRT vertex-only {:.4}",
                c.scene.mesh.positions.len(),
                c.bake.cuts.mean_cut_size(),
                relative_rmse(&transfer, &mc, "transfer vs MC")?,
                relative_rmse(&prt, &mc, "PRT vs MC")?,
                relative_rmse(&prt_v, &mc, "PRT vertex-only vs MC")?
            );
        }
    }
    Ok(())
}

/// Study: renders one frame REPS times for profiling, e.g. `cargo run --release --features studies
/// --example render_studies -- profile_frame MESH=bunny PD=4 E=1 REPS=5`.
fn profile_frame() -> anyhow::Result<()> {
    let mesh: String = setting("MESH", "bunny")?;
    let env: String = setting("ENV", "studio_512")?;
    let (pd, e, reps): (f64, f64, usize) = (
        setting("PD", "4")?,
        setting("E", "1")?,
        setting("REPS", "5")?,
    );
    let (w, h): (u32, u32) = (setting("W", "160")?, setting("H", "120")?);
    if w == 0 || h == 0 {
        bail!("settings W={w}, H={h}: the frame must have at least one pixel");
    }
    let transfer_mode = arg("MODE")?.as_deref() == Some("transfer");
    let c = checked_case(&mesh, &env)?;
    let lobes = glint::sphere::LobeSet::new(
        glint::sphere::LobeLayout::Isotropic { count: 24 },
        glint::sphere::srbf::lambda_from_sigma(glint::sphere::srbf::PAPER_SIGMA).map_err(flat)?,
    )
    .map_err(flat)?;
    let mut co = vec![0.0; lobes.len()];
    (co[0], co[3], co[9]) = (0.8, 0.5, 0.3);
    let coefficients = [co.as_slice(), co.as_slice(), co.as_slice()];
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let prt = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        PrtSettings {
            partition_deg: pd,
            prefilter: true,
            max_edge_px: e,
            per_pixel: e < 0.0,
            ..PrtSettings::default()
        },
    );
    let mut camera = first_camera(&c.scene)?.clone();
    camera.aspect = w as f32 / h as f32;
    let shading = Shading {
        rho_d: [0.5; 3],
        f0: 0.04,
        specular: Specular::Table(&table),
    };
    if transfer_mode {
        let ctx = glint::transfer::TransferContext::new(
            &c.scene.mesh,
            &c.bake.cuts,
            &c.tree,
            &lobes,
            c.tangents.as_deref(),
            None,
        );
        let mut best = f64::MAX;
        let mut n = 0;
        for _ in 0..reps {
            let t0 = std::time::Instant::now();
            n = std::hint::black_box(ctx.compute(&light, &camera, w, h, 0.04))
                .pixels
                .len();
            best = best.min(t0.elapsed().as_secs_f64());
        }
        println!(
            "{mesh} {w}x{h} transfer: {n} pixels, shading partitions {:?}, best {best:.3} s",
            ctx.shading_partitions()
        );
        return Ok(());
    }
    let t0 = std::time::Instant::now();
    let sm = prt.shading_mesh(&camera, w, h);
    let t_mesh = t0.elapsed().as_secs_f64();
    let mut best = f64::MAX;
    for _ in 0..reps {
        let t0 = std::time::Instant::now();
        std::hint::black_box(prt.render(&light, &camera, w, h, &shading));
        best = best.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "{mesh} {w}x{h} partition {pd}° edge {e}: {} points, subdivision {}, shading mesh {t_mesh:.3} s, frame best {best:.3} s",
        sm.points.len(),
        sm.subdivision
    );
    Ok(())
}

/// Study: PRT and transfer vs Monte Carlo with the bake's adaptive refinement at several
/// thresholds: `GLINT_REFINE=mesh:threshold:1/min_edge:rounds[:cell_deg],... cargo run --release
/// --features studies --example render_studies -- refine_study`.
fn refine_study() -> anyhow::Result<()> {
    const KEY: &str = "GLINT_REFINE";
    let spec: String = setting(KEY, "teapot:0.05:128:3")?;
    // Every item is read before the first bake, so that a bad one fails at once.
    let items = spec
        .split(',')
        .map(|item| {
            let [mesh, threshold, inv_edge, rounds, cell_deg] =
                fields(KEY, item, "mesh:threshold:1/min_edge:rounds[:cell_deg]", 4)?;
            let (threshold, inv_edge, rounds): (f64, f64, u32) = (
                field(KEY, item, "threshold", threshold)?,
                field(KEY, item, "1/min_edge", inv_edge)?,
                field(KEY, item, "rounds", rounds)?,
            );
            let cell_deg: Option<f64> = if cell_deg.is_empty() {
                None
            } else {
                Some(field(KEY, item, "cell_deg", cell_deg)?)
            };
            Ok((item, mesh, threshold, inv_edge, rounds, cell_deg))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    // One material per mesh, fitted on the mesh as imported, so that the rows differ only in the
    // bake.
    let mut materials = std::collections::HashMap::<String, glint::fit::material::Material>::new();
    for (item, mesh, threshold, inv_edge, rounds, cell_deg) in items {
        let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))
            .map_err(flat)?;
        let env =
            glint::env::load(&common::assets().join("hdr/small/studio_512.exr")).map_err(flat)?;
        let mut settings = BakeSettings::default();
        settings.refine = glint::bake::RefineSettings {
            rounds,
            threshold,
            min_edge: 1.0 / inv_edge,
            ..Default::default()
        };
        settings.cell_deg = cell_deg;
        let t0 = std::time::Instant::now();
        let baker = Baker::new(&scene, &env, settings).map_err(flat)?;
        let bake = baker.bake_refined(None, &|_| {});
        let bake_secs = t0.elapsed().as_secs_f64();
        let refined = bake.scene(&scene).map_err(flat)?;
        let (baker_offset, set, tree) = (baker.ray_offset(), baker.set.clone(), baker.tree.clone());
        drop(baker);
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&refined.mesh);
        println!("{}", bake.decisions.refine_reason);
        let c = Case {
            scene: refined,
            env,
            baker_offset,
            tangents,
            set,
            tree,
            bake,
        };
        let m = match materials.entry(mesh.to_string()) {
            std::collections::hash_map::Entry::Occupied(e) => e.get().clone(),
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(fitted(&checked_case(mesh, "studio_512")?)).clone()
            }
        };
        let lobes = m.lobes().map_err(flat)?;
        let coefficients = [
            m.coefficients[0].as_slice(),
            m.coefficients[1].as_slice(),
            m.coefficients[2].as_slice(),
        ];
        let camera = first_camera(&c.scene)?;
        let (w, h) = (160, 120);
        let (prt, _, transfer) = prt_and_transfer(&c, &m, w, h);
        let material = ExactMaterial {
            lobes: &lobes,
            coefficients,
            rho_d: m.rho_d,
            f0: m.f0,
        };
        let tracer = glint::bake::Tracer::new(&scene.mesh);
        let (_, base_tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
        let mc = render_reference(
            &scene.mesh,
            base_tangents.as_deref(),
            &tracer,
            c.baker_offset,
            &c.env,
            0.0,
            material,
            camera,
            w,
            h,
            4096,
            7,
        );
        println!(
            "{item}: {} vertices, mean cut {:.0}, rays {}, bake {bake_secs:.2} s; vs MC: transfer {:.4}, PRT {:.4}",
            c.scene.mesh.positions.len(),
            c.bake.cuts.mean_cut_size(),
            c.bake.stats.rays_traced,
            relative_rmse(&transfer, &mc, "transfer vs MC")?,
            relative_rmse(&prt, &mc, "PRT vs MC")?,
        );
    }
    Ok(())
}

/// Study: the grazing sharp-lobe case (bunny under samples/studio_1k, orbit 20,15,2.5, environment
/// turned 90°, one sharp ring lobe) with one ingredient of the PRT frame switched at a time, and
/// its worst pixels. `cargo run --release --features studies --example render_studies --
/// sharp_lobe_diagnose` (MESH=teapot, ORBIT=az,el,dist, ROT=deg, SPP=n).
fn sharp_lobe_diagnose() -> anyhow::Result<()> {
    let mesh: String = setting("MESH", "bunny")?;
    let orbit: Vec<f32> = list_setting("ORBIT", "20,15,2.5")?;
    let rot: f64 = setting("ROT", "90")?;
    let spp: u32 = setting("SPP", "2048")?;
    let noise = flag("NOISE")?;
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let t0 = std::time::Instant::now();
    let c = checked_case_at(
        &samples.join(format!("{mesh}.glb")),
        &samples.join("studio_1k.exr"),
        true,
    )?;
    println!(
        "bake {:.1} s, {} vertices",
        t0.elapsed().as_secs_f64(),
        c.scene.mesh.positions.len()
    );
    let imported = glint::scene::import(&samples.join(format!("{mesh}.glb")))
        .map_err(flat)?
        .mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160, 120);
    let camera = if let [az, el, dist] = orbit[..] {
        glint::scene::orbit_camera(&c.scene.bounds, az, el, dist, w, h)
    } else {
        first_camera(&c.scene)?.clone()
    };
    let base = prt_and_mc(
        &c,
        &imported,
        &m,
        &camera,
        rot,
        w,
        h,
        spp,
        PrtSettings::default(),
    );
    let mc = &base.mc;
    let sil = glint::accuracy::silhouette_mask(mc);
    println!(
        "MC {:.1} s ({spp} spp), PRT {:.3} s; {} object pixels, {} silhouette",
        base.mc_secs,
        base.prt_secs,
        mc.covered_count(),
        sil.iter().filter(|&&s| s).count()
    );
    let report = |label: &str, img: &glint::render::Image| {
        let (all, s) = (rmse_where(img, mc, None), rmse_where(img, mc, Some(&sil)));
        let interior: Vec<bool> = sil.iter().map(|x| !x).collect();
        println!(
            "{label:>36}: object {:.2} %, silhouette {:.2} %, interior {:.2} %",
            100.0 * all,
            100.0 * s,
            100.0 * rmse_where(img, mc, Some(&interior))
        );
    };
    report("default", &base.prt);
    if noise {
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&imported);
        let lobes = m.lobes().map_err(flat)?;
        let coefficients = [
            m.coefficients[0].as_slice(),
            m.coefficients[1].as_slice(),
            m.coefficients[2].as_slice(),
        ];
        let material = ExactMaterial {
            lobes: &lobes,
            coefficients,
            rho_d: m.rho_d,
            f0: m.f0,
        };
        let mc2 = render_reference(
            &imported,
            tangents.as_deref(),
            &glint::bake::Tracer::new(&imported),
            c.baker_offset,
            &c.env,
            rot.to_radians(),
            material,
            &camera,
            w,
            h,
            spp,
            8,
        );
        println!(
            "MC noise (one image): object {:.2} %, silhouette {:.2} %",
            100.0 * rmse_where(&mc2, mc, None) / 2f64.sqrt(),
            100.0 * rmse_where(&mc2, mc, Some(&sil)) / 2f64.sqrt()
        );
    }
    let lobes = m.lobes().map_err(flat)?;
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let light = LightSums::new(&c.env, &c.set, &c.tree, rot.to_radians());
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let d = PrtSettings::default();
    let variants = [
        ("exact lobes", d, true),
        (
            "no grazing tiers",
            PrtSettings {
                grazing_tiers: false,
                ..d
            },
            false,
        ),
        (
            "no prefilter",
            PrtSettings {
                prefilter: false,
                ..d
            },
            false,
        ),
        (
            "per run",
            PrtSettings {
                merge_runs: false,
                ..d
            },
            false,
        ),
        (
            "texel lookups",
            PrtSettings {
                texel_lookups: true,
                ..d
            },
            false,
        ),
        (
            "partition 4°",
            PrtSettings {
                partition_deg: 4.0,
                ..d
            },
            false,
        ),
        (
            "partition 2°",
            PrtSettings {
                partition_deg: 2.0,
                ..d
            },
            false,
        ),
        (
            "partition 1°",
            PrtSettings {
                partition_deg: 1.0,
                ..d
            },
            false,
        ),
        (
            "partition 1° no prefilter",
            PrtSettings {
                partition_deg: 1.0,
                prefilter: false,
                ..d
            },
            false,
        ),
        (
            "horizon leaves 1",
            PrtSettings {
                horizon_leaves: 1,
                ..d
            },
            false,
        ),
        (
            "vertex shading",
            PrtSettings {
                per_pixel: false,
                max_edge_px: 0.0,
                ..d
            },
            false,
        ),
    ];
    let mut images = Vec::new();
    for (label, settings, exact) in variants {
        let prt = Prt::new(
            &c.scene.mesh,
            &c.bake.cuts,
            &c.tree,
            c.tangents.as_deref(),
            settings,
        );
        let specular = if exact {
            Specular::Exact {
                lobes: &lobes,
                coefficients,
            }
        } else {
            Specular::Table(&table)
        };
        let img = prt.render(
            &light,
            &camera,
            w,
            h,
            &Shading {
                rho_d: m.rho_d,
                f0: m.f0,
                specular,
            },
        );
        report(label, &img);
        images.push((label, img));
    }
    let ctx = glint::transfer::TransferContext::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        &lobes,
        c.tangents.as_deref(),
        None,
    );
    let t = ctx.compute(&light, &camera, w, h, m.f0);
    let mut transfer = glint::render::Image::new(w, h);
    for (p, v) in t.pixels.iter().zip(t.render(m.rho_d, coefficients)) {
        transfer.set(p.x, p.y, v.map(|x| x as f32));
    }
    report("per-pixel transfer (tiers)", &transfer);
    // The worst pixels, with their view cosine.
    let eye = camera.eye();
    let mut rows: Vec<(f64, usize, f64)> = t
        .pixels
        .iter()
        .map(|p| {
            let k = (p.y * w + p.x) as usize;
            let wo_z = (eye - p.position).normalize().dot(p.normal) as f64;
            (
                ((base.prt.pixels[k][1] - mc.pixels[k][1]) as f64).powi(2),
                k,
                wo_z,
            )
        })
        .collect();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let total: f64 = rows.iter().map(|r| r.0).sum();
    let mut by_cos = [0.0f64; 5];
    for r in &rows {
        let bin = [0.05, 0.15, 0.3, 0.6, 2.0]
            .iter()
            .position(|&b| r.2 < b)
            .with_context(|| format!("pixel {}: view cosine {} out of range", r.1, r.2))?;
        by_cos[bin] += r.0 / total;
    }
    println!(
        "share of the squared error (G) by wo·n: <0.05 {:.2}, <0.15 {:.2}, <0.3 {:.2}, <0.6 {:.2}, ≥0.6 {:.2}",
        by_cos[0], by_cos[1], by_cos[2], by_cos[3], by_cos[4]
    );
    for r in rows.iter().take(12) {
        let k = r.1;
        let g = |img: &glint::render::Image| img.pixels[k][1];
        let vals: Vec<String> = images
            .iter()
            .map(|(l, img)| format!("{l} {:.3}", g(img)))
            .collect();
        println!(
            "pixel ({}, {}) wo·n {:.3} sil {}: MC {:.3} PRT {:.3} transfer {:.3} | {}",
            k % w as usize,
            k / w as usize,
            r.2,
            sil[k],
            g(mc),
            g(&base.prt),
            g(&transfer),
            vals.join(", ")
        );
    }
    Ok(())
}

/// Study: the grazing case's remaining error split by ingredient at chosen pixels, by quadrature
/// over the direction set's texels (k×k sub-directions each, env `K`, default 6; 4 suffices), green
/// channel, noise-free: Q_mc = Σ L(d) V_ray(d) f_r(d) cos dω with L read as the reference reads it
/// (nearest texel), on the imported mesh (what Monte Carlo estimates); on the PRT's (refined) mesh:
/// Q_geo (the same; its rays leave the refined mesh's smooth surface but hit the imported mesh, so
/// a few pixels self-shadow: an artefact of this tool), Q_leafL (L constant per leaf, as in
/// `LightSums`), Q_cutV (and V from the corners' cuts per leaf: the PRT's own inputs, the BRDF
/// integrated exactly), and Q with the map's own L and the cuts' V. Pixels: the `N` (default 40)
/// worst by the PRT's error against MC, `N` at random, and every `STRIDE`-th (default 3) seen at
/// wo·n < `GZ` (default 0.3); the last class is also patched into the PRT frame (RGB, map L, cut V)
/// to show what resolving the light and the BRDF inside leaves at those points would give against
/// MC. `RES` bakes at that direction-set resolution; `ALL` prints every pixel; `PIX=k,k,…` takes
/// only those pixels (index y·160 + x); `MAP` is the environment (default samples/studio_1k.exr). Bunny, rotation 90°,
/// K = 4, wo·n < 0.3 (251 pixels, 44 s): against Q_mc the PRT is 8.9 %, Q_leafL 6.3 %, Q_cutV 5.5
/// %, Q with map L and cut V 0.45 %; the patched frame is 3.24 % off MC at 2048 spp (silhouette
/// 4.02 %; unpatched 5.92 / 8.23 %). `cargo run --release --features studies --example
/// render_studies -- sharp_lobe_quadrature` (MESH, ORBIT, ROT, SPP).
fn sharp_lobe_quadrature() -> anyhow::Result<()> {
    use glam::{DVec3, Vec3A};
    let mesh: String = setting("MESH", "bunny")?;
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let res: Option<usize> = optional_setting("RES")?;
    let map = arg("MAP")?.map_or_else(|| samples.join("studio_1k.exr"), PathBuf::from);
    let orbit: Vec<f32> = list_setting("ORBIT", "20,15,2.5")?;
    let [az, el, dist] = orbit[..] else {
        bail!(
            "setting ORBIT: {} values, expected 3 (azimuth,elevation,distance)",
            orbit.len()
        );
    };
    let rot: f64 = setting("ROT", "90")?;
    let spp: u32 = setting("SPP", "1024")?;
    let kk: usize = setting("K", "6")?;
    let npx: usize = setting("N", "40")?;
    let stride: usize = setting("STRIDE", "3")?;
    if stride == 0 {
        bail!("setting STRIDE=0: must be at least 1");
    }
    let gz: f64 = setting("GZ", "0.3")?;
    let pix: Option<Vec<usize>> = match arg("PIX")? {
        Some(p) => Some(parse_list("PIX", &p)?),
        None => None,
    };
    let all = flag("ALL")?;
    let c = {
        let (mesh, env) = (samples.join(format!("{mesh}.glb")), map);
        let scene = glint::scene::import(&mesh).map_err(flat)?;
        let env = glint::env::load(&env).map_err(flat)?;
        let baker = Baker::new(
            &scene,
            &env,
            BakeSettings {
                resolution: res,
                ..BakeSettings::default()
            },
        )
        .map_err(flat)?;
        let bake = baker.bake_refined(None, &|_| {});
        let offset = baker.ray_offset();
        let (set, tree) = (baker.set.clone(), baker.tree.clone());
        drop(baker);
        let scene = bake.scene(&scene).map_err(flat)?;
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
        Case {
            scene,
            env,
            baker_offset: offset,
            bake,
            tangents,
            set,
            tree,
        }
    };
    println!("direction set {} per side", c.set.resolution());
    let imported = glint::scene::import(&samples.join(format!("{mesh}.glb")))
        .map_err(flat)?
        .mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160u32, 120u32);
    let camera = glint::scene::orbit_camera(&c.scene.bounds, az, el, dist, w, h);
    let pair = prt_and_mc(
        &c,
        &imported,
        &m,
        &camera,
        rot,
        w,
        h,
        spp,
        PrtSettings::default(),
    );
    let sil = glint::accuracy::silhouette_mask(&pair.mc);
    println!(
        "PRT {:.3} s; PRT vs MC ({spp} spp): object {:.2} %, silhouette {:.2} %",
        pair.prt_secs,
        100.0 * rmse_where(&pair.prt, &pair.mc, None),
        100.0 * rmse_where(&pair.prt, &pair.mc, Some(&sil))
    );
    let lobes = m.lobes().map_err(flat)?;
    let light = LightSums::new(&c.env, &c.set, &c.tree, rot.to_radians());
    let tracer = glint::bake::Tracer::new(&imported);
    let eye = camera.eye().as_dvec3();
    let mut texel_leaf = vec![0usize; c.set.len()];
    for (l, &t) in c.tree.leaf_texels().iter().enumerate() {
        texel_leaf[t as usize] = l;
    }
    let frags_ref = glint::raster::rasterize(&c.scene.mesh, &camera, w, h);
    let frags_imp = glint::raster::rasterize(&imported, &camera, w, h);
    let at = |fr: &[glint::raster::Fragment], k: usize| {
        fr.iter().find(|f| (f.y * w + f.x) as usize == k).copied()
    };
    // Candidate pixels.
    let mut rows: Vec<(f64, usize)> = frags_ref
        .iter()
        .map(|f| (f.y * w + f.x) as usize)
        .filter(|&k| pair.mc.covered[k])
        .map(|k| {
            (
                ((pair.prt.pixels[k][1] - pair.mc.pixels[k][1]) as f64).powi(2),
                k,
            )
        })
        .collect();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut chosen: Vec<usize> = rows.iter().take(npx).map(|r| r.1).collect();
    let mut rng = glint::math::rng::Rng::new(11);
    for _ in 0..npx {
        let row = rows
            .get((rng.next_f64() * rows.len() as f64) as usize)
            .context("no pixel of the object to choose from")?;
        chosen.push(row.1);
    }
    // Then every `STRIDE`-th pixel seen at wo·n < 0.3 (class G).
    let grazing: Vec<usize> = frags_ref
        .iter()
        .filter(|f| {
            let tri = c.scene.mesh.triangles[f.triangle as usize];
            let p: DVec3 = (0..3)
                .map(|i| c.scene.mesh.positions[tri[i] as usize].as_dvec3() * f.bary[i] as f64)
                .sum();
            let n = (0..3)
                .map(|i| c.scene.mesh.normals[tri[i] as usize].as_dvec3() * f.bary[i] as f64)
                .sum::<DVec3>()
                .normalize();
            let won = (eye - p).normalize().dot(n);
            won > 0.0 && won < gz
        })
        .map(|f| (f.y * w + f.x) as usize)
        .step_by(stride)
        .collect();
    chosen.extend(grazing);
    if let Some(p) = pix {
        chosen = p;
    }
    let variants: Vec<glint::render::Image> = [
        PrtSettings {
            partition_deg: 1.0,
            ..PrtSettings::default()
        },
        PrtSettings {
            partition_deg: 1.0,
            prefilter: false,
            ..PrtSettings::default()
        },
    ]
    .into_iter()
    .map(|s| {
        let prt = Prt::new(
            &c.scene.mesh,
            &c.bake.cuts,
            &c.tree,
            c.tangents.as_deref(),
            s,
        );
        let coefficients = [
            m.coefficients[0].as_slice(),
            m.coefficients[1].as_slice(),
            m.coefficients[2].as_slice(),
        ];
        let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
        prt.render(
            &light,
            &camera,
            w,
            h,
            &Shading {
                rho_d: m.rho_d,
                f0: m.f0,
                specular: Specular::Table(&table),
            },
        )
    })
    .collect();
    let f0 = m.f0;
    let coeff = m.coefficients[1][0];
    let fr = |wi: DVec3, wo: DVec3| -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        let d = m.rho_d[1] / std::f64::consts::PI;
        if wo.z <= 0.0 {
            return d;
        }
        let hh = (wi + wo).normalize();
        d + coeff * lobes.eval_exact(0, hh) * glint::brdf::static_term(wi, wo, f0)
    };
    // Geometry of a fragment: (position, normal, frame, corners, ray origin).
    let geom = |mesh: &glint::scene::Mesh, f: glint::raster::Fragment| {
        let tri = mesh.triangles[f.triangle as usize];
        let b = f.bary.map(|x| x as f64);
        let p: DVec3 = (0..3)
            .map(|i| mesh.positions[tri[i] as usize].as_dvec3() * b[i])
            .sum();
        let n = (0..3)
            .map(|i| mesh.normals[tri[i] as usize].as_dvec3() * b[i])
            .sum::<DVec3>()
            .normalize();
        let corners = [(tri[0], b[0]), (tri[1], b[1]), (tri[2], b[2])];
        let o = glint::scene::smooth_surface_point(mesh, &corners, p) + n * c.baker_offset;
        (p, n, glint::sphere::Frame::from_normal(n), corners, o)
    };
    let leaves = c.tree.leaf_count();
    let mut acc = [[[0.0f64; 2]; 7]; 3];
    let mut agg = [[0.0f64; 4]; 3]; // per class: Σ (PRT − Q_cutV)², Σ Q_cutV², Σ (PRT 1° unfiltered − Q_cutV)², Σ (Q_cutV − Q_mc)² over Q_mc² ...  // per class W, R, G: (Σ (x − Q_mc)², Σ Q_mc²) for MC, PRT, Q_geo, Q_leafL, Q_cutV, PRT 1°, PRT 1° unfiltered
    let t0 = std::time::Instant::now();
    // The PRT frame with the grazing pixels replaced by Q with the map's own L and the cuts' V
    // (RGB): what supersampling the specular term inside leaves at those points could reach.
    let mut patched = pair.prt.clone();
    println!("pixel        wo.n   MC     Q_mc   Q_geo  Q_leafL Q_cutV PRT   (G)");
    for (i, &k) in chosen.iter().enumerate() {
        let (Some(fa), Some(fb)) = (at(&frags_imp, k), at(&frags_ref, k)) else {
            continue;
        };
        let mut q = [0.0f64; 5];
        let mut q_rgb = [0.0f64; 3];
        for (gi, (mesh, f)) in [(&imported, fa), (&c.scene.mesh, fb)]
            .into_iter()
            .enumerate()
        {
            let (p, n, frame, corners, o) = geom(mesh, f);
            let wo = frame.to_local((eye - p).normalize());
            let o = Vec3A::new(o.x as f32, o.y as f32, o.z as f32);
            // V per leaf from the cuts (refined mesh only).
            let mut vcut = vec![0.0f64; leaves];
            if gi == 1 {
                for &(v, b) in &corners {
                    for sp in c.bake.cuts.spans(v as usize, &c.tree) {
                        for l in sp.first..sp.end {
                            vcut[l as usize] += b * sp.v as f64;
                        }
                    }
                }
            }
            for t in 0..c.set.len() {
                let l = texel_leaf[t];
                let omega = c.set.solid_angles()[t];
                if c.tree.leaf_directions()[l].dot(n) < -0.05 {
                    continue;
                }
                for (d, wt) in c.set.texel_samples(t, kk) {
                    let wi = frame.to_local(d);
                    let f = fr(wi, wo);
                    if f <= 0.0 {
                        continue;
                    }
                    let base = f * wi.z * wt * omega;
                    let vray = if tracer.occluded(o, Vec3A::new(d.x as f32, d.y as f32, d.z as f32))
                    {
                        0.0
                    } else {
                        1.0
                    };
                    let ln = c.env.lookup_nearest(d, rot.to_radians())[1];
                    if gi == 0 {
                        q[0] += base * ln * vray;
                    } else {
                        let ll = light.leaf_radiance()[l][1];
                        q[1] += base * ln * vray;
                        q[2] += base * ll * vray;
                        q[3] += base * ll * vcut[l];
                        q[4] += base * ln * vcut[l];
                        let lr = c.env.lookup_nearest(d, rot.to_radians());
                        for ch in 0..3 {
                            q_rgb[ch] += base * lr[ch] * vcut[l];
                        }
                    }
                }
            }
        }
        let (_, _, frame, _, _) = geom(&c.scene.mesh, fb);
        let p = geom(&c.scene.mesh, fb).0;
        let won = frame.to_local((eye - p).normalize()).z;
        let (mc, prt) = (pair.mc.pixels[k][1] as f64, pair.prt.pixels[k][1] as f64);
        let (p1, p1n) = (
            variants[0].pixels[k][1] as f64,
            variants[1].pixels[k][1] as f64,
        );
        let class = if i < npx {
            0
        } else if i < 2 * npx {
            1
        } else {
            2
        };
        if class == 2 {
            patched.set(
                (k % w as usize) as u32,
                (k / w as usize) as u32,
                q_rgb.map(|x| x as f32),
            );
        }
        if class < 2 || all || (q[1] - q[0]).abs() > 0.03 * q[0] || (prt - q[3]).abs() > 0.1 * q[3]
        {
            println!(
                "({:3},{:3}) {} {:.3} {:.4} {:.4} {:.4} {:.4} {:.4} {:.4} | 1° {:.4} 1°np {:.4}",
                k % w as usize,
                k / w as usize,
                ["W", "R", "G"][class],
                won,
                mc,
                q[0],
                q[1],
                q[2],
                q[3],
                prt,
                p1,
                p1n
            );
        }
        agg[class][0] += (prt - q[3]).powi(2);
        agg[class][1] += q[3] * q[3];
        agg[class][2] += (p1n - q[3]).powi(2);
        agg[class][3] += (q[4] - q[0]).powi(2);
        for (j, x) in [mc, prt, q[1], q[2], q[3], p1, p1n].into_iter().enumerate() {
            acc[class][j][0] += (x - q[0]).powi(2);
            acc[class][j][1] += q[0] * q[0];
        }
    }
    for (class, name) in ["worst", "random", "grazing"].iter().enumerate() {
        let r = |j: usize| 100.0 * (acc[class][j][0] / acc[class][j][1]).sqrt();
        println!(
            "{name} pixels, relative RMSE against Q_mc: MC {:.2} %, PRT {:.2} %, Q_geo {:.2} %, Q_leafL {:.2} %, Q_cutV {:.2} %, PRT 1° {:.2} %, PRT 1° unfiltered {:.2} %",
            r(0),
            r(1),
            r(2),
            r(3),
            r(4),
            r(5),
            r(6)
        );
        println!(
            "    against Q_cutV (the PRT's own inputs): PRT {:.2} %, PRT 1° unfiltered {:.2} %; Q with the map's own L and the cuts' V against Q_mc: {:.2} %",
            100.0 * (agg[class][0] / agg[class][1]).sqrt(),
            100.0 * (agg[class][2] / agg[class][1]).sqrt(),
            100.0 * (agg[class][3] / acc[class][0][1]).sqrt()
        );
    }
    println!(
        "{} pixels in {:.1} s",
        chosen.len(),
        t0.elapsed().as_secs_f64()
    );
    println!(
        "PRT with the grazing pixels (every {stride}th) patched: vs MC object {:.2} %, silhouette {:.2} % (unpatched {:.2} %, {:.2} %)",
        100.0 * rmse_where(&patched, &pair.mc, None),
        100.0 * rmse_where(&patched, &pair.mc, Some(&sil)),
        100.0 * rmse_where(&pair.prt, &pair.mc, None),
        100.0 * rmse_where(&pair.prt, &pair.mc, Some(&sil))
    );
    Ok(())
}

/// Study: `render_studies bake_error MESH=bunny MAP=studio_1k CONFIGS=5.625:2:0,11.25:3:0.002`
/// bakes the mesh as imported (no refinement (e), every vertex traced) with each configuration
/// (cell degrees : boundary levels : boundary budget), and prints rays, seconds and the relative RMS
/// error of the irradiance of the map's luminance over the vertices against a ray per direction,
/// at the rotations ROTS (degrees about +Y).
fn bake_error() -> anyhow::Result<()> {
    const KEY: &str = "CONFIGS";
    let mesh: String = setting("MESH", "bunny")?;
    let map: String = setting("MAP", "studio_1k")?;
    let configs: Vec<(f64, u32, f64)> = setting::<String>(KEY, "5.625:2:0")?
        .split(',')
        .map(|c| {
            let [cell, levels, budget] = fields(KEY, c, "cell_deg:levels:budget", 3)?;
            Ok((
                field(KEY, c, "cell_deg", cell)?,
                field(KEY, c, "levels", levels)?,
                field(KEY, c, "budget", budget)?,
            ))
        })
        .collect::<anyhow::Result<_>>()?;
    let rots: Vec<f64> = list_setting("ROTS", "0,90,180,270")?;
    let skip_reference = arg("EXACT")?.as_deref() == Some("0");
    let scene =
        glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).map_err(flat)?;
    let env = glint::env::load(&common::assets().join(format!("hdr/{map}.exr"))).map_err(flat)?;
    let base = BakeSettings {
        refine: glint::bake::RefineSettings {
            rounds: 0,
            interpolate: false,
            ..Default::default()
        },
        ..BakeSettings::default()
    };
    let bake_with = |deg: f64, levels: u32, budget: f64| {
        let mut settings = base;
        settings.cell_deg = Some(deg);
        settings.boundary_levels = Some(levels);
        settings.cut.boundary_budget = budget;
        let t0 = std::time::Instant::now();
        let baker = Baker::new(&scene, &env, settings).map_err(flat)?;
        let bake = baker.bake_all(None, &|_| {});
        let secs = t0.elapsed().as_secs_f64();
        let irradiance: Vec<Vec<f64>> = rots
            .iter()
            .map(|&rot| {
                let radiance = glint::light::texel_radiance(&env, &baker.set, rot.to_radians());
                let luminance = glint::bake::decisions::leaf_grey(&baker.tree, &radiance);
                (0..bake.cuts.vertex_count())
                    .map(|v| {
                        let Some((_, n)) = baker.ray_origin(v) else {
                            return 0.0;
                        };
                        glint::bake::decisions::cut_irradiance(
                            &baker.tree,
                            bake.cuts.cut(v),
                            &luminance,
                            n,
                        )
                    })
                    .collect()
            })
            .collect();
        anyhow::Ok((bake.stats.rays_traced, secs, irradiance))
    };
    // EXACT=0 skips the reference (errors print as NaN).
    let (exact_rays, exact_secs, exact) = if skip_reference {
        (0, 0.0, vec![Vec::new(); rots.len()])
    } else {
        bake_with(0.0, 0, 0.0)?
    };
    println!("{mesh} under {map}: a ray per direction {exact_rays} rays, {exact_secs:.2} s");
    println!("| cells | levels | budget | rays | bake (s) | error per rotation ({rots:?}) |");
    println!("|---|---|---|---|---|---|");
    for &(cell, levels, budget) in &configs {
        let (rays, secs, e) = bake_with(cell, levels, budget)?;
        let errors: Vec<String> = e
            .iter()
            .zip(&exact)
            .map(|(a, b)| {
                if b.is_empty() {
                    return "NaN".to_string();
                }
                let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
                let den: f64 = b.iter().map(|y| y * y).sum();
                format!("{:.3} %", 100.0 * (num / den).sqrt())
            })
            .collect();
        println!(
            "| {cell}° | {levels} | {budget} | {:.2} M | {secs:.2} | {} |",
            rays as f64 / 1e6,
            errors.join(", ")
        );
    }
    Ok(())
}
