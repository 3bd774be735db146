//! Bake, transfer and energy-table benchmarks: `cargo bench --bench bake --no-default-features [--
//! SECTION… MESH… MAP…]`, sections `energy`, `rays`, `matrix`, `view`, `million` (default: all);
//! mesh and map names narrow the matrix.
//!
//! - `energy`: the energy table of the paper's layout (hemicube-7, J = 147, σ = π/40, 257 × 147
//!   entries) and the isotropic J = 24 set: integrated entry by entry (each (row, lobe) pair on its
//!   own, as the table used to be built) and as the table builds it now (each distinct geometry
//!   once), then read back from the disk cache; median of 3 each, side by side in one run.
//! - `rays`: the bake's rays (cell directions above the tangent plane at ~1,000 vertices) one at a
//!   time through the CWBVH (three build qualities) and in packets through the BVH2, and through
//!   Embree one at a time, in packets and in streams where the build has it, side by side.
//! - `million`: the 1.6 M-triangle mesh (dragon_100k split twice): bake time, peak memory and the
//!   visibility error at 400 vertices.
//! - `matrix`: `glint bake`'s default bake (decisions, refinement) of each of bunny, teapot,
//!   suzanne, dragon.glb and dragon_100k under each of studio_1k, courtyard_1k and interior_1k:
//!   median of 3 of the whole bake's seconds, with its rays, rays/s and refined vertices; with
//!   `single` among the arguments, each bake also with the tracer one ray at a time, side by side;
//!   with `obvhs`, each bake also with obvhs tracing the rays (where the build has Embree), side
//!   by side; with `traced`, each bake also with every vertex traced in full (no vertex sampling, decision
//!   (f)), side by side; with `unbudgeted`, each bake that refines shadow edges also as 5.625°
//!   cells refined twice at every shadow edge (no light budget), side by side.
//! - `view`: dragon_100k.glb (49,892 vertices) under courtyard_1k, default bake settings. Prints,
//!   per run (two runs, so the second shows warm caches): the bake's seconds (decisions and
//!   refinement included), rays and the refined vertex count; then, for the isotropic J = 24 lobe
//!   set at σ = π/40, the light sums (from scratch, and from a kept `LightSource` as the app makes
//!   them) and the transfer at 160×120 from the default camera for two rotations of the
//!   environment — what a new view or a rotated light costs: the median of 5 computes with the
//!   fastest and slowest (one compute is ~45 ms, so a single one reads the machine's noise as much
//!   as the code).

use glint::bake::tracer::Backend;
use glint::bake::{BakeSettings, Baker};
use glint::light::LightSums;
use glint::sphere::{LobeLayout, LobeSet, srbf};
use std::time::Instant;

#[path = "../tests/it/common.rs"]
mod common;
#[path = "support/timing.rs"]
mod timing;
use timing::{median_of, try_median_of};

fn main() {
    if let Err(e) = run() {
        eprintln!("bake bench: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let sections: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let named = |s: &String| ["energy", "rays", "matrix", "view", "million"].contains(&s.as_str());
    let wants = |name: &str| !sections.iter().any(named) || sections.iter().any(|s| s == name);
    if wants("energy") {
        energy()?;
    }
    if wants("rays") {
        rays()?;
    }
    if wants("matrix") {
        // Mesh and map names among the arguments narrow the matrix to them.
        let meshes: Vec<&str> = MESHES
            .into_iter()
            .filter(|m| sections.iter().any(|s| s == m))
            .collect();
        let maps: Vec<&str> = MAPS
            .into_iter()
            .filter(|m| sections.iter().any(|s| s == m))
            .collect();
        let side_by_side = if sections.iter().any(|s| s == "single") {
            Some(Baseline::OneRayAtATime)
        } else if sections.iter().any(|s| s == "obvhs") {
            Some(Baseline::Obvhs)
        } else if sections.iter().any(|s| s == "traced") {
            Some(Baseline::EveryVertexTraced)
        } else if sections.iter().any(|s| s == "unbudgeted") {
            Some(Baseline::Unbudgeted)
        } else {
            None
        };
        matrix(
            if meshes.is_empty() { &MESHES } else { &meshes },
            if maps.is_empty() { &MAPS } else { &maps },
            side_by_side,
        )?;
    }
    if wants("view") {
        view()?;
    }
    if wants("million") {
        million()?;
    }
    Ok(())
}

fn energy() -> anyhow::Result<()> {
    use glint::brdf::energy::{
        EnergyQuadrature, EnergyTable, default_outgoing, lobe_set_albedo_parts,
    };
    use glint::math::GaussLegendre;
    use rayon::prelude::*;
    let lambda = srbf::lambda_from_sigma(srbf::PAPER_SIGMA)?;
    let cache = std::env::temp_dir().join(format!("glint-bench-energy-{}", std::process::id()));
    println!(
        "| lobes | entries | entry by entry (s) | distinct geometries once (s) | from the disk cache (s) | largest difference |"
    );
    println!("|---|---|---|---|---|---|");
    for layout in [LobeLayout::PAPER, LobeLayout::Isotropic { count: 24 }] {
        let lobes = LobeSet::new(layout, lambda)?;
        let outgoing = default_outgoing(&lobes);
        let quad = EnergyQuadrature::default();
        let rule = GaussLegendre::new(quad.radial_points);
        let (plain_secs, plain) = median_of(3, || {
            outgoing
                .par_iter()
                .map(|&wo| {
                    (0..lobes.len())
                        .map(|j| lobe_set_albedo_parts(&lobes, j, wo, &quad, &rule))
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        });
        let (table_secs, table) = median_of(3, || EnergyTable::new(&lobes, &outgoing, &quad));
        let _ = std::fs::remove_dir_all(&cache);
        glint::fit::energy_cache::table_in(&lobes, Some(&cache));
        let (disk_secs, disk) = median_of(3, || glint::fit::energy_cache::load(&lobes, &cache));
        let disk =
            disk.ok_or_else(|| anyhow::anyhow!("the energy table is not in the disk cache"))?;
        assert_eq!(disk.parts(), table.parts());
        let largest = plain
            .iter()
            .flatten()
            .enumerate()
            .map(|(k, &(a, b))| {
                let want = 0.04 * a + b;
                (table.entry(k / lobes.len(), k % lobes.len(), 0.04) - want).abs() / want.max(1e-12)
            })
            .fold(0.0f64, f64::max);
        println!(
            "| {} | {} × {} | {plain_secs:.3} | {table_secs:.3} | {disk_secs:.4} | {largest:.1e} |",
            layout.name(),
            table.rows(),
            table.cols()
        );
    }
    let _ = std::fs::remove_dir_all(&cache);
    Ok(())
}

/// Occlusion rays as the bake casts them: from each of ~1,000 vertices (offset 1e-4 of the
/// diagonal along the normal) along the mean direction of every 5.625° visibility cell above its
/// tangent plane (a 64-per-side direction set's light tree, cells of ≤ 12 leaves, in leaf order as
/// the bake visits them), one ray at a time through obvhs's CWBVH (three build qualities) and in
/// packets of 8 through its BVH2, and through Embree one at a time, in packets of 8, in packets of
/// 16 and as the bake calls it (one stream per vertex in a scene of at least
/// `glint::bake::embree::STREAM_TRIANGLES` triangles, which the row's name must match; packets of
/// 16 below), side by side; then Embree's packets of 16 against its stream, each vertex's rays in
/// calls of 8 to 128.
fn rays() -> anyhow::Result<()> {
    use glam::{Vec3, Vec3A};
    use glint::bake::tracer::{BvhBuildParams, PACKET, Tracer};
    use glint::sphere::{DirectionSet, LightTree};
    use rayon::prelude::*;
    let tree = LightTree::build(&DirectionSet::cube(64)?);
    fn cells(tree: &LightTree, k: usize, out: &mut Vec<Vec3A>) {
        let node = tree.nodes()[k];
        if node.count <= 12 || node.is_leaf() {
            out.push(node.mean_direction.as_vec3().into());
        } else {
            cells(tree, node.left as usize, out);
            cells(tree, node.right as usize, out);
        }
    }
    let mut dirs = Vec::new();
    cells(&tree, 0, &mut dirs);
    println!(
        "| mesh | triangles | tracer | build (s) | rays | trace (s), median of 3 | M rays/s | occluded |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut grouping = Vec::new();
    let mut by_call = Vec::new();
    for mesh in ["bunny", "dragon", "dragon_100k"] {
        let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
        let m = &scene.mesh;
        let offset = 1e-4 * (scene.bounds.max - scene.bounds.min).length();
        let step = (m.positions.len() / 1000).max(1);
        let vertices: Vec<(Vec3A, Vec<Vec3A>)> = (0..m.positions.len())
            .step_by(step)
            .map(|i| {
                let n: Vec3 = m.normals[i];
                let above = dirs
                    .iter()
                    .copied()
                    .filter(|d| d.dot(n.into()) > 0.0)
                    .collect();
                ((m.positions[i] + n * offset).into(), above)
            })
            .collect();
        let rays: usize = vertices.iter().map(|(_, d)| d.len()).sum();
        let row = |name: &str, build: f64, secs: f64, hits: usize| {
            println!(
                "| {mesh} | {} | {name} | {build:.3} | {:.2} M | {secs:.3} | {:.2} | {:.2} % |",
                m.triangles.len(),
                rays as f64 / 1e6,
                rays as f64 / secs / 1e6,
                100.0 * hits as f64 / rays as f64
            );
        };
        let singles = |tracer: &Tracer| {
            median_of(3, || {
                vertices
                    .par_iter()
                    .map(|(o, ds)| ds.iter().filter(|d| tracer.occluded(*o, **d)).count())
                    .sum::<usize>()
            })
        };
        // A vertex's rays in calls of at most `call` consecutive directions (0: one call).
        let packets = |tracer: &Tracer, how: Grouped, call: usize| {
            median_of(3, || {
                vertices
                    .par_iter()
                    .map(|(o, ds)| {
                        let mut out = vec![false; ds.len()];
                        let call = if call == 0 { ds.len().max(1) } else { call };
                        for (d, out) in ds.chunks(call).zip(out.chunks_mut(call)) {
                            match how {
                                Grouped::Eights => tracer.occluded_from_8(*o, d, out),
                                Grouped::Sixteens => tracer.occluded_from_packets(*o, d, out),
                                Grouped::Bake => tracer.occluded_from(*o, d, out),
                            }
                        }
                        out.iter().filter(|&&h| h).count()
                    })
                    .sum::<usize>()
            })
        };
        for (name, params) in [
            (
                "obvhs CWBVH fast build, one ray at a time",
                BvhBuildParams::fast_build(),
            ),
            (
                "obvhs CWBVH medium build, one ray at a time",
                BvhBuildParams::medium_build(),
            ),
            (
                "obvhs CWBVH slow build, one ray at a time",
                BvhBuildParams::slow_build(),
            ),
        ] {
            let t = Instant::now();
            let tracer = Tracer::with_params(m, params);
            let build = t.elapsed().as_secs_f64();
            let (secs, hits) = singles(&tracer);
            row(name, build, secs, hits);
        }
        let t = Instant::now();
        let tracer = Tracer::with_backend(m, Backend::Obvhs);
        let build = t.elapsed().as_secs_f64();
        let (secs, hits) = packets(&tracer, Grouped::Bake, 0);
        row(
            &format!("obvhs BVH2, packets of {PACKET}"),
            build,
            secs,
            hits,
        );
        if Backend::available().contains(&Backend::Embree) {
            let t = Instant::now();
            let tracer = Tracer::with_backend(m, Backend::Embree);
            let build = t.elapsed().as_secs_f64();
            let (secs, hits) = singles(&tracer);
            row("Embree 3, one ray at a time", build, secs, hits);
            let (secs, hits) = packets(&tracer, Grouped::Eights, 0);
            row("Embree 3, packets of 8", build, secs, hits);
            let (secs, hits) = packets(&tracer, Grouped::Sixteens, 0);
            row("Embree 3, packets of 16", build, secs, hits);
            let (secs, hits) = packets(&tracer, Grouped::Bake, 0);
            row(
                "Embree 3, as the bake calls it (a stream from 8,192 triangles)",
                build,
                secs,
                hits,
            );
            let total: usize = vertices.iter().map(|(_, ds)| ds.len()).sum();
            for call in [8, 16, 32, 64, 128] {
                let (a, _) = packets(&tracer, Grouped::Sixteens, call);
                let b = {
                    // The stream at every size of call, STREAM_MIN aside.
                    let (secs, _) = median_of(3, || {
                        vertices
                            .par_iter()
                            .map(|(o, ds)| {
                                let mut out = vec![false; ds.len()];
                                for (d, out) in ds.chunks(call).zip(out.chunks_mut(call)) {
                                    tracer.occluded_stream(*o, d, out);
                                }
                                out.iter().filter(|&&h| h).count()
                            })
                            .sum::<usize>()
                    });
                    secs
                };
                by_call.push(format!(
                    "| {mesh} | {call} | {:.2} | {:.2} |",
                    total as f64 / a / 1e6,
                    total as f64 / b / 1e6
                ));
            }
            grouping.push(grouping_row(mesh, m, &tracer, &dirs, offset));
        }
    }
    table(
        &[
            "mesh",
            "rays per call",
            "Embree packets of 16: M rays/s, median of 3",
            "Embree stream: M rays/s, median of 3",
        ],
        &by_call,
    );
    table(
        &[
            "mesh",
            "rays",
            "packets of 16 per vertex: trace (s), median of 3",
            "M rays/s",
            "packets of 16 across 16 vertices: trace (s), median of 3",
            "M rays/s",
            "occluded (both)",
        ],
        &grouping,
    );
    Ok(())
}

/// Prints a Markdown table of `rows` (each already a `| … |` line) under `header`, after an empty
/// line; nothing where there are no rows.
fn table(header: &[&str], rows: &[String]) {
    if rows.is_empty() {
        return;
    }
    println!();
    println!("| {} |", header.join(" | "));
    println!("|{}", "---|".repeat(header.len()));
    for row in rows {
        println!("{row}");
    }
}

/// How the rays bench hands a vertex's rays to the tracer.
#[derive(Clone, Copy)]
enum Grouped {
    /// Embree's packets of 8 ([`glint::bake::tracer::Tracer::occluded_from_8`]).
    Eights,
    /// Embree's packets of 16 at every size of call
    /// ([`glint::bake::tracer::Tracer::occluded_from_packets`]).
    Sixteens,
    /// As the bake does ([`glint::bake::tracer::Tracer::occluded_from`]).
    Bake,
}

/// The same rays grouped two ways, for Embree's packets of 16: 64 patches of 16 vertices
/// consecutive in Morton order (neighbours, as a thread of the bake takes them), each vertex with
/// the rays bench's cell directions above its tangent plane. Per vertex: a vertex's rays in leaf
/// order (the bake's packets). Across vertices: one direction from every vertex of the patch that
/// sees it, then the next direction (same direction, nearby origins).
fn grouping_row(
    mesh: &str,
    m: &glint::scene::Mesh,
    tracer: &glint::bake::tracer::Tracer,
    dirs: &[glam::Vec3A],
    offset: f32,
) -> String {
    use glam::Vec3A;
    use rayon::prelude::*;
    let (lo, hi) = m.positions.iter().fold(
        (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let spread = |x: u64| {
        let mut x = x & 0x1f_ffff;
        x = (x | x << 32) & 0x001f_0000_0000_ffff;
        x = (x | x << 16) & 0x001f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    };
    let code = |p: glam::Vec3| {
        let q = ((p - lo) / (hi - lo).max(glam::Vec3::splat(1e-30)) * 2_097_151.0).as_u64vec3();
        spread(q.x) | spread(q.y) << 1 | spread(q.z) << 2
    };
    let mut order: Vec<usize> = (0..m.positions.len()).collect();
    order.sort_by_key(|&i| code(m.positions[i]));
    let patches: Vec<Patch> = (0..64)
        .map(|k| {
            let start = (k * order.len() / 64).min(order.len().saturating_sub(16));
            order[start..(start + 16).min(order.len())]
                .iter()
                .map(|&i| {
                    let n = m.normals[i];
                    ((m.positions[i] + n * offset).into(), n.into())
                })
                .collect()
        })
        .collect();
    let per_vertex = |patch: &Patch| {
        patch
            .iter()
            .map(|(o, n)| {
                let ds: Vec<Vec3A> = dirs.iter().copied().filter(|d| d.dot(*n) > 0.0).collect();
                let mut out = vec![false; ds.len()];
                tracer.occluded_from(*o, &ds, &mut out);
                (ds.len(), out.iter().filter(|&&h| h).count())
            })
            .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    };
    let across = |patch: &Patch| {
        let (origins, ds): (Vec<Vec3A>, Vec<Vec3A>) = dirs
            .iter()
            .flat_map(|d| {
                patch
                    .iter()
                    .filter(move |(_, n)| d.dot(*n) > 0.0)
                    .map(move |(o, _)| (*o, *d))
            })
            .unzip();
        let mut out = vec![false; ds.len()];
        tracer.occluded_rays(&origins, &ds, &mut out);
        (ds.len(), out.iter().filter(|&&h| h).count())
    };
    // A patch: each vertex's ray origin and normal.
    type Patch = Vec<(Vec3A, Vec3A)>;
    let sum = |f: &(dyn Fn(&Patch) -> (usize, usize) + Sync)| {
        median_of(3, || {
            patches
                .par_iter()
                .map(f)
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        })
    };
    let (t_vertex, (rays, hits_vertex)) = sum(&per_vertex);
    let (t_across, (_, hits_across)) = sum(&across);
    let occluded = if hits_vertex == hits_across {
        format!("{:.2} %", 100.0 * hits_vertex as f64 / rays as f64)
    } else {
        format!("{hits_vertex} / {hits_across} rays (differ)")
    };
    format!(
        "| {mesh} | {:.2} M | {t_vertex:.3} | {:.2} | {t_across:.3} | {:.2} | {occluded} |",
        rays as f64 / 1e6,
        rays as f64 / t_vertex / 1e6,
        rays as f64 / t_across / 1e6,
    )
}

const MESHES: [&str; 5] = ["bunny", "teapot", "suzanne", "dragon", "dragon_100k"];
const MAPS: [&str; 3] = ["studio_1k", "courtyard_1k", "interior_1k"];

/// What the matrix bakes beside the default bake, in the same run.
#[derive(Clone, Copy, PartialEq)]
enum Baseline {
    /// The tracer one ray at a time (`Tracer::set_packets(false)`).
    OneRayAtATime,
    /// obvhs tracing the rays (`Backend::Obvhs`) where the default is Embree.
    Obvhs,
    /// Every vertex traced in full (`RefineSettings::interpolate` off).
    EveryVertexTraced,
    /// Where decision (d) refines shadow edges, 5.625° cells refined twice at every shadow edge (no
    /// light budget): what the bake did before the budget and the 11.25° candidate with three
    /// levels.
    Unbudgeted,
}

/// `side_by_side`: each bake also as the baseline, in the same run.
fn matrix(meshes: &[&str], maps: &[&str], side_by_side: Option<Baseline>) -> anyhow::Result<()> {
    let baseline = match side_by_side {
        Some(Baseline::OneRayAtATime) => " bake, one ray at a time (s) |",
        Some(Baseline::Obvhs) => " bake, rays through obvhs (s; rays) |",
        Some(Baseline::EveryVertexTraced) => " bake, every vertex traced (s; rays) |",
        Some(Baseline::Unbudgeted) => " bake, 5.625° cells refined at every edge (s; rays) |",
        None => "",
    };
    // The tracer decides the figures (obvhs's rays are 2–4× slower): say which one this build uses.
    let backend = Backend::best();
    println!(
        "The bakes' rays go through {}{}.",
        backend.name(),
        match backend {
            Backend::Embree => "",
            Backend::Obvhs =>
                " (this build did not find Embree: `apt-get install libembree-dev` and rebuild to bench what users with it run)",
        }
    );
    println!();
    println!(
        "| mesh | map |{baseline} bake (s), median of 3 | deciding (s) | stages (s): sampled / interpolated / traced / refinement | imported vertices | baked vertices | rays | rays/s |"
    );
    println!(
        "|---|---|{}---|---|---|---|---|---|---|",
        if baseline.is_empty() { "" } else { "---|" }
    );
    for &mesh in meshes {
        let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
        for map in maps {
            let env = glint::env::load(&common::assets().join(format!("hdr/{map}.exr")))?;
            // The unbudgeted baseline's settings, decided once outside the timing (so that its
            // bakes make one set of decisions, as the default's do).
            let refines = side_by_side == Some(Baseline::Unbudgeted)
                && Baker::new(&scene, &env, BakeSettings::default())?
                    .decisions
                    .boundary_levels
                    > 0;
            let bake = |baseline: Option<Baseline>| {
                try_median_of(3, || -> anyhow::Result<_> {
                    let mut settings = BakeSettings::default();
                    settings.refine.interpolate = baseline != Some(Baseline::EveryVertexTraced);
                    if baseline == Some(Baseline::Unbudgeted) && refines {
                        settings.cell_deg = Some(5.625);
                        settings.boundary_levels = Some(2);
                        settings.cut.boundary_budget = 0.0;
                    }
                    let backend = if baseline == Some(Baseline::Obvhs) {
                        Backend::Obvhs
                    } else {
                        Backend::best()
                    };
                    let mut baker = Baker::with_backend(&scene, &env, settings, backend)?;
                    baker
                        .tracer
                        .set_packets(baseline != Some(Baseline::OneRayAtATime));
                    Ok(baker.bake_refined(None, &|_| {}).stats)
                })
            };
            let (base_secs, base) = match side_by_side {
                Some(b) => {
                    let (t, s) = bake(Some(b))?;
                    (t, Some(s))
                }
                None => (f64::NAN, None),
            };
            let (secs, stats) = bake(None)?;
            // Packets and single rays disagree only for rays within rounding of a triangle's edge
            // (about 1 in 10⁵), which can move a boundary cell: the rays differ as little.
            // So do the two tracers.
            if let (Some(s), Some(Baseline::OneRayAtATime | Baseline::Obvhs)) =
                (&base, side_by_side)
            {
                let (a, b) = (s.rays_traced as f64, stats.rays_traced as f64);
                assert!(
                    (a - b).abs() <= 1e-4 * b,
                    "{a} rays in the baseline, {b} in the default bake"
                );
            }
            let base = match (base, side_by_side) {
                (
                    Some(s),
                    Some(Baseline::EveryVertexTraced | Baseline::Unbudgeted | Baseline::Obvhs),
                ) => {
                    format!(" {base_secs:.2}; {:.1} M |", s.rays_traced as f64 / 1e6)
                }
                (Some(_), _) => format!(" {base_secs:.2} |"),
                (None, _) => String::new(),
            };
            // The stages' seconds (`BakeStats::stages`), the refinement's rounds together.
            let stage = |prefix: &str| -> f64 {
                stats
                    .stages
                    .iter()
                    .filter(|s| s.stage.starts_with(prefix))
                    .map(|s| s.seconds)
                    .sum()
            };
            println!(
                "| {mesh} | {map} |{base} {secs:.2} | {:.2} | {:.2} / {:.2} / {:.2} / {:.2} | {} | {} | {:.1} M | {:.2} M |",
                stats.decision_seconds,
                stage("sampled"),
                stage("interpolated"),
                stage("traced"),
                stage("refinement"),
                scene.mesh.positions.len(),
                stats.vertices,
                stats.rays_traced as f64 / 1e6,
                stats.rays_traced as f64 / (stats.seconds - stats.decision_seconds).max(1e-9) / 1e6,
            );
        }
    }
    Ok(())
}

/// Peak resident set size of this process so far (bytes; Linux's `ru_maxrss` is in KiB).
fn peak_rss() -> u64 {
    // SAFETY: getrusage writes a plain struct of integers; a zeroed one is a valid value for it.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: RUSAGE_SELF with a valid pointer to that struct.
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) };
    usage.ru_maxrss as u64 * 1024
}

/// Resident set size now (bytes; `/proc/self/statm`, 4 KiB pages).
fn current_rss() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| {
            s.split_whitespace()
                .nth(1)
                .and_then(|v| v.parse::<u64>().ok())
        })
        .unwrap_or(0)
        * 4096
}

/// The million-triangle mesh: dragon_100k with every edge split twice (4× the triangles each
/// time), baked with the defaults under courtyard_1k, once (it is the slowest case), in a process
/// of its own so that the peak RSS is this bake's (run `-- million` alone).
fn million() -> anyhow::Result<()> {
    let mut scene = glint::scene::import(&common::assets().join("glb/dragon_100k.glb"))?;
    for _ in 0..2 {
        glint::scene::split_edges(&mut scene.mesh, &|_, _| true);
    }
    let env = glint::env::load(&common::assets().join("hdr/courtyard_1k.exr"))?;
    let before = peak_rss();
    let t = Instant::now();
    let baker = Baker::new(&scene, &env, BakeSettings::default())?;
    let after_decisions = peak_rss();
    let live_after_decisions = current_rss();
    let bake = baker.bake_refined(None, &|_| {});
    let secs = t.elapsed().as_secs_f64();
    let s = &bake.stats;
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    println!(
        "| triangles | vertices | baked vertices | bake (s) | deciding (s) | rays | rays/s | peak RSS before the bake | after the decisions (BVHs; live) | after the bake | cuts |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {} | {} | {secs:.1} | {:.2} | {:.1} M | {:.2} M | {:.0} MiB | {:.0} MiB ({:.0} MiB) | {:.0} MiB | {:.0} MiB ({:.0} B/vertex) |",
        scene.mesh.triangles.len(),
        scene.mesh.positions.len(),
        s.vertices,
        s.decision_seconds,
        s.rays_traced as f64 / 1e6,
        s.rays_traced as f64 / (s.seconds - s.decision_seconds).max(1e-9) / 1e6,
        mib(before),
        mib(after_decisions),
        mib(live_after_decisions),
        mib(peak_rss()),
        mib(s.bytes as u64),
        s.bytes_per_vertex,
    );
    million_error(&scene, &env, &baker, &bake)
}

/// The visibility error of the million-triangle bake at 400 vertices spread over the mesh, as
/// `tests/it/bake_visibility.rs` measures it on dragon_100k: per vertex Σ_ℓ L_ℓ Ω_ℓ c_ℓ |V − V_true|
/// over Σ_ℓ L_ℓ Ω_ℓ c_ℓ (L the map's luminance, V_true a ray per direction), against the same
/// vertices each traced on its own with the same cells.
fn million_error(
    scene: &glint::scene::Scene,
    env: &glint::env::EnvMap,
    baker: &Baker,
    bake: &glint::bake::Bake,
) -> anyhow::Result<()> {
    let mut every = BakeSettings::default();
    every.refine.interpolate = false;
    let tracing = Baker::new(scene, env, every)?;
    let luminance = common::leaf_luminance(env, baker);
    let n = scene.mesh.positions.len();
    let sample = common::error_sample(n);
    let alone = glint::bake::Cuts::from_vertex_cuts(&tracing.bake_vertices(&sample, &|_| {}));
    let error =
        |v: u32, entries: &[(u32, f32)]| common::visibility_error(baker, &luminance, v, entries);
    let (mut baked, mut traced, mut total) = (0.0, 0.0, 0.0);
    for (i, &v) in sample.iter().enumerate() {
        let (e, w) = error(v, &bake.cuts.cut(v as usize).collect::<Vec<_>>());
        let (et, _) = error(v, &alone.cut(i).collect::<Vec<_>>());
        (baked, traced, total) = (baked + e, traced + et, total + w);
    }
    println!(
        "visibility error at 400 vertices against a ray per direction: {:.2} % baked, {:.2} % each traced on its own",
        100.0 * baked / total,
        100.0 * traced / total
    );
    Ok(())
}

fn view() -> anyhow::Result<()> {
    let scene = glint::scene::import(&common::assets().join("glb/dragon_100k.glb"))?;
    let env = glint::env::load(&common::assets().join("hdr/courtyard_1k.exr"))?;
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA)?,
    )?;
    let camera = glint::scene::default_camera(&scene.bounds);
    println!(
        "| run | bake (s) | deciding (s) | vertices | rays | rays/s | bytes/vertex | rotation | light sums (s) | light sums, kept source (s) | transfer 160×120 (s), median of 5 (min–max) | pixels |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for run in 1..=2 {
        let t = Instant::now();
        let baker = Baker::new(&scene, &env, BakeSettings::default())?;
        let bake = baker.bake_refined(None, &|_| {});
        let bake_secs = t.elapsed().as_secs_f64();
        let s = &bake.stats;
        let mesh = bake.mesh(&scene.mesh)?;
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
    Ok(())
}
