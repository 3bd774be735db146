//! The renderers against each other (method.md §7, issue #5): the CPU PRT render (default settings,
//! tabulated p) against the Monte Carlo reference (exact visibility, exact lobes, the environment map
//! itself, 4096 spp) on the bunny and the teapot; the table against the exact lobe sum; a white furnace.

mod common;

use glint::bake::{BakeSettings, Baker};
use glint::env::EnvMap;
use glint::fit::run::{FitSettings, fit};
use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, Specular};
use glint::render::reference::{ExactMaterial, render_reference};
use glint::render::table::{PhTable, default_resolution};
use glint::scene::Scene;

struct Case {
    /// The baked scene (its mesh refined when the bake refined it).
    scene: Scene,
    env: EnvMap,
    baker_offset: f64,
    bake: glint::bake::Bake,
    tangents: Option<Vec<glam::Vec4>>,
    set: glint::sphere::DirectionSet,
    tree: glint::sphere::LightTree,
}

/// The mesh baked as imported.
fn case(mesh: &str, env: &str) -> Case {
    case_with(mesh, env, false)
}

/// With `refined`, baked as `glint bake` does: the mesh refined where visibility changes (decision (e)).
fn case_with(mesh: &str, env: &str, refined: bool) -> Case {
    case_at(&common::assets().join(format!("glb/{mesh}.glb")), &common::assets().join(format!("hdr/small/{env}.exr")), refined)
}

/// [`case_with`] for a scene and an environment given by path.
fn case_at(mesh: &std::path::Path, env: &std::path::Path, refined: bool) -> Case {
    let scene = glint::scene::import(mesh).unwrap();
    let env = glint::env::load(env).unwrap();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let bake = if refined { baker.bake_refined(None, &|_| {}) } else { baker.bake_all(None, &|_| {}) };
    let offset = baker.ray_offset();
    let (set, tree) = (baker.set.clone(), baker.tree.clone());
    drop(baker);
    let scene = bake.scene(&scene).unwrap();
    let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
    Case { scene, env, baker_offset: offset, bake, tangents, set, tree }
}

const STROKES: &str = include_str!("../samples/strokes/bunny-highlight.json");

/// Fits the sample strokes (a highlight painted on the default view) and returns the material.
fn fitted(c: &Case) -> glint::fit::material::Material {
    let views = glint::fit::strokes::parse(STROKES).unwrap();
    let outcome = fit(&c.scene, &c.env, &c.bake.cuts, c.bake.decisions.resolution, c.tangents.as_deref(), c.bake.decisions.anisotropic, &views, &FitSettings::default()).unwrap();
    let m = outcome.material;
    assert!(m.coefficients.iter().flatten().any(|&x| x > 0.0), "the strokes must produce a specular lobe");
    m
}

/// Errors of one comparison, relative RMSE over the object's pixels.
struct Errors {
    prt_vs_mc: f64,
    prt_vs_transfer: f64,
    transfer_vs_mc: f64,
    table_vs_exact: f64,
    mc_noise: f64,
}

fn compare(mesh: &str, w: u32, h: u32) -> Errors {
    let c = case_with(mesh, "studio_512", true);
    // The truth is rendered on the mesh as imported (the refinement does not move the surface).
    let imported = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
    let (_, imported_tangents, _) = glint::bake::decisions::decide_frames(&imported.mesh);
    let m = fitted(&c);
    let lobes = m.lobes().unwrap();
    let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
    let camera = &c.scene.cameras[0];
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings::default());
    let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let t0 = std::time::Instant::now();
    let tab = prt.render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) });
    let frame = t0.elapsed().as_secs_f64();
    let exact = prt.render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Exact { lobes: &lobes, coefficients } });
    // The per-pixel transfer render (same cuts, T·c + ρd E/π): what the PRT frame approximates.
    let ctx = glint::transfer::TransferContext::new(&c.scene.mesh, &c.bake.cuts, &c.tree, &lobes, c.tangents.as_deref(), None);
    let t = ctx.compute(&light, camera, w, h, m.f0);
    let mut transfer = glint::render::Image::new(w, h);
    for (p, v) in t.pixels.iter().zip(t.render(m.rho_d, coefficients)) {
        transfer.set(p.x, p.y, v.map(|x| x as f32));
    }
    let t0 = std::time::Instant::now();
    let material = ExactMaterial { lobes: &lobes, coefficients, rho_d: m.rho_d, f0: m.f0 };
    let tracer = glint::bake::Tracer::new(&imported.mesh);
    let mc = render_reference(&imported.mesh, imported_tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 4096, 7);
    let mc_secs = t0.elapsed().as_secs_f64();
    // The reference's own noise: a second 4096-spp render with another seed (the difference of two
    // is √2 × the noise of one).
    let mc2 = render_reference(&imported.mesh, imported_tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 4096, 8);
    let diffuse_only = prt.render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::None });
    // The BRDF once per partition node (merged runs, the default) against once per run.
    let per_run = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings { merge_runs: false, ..PrtSettings::default() }).render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) });
    let merged_vs_per_run = tab.relative_rmse(&per_run).unwrap();
    println!("{mesh}: merged runs vs the BRDF per run {merged_vs_per_run:.5}, per run vs MC {:.4}", per_run.relative_rmse(&mc).unwrap());
    assert!(merged_vs_per_run < 0.005, "{mesh}: merged runs {merged_vs_per_run} off the per-run frame");
    let e = Errors {
        prt_vs_mc: tab.relative_rmse(&mc).unwrap(),
        prt_vs_transfer: tab.relative_rmse(&transfer).unwrap(),
        transfer_vs_mc: transfer.relative_rmse(&mc).unwrap(),
        table_vs_exact: tab.relative_rmse(&exact).unwrap(),
        mc_noise: mc2.relative_rmse(&mc).unwrap() / 2f64.sqrt(),
    };
    let e_diffuse = diffuse_only.relative_rmse(&mc).unwrap();
    println!(
        "{mesh} {w}x{h}: {} baked vertices ({}), {} object pixels, shading subdivision {}, PRT frame {frame:.3} s, MC {mc_secs:.1} s; relative RMSE: PRT vs MC {:.4}, PRT vs per-pixel transfer {:.4}, transfer vs MC {:.4}, table vs exact lobes {:.5}, MC noise {:.4}, diffuse-only vs MC {e_diffuse:.3}",
        c.scene.mesh.positions.len(),
        c.bake.decisions.refine_reason,
        tab.covered_count(),
        prt.shading_mesh(camera, w, h).subdivision,
        e.prt_vs_mc,
        e.prt_vs_transfer,
        e.transfer_vs_mc,
        e.table_vs_exact,
        e.mc_noise
    );
    assert!(e_diffuse > 0.3, "the specular term must matter in this comparison (diffuse-only is {e_diffuse} off)");
    assert!(e.mc_noise < 0.015, "reference noise {}", e.mc_noise);
    assert!(e.table_vs_exact <= 0.005, "{mesh}: table vs exact lobes {} > 0.5 %", e.table_vs_exact);
    e
}

// The goal is PRT vs Monte Carlo within 2 %: met (2026-11-24: bunny 1.27 %, teapot 1.70 %),
// baked as `glint bake` does — the mesh refined where visibility changes (decision (e)) and, under the
// studio's small bright lights, cells at shadow edges traced again at half and a quarter of the cell
// (decision (d)'s boundary refinement; 2.11 % and 3.40 % without it) — and shaded per pixel. The frame
// is within 0.5 % of the per-pixel transfer render, which shares the cuts. The bounds are the goal, so
// a regression past it (a bake that stops refining cells or the mesh, a frame that interpolates again)
// fails.
#[test]
fn prt_against_monte_carlo_on_the_bunny() {
    let e = compare("bunny", 160, 120);
    assert!(e.prt_vs_transfer <= 0.01, "PRT vs per-pixel transfer {}", e.prt_vs_transfer);
    assert!(e.prt_vs_mc <= 0.02, "PRT vs Monte Carlo {}", e.prt_vs_mc);
}

#[test]
fn prt_against_monte_carlo_on_the_teapot() {
    let e = compare("teapot", 160, 120);
    assert!(e.prt_vs_transfer <= 0.01, "PRT vs per-pixel transfer {}", e.prt_vs_transfer);
    assert!(e.prt_vs_mc <= 0.02, "PRT vs Monte Carlo {}", e.prt_vs_mc);
}

/// Developer tool (not run by CI): `MESH=teapot cargo test --test render diagnose -- --ignored --nocapture`
/// prints PRT, transfer and Monte Carlo errors for a grid of PRT settings (ES: shading-triangle edges in
/// pixels; a negative value shades per pixel) and writes images to /tmp/diag.
#[test]
#[ignore]
fn diagnose() {
    let mesh = std::env::var("MESH").unwrap_or("bunny".into());
    let (w, h) = (160, 120);
    let c = case(&mesh, "studio_512");
    let m = fitted(&c);
    println!("coefficients R: {:?}", m.coefficients[0]);
    let lobes = m.lobes().unwrap();
    let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
    let zero = vec![0.0; lobes.len()];
    let zc = [zero.as_slice(), zero.as_slice(), zero.as_slice()];
    let camera = &c.scene.cameras[0];
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let tracer = glint::bake::Tracer::new(&c.scene.mesh);
    let out = std::path::Path::new("/tmp/diag");
    std::fs::create_dir_all(out).unwrap();
    for (name, coef) in [("diffuse", zc), ("full", coefficients)] {
        let material = ExactMaterial { lobes: &lobes, coefficients: coef, rho_d: m.rho_d, f0: m.f0 };
        let mc = render_reference(&c.scene.mesh, c.tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 1024, 7);
        let mc2 = render_reference(&c.scene.mesh, c.tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 1024, 8);
        // Transfer (per pixel) render.
        let ctx = glint::transfer::TransferContext::new(&c.scene.mesh, &c.bake.cuts, &c.tree, &lobes, c.tangents.as_deref(), None);
        let t = ctx.compute(&light, camera, w, h, m.f0);
        let tr = t.render(m.rho_d, coef);
        let mut timg = glint::render::Image::new(w, h);
        for (p, v) in t.pixels.iter().zip(&tr) {
            timg.set(p.x, p.y, v.map(|x| x as f32));
        }
        let mut variants = vec![("default".to_string(), PrtSettings::default())];
        let pds: Vec<f64> = std::env::var("PDS").map(|v| v.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or(vec![1.0, 2.0, 4.0]);
        let es: Vec<f64> = std::env::var("ES").map(|v| v.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or(vec![0.0, 1.0, 2.0, 4.0]);
        for &pd in &pds {
            for &e in &es {
                variants.push((format!("p{pd}e{e}"), PrtSettings { partition_deg: pd, prefilter: true, max_edge_px: e, per_pixel: e < 0.0, ..PrtSettings::default() }));
            }
        }
        for (label, settings) in variants {
            let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), settings);
            let table = PhTable::build(&lobes, coef, default_resolution(lobes.lambda()));
            let t0 = std::time::Instant::now();
            let img = prt.render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) });
            let secs = t0.elapsed().as_secs_f64();
            println!("{name} {label}: PRT vs MC {:.4}, PRT vs transfer {:.4}, frame {secs:.3} s, partition nodes {}", img.relative_rmse(&mc).unwrap(), img.relative_rmse(&timg).unwrap(), prt.partition_nodes());
            img.write(&out.join(format!("{mesh}_{name}_{label}.exr")), 1.0).unwrap();
        }
        println!("{name}: transfer vs MC {:.4}, MC noise {:.4}", timg.relative_rmse(&mc).unwrap(), mc2.relative_rmse(&mc).unwrap());
        let mut diff = glint::render::Image::new(w, h);
        let mut signed = 0.0f64;
        for k in 0..diff.pixels.len() {
            if mc.covered[k] && timg.covered[k] {
                let (a, b) = (timg.pixels[k][1], (mc.pixels[k][1] + mc2.pixels[k][1]) * 0.5);
                signed += (a - b) as f64;
                diff.pixels[k] = if a > b { [(a - b) * 10.0, 0.0, 0.0] } else { [0.0, 0.0, (b - a) * 10.0] };
            }
        }
        println!("{name}: mean signed (transfer - MC) {:.4e} per pixel, mean MC {:.4e}", signed / mc.covered_count() as f64, mc.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / mc.covered_count() as f64);
        diff.write(&out.join(format!("{mesh}_{name}_diff.png")), 1.0).unwrap();
        mc.write(&out.join(format!("{mesh}_{name}_mc.exr")), 1.0).unwrap();
        mc2.write(&out.join(format!("{mesh}_{name}_mc2.exr")), 1.0).unwrap();
        timg.write(&out.join(format!("{mesh}_{name}_transfer.exr")), 1.0).unwrap();
        mc.write(&out.join(format!("{mesh}_{name}_mc.png")), 1.0).unwrap();
        timg.write(&out.join(format!("{mesh}_{name}_transfer.png")), 1.0).unwrap();
    }
}

/// Diffuse PRT on an unoccluded sphere against the closed form: L(d) = 1 + a·d gives
/// E(n) = π + (2π/3) a·n, so with ρd = 1 the radiance is 1 + (2/3) a·n at every vertex. The white
/// furnace is a = 0.
#[test]
fn diffuse_prt_matches_the_closed_form_on_a_sphere() {
    let mesh = common::uv_sphere(1.0, 48, 24, false);
    let scene = common::scene_from_mesh(mesh);
    for a in [glam::DVec3::ZERO, glam::DVec3::new(0.3, 0.5, -0.2)] {
        let env = EnvMap::from_fn(512, 256, |d| [(1.0 + a.dot(d)) as f32; 3]).unwrap();
        let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
        let bake = baker.bake_all(None, &|_| {});
        assert_eq!(bake.stats.rays_traced, 0);
        let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
        for settings in [PrtSettings::default(), PrtSettings { partition_deg: 30.0, ..PrtSettings::default() }] {
            let prt = Prt::new(&scene.mesh, &bake.cuts, &baker.tree, None, settings);
            let shading = Shading { rho_d: [1.0; 3], f0: 0.04, specular: Specular::None };
            let mut worst = 0.0f64;
            for v in 0..scene.mesh.positions.len() as u32 {
                let p = glint::render::prt::ShadingPoint { corners: [v; 3], bary: [1.0, 0.0, 0.0] };
                let got = prt.shade_point(&p, &light, glam::DVec3::new(0.0, 0.0, 10.0), &shading)[0];
                let n = scene.mesh.normals[v as usize].as_dvec3();
                let want = 1.0 + 2.0 / 3.0 * a.dot(n);
                worst = worst.max((got - want).abs() / want);
            }
            println!("a = {a}, partition {}°: worst relative error {worst:.2e}", settings.partition_deg);
            assert!(worst < 2e-3, "a = {a}: {worst}");
        }
    }
}

/// The default PRT frame, the vertex-only PRT frame and the per-pixel transfer render of `m` in the
/// case's first camera.
fn prt_and_transfer(c: &Case, m: &glint::fit::material::Material, w: u32, h: u32) -> (glint::render::Image, glint::render::Image, glint::render::Image) {
    let lobes = m.lobes().unwrap();
    let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
    let camera = &c.scene.cameras[0];
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let shading = Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) };
    let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings::default()).render(&light, camera, w, h, &shading);
    let prt_v = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings { max_edge_px: 0.0, per_pixel: false, ..PrtSettings::default() }).render(&light, camera, w, h, &shading);
    let ctx = glint::transfer::TransferContext::new(&c.scene.mesh, &c.bake.cuts, &c.tree, &lobes, c.tangents.as_deref(), None);
    let t = ctx.compute(&light, camera, w, h, m.f0);
    let mut transfer = glint::render::Image::new(w, h);
    for (p, v) in t.pixels.iter().zip(t.render(m.rho_d, coefficients)) {
        transfer.set(p.x, p.y, v.map(|x| x as f32));
    }
    (prt, prt_v, transfer)
}

/// Dev study (ignored): transfer and PRT vs Monte Carlo as visibility is baked on a midpoint-subdivided
/// mesh (`cargo test --test render subdivision_study -- --ignored --nocapture`).
#[test]
#[ignore]
fn subdivision_study() {
    let spec = std::env::var("GLINT_STUDY").unwrap_or_else(|_| "teapot:0:11.25:0.02,teapot:1:11.25:0.02".into());
    for item in spec.split(',') {
        let f: Vec<&str> = item.split(':').collect();
        let (mesh, levels, cell_deg, epsilon): (&str, usize, f64, f64) = (f[0], f[1].parse().unwrap(), f[2].parse().unwrap(), f[3].parse().unwrap());
        {
            let mut scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
            for _ in 0..levels {
                scene.mesh = glint::scene::subdivide_midpoint(&scene.mesh);
            }
            let env = glint::env::load(&common::assets().join("hdr/small/studio_512.exr")).unwrap();
            let t0 = std::time::Instant::now();
            let mut settings = BakeSettings { cell_deg: Some(cell_deg), ..BakeSettings::default() };
            settings.cut.epsilon = epsilon;
            let baker = Baker::new(&scene, &env, settings).unwrap();
            let bake = baker.bake_all(None, &|_| {});
            let bake_secs = t0.elapsed().as_secs_f64();
            let (baker_offset, tangents, set, tree) = (baker.ray_offset(), baker.tangents.clone(), baker.set.clone(), baker.tree.clone());
            drop(baker);
            let c = Case { scene, env, baker_offset, tangents, set, tree, bake };
            let m = fitted(&c);
            let lobes = m.lobes().unwrap();
            let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
            let camera = &c.scene.cameras[0];
            let (w, h) = (160, 120);
            let (prt, prt_v, transfer) = prt_and_transfer(&c, &m, w, h);
            let material = ExactMaterial { lobes: &lobes, coefficients, rho_d: m.rho_d, f0: m.f0 };
            let tracer = glint::bake::Tracer::new(&c.scene.mesh);
            let mc = render_reference(&c.scene.mesh, c.tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 4096, 7);
            println!(
                "{mesh} levels {levels} cell {cell_deg}° ε {epsilon}: {} vertices, mean cut {:.0}, bake {bake_secs:.2} s; vs MC: transfer {:.4}, PRT {:.4}, PRT vertex-only {:.4}",
                c.scene.mesh.positions.len(),
                c.bake.cuts.mean_cut_size(),
                transfer.relative_rmse(&mc).unwrap(),
                prt.relative_rmse(&mc).unwrap(),
                prt_v.relative_rmse(&mc).unwrap()
            );
        }
    }
}

/// The cached frame (per-vertex light kept across views and materials) equals the direct frame: for
/// new views and a new material from one cache, with vertex shading and with subdivided shading
/// (whose interior points are shaded directly), on a mesh with and one without a tangent field.
#[test]
fn cached_frames_equal_direct_frames() {
    for mesh in ["bunny", "teapot"] {
        let c = case(mesh, "studio_512");
        let m = fitted(&c);
        let lobes = m.lobes().unwrap();
        let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
        let co = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
        let table = PhTable::build(&lobes, co, default_resolution(lobes.lambda()));
        let halved: Vec<Vec<f64>> = m.coefficients.iter().map(|ch| ch.iter().map(|x| 0.5 * x).collect()).collect();
        let table2 = PhTable::build(&lobes, [&halved[0], &halved[1], &halved[2]], default_resolution(lobes.lambda()));
        for max_edge_px in [0.0, 2.0] {
            let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings { partition_deg: 16.0, max_edge_px, per_pixel: false, ..PrtSettings::default() });
            let mut cache = glint::render::VertexLight::default();
            let cameras = [c.scene.cameras[0].clone(), glint::scene::orbit_camera(&c.scene.bounds, 70.0, 25.0, 0.0, 160, 120)];
            for (k, camera) in cameras.iter().enumerate() {
                for (t, rho_d) in [(&table, m.rho_d), (&table2, [0.3, 0.4, 0.5])] {
                    let shading = Shading { rho_d, f0: m.f0, specular: Specular::Table(t) };
                    let direct = prt.render(&light, camera, 160, 120, &shading);
                    let cached = prt.render_cached(&mut cache, &light, camera, 160, 120, &shading);
                    let e = cached.relative_rmse(&direct).unwrap();
                    assert!(e < 1e-6, "{mesh}, edge {max_edge_px}, view {k}: cached vs direct {e}");
                    assert_eq!(cached.covered, direct.covered);
                }
                assert!(cache.cached_vertices() > 0, "{mesh}: the cache was filled");
            }
        }
    }
}

/// Developer tool (not run by CI): renders one frame REPS times for profiling, e.g.
/// `MESH=bunny PD=4 E=1 REPS=5 cargo test --test render profile_frame -- --ignored --nocapture`.
#[test]
#[ignore]
fn profile_frame() {
    let var = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let mesh = var("MESH", "bunny");
    let env = var("ENV", "studio_512");
    let (pd, e, reps): (f64, f64, usize) = (var("PD", "4").parse().unwrap(), var("E", "1").parse().unwrap(), var("REPS", "5").parse().unwrap());
    let (w, h): (u32, u32) = (var("W", "160").parse().unwrap(), var("H", "120").parse().unwrap());
    let c = case(&mesh, &env);
    let lobes = glint::sphere::LobeSet::new(glint::sphere::LobeLayout::Isotropic { count: 24 }, glint::sphere::srbf::lambda_from_sigma(glint::sphere::srbf::PAPER_SIGMA).unwrap()).unwrap();
    let mut co = vec![0.0; lobes.len()];
    (co[0], co[3], co[9]) = (0.8, 0.5, 0.3);
    let coefficients = [co.as_slice(), co.as_slice(), co.as_slice()];
    let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), PrtSettings { partition_deg: pd, prefilter: true, max_edge_px: e, per_pixel: e < 0.0, ..PrtSettings::default() });
    let mut camera = c.scene.cameras[0].clone();
    camera.aspect = w as f32 / h as f32;
    let shading = Shading { rho_d: [0.5; 3], f0: 0.04, specular: Specular::Table(&table) };
    if std::env::var("MODE").as_deref() == Ok("transfer") {
        let ctx = glint::transfer::TransferContext::new(&c.scene.mesh, &c.bake.cuts, &c.tree, &lobes, c.tangents.as_deref(), None);
        let mut best = f64::MAX;
        let mut n = 0;
        for _ in 0..reps {
            let t0 = std::time::Instant::now();
            n = std::hint::black_box(ctx.compute(&light, &camera, w, h, 0.04)).pixels.len();
            best = best.min(t0.elapsed().as_secs_f64());
        }
        println!("{mesh} {w}x{h} transfer: {n} pixels, shading partitions {:?}, best {best:.3} s", ctx.shading_partitions());
        return;
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
    println!("{mesh} {w}x{h} partition {pd}° edge {e}: {} points, subdivision {}, shading mesh {t_mesh:.3} s, frame best {best:.3} s", sm.points.len(), sm.subdivision);
}

/// Dev study (ignored): PRT and transfer vs Monte Carlo with the bake's adaptive refinement at several
/// thresholds, `GLINT_REFINE=mesh:threshold:1/min_edge:rounds[:cell_deg],... cargo test --test render
/// refine_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn refine_study() {
    let spec = std::env::var("GLINT_REFINE").unwrap_or_else(|_| "teapot:0.05:128:3".into());
    // One material per mesh, fitted on the mesh as imported, so that the rows differ only in the bake.
    let mut materials = std::collections::HashMap::new();
    for item in spec.split(',') {
        let f: Vec<&str> = item.split(':').collect();
        let (mesh, threshold, inv_edge, rounds): (&str, f64, f64, u32) = (f[0], f[1].parse().unwrap(), f[2].parse().unwrap(), f[3].parse().unwrap());
        let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
        let env = glint::env::load(&common::assets().join("hdr/small/studio_512.exr")).unwrap();
        let mut settings = BakeSettings::default();
        settings.refine = glint::bake::RefineSettings { rounds, threshold, min_edge: 1.0 / inv_edge, ..Default::default() };
        settings.cell_deg = f.get(4).and_then(|x| x.parse().ok());
        let t0 = std::time::Instant::now();
        let baker = Baker::new(&scene, &env, settings).unwrap();
        let bake = baker.bake_refined(None, &|_| {});
        let bake_secs = t0.elapsed().as_secs_f64();
        let refined = bake.scene(&scene).unwrap();
        let (baker_offset, set, tree) = (baker.ray_offset(), baker.set.clone(), baker.tree.clone());
        drop(baker);
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&refined.mesh);
        println!("{}", bake.decisions.refine_reason);
        let c = Case { scene: refined, env, baker_offset, tangents, set, tree, bake };
        let m = materials.entry(mesh.to_string()).or_insert_with(|| fitted(&case(mesh, "studio_512"))).clone();
        let lobes = m.lobes().unwrap();
        let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
        let camera = &c.scene.cameras[0];
        let (w, h) = (160, 120);
        let (prt, _, transfer) = prt_and_transfer(&c, &m, w, h);
        let material = ExactMaterial { lobes: &lobes, coefficients, rho_d: m.rho_d, f0: m.f0 };
        let tracer = glint::bake::Tracer::new(&scene.mesh);
        let (_, base_tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
        let mc = render_reference(&scene.mesh, base_tangents.as_deref(), &tracer, c.baker_offset, &c.env, 0.0, material, camera, w, h, 4096, 7);
        println!(
            "{item}: {} vertices, mean cut {:.0}, rays {}, bake {bake_secs:.2} s; vs MC: transfer {:.4}, PRT {:.4}",
            c.scene.mesh.positions.len(),
            c.bake.cuts.mean_cut_size(),
            c.bake.stats.rays_traced,
            transfer.relative_rmse(&mc).unwrap(),
            prt.relative_rmse(&mc).unwrap(),
        );
    }
}

/// Relative RMSE of `a` against `b` over the pixels both cover where `mask` holds (all with `None`):
/// the accuracy matrix's measure (`glint::accuracy::masked_rel_rmse`).
fn rmse_where(a: &glint::render::Image, b: &glint::render::Image, mask: Option<&[bool]>) -> f64 {
    let all;
    let mask = match mask {
        Some(m) => m,
        None => {
            all = vec![true; b.pixels.len()];
            &all
        }
    };
    glint::accuracy::masked_rel_rmse(a, b, mask).0
}

/// One sharp ring lobe along the normal (isotropic-24 at the paper's σ, λ = 81, only θ_j = 0 set,
/// scaled to a directional albedo of at most 0.9), ρd = 0.05, F0 = 0.04.
fn one_sharp_lobe() -> glint::fit::material::Material {
    use glint::sphere::srbf::{PAPER_SIGMA, lambda_from_sigma};
    let lobes = glint::sphere::LobeSet::new(glint::sphere::LobeLayout::Isotropic { count: 24 }, lambda_from_sigma(PAPER_SIGMA).unwrap()).unwrap();
    let mut c = vec![0.0; lobes.len()];
    c[0] = 1.0;
    let albedo = glint::brdf::energy::EnergyTable::cached(&lobes).albedo(&c, 0.04).into_iter().fold(0.0, f64::max);
    c[0] = 0.9 / albedo;
    glint::fit::material::Material::new(&lobes, PAPER_SIGMA, [c.clone(), c.clone(), c], [0.05; 3], 0.04, Default::default())
}

/// PRT (default settings, tabulated p) and Monte Carlo images of `m` for a case, a camera and a
/// rotation, the reference on the mesh as imported (`imported`).
struct Pair {
    prt: glint::render::Image,
    mc: glint::render::Image,
    prt_secs: f64,
    mc_secs: f64,
}

#[allow(clippy::too_many_arguments)]
fn prt_and_mc(c: &Case, imported: &glint::scene::Mesh, m: &glint::fit::material::Material, camera: &glint::scene::Camera, rotation_deg: f64, w: u32, h: u32, spp: u32, settings: PrtSettings) -> Pair {
    let lobes = m.lobes().unwrap();
    let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
    let rotation = rotation_deg.to_radians();
    let light = LightSums::new(&c.env, &c.set, &c.tree, rotation);
    let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), settings);
    let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let t0 = std::time::Instant::now();
    let img = prt.render(&light, camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) });
    let prt_secs = t0.elapsed().as_secs_f64();
    let (_, tangents, _) = glint::bake::decisions::decide_frames(imported);
    let tracer = glint::bake::Tracer::new(imported);
    let material = ExactMaterial { lobes: &lobes, coefficients, rho_d: m.rho_d, f0: m.f0 };
    let t0 = std::time::Instant::now();
    let mc = render_reference(imported, tangents.as_deref(), &tracer, c.baker_offset, &c.env, rotation, material, camera, w, h, spp, 7);
    Pair { prt: img, mc, prt_secs, mc_secs: t0.elapsed().as_secs_f64() }
}

/// Developer tool (not run by CI): issue 28's case (bunny under samples/studio_1k, orbit 20,15,2.5,
/// environment turned 90°, one sharp ring lobe) with one ingredient of the PRT frame switched at a
/// time, and its worst pixels. `cargo test --test render sharp_lobe_diagnose -- --ignored --nocapture`
/// (MESH=teapot, ORBIT=az,el,dist, ROT=deg, SPP=n).
#[test]
#[ignore]
fn sharp_lobe_diagnose() {
    let var = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let mesh = var("MESH", "bunny");
    let samples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let t0 = std::time::Instant::now();
    let c = case_at(&samples.join(format!("{mesh}.glb")), &samples.join("studio_1k.exr"), true);
    println!("bake {:.1} s, {} vertices", t0.elapsed().as_secs_f64(), c.scene.mesh.positions.len());
    let imported = glint::scene::import(&samples.join(format!("{mesh}.glb"))).unwrap().mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160, 120);
    let orbit: Vec<f32> = var("ORBIT", "20,15,2.5").split(',').map(|x| x.parse().unwrap()).collect();
    let camera = if orbit.len() == 3 { glint::scene::orbit_camera(&c.scene.bounds, orbit[0], orbit[1], orbit[2], w, h) } else { c.scene.cameras[0].clone() };
    let rot: f64 = var("ROT", "90").parse().unwrap();
    let spp: u32 = var("SPP", "2048").parse().unwrap();
    let base = prt_and_mc(&c, &imported, &m, &camera, rot, w, h, spp, PrtSettings::default());
    let mc = &base.mc;
    let sil = glint::accuracy::silhouette_mask(mc);
    println!("MC {:.1} s ({spp} spp), PRT {:.3} s; {} object pixels, {} silhouette", base.mc_secs, base.prt_secs, mc.covered_count(), sil.iter().filter(|&&s| s).count());
    let report = |label: &str, img: &glint::render::Image| {
        let (all, s) = (rmse_where(img, mc, None), rmse_where(img, mc, Some(&sil)));
        let interior: Vec<bool> = sil.iter().map(|x| !x).collect();
        println!("{label:>36}: object {:.2} %, silhouette {:.2} %, interior {:.2} %", 100.0 * all, 100.0 * s, 100.0 * rmse_where(img, mc, Some(&interior)));
    };
    report("default", &base.prt);
    if std::env::var("NOISE").is_ok() {
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&imported);
        let lobes = m.lobes().unwrap();
        let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
        let material = ExactMaterial { lobes: &lobes, coefficients, rho_d: m.rho_d, f0: m.f0 };
        let mc2 = render_reference(&imported, tangents.as_deref(), &glint::bake::Tracer::new(&imported), c.baker_offset, &c.env, rot.to_radians(), material, &camera, w, h, spp, 8);
        println!("MC noise (one image): object {:.2} %, silhouette {:.2} %", 100.0 * rmse_where(&mc2, mc, None) / 2f64.sqrt(), 100.0 * rmse_where(&mc2, mc, Some(&sil)) / 2f64.sqrt());
    }
    let lobes = m.lobes().unwrap();
    let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
    let light = LightSums::new(&c.env, &c.set, &c.tree, rot.to_radians());
    let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let d = PrtSettings::default();
    let variants = [
        ("exact lobes", d, true),
        ("no grazing tiers", PrtSettings { grazing_tiers: false, ..d }, false),
        ("no prefilter", PrtSettings { prefilter: false, ..d }, false),
        ("per run", PrtSettings { merge_runs: false, ..d }, false),
        ("texel lookups", PrtSettings { texel_lookups: true, ..d }, false),
        ("partition 4°", PrtSettings { partition_deg: 4.0, ..d }, false),
        ("partition 2°", PrtSettings { partition_deg: 2.0, ..d }, false),
        ("partition 1°", PrtSettings { partition_deg: 1.0, ..d }, false),
        ("partition 1° no prefilter", PrtSettings { partition_deg: 1.0, prefilter: false, ..d }, false),
        ("horizon leaves 1", PrtSettings { horizon_leaves: 1, ..d }, false),
        ("vertex shading", PrtSettings { per_pixel: false, max_edge_px: 0.0, ..d }, false),
    ];
    let mut images = Vec::new();
    for (label, settings, exact) in variants {
        let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), settings);
        let specular = if exact { Specular::Exact { lobes: &lobes, coefficients } } else { Specular::Table(&table) };
        let img = prt.render(&light, &camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular });
        report(label, &img);
        images.push((label, img));
    }
    let ctx = glint::transfer::TransferContext::new(&c.scene.mesh, &c.bake.cuts, &c.tree, &lobes, c.tangents.as_deref(), None);
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
            (((base.prt.pixels[k][1] - mc.pixels[k][1]) as f64).powi(2), k, wo_z)
        })
        .collect();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let total: f64 = rows.iter().map(|r| r.0).sum();
    let mut by_cos = [0.0f64; 5];
    for r in &rows {
        by_cos[[0.05, 0.15, 0.3, 0.6, 2.0].iter().position(|&b| r.2 < b).unwrap()] += r.0 / total;
    }
    println!("share of the squared error (G) by wo·n: <0.05 {:.2}, <0.15 {:.2}, <0.3 {:.2}, <0.6 {:.2}, ≥0.6 {:.2}", by_cos[0], by_cos[1], by_cos[2], by_cos[3], by_cos[4]);
    for r in rows.iter().take(12) {
        let k = r.1;
        let g = |img: &glint::render::Image| img.pixels[k][1];
        let vals: Vec<String> = images.iter().map(|(l, img)| format!("{l} {:.3}", g(img))).collect();
        println!("pixel ({}, {}) wo·n {:.3} sil {}: MC {:.3} PRT {:.3} transfer {:.3} | {}", k % w as usize, k / w as usize, r.2, sil[k], g(mc), g(&base.prt), g(&transfer), vals.join(", "));
    }
}

/// Issue 28: a sharp lobe seen at grazing angles. The bunny under samples/studio_1k, orbit 20,15,2.5,
/// the environment turned 90°, one sharp ring lobe along n ([`one_sharp_lobe`]); the PRT frame (per
/// pixel, the default) against the Monte Carlo reference over object pixels and over silhouette pixels
/// (object pixels with a background 4-neighbour). With one 8° partition for every point and the
/// pre-filter's geometric-mean spread the frame was 28.8 % off (silhouette 41.1 %); the peak-matched
/// spread alone 17.9 % (25.5 %, the "one partition" row printed here); with the grazing tiers 5.9 %
/// (8.2 %), which include the reference's own noise (2.2 % at 2048 spp). Not the issue's
/// goal (2 % / 4 %): with every point at 1° partitions the floor is still 5.9 %, so what remains is
/// not the partition (`sharp_lobe_diagnose` switches one ingredient at a time). `sharp_lobe_quadrature`
/// finds it: neither visibility (the cuts' V against rays: 0.45 % at wo·n < 0.3) nor
/// geometry, but the light's angular resolution: at wo·n ≈ 0.1 the lobe covers ≈ 2σ·wo·h ≈ 1° of wi
/// across the plane of wi and wo, less than a leaf (1.4° at 64 per side), and both the per-leaf constant
/// radiance (6.3 % at those pixels) and the BRDF taken once per leaf-sized node (5.5 % more against the
/// PRT's own inputs) miss it; resolved inside leaves at those pixels only, the frame is 3.2 % off MC.
#[test]
fn sharp_lobe_at_grazing_views_against_monte_carlo() {
    let samples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let c = case_at(&samples.join("bunny.glb"), &samples.join("studio_1k.exr"), true);
    let imported = glint::scene::import(&samples.join("bunny.glb")).unwrap().mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160, 120);
    let camera = glint::scene::orbit_camera(&c.scene.bounds, 20.0, 15.0, 2.5, w, h);
    let pair = prt_and_mc(&c, &imported, &m, &camera, 90.0, w, h, 2048, PrtSettings::default());
    let old = prt_and_mc(&c, &imported, &m, &camera, 90.0, w, h, 1, PrtSettings { grazing_tiers: false, ..PrtSettings::default() });
    let sil = glint::accuracy::silhouette_mask(&pair.mc);
    let (object, silhouette) = (rmse_where(&pair.prt, &pair.mc, None), rmse_where(&pair.prt, &pair.mc, Some(&sil)));
    let (old_object, old_silhouette) = (rmse_where(&old.prt, &pair.mc, None), rmse_where(&old.prt, &pair.mc, Some(&sil)));
    println!(
        "sharp lobe, orbit: {} object pixels, {} silhouette; PRT {:.3} s (one partition {:.3} s), MC {:.1} s; PRT vs MC: object {:.2} %, silhouette {:.2} % (one partition: {:.2} %, {:.2} %)",
        pair.mc.covered_count(),
        sil.iter().filter(|&&s| s).count(),
        pair.prt_secs,
        old.prt_secs,
        pair.mc_secs,
        100.0 * object,
        100.0 * silhouette,
        100.0 * old_object,
        100.0 * old_silhouette
    );
    assert!(object <= 0.065 && silhouette <= 0.09, "PRT vs MC: object {object}, silhouette {silhouette}");
}

/// Developer tool (not run by CI): issue 28's remaining error split by ingredient at chosen pixels, by
/// quadrature over the direction set's texels (k×k sub-directions each, env `K`, default 6; 4 suffices),
/// green channel, noise-free: Q_mc = Σ L(d) V_ray(d) f_r(d) cos dω with L read as the reference reads it
/// (nearest texel), on the imported mesh (what Monte Carlo estimates); on the PRT's (refined) mesh:
/// Q_geo (the same; its rays leave the refined mesh's smooth surface but hit the imported mesh, so a few
/// pixels self-shadow: an artefact of this tool), Q_leafL (L constant per leaf, as in `LightSums`),
/// Q_cutV (and V from the corners' cuts per leaf: the PRT's own inputs, the BRDF integrated exactly),
/// and Q with the map's own L and the cuts' V. Pixels: the `N` (default 40) worst by the PRT's error
/// against MC, `N` at random, and every `STRIDE`-th (default 3) seen at wo·n < `GZ` (default 0.3); the
/// last class is also patched into the PRT frame (RGB, map L, cut V) to show what resolving the light
/// and the BRDF inside leaves at those points would give against MC. `RES` bakes at that direction-set
/// resolution; `ALL` prints every pixel. Bunny, rotation 90°, K = 4, wo·n < 0.3 (251
/// pixels, 44 s): against Q_mc the PRT is 8.9 %, Q_leafL 6.3 %, Q_cutV 5.5 %, Q with map L and cut V
/// 0.45 %; the patched frame is 3.24 % off MC at 2048 spp (silhouette 4.02 %; unpatched 5.92 / 8.23 %).
/// `cargo test --test render sharp_lobe_quadrature -- --ignored --nocapture` (MESH, ORBIT, ROT, SPP).
#[test]
#[ignore]
fn sharp_lobe_quadrature() {
    use glam::{DVec3, Vec3A};
    let var = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let mesh = var("MESH", "bunny");
    let samples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let res: Option<usize> = std::env::var("RES").ok().map(|r| r.parse().unwrap());
    let c = {
        let (mesh, env) = (samples.join(format!("{mesh}.glb")), samples.join("studio_1k.exr"));
        let scene = glint::scene::import(&mesh).unwrap();
        let env = glint::env::load(&env).unwrap();
        let baker = Baker::new(&scene, &env, BakeSettings { resolution: res, ..BakeSettings::default() }).unwrap();
        let bake = baker.bake_refined(None, &|_| {});
        let offset = baker.ray_offset();
        let (set, tree) = (baker.set.clone(), baker.tree.clone());
        drop(baker);
        let scene = bake.scene(&scene).unwrap();
        let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
        Case { scene, env, baker_offset: offset, bake, tangents, set, tree }
    };
    println!("direction set {} per side", c.set.resolution());
    let imported = glint::scene::import(&samples.join(format!("{mesh}.glb"))).unwrap().mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160u32, 120u32);
    let orbit: Vec<f32> = var("ORBIT", "20,15,2.5").split(',').map(|x| x.parse().unwrap()).collect();
    let camera = glint::scene::orbit_camera(&c.scene.bounds, orbit[0], orbit[1], orbit[2], w, h);
    let rot: f64 = var("ROT", "90").parse().unwrap();
    let spp: u32 = var("SPP", "1024").parse().unwrap();
    let kk: usize = var("K", "6").parse().unwrap();
    let npx: usize = var("N", "40").parse().unwrap();
    let pair = prt_and_mc(&c, &imported, &m, &camera, rot, w, h, spp, PrtSettings::default());
    let sil = glint::accuracy::silhouette_mask(&pair.mc);
    println!("PRT {:.3} s; PRT vs MC ({spp} spp): object {:.2} %, silhouette {:.2} %", pair.prt_secs, 100.0 * rmse_where(&pair.prt, &pair.mc, None), 100.0 * rmse_where(&pair.prt, &pair.mc, Some(&sil)));
    let lobes = m.lobes().unwrap();
    let light = LightSums::new(&c.env, &c.set, &c.tree, rot.to_radians());
    let tracer = glint::bake::Tracer::new(&imported);
    let eye = camera.eye().as_dvec3();
    let mut texel_leaf = vec![0usize; c.set.len()];
    for (l, &t) in c.tree.leaf_texels().iter().enumerate() {
        texel_leaf[t as usize] = l;
    }
    let frags_ref = glint::raster::rasterize(&c.scene.mesh, &camera, w, h);
    let frags_imp = glint::raster::rasterize(&imported, &camera, w, h);
    let at = |fr: &[glint::raster::Fragment], k: usize| fr.iter().find(|f| (f.y * w + f.x) as usize == k).copied();
    // Candidate pixels.
    let mut rows: Vec<(f64, usize)> = frags_ref.iter().map(|f| (f.y * w + f.x) as usize).filter(|&k| pair.mc.covered[k]).map(|k| (((pair.prt.pixels[k][1] - pair.mc.pixels[k][1]) as f64).powi(2), k)).collect();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut chosen: Vec<usize> = rows.iter().take(npx).map(|r| r.1).collect();
    let mut rng = glint::math::rng::Rng::new(11);
    for _ in 0..npx {
        chosen.push(rows[(rng.next_f64() * rows.len() as f64) as usize].1);
    }
    // Then every `STRIDE`-th pixel seen at wo·n < 0.3 (class G).
    let stride: usize = var("STRIDE", "3").parse().unwrap();
    let gz: f64 = var("GZ", "0.3").parse().unwrap();
    let grazing: Vec<usize> = frags_ref
        .iter()
        .filter(|f| {
            let tri = c.scene.mesh.triangles[f.triangle as usize];
            let p: DVec3 = (0..3).map(|i| c.scene.mesh.positions[tri[i] as usize].as_dvec3() * f.bary[i] as f64).sum();
            let n = (0..3).map(|i| c.scene.mesh.normals[tri[i] as usize].as_dvec3() * f.bary[i] as f64).sum::<DVec3>().normalize();
            let won = (eye - p).normalize().dot(n);
            won > 0.0 && won < gz
        })
        .map(|f| (f.y * w + f.x) as usize)
        .step_by(stride)
        .collect();
    chosen.extend(grazing);
    let variants: Vec<glint::render::Image> = [PrtSettings { partition_deg: 1.0, ..PrtSettings::default() }, PrtSettings { partition_deg: 1.0, prefilter: false, ..PrtSettings::default() }]
        .into_iter()
        .map(|s| {
            let prt = Prt::new(&c.scene.mesh, &c.bake.cuts, &c.tree, c.tangents.as_deref(), s);
            let coefficients = [m.coefficients[0].as_slice(), m.coefficients[1].as_slice(), m.coefficients[2].as_slice()];
            let table = PhTable::build(&lobes, coefficients, default_resolution(lobes.lambda()));
            prt.render(&light, &camera, w, h, &Shading { rho_d: m.rho_d, f0: m.f0, specular: Specular::Table(&table) })
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
        let p: DVec3 = (0..3).map(|i| mesh.positions[tri[i] as usize].as_dvec3() * b[i]).sum();
        let n = (0..3).map(|i| mesh.normals[tri[i] as usize].as_dvec3() * b[i]).sum::<DVec3>().normalize();
        let corners = [(tri[0], b[0]), (tri[1], b[1]), (tri[2], b[2])];
        let o = glint::scene::smooth_surface_point(mesh, &corners, p) + n * c.baker_offset;
        (p, n, glint::sphere::Frame::from_normal(n), corners, o)
    };
    let leaves = c.tree.leaf_count();
    let mut acc = [[[0.0f64; 2]; 7]; 3];
    let mut agg = [[0.0f64; 4]; 3]; // per class: Σ (PRT − Q_cutV)², Σ Q_cutV², Σ (PRT 1° unfiltered − Q_cutV)², Σ (Q_cutV − Q_mc)² over Q_mc² ...  // per class W, R, G: (Σ (x − Q_mc)², Σ Q_mc²) for MC, PRT, Q_geo, Q_leafL, Q_cutV, PRT 1°, PRT 1° unfiltered
    let t0 = std::time::Instant::now();
    // The PRT frame with the grazing pixels replaced by Q with the map's own L and the cuts' V (RGB):
    // what supersampling the specular term inside leaves at those points could reach.
    let mut patched = pair.prt.clone();
    println!("pixel        wo.n   MC     Q_mc   Q_geo  Q_leafL Q_cutV PRT   (G)");
    for (i, &k) in chosen.iter().enumerate() {
        let (Some(fa), Some(fb)) = (at(&frags_imp, k), at(&frags_ref, k)) else { continue };
        let mut q = [0.0f64; 5];
        let mut q_rgb = [0.0f64; 3];
        for (gi, (mesh, f)) in [(&imported, fa), (&c.scene.mesh, fb)].into_iter().enumerate() {
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
                    let vray = if tracer.occluded(o, Vec3A::new(d.x as f32, d.y as f32, d.z as f32)) { 0.0 } else { 1.0 };
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
        let (p1, p1n) = (variants[0].pixels[k][1] as f64, variants[1].pixels[k][1] as f64);
        let class = if i < npx { 0 } else if i < 2 * npx { 1 } else { 2 };
        if class == 2 {
            patched.set((k % w as usize) as u32, (k / w as usize) as u32, q_rgb.map(|x| x as f32));
        }
        if class < 2 || std::env::var("ALL").is_ok() || (q[1] - q[0]).abs() > 0.03 * q[0] || (prt - q[3]).abs() > 0.1 * q[3] {
            println!("({:3},{:3}) {} {:.3} {:.4} {:.4} {:.4} {:.4} {:.4} {:.4} | 1° {:.4} 1°np {:.4}", k % w as usize, k / w as usize, ["W", "R", "G"][class], won, mc, q[0], q[1], q[2], q[3], prt, p1, p1n);
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
        println!("{name} pixels, relative RMSE against Q_mc: MC {:.2} %, PRT {:.2} %, Q_geo {:.2} %, Q_leafL {:.2} %, Q_cutV {:.2} %, PRT 1° {:.2} %, PRT 1° unfiltered {:.2} %", r(0), r(1), r(2), r(3), r(4), r(5), r(6));
        println!("    against Q_cutV (the PRT's own inputs): PRT {:.2} %, PRT 1° unfiltered {:.2} %; Q with the map's own L and the cuts' V against Q_mc: {:.2} %", 100.0 * (agg[class][0] / agg[class][1]).sqrt(), 100.0 * (agg[class][2] / agg[class][1]).sqrt(), 100.0 * (agg[class][3] / acc[class][0][1]).sqrt());
    }
    println!("{} pixels in {:.1} s", chosen.len(), t0.elapsed().as_secs_f64());
    println!("PRT with the grazing pixels (every {stride}th) patched: vs MC object {:.2} %, silhouette {:.2} % (unpatched {:.2} %, {:.2} %)", 100.0 * rmse_where(&patched, &pair.mc, None), 100.0 * rmse_where(&patched, &pair.mc, Some(&sil)), 100.0 * rmse_where(&pair.prt, &pair.mc, None), 100.0 * rmse_where(&pair.prt, &pair.mc, Some(&sil)));
}
