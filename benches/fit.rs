//! Fit benchmarks: `cargo bench --bench fit`. Prints median times over repeated runs.
//!
//! Problems: the real transfer of the bunny under courtyard (default view, isotropic J = 24) at the
//! fit resolution 160×120 and at full resolution 640×480; and transfers of the same size with J =
//! 147 and J = 300 lobes (the paper's anisotropic count and a finer one), built from a UV sphere
//! with a tangent field so that anisotropic lobes apply. 256 energy rows (anisotropic) / 33
//! (isotropic).

use glint::bake::{BakeSettings, Baker};
use glint::fit::problem::{ViewData, normal_equations, solve_rgb};
use glint::fit::qp::{HotStart, QpSolver};
use glint::light::LightSums;
use glint::scene::Scene;
use glint::sphere::{LobeLayout, LobeSet, srbf};
use glint::transfer::{Transfer, TransferContext};
use std::path::Path;

#[path = "../tests/it/common.rs"]
mod common;
#[path = "support/timing.rs"]
mod timing;

/// Median milliseconds of `n` runs of `f` ([`timing::time`]).
fn time<T>(n: usize, f: impl FnMut() -> T) -> f64 {
    timing::time(n, f) * 1e3
}

/// [`time`] for a fallible `f`.
fn try_time<T, E>(n: usize, f: impl FnMut() -> Result<T, E>) -> Result<f64, E> {
    timing::try_time(n, f).map(|secs| secs * 1e3)
}

fn transfer_for(
    scene: &Scene,
    env: &glint::env::EnvMap,
    layout: LobeLayout,
    size: (u32, u32),
) -> anyhow::Result<(Transfer, LobeSet)> {
    let baker = Baker::new(
        scene,
        env,
        BakeSettings {
            resolution: Some(32),
            ..BakeSettings::default()
        },
    )?;
    let bake = baker.bake_all(None, &|_| {});
    let lobes = LobeSet::new(layout, srbf::lambda_from_sigma(srbf::PAPER_SIGMA)?)?;
    let light = LightSums::new(env, &baker.set, &baker.tree, 0.0);
    let mut camera = scene.cameras[0].clone();
    camera.width = size.0 * 4;
    camera.height = size.1 * 4;
    let ctx = TransferContext::new(
        &scene.mesh,
        &bake.cuts,
        &baker.tree,
        &lobes,
        baker.tangents.as_deref(),
        None,
    );
    Ok((ctx.compute(&light, &camera, size.0, size.1, 0.04), lobes))
}

fn bench(label: &str, transfer: &Transfer, lobes: &LobeSet) -> anyhow::Result<()> {
    if !selected(label) {
        return Ok(());
    }
    let energy = glint::brdf::EnergyTable::with_defaults(lobes);
    let n = transfer.pixels.len();
    // A bright stroke's worth of targets over a third of the pixels, keep weight elsewhere.
    let zero = vec![0.0; lobes.len()];
    let current = transfer.render([0.5; 3], [&zero, &zero, &zero]);
    let target: Vec<[f64; 3]> = current
        .iter()
        .enumerate()
        .map(|(i, b)| {
            if i % 3 == 0 {
                [b[0] + 1.5, b[1] + 1.2, b[2] + 1.0]
            } else {
                *b
            }
        })
        .collect();
    let weight: Vec<f64> = (0..n).map(|i| if i % 3 == 0 { 1.0 } else { 0.1 }).collect();
    let data = [ViewData {
        transfer,
        target: &target,
        weight: &weight,
    }];
    let form = time(5, || {
        (0..3)
            .map(|c| normal_equations(&data, c, 0.5))
            .collect::<Vec<_>>()
    });
    let cold = try_time(5, || solve_rgb(&data, Some((&energy, 0.04)), [0.5; 3]))?;
    // Warm and hot re-solves after a small stroke (q changes by a few % on 10 % of the lobes).
    let eq = normal_equations(&data, 0, 0.5);
    let solver = QpSolver::new(
        &eq.h,
        eq.j,
        &energy.matrix(0.04),
        &vec![0.5; energy.rows()],
        energy.rows(),
    )?;
    let q: Vec<f64> = eq.r.iter().map(|x| -x).collect();
    let first = solver.solve(&q, None)?;
    let plain = solver.solve_unseeded(&q)?;
    let cold_seeded = try_time(5, || solver.solve(&q, None))?;
    let cold_plain = try_time(5, || solver.solve_unseeded(&q))?;
    let rows = first
        .active
        .iter()
        .filter(|c| matches!(c, glint::fit::qp::Constraint::Row(_)))
        .count();
    let q2: Vec<f64> = q
        .iter()
        .enumerate()
        .map(|(i, x)| if i % 10 == 0 { x * 1.03 } else { *x })
        .collect();
    let warm = try_time(20, || solver.solve(&q2, Some(&first.active)))?;
    let mut hot = HotStart::default();
    solver.solve_hot(&q, &mut hot)?;
    let hot_ms = try_time(20, || {
        let mut h = hot.clone();
        solver.solve_hot(&q2, &mut h)
    })?;
    println!(
        "{label}: N = {n} pixels, J = {}, {} energy rows | form H (RGB) {form:.2} ms | cold fit incl. H (RGB) {cold:.2} ms | warm re-solve {warm:.3} ms/channel | hot re-solve {hot_ms:.3} ms/channel",
        lobes.len(),
        energy.rows()
    );
    println!(
        "    red channel cold: seeded {cold_seeded:.3} ms ({} GI iterations), plain GI {cold_plain:.3} ms ({} iterations); {} active ({rows} energy rows)",
        first.iterations,
        plain.iterations,
        first.active.len()
    );
    Ok(())
}

/// `GLINT_BENCH_ONLY=640x480 cargo bench --bench fit` runs only the rows whose label contains it.
fn selected(label: &str) -> bool {
    std::env::var("GLINT_BENCH_ONLY").map_or(true, |f| label.contains(&f))
}

fn main() {
    if let Err(e) = run() {
        eprintln!("fit bench: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    let env = glint::env::load(&assets.join("hdr/small/courtyard_512.exr"))?;
    let bunny = glint::scene::import(&assets.join("glb/bunny.glb"))?;
    let iso = LobeLayout::Isotropic { count: 24 };
    for size in [(160, 120), (640, 480)] {
        let label = format!("bunny {}x{}, isotropic", size.0, size.1);
        if selected(&label) {
            let (t, l) = transfer_for(&bunny, &env, iso, size)?;
            bench(&label, &t, &l)?;
        }
    }
    // A tangent-carrying sphere (1.6 K pixels at 160x120 with the default camera ~ the paper's N).
    let sphere = sphere_scene();
    for layout in [LobeLayout::PAPER, LobeLayout::Fibonacci { count: 300 }] {
        for size in [(160, 120), (200, 150), (640, 480)] {
            let label = format!("sphere {}x{}, {}", size.0, size.1, layout.name());
            if selected(&label) {
                let (t, l) = transfer_for(&sphere, &env, layout, size)?;
                bench(&label, &t, &l)?;
            }
        }
    }
    Ok(())
}

fn sphere_scene() -> Scene {
    common::scene_from_mesh(common::uv_sphere(0.5, 64, 32, true))
}
