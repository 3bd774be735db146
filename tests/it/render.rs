//! The renderers against each other (method.md §7): the CPU PRT render (default settings,
//! tabulated p) against the Monte Carlo reference (exact visibility, exact lobes, the environment
//! map itself, 4096 spp) on the bunny and the teapot; the table against the exact lobe sum; a white
//! furnace.

use crate::common;
use crate::render_cases::*;

use glint::bake::{BakeSettings, Baker};
use glint::env::EnvMap;

use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, Specular};

use glint::render::table::{PhPyramid, default_resolution};

// The goal is PRT vs Monte Carlo within 2 %: met (bunny 1.27 %, teapot 1.70 %),
// baked as `glint bake` does — the mesh refined where visibility changes (decision (e)) and, under
// the studio's small bright lights, cells at shadow edges traced again at half and a quarter of the
// cell (decision (d)'s boundary refinement; 2.11 % and 3.40 % without it) — and shaded per pixel.
// The frame is within 0.5 % of the per-pixel transfer render, which shares the cuts. The bounds are
// the goal, so a regression past it (a bake that stops refining cells or the mesh, a frame that
// interpolates again) fails.
#[test]
fn prt_against_monte_carlo_on_the_bunny() {
    let e = compare("bunny", 160, 120);
    assert!(
        e.prt_vs_transfer <= 0.01,
        "PRT vs per-pixel transfer {}",
        e.prt_vs_transfer
    );
    assert!(e.prt_vs_mc <= 0.02, "PRT vs Monte Carlo {}", e.prt_vs_mc);
}

#[test]
fn prt_against_monte_carlo_on_the_teapot() {
    let e = compare("teapot", 160, 120);
    assert!(
        e.prt_vs_transfer <= 0.01,
        "PRT vs per-pixel transfer {}",
        e.prt_vs_transfer
    );
    assert!(e.prt_vs_mc <= 0.02, "PRT vs Monte Carlo {}", e.prt_vs_mc);
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
        for settings in [
            PrtSettings::default(),
            PrtSettings {
                partition_deg: 30.0,
                ..PrtSettings::default()
            },
        ] {
            let prt = Prt::new(&scene.mesh, &bake.cuts, &baker.tree, None, settings);
            let shading = Shading {
                rho_d: [1.0; 3],
                f0: 0.04,
                specular: Specular::None,
            };
            let mut worst = 0.0f64;
            for v in 0..scene.mesh.positions.len() as u32 {
                let p = glint::render::prt::ShadingPoint {
                    corners: [v; 3],
                    bary: [1.0, 0.0, 0.0],
                };
                let got =
                    prt.shade_point(&p, &light, glam::DVec3::new(0.0, 0.0, 10.0), &shading)[0];
                let n = scene.mesh.normals[v as usize].as_dvec3();
                let want = 1.0 + 2.0 / 3.0 * a.dot(n);
                worst = worst.max((got - want).abs() / want);
            }
            println!(
                "a = {a}, partition {}°: worst relative error {worst:.2e}",
                settings.partition_deg
            );
            assert!(worst < 2e-3, "a = {a}: {worst}");
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
        let co = [
            m.coefficients[0].as_slice(),
            m.coefficients[1].as_slice(),
            m.coefficients[2].as_slice(),
        ];
        let table = PhPyramid::build(&lobes, co, default_resolution(lobes.lambda()));
        let halved: Vec<Vec<f64>> = m
            .coefficients
            .iter()
            .map(|ch| ch.iter().map(|x| 0.5 * x).collect())
            .collect();
        let table2 = PhPyramid::build(
            &lobes,
            [&halved[0], &halved[1], &halved[2]],
            default_resolution(lobes.lambda()),
        );
        for max_edge_px in [0.0, 2.0] {
            let prt = Prt::new(
                &c.scene.mesh,
                &c.bake.cuts,
                &c.tree,
                c.tangents.as_deref(),
                PrtSettings {
                    partition_deg: 16.0,
                    max_edge_px,
                    per_pixel: false,
                    ..PrtSettings::default()
                },
            );
            let mut cache = glint::render::VertexLight::default();
            let cameras = [
                c.scene.cameras[0].clone(),
                glint::scene::orbit_camera(&c.scene.bounds, 70.0, 25.0, 0.0, 160, 120),
            ];
            for (k, camera) in cameras.iter().enumerate() {
                for (t, rho_d) in [(&table, m.rho_d), (&table2, [0.3, 0.4, 0.5])] {
                    let shading = Shading {
                        rho_d,
                        f0: m.f0,
                        specular: Specular::Table(t),
                    };
                    let direct = prt.render(&light, camera, 160, 120, &shading);
                    let cached = prt.render_cached(&mut cache, &light, camera, 160, 120, &shading);
                    let e = cached.relative_rmse(&direct).unwrap();
                    assert!(
                        e < 1e-6,
                        "{mesh}, edge {max_edge_px}, view {k}: cached vs direct {e}"
                    );
                    assert_eq!(cached.covered, direct.covered);
                }
                assert!(cache.cached_vertices() > 0, "{mesh}: the cache was filled");
            }
        }
    }
}

/// Issue 28: a sharp lobe seen at grazing angles. The bunny under samples/studio_1k, orbit
/// 20,15,2.5, the environment turned 90°, one sharp ring lobe along n ([`one_sharp_lobe`]); the PRT
/// frame (per pixel, the default) against the Monte Carlo reference over object pixels and over
/// silhouette pixels (object pixels with a background 4-neighbour), the reference's own noise (a
/// second seed) taken out in quadrature. With one 8° partition for every point and the pre-filter's
/// geometric-mean spread the frame was 28.8 % off (silhouette 41.1 %); the peak-matched spread
/// alone 17.9 % (25.5 %); with the grazing tiers 5.9 % (8.2 %). What remained was the light's
/// angular resolution (`render_studies -- sharp_lobe_quadrature`): at wo·n ≈ 0.1 the lobe covers
/// ≈ 2σ·wo·h ≈ 1° of wi across the plane of wi and wo, less than a leaf (1.4° at 64 per side), and
/// both the per-leaf constant radiance and the BRDF taken once per leaf-sized run miss it. With
/// the brightest runs of grazing points integrated inside their leaves
/// ([`PrtSettings::resolve_leaves`], the default) the frame is within the goal (2 % over
/// object pixels, 4 % over silhouette pixels, less the reference's noise); the "runs only" row
/// printed is the frame without it, against the same reference.
#[test]
fn sharp_lobe_at_grazing_views_against_monte_carlo() {
    let samples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let c = case_at(
        &samples.join("bunny.glb"),
        &samples.join("studio_1k.exr"),
        true,
    );
    let imported = glint::scene::import(&samples.join("bunny.glb"))
        .unwrap()
        .mesh;
    let m = one_sharp_lobe();
    let (w, h) = (160, 120);
    let spp = 2048;
    let camera = glint::scene::orbit_camera(&c.scene.bounds, 20.0, 15.0, 2.5, w, h);
    let pair = prt_and_mc(
        &c,
        &imported,
        &m,
        &camera,
        90.0,
        w,
        h,
        spp,
        PrtSettings::default(),
    );
    let runs_only = prt_and_mc(
        &c,
        &imported,
        &m,
        &camera,
        90.0,
        w,
        h,
        1,
        PrtSettings {
            resolve_leaves: false,
            ..PrtSettings::default()
        },
    );
    let second = mc_render(&c, &imported, &m, &camera, 90.0, (w, h), spp, 8);
    let sil = glint::accuracy::silhouette_mask(&pair.mc);
    let noise =
        |mask: Option<&[bool]>| rmse_where(&second, &pair.mc, mask) / std::f64::consts::SQRT_2;
    let less = |e: f64, n: f64| (e * e - n * n).max(0.0).sqrt();
    let (noise_object, noise_silhouette) = (noise(None), noise(Some(&sil)));
    let (object, silhouette) = (
        rmse_where(&pair.prt, &pair.mc, None),
        rmse_where(&pair.prt, &pair.mc, Some(&sil)),
    );
    let (old_object, old_silhouette) = (
        rmse_where(&runs_only.prt, &pair.mc, None),
        rmse_where(&runs_only.prt, &pair.mc, Some(&sil)),
    );
    println!(
        "sharp lobe, orbit: {} object pixels, {} silhouette; PRT {:.3} s (runs only {:.3} s), MC {:.1} s at {spp} spp; \
         PRT vs MC: object {:.2} %, silhouette {:.2} % (runs only: {:.2} %, {:.2} %); MC noise {:.2} %, {:.2} %; \
         less noise: object {:.2} %, silhouette {:.2} % (runs only: {:.2} %, {:.2} %)",
        pair.mc.covered_count(),
        sil.iter().filter(|&&s| s).count(),
        pair.prt_secs,
        runs_only.prt_secs,
        pair.mc_secs,
        100.0 * object,
        100.0 * silhouette,
        100.0 * old_object,
        100.0 * old_silhouette,
        100.0 * noise_object,
        100.0 * noise_silhouette,
        100.0 * less(object, noise_object),
        100.0 * less(silhouette, noise_silhouette),
        100.0 * less(old_object, noise_object),
        100.0 * less(old_silhouette, noise_silhouette),
    );
    assert!(
        less(object, noise_object) <= 0.02 && less(silhouette, noise_silhouette) <= 0.04,
        "PRT vs MC less its noise: object {object} (noise {noise_object}), silhouette {silhouette} (noise {noise_silhouette})"
    );
}
