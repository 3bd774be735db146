//! Render benchmarks: `cargo bench --bench render`. Prints median times of the CPU PRT
//! frame (shade the view's points, interpolate; 2 threads here) and of building the p(h) table.
//!
//! Inputs: bunny.glb under studio_512 and dragon_100k.glb (49,892 vertices) under courtyard_1k,
//! baked with the default settings; an isotropic material with three ring lobes (J = 24, σ = π/40);
//! the scene's default camera at 160×120 and 640×480; the default shading density (every covered
//! pixel shaded at its own point), 1-pixel shading triangles and vertex shading only. Then the wgpu
//! preview (vertex shading) on the first adapter: on a machine without a GPU that is Mesa's
//! lavapipe, which says nothing of a GPU's speed; the table says which adapter ran. Frame = shade +
//! raster + readback of the image (the app skips the readback); light = the per-rotation upload.
//! Last, the app's still frame: the preview frame (vertex shading, `app::engine::preview_settings`)
//! and the still frame that replaces it once the view rests (`glint render`'s PRT frame), timed at
//! 640×480 and measured against the Monte Carlo reference at 320×240 (2 × 1024 spp; the reference's
//! own noise, estimated from its two halves, is printed beside the errors); `-- still` runs only
//! that table, and `-- still --spp N` takes 2 × N spp for the reference (a less noisy one).
//!
//! `-- gpu` runs only the wgpu preview's frame rate, as the app drives it (`app::engine`): the
//! app's preview settings, the camera orbiting so that every frame shades the vertices anew, at
//! 640×480 to 3840×2160. Per size: the app's frame (shade, raster, readback into an image, waited
//! for), the frame without readback (100 frames submitted back to back, then one wait: what the
//! GPU sustains), and a light rotation (light sums on the CPU, upload, frame); `-- gpu bunny` or
//! `-- gpu dragon_100k` runs that scene only.

use glint::bake::{BakeSettings, Baker};
use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, Specular};
use glint::render::table::{PhPyramid, default_resolution};
use glint::sphere::{LobeLayout, LobeSet, srbf};
use std::time::Instant;

#[path = "../tests/it/common.rs"]
mod common;
#[path = "support/timing.rs"]
mod timing;
use timing::{median, time, try_time};

fn main() {
    if let Err(e) = run() {
        eprintln!("render bench: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA)?,
    )?;
    let mut c = vec![0.0; lobes.len()];
    (c[0], c[3], c[9]) = (0.8, 0.5, 0.3);
    let coefficients = [c.as_slice(), c.as_slice(), c.as_slice()];
    let t_table = time(5, || {
        PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()))
    });
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    println!(
        "p(h) table {}² with {} filtered levels ({:.1} MB): build {:.1} ms",
        table.resolution(),
        table.level_count(),
        table.bytes() as f64 / 1e6,
        t_table * 1e3
    );
    let shading = Shading {
        rho_d: [0.5; 3],
        f0: 0.04,
        specular: Specular::Table(&table),
    };
    // `cargo bench --bench render -- still`: the still-frame table only.
    #[cfg(feature = "gui")]
    if std::env::args().any(|a| a == "still") {
        let args: Vec<String> = std::env::args().collect();
        let spp = match args.iter().position(|a| a == "--spp") {
            None => 1024,
            Some(i) => match args.get(i + 1).and_then(|n| n.parse().ok()) {
                Some(n) => n,
                None => {
                    eprintln!("render bench: --spp takes a whole number of samples");
                    std::process::exit(2);
                }
            },
        };
        return still_frames(&shading, spp);
    }
    // `cargo bench --bench render -- gpu`: the wgpu preview's frame rate table only.
    #[cfg(feature = "gui")]
    if std::env::args().any(|a| a == "gpu") {
        return gpu_frames(&table);
    }
    let mut gpu_rows = Vec::new();
    println!("| scene | vertices | size | shading | subdivision | points | frame (s) | fps |");
    println!("|---|---|---|---|---|---|---|---|");
    for (mesh, env) in [
        ("bunny", "hdr/small/studio_512.exr"),
        ("dragon_100k", "hdr/courtyard_1k.exr"),
    ] {
        let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
        let env = glint::env::load(&common::assets().join(env))?;
        let baker = Baker::new(&scene, &env, BakeSettings::default())?;
        let bake = baker.bake_refined(None, &|_| {});
        let scene = bake.scene(&scene)?;
        let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
        let default_deg = PrtSettings::default().partition_deg;
        // The last rows are the default with its grazing points' runs resolved inside their
        // leaves below a lower view cosine, and not at all, side by side.
        let below = glint::render::prt::RESOLVE_BELOW;
        for (label, max_edge_px, partition_deg, per_pixel, resolve_leaves, resolve_below) in [
            ("vertices", 0.0, default_deg, false, true, below),
            ("vertices", 0.0, 16.0, false, true, below),
            ("1-px triangles", 1.0, default_deg, false, true, below),
            ("per pixel (default)", 1.0, default_deg, true, true, below),
            (
                "per pixel, grazing runs resolved below wo·n = 0.3",
                1.0,
                default_deg,
                true,
                true,
                0.3,
            ),
            (
                "per pixel, grazing runs not resolved",
                1.0,
                default_deg,
                true,
                false,
                below,
            ),
        ] {
            let prt = Prt::new(
                &scene.mesh,
                &bake.cuts,
                &baker.tree,
                None,
                PrtSettings {
                    max_edge_px,
                    partition_deg,
                    per_pixel,
                    resolve_leaves,
                    resolve_below,
                    ..PrtSettings::default()
                },
            );
            let label = format!("{label}, {partition_deg}° partition");
            for (w, h) in [(160, 120), (640, 480)] {
                let mut camera = scene.cameras[0].clone();
                camera.aspect = w as f32 / h as f32;
                let sm = prt.shading_mesh(&camera, w, h);
                let reps = if sm.points.len() > 100_000 { 1 } else { 3 };
                let secs = time(reps, || prt.render(&light, &camera, w, h, &shading));
                println!(
                    "| {mesh} | {} | {w}×{h} | {label} | {} | {} | {secs:.3} | {:.1} |",
                    scene.mesh.positions.len(),
                    sm.subdivision,
                    sm.points.len(),
                    1.0 / secs
                );
                if max_edge_px == 0.0 && !per_pixel {
                    // The per-vertex light cached (what a new view or a new material reuses; the
                    // app's CPU preview): the first frame fills it, later frames evaluate the BRDF
                    // only.
                    let mut cache = glint::render::VertexLight::default();
                    let t0 = Instant::now();
                    std::hint::black_box(
                        prt.render_cached(&mut cache, &light, &camera, w, h, &shading),
                    );
                    let fill = t0.elapsed().as_secs_f64();
                    let secs = time(5, || {
                        prt.render_cached(&mut cache, &light, &camera, w, h, &shading)
                    });
                    println!(
                        "| {mesh} | {} | {w}×{h} | {label}, light cached ({:.0} MB; first frame {fill:.3} s) | {} | {} | {secs:.3} | {:.1} |",
                        scene.mesh.positions.len(),
                        cache.bytes() as f64 / 1e6,
                        sm.subdivision,
                        sm.points.len(),
                        1.0 / secs
                    );
                }
            }
        }
        // The CPU preview after a light rotation: new light sums (from the kept source) and a frame
        // at the app's preview settings (vertices, 16° partition, 64-leaf horizon clips:
        // engine.rs), over the view's shading mesh, which the app keeps while the view does not
        // change.
        let source = glint::light::LightSource::new(&env);
        std::hint::black_box(LightSums::from_source(
            &source,
            &baker.set,
            &baker.tree,
            0.0,
        ));
        let preview = Prt::new(
            &scene.mesh,
            &bake.cuts,
            &baker.tree,
            None,
            PrtSettings {
                max_edge_px: 0.0,
                per_pixel: false,
                partition_deg: 16.0,
                horizon_leaves: 64,
                ..PrtSettings::default()
            },
        );
        for (w, h) in [(160, 120), (640, 480)] {
            let mut camera = scene.cameras[0].clone();
            camera.aspect = w as f32 / h as f32;
            let mut rotation = 0.0;
            let sm = preview.shading_mesh(&camera, w, h);
            let secs = time(5, || {
                rotation += 0.1;
                let light = LightSums::from_source(&source, &baker.set, &baker.tree, rotation);
                preview.render_mesh(&sm, &light, &camera, w, h, &shading)
            });
            let light_secs = time(5, || {
                LightSums::from_source(&source, &baker.set, &baker.tree, 0.3)
            });
            println!(
                "| {mesh} | {} | {w}×{h} | app preview after a light rotation (light sums {light_secs:.3} s + frame; 16° partition, 64-leaf horizon clips, the view's shading mesh kept) | 0 | | {secs:.3} | {:.1} |",
                scene.mesh.positions.len(),
                1.0 / secs
            );
        }
        #[cfg(feature = "gui")]
        match glint::gpu::GpuContext::headless() {
            Ok(ctx) => {
                let settings = PrtSettings {
                    max_edge_px: 0.0,
                    per_pixel: false,
                    ..PrtSettings::default()
                };
                let mut preview = glint::gpu::GpuPreview::new(
                    &ctx,
                    &scene.mesh,
                    &bake.cuts,
                    &baker.tree,
                    None,
                    settings,
                )?;
                preview.set_material([0.5; 3], 0.04, Some(&table))?;
                let t_light = try_time(3, || preview.set_light(&light, &baker.tree))?;
                for (w, h) in [(160, 120), (640, 480)] {
                    let mut camera = scene.cameras[0].clone();
                    camera.aspect = w as f32 / h as f32;
                    preview.render(&camera, w, h)?;
                    let secs = try_time(5, || preview.render(&camera, w, h))?;
                    gpu_rows.push(format!(
                        "| {mesh} | {} | {w}×{h} | {} | {secs:.3} | {:.1} | {:.1} |",
                        scene.mesh.positions.len(),
                        ctx.describe(),
                        1.0 / secs,
                        t_light * 1e3
                    ));
                }
            }
            Err(e) => gpu_rows.push(format!("| {mesh} | no adapter: {e} | | | | |")),
        }
        #[cfg(not(feature = "gui"))]
        gpu_rows.push(format!(
            "| {mesh} | built without the gui feature | | | | |"
        ));
    }
    println!();
    println!("| scene | vertices | size | wgpu adapter | frame (s) | fps | light upload (ms) |");
    println!("|---|---|---|---|---|---|---|");
    for row in gpu_rows {
        println!("{row}");
    }
    #[cfg(feature = "gui")]
    still_frames(&shading, 1024)?;
    Ok(())
}

/// The app's still frame against its preview frame (see the module docs), the reference at 2 ×
/// `spp` samples a pixel.
#[cfg(feature = "gui")]
fn still_frames(shading: &Shading, spp: u32) -> anyhow::Result<()> {
    use glint::app::engine::preview_settings;
    use glint::render::{ExactMaterial, render_reference};
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA)?,
    )?;
    let mut c = vec![0.0; lobes.len()];
    (c[0], c[3], c[9]) = (0.8, 0.5, 0.3);
    let exact = ExactMaterial {
        lobes: &lobes,
        coefficients: [&c, &c, &c],
        rho_d: shading.rho_d,
        f0: shading.f0,
    };
    println!();
    println!(
        "| scene | CPU preview frame 640×480 (s) | still frame 640×480 (s) | CPU preview vs MC | wgpu preview's shading vs MC | still vs MC | MC noise (2 × {spp} spp) | CPU preview, still vs MC less noise |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (mesh, env) in [
        ("bunny", "hdr/small/studio_512.exr"),
        ("dragon_100k", "hdr/courtyard_1k.exr"),
    ] {
        let imported = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
        let env = glint::env::load(&common::assets().join(env))?;
        let baker = Baker::new(&imported, &env, BakeSettings::default())?;
        let bake = baker.bake_refined(None, &|_| {});
        let scene = bake.scene(&imported)?;
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
        let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
        let frame = |settings: PrtSettings, w: u32, h: u32| {
            let camera = glint::scene::Camera {
                aspect: w as f32 / h as f32,
                ..scene.cameras[0].clone()
            };
            let prt = Prt::new(
                &scene.mesh,
                &bake.cuts,
                &baker.tree,
                tangents.as_deref(),
                settings,
            );
            prt.render(&light, &camera, w, h, shading)
        };
        let t_preview = time(3, || frame(preview_settings(false), 640, 480));
        let t_still = time(3, || frame(PrtSettings::default(), 640, 480));
        let (w, h) = (320, 240);
        let camera = glint::scene::Camera {
            aspect: w as f32 / h as f32,
            ..scene.cameras[0].clone()
        };
        let tracer = glint::bake::Tracer::new(&imported.mesh);
        let offset = 1e-4 * imported.bounds.diagonal() as f64;
        let (_, imported_tangents, _) = glint::bake::decisions::decide_frames(&imported.mesh);
        let half = |seed| {
            render_reference(
                &imported.mesh,
                imported_tangents.as_deref(),
                &tracer,
                offset,
                &env,
                0.0,
                exact,
                &camera,
                w,
                h,
                spp,
                seed,
            )
        };
        let (a, b) = (half(1), half(2));
        let mut mc = a.clone();
        for (p, q) in mc.pixels.iter_mut().zip(&b.pixels) {
            *p = std::array::from_fn(|k| 0.5 * (p[k] + q[k]));
        }
        let mask = vec![true; (w * h) as usize];
        let err = |img: &glint::render::Image| glint::accuracy::masked_rel_rmse(img, &mc, &mask).0;
        let noise = 0.5 * glint::accuracy::masked_rel_rmse(&a, &b, &mask).0;
        let (preview, still) = (
            frame(preview_settings(false), w, h),
            frame(PrtSettings::default(), w, h),
        );
        let gpu_preview = frame(preview_settings(true), w, h);
        let less = |e: f64| (e * e - noise * noise).max(0.0).sqrt();
        println!(
            "| {mesh} | {t_preview:.3} | {t_still:.3} | {:.2} % | {:.2} % | {:.2} % | {:.2} % | {:.2} %, {:.2} % |",
            100.0 * err(&preview),
            100.0 * err(&gpu_preview),
            100.0 * err(&still),
            100.0 * noise,
            100.0 * less(err(&preview)),
            100.0 * less(err(&still)),
        );
    }
    Ok(())
}

/// The wgpu preview's frame rate as the app drives it (see the module docs, `-- gpu`).
#[cfg(feature = "gui")]
fn gpu_frames(table: &PhPyramid) -> anyhow::Result<()> {
    use glint::app::engine::preview_settings;
    use glint::light::LightSource;
    use glint::scene::orbit_camera;
    let ctx = glint::gpu::GpuContext::headless()?;
    let software = ctx.info.device_type == wgpu::DeviceType::Cpu;
    println!(
        "adapter: {}; {} CPU threads",
        ctx.describe(),
        rayon::current_num_threads()
    );
    println!();
    println!(
        "| scene | vertices | triangles | size | app frame with readback (ms) | fps | frame without readback, 100 back to back (ms) | fps | light rotation: sums + upload + frame (ms) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    // `-- gpu dragon_100k` (or `bunny`): that scene only.
    let args: Vec<String> = std::env::args().collect();
    for (mesh, env) in [
        ("bunny", "hdr/small/studio_512.exr"),
        ("dragon_100k", "hdr/courtyard_1k.exr"),
    ] {
        if args.iter().any(|a| a == "bunny" || a == "dragon_100k")
            && !args.iter().any(|a| a == mesh)
        {
            continue;
        }
        let imported = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
        let env = glint::env::load(&common::assets().join(env))?;
        let baker = Baker::new(&imported, &env, BakeSettings::default())?;
        let bake = baker.bake_refined(None, &|_| {});
        let scene = bake.scene(&imported)?;
        let source = LightSource::new(&env);
        let t0 = Instant::now();
        let mut preview = glint::gpu::GpuPreview::new(
            &ctx,
            &scene.mesh,
            &bake.cuts,
            &baker.tree,
            None,
            preview_settings(true),
        )?;
        preview.set_material([0.5; 3], 0.04, Some(table))?;
        preview.set_light(
            &LightSums::from_source(&source, &baker.set, &baker.tree, 0.0),
            &baker.tree,
        )?;
        let upload = t0.elapsed().as_secs_f64();
        let vertices = scene.mesh.positions.len();
        let triangles = scene.mesh.triangles.len();
        let sizes: &[(u32, u32)] = if software {
            &[(640, 480)]
        } else {
            &[(640, 480), (1280, 720), (1920, 1080), (3840, 2160)]
        };
        for &(w, h) in sizes {
            // The camera turns 1° a frame about the object: each frame shades every vertex anew.
            let camera = |i: usize| orbit_camera(&scene.bounds, i as f32, 20.0, 0.0, w, h);
            preview.render(&camera(0), w, h)?;
            let frames = if software { 1 } else { 30 };
            let mut app = Vec::with_capacity(frames);
            for i in 0..frames {
                let t = Instant::now();
                std::hint::black_box(preview.render(&camera(i), w, h)?);
                app.push(t.elapsed().as_secs_f64());
            }
            let app = median(app);
            let burst = if software { 1 } else { 100 };
            let mut sustained = Vec::new();
            for _ in 0..if software { 1 } else { 3 } {
                let t = Instant::now();
                for i in 0..burst {
                    preview.draw(&camera(i), w, h)?;
                }
                ctx.device.poll(wgpu::PollType::wait_indefinitely())?;
                sustained.push(t.elapsed().as_secs_f64() / burst as f64);
            }
            let sustained = median(sustained);
            let mut rotation = Vec::new();
            for i in 1..=if software { 1 } else { 5 } {
                let t = Instant::now();
                let light = LightSums::from_source(
                    &source,
                    &baker.set,
                    &baker.tree,
                    (10.0 * i as f64).to_radians(),
                );
                preview.set_light(&light, &baker.tree)?;
                std::hint::black_box(preview.render(&camera(0), w, h)?);
                rotation.push(t.elapsed().as_secs_f64());
            }
            let rotation = median(rotation);
            println!(
                "| {mesh} | {vertices} | {triangles} | {w}×{h} | {:.2} | {:.0} | {:.3} | {:.0} | {:.1} |",
                app * 1e3,
                1.0 / app,
                sustained * 1e3,
                1.0 / sustained,
                rotation * 1e3
            );
        }
        println!(
            "(upload of {mesh}'s bake, material and light: {:.0} ms)",
            upload * 1e3
        );
    }
    Ok(())
}
