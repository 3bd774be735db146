//! Bake and transfer benchmarks: `cargo bench --bench bake --no-default-features`.
//!
//! Inputs: dragon_100k.glb (49,892 vertices) under courtyard_1k, default bake settings (decisions
//! made and the mesh refined, as `glint bake` does). Prints, per run (two runs, so the second shows
//! warm caches): the bake's seconds (decisions and refinement included), rays and the refined
//! vertex count; then, for the isotropic J = 24 lobe set at σ = π/40, the light sums (from scratch,
//! and from a kept `LightSource` as the app makes them) and the transfer at 160×120 from the
//! default camera for two rotations of the environment — what a new view or a rotated light costs:
//! the median of 5 computes with the fastest and slowest (one compute is ~45 ms, so a single one
//! reads the machine's noise as much as the code).

use glint::bake::{BakeSettings, Baker};
use glint::light::LightSums;
use glint::sphere::{LobeLayout, LobeSet, srbf};
use std::time::Instant;

#[path = "../tests/it/common.rs"]
mod common;

fn main() {
    let scene = glint::scene::import(&common::assets().join("glb/dragon_100k.glb")).unwrap();
    let env = glint::env::load(&common::assets().join("hdr/courtyard_1k.exr")).unwrap();
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
    )
    .unwrap();
    let camera = glint::scene::default_camera(&scene.bounds);
    println!(
        "| run | bake (s) | deciding (s) | vertices | rays | rays/s | bytes/vertex | rotation | light sums (s) | light sums, kept source (s) | transfer 160×120 (s), median of 5 (min–max) | pixels |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for run in 1..=2 {
        let t = Instant::now();
        let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
        let bake = baker.bake_refined(None, &|_| {});
        let bake_secs = t.elapsed().as_secs_f64();
        let s = &bake.stats;
        let mesh = bake.mesh(&scene.mesh).unwrap();
        let ctx = glint::transfer::TransferContext::new(
            &mesh,
            &bake.cuts,
            &baker.tree,
            &lobes,
            None,
            None,
        );
        // The app keeps the environment's sample points (a `LightSource`) and rotates by a shift in
        // u.
        let source = glint::light::LightSource::new(&env);
        std::hint::black_box(LightSums::from_source(
            &source,
            &baker.set,
            &baker.tree,
            0.0,
        ));
        for rotation in [0.0, 0.7] {
            let t = Instant::now();
            let light = LightSums::new(&env, &baker.set, &baker.tree, rotation);
            let light_secs = t.elapsed().as_secs_f64();
            let t = Instant::now();
            std::hint::black_box(LightSums::from_source(
                &source,
                &baker.set,
                &baker.tree,
                rotation + 0.1,
            ));
            let source_secs = t.elapsed().as_secs_f64();
            let transfer = ctx.compute(&light, &camera, 160, 120, 0.04);
            let mut times: Vec<f64> = std::iter::once(transfer.seconds)
                .chain((1..5).map(|_| ctx.compute(&light, &camera, 160, 120, 0.04).seconds))
                .collect();
            times.sort_by(f64::total_cmp);
            println!(
                "| {run} | {bake_secs:.2} | {:.2} | {} | {} | {:.2} M | {:.0} | {rotation} | {light_secs:.3} | {source_secs:.3} | {:.3} ({:.3}–{:.3}) | {} |",
                s.decision_seconds,
                s.vertices,
                s.rays_traced,
                s.rays_traced as f64 / (bake_secs - s.decision_seconds).max(1e-9) / 1e6,
                s.bytes_per_vertex,
                times[2],
                times[0],
                times[4],
                transfer.pixels.len()
            );
        }
    }
}
