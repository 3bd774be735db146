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
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
    let env = glint::env::load(&common::assets().join(format!("hdr/small/{env}.exr"))).unwrap();
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
