//! Fallback benchmarks: `cargo bench --bench fallback`. The glTF and UsdPreviewSurface fallbacks of
//! two materials, with the time each step takes (median of 3 runs) and the errors before (the
//! one-lobe fallback) and after (the layered one).
//!
//! Materials: the demo material (the sample strokes fitted on the bunny under samples/studio_1k,
//! default view) and one sharp ring lobe along the normal (λ = 81, ρd = 0.05). Each is fitted with
//! uniform weighting (no scene) and with the scene's weighting: the bunny under studio_1k seen
//! from the default camera (demo) and from the orbit 20°, 15°, 2.5 radii (sharp lobe).
//!
//! `cargo bench --bench fallback -- floor`: instead, the glTF model's floor under the scene's
//! weighting (`layered_fallback::model_floor`: 32 random starts over every isotropic parameter,
//! then a coloured specular colour), beside the exported fit, for the demo material, the sharp
//! key-light highlight (samples/strokes/bunny-key-light.json fitted on the same bunny, default
//! view) and the sharp lobe; with the clearcoat's roughness floored as exported and with it free
//! down to 0.02.

use glint::export::{
    layered_fallback::{MIN_COAT_ROUGHNESS, Objective, fit_gltf, fit_preview, model_floor},
    material_fallback, scene_camera, scene_environment, scene_mesh,
};
use glint::render::table::PhPyramid;
use std::time::Instant;

#[path = "../tests/it/common.rs"]
mod common;
#[path = "../tests/it/render_cases.rs"]
mod render_cases;
#[path = "support/timing.rs"]
mod timing;

/// The material's lobes and its p(h) table at the export's default resolution.
fn table_of(
    material: &glint::fit::material::Material,
) -> anyhow::Result<(glint::sphere::LobeSet, PhPyramid)> {
    let lobes = material.lobes()?;
    let coefficients = [
        material.coefficients[0].as_slice(),
        material.coefficients[1].as_slice(),
        material.coefficients[2].as_slice(),
    ];
    let table = PhPyramid::build_unfiltered(&lobes, coefficients, 512);
    Ok((lobes, table))
}

/// The case's mesh as the export describes it, seen from `camera` under the case's map.
fn scene_for(
    c: &render_cases::Case,
    camera: &glint::scene::Camera,
    w: u32,
    h: u32,
) -> glint_exporters::SceneMesh {
    let mut mesh = scene_mesh(&c.scene.mesh, c.tangents.as_deref());
    mesh.camera = Some(scene_camera(camera, w, h));
    mesh.environment = Some(scene_environment(&c.env, 0.0));
    mesh
}

fn main() {
    if let Err(e) = run() {
        eprintln!("fallback bench: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let samples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let c = render_cases::case_at(
        &samples.join("bunny.glb"),
        &samples.join("studio_1k.exr"),
        true,
    );
    let (w, h) = (640, 480);
    let default_camera = glint::scene::view::render_view(&c.scene, None, None, Some("640x480"))?.0;
    let orbit = glint::scene::orbit_camera(&c.scene.bounds, 20.0, 15.0, 2.5, w, h);
    if std::env::args().any(|a| a == "floor") {
        let key_light =
            render_cases::fitted_with(&c, include_str!("../samples/strokes/bunny-key-light.json"));
        let materials = [
            ("demo", render_cases::fitted(&c), default_camera.clone()),
            ("key light", key_light, default_camera),
            ("sharp lobe", render_cases::one_sharp_lobe(), orbit),
        ];
        println!(
            "| material | exported glTF fit | floor, coat roughness ≥ {MIN_COAT_ROUGHNESS} | with a coloured specular | floor, coat roughness ≥ 0.02 | floor's parameters (coat ≥ {MIN_COAT_ROUGHNESS}) | seconds |"
        );
        println!("|---|---|---|---|---|---|---|");
        for (name, material, camera) in materials {
            let (lobes, table) = table_of(&material)?;
            let one = material_fallback(&material, &lobes, &table);
            let mesh = scene_for(&c, &camera, w, h);
            let objective = Objective::new(&table, material.rho_d, material.f0, Some(&mesh));
            let gltf = fit_gltf(&objective, &one.fallback);
            let t = Instant::now();
            let floor = model_floor(&objective, 32, 7, MIN_COAT_ROUGHNESS);
            let secs = t.elapsed().as_secs_f64();
            let free = model_floor(&objective, 32, 7, 0.02);
            let pct =
                |e: (f64, f64)| format!("{:.2} % (uniform {:.1} %)", e.0 * 100.0, e.1 * 100.0);
            println!(
                "| {name} | {} | {} | {} | {} | {:.3?} | {secs:.1} |",
                pct((gltf.relative_error, gltf.uniform_relative_error)),
                pct(floor.grey),
                pct(floor.coloured_specular),
                pct(free.grey),
                floor.params,
            );
        }
        return Ok(());
    }
    let materials = [
        ("demo", render_cases::fitted(&c), default_camera),
        ("sharp lobe", render_cases::one_sharp_lobe(), orbit),
    ];
    for (name, material, camera) in materials {
        let (lobes, table) = table_of(&material)?;
        let (t_one, one) = timing::median_of(3, || material_fallback(&material, &lobes, &table));
        let mesh = scene_for(&c, &camera, w, h);
        for scene in [None, Some(&mesh)] {
            let (t_sets, objective) = timing::median_of(3, || {
                Objective::new(&table, material.rho_d, material.f0, scene)
            });
            let (t_gltf, gltf) = timing::median_of(3, || fit_gltf(&objective, &one.fallback));
            let (t_usd, usd) = timing::median_of(3, || fit_preview(&objective, &gltf));
            println!(
                "{name}, {} weighting: one-lobe fit {t_one:.3} s, pairs {t_sets:.3} s, glTF {t_gltf:.3} s, USD {t_usd:.3} s; total {:.3} s",
                objective.weighting().name(),
                t_one + t_sets + t_gltf + t_usd
            );
            println!(
                "  before (one-lobe): {:.1} % (its own measure: {:.1} %); after: {}",
                gltf.one_lobe_relative_error * 100.0,
                one.fallback.relative_error * 100.0,
                gltf.summary(material.layout.is_isotropic())
            );
            println!("  {}", usd.summary());
        }
    }
    Ok(())
}
