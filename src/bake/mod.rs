//! The bake: per-vertex visibility cuts through the light tree (method.md §4), with the decisions
//! of what the scene calls for. View- and light-independent: a new view or a rotated environment
//! needs no new ray tracing.
//!
//! Inputs: an imported [`Scene`], an [`EnvMap`] (only for decision (c): how fine the direction set
//! must be), [`BakeSettings`]. Outputs: a [`Bake`]: decisions with reasons, the direction-set
//! resolution, and per vertex a cut (tree nodes in pre-order with their cosine-weighted visible
//! fraction V_k, see [`cuts`]), plus statistics. [`file`](mod@file) stores it, versioned and checksummed.
//!
//! Invariants: no IO here (see [`file`](mod@file)); the result is identical for any thread count (a traced
//! vertex's cut depends on that vertex only, an interpolated one's on its sampled neighbours' cuts,
//! decision (f), [`sparse`]); vertices can be baked in any order and in parts
//! ([`Baker::bake_set`]), with the same result, so the app can start fitting once the view's
//! vertices are done.

pub mod cuts;
pub mod decisions;
#[cfg(embree)]
pub mod embree;
pub mod file;
pub mod loaded;
pub mod packed;
pub mod refine;
pub mod runs;
pub mod sparse;
pub mod tracer;

use crate::env::EnvMap;
use crate::scene::Scene;
use crate::sphere::{DirectionSet, LightTree, SphereError, srbf};
pub use cuts::{CutScratch, CutSettings, VertexCut};
pub use decisions::{Decisions, FrameSource};
use glam::{DVec3, Vec4};
pub use loaded::{LoadBakeError, LoadedBake};
pub use packed::{Cuts, PartialBake, VertexRecord};
use rayon::prelude::*;
pub use refine::{RefineSettings, Refinement};
pub use runs::{Span, for_each_run};
use serde::{Deserialize, Serialize};
pub use tracer::Tracer;

/// Bake parameters (each a knob of the accuracy study).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BakeSettings {
    /// Texels per cube-face side of the direction set; `None` decides it from the environment.
    pub resolution: Option<usize>,
    /// σ of the lobes the fit will use (decides the direction-set resolution).
    pub sigma: f64,
    /// The cut's knobs.
    pub cut: CutSettings,
    /// Trace even when no ray can hit the scene (to check decision (a)).
    pub force_trace: bool,
    /// Angular size of a visibility cell (degrees); sets `cut.cell_leaves` for the chosen
    /// resolution so that the number of rays does not grow with it: cells are the tree's largest
    /// nodes of at most (n · cell_deg / 90°)² leaves (at most 64 at n = 64 for 11.25°, so nodes of
    /// 48: the tree's node sizes are 3·2^k; 0 gives a ray per direction). `None` decides it from
    /// the scene and the environment (decision (d), [`decisions::decide_cell`]): 11.25°, refined at
    /// the shadow edges of small bright lights where they need it.
    pub cell_deg: Option<f64>,
    /// Adaptive refinement of the mesh where visibility changes between vertices (decision (e),
    /// [`refine`]); used by [`Baker::bake_refined`].
    pub refine: RefineSettings,
    /// Boundary refinement of the visibility cells ([`CutSettings::boundary_levels`]); `None`
    /// decides it with the cell size (decision (d), [`decisions::decide_boundary`]).
    #[serde(default)]
    pub boundary_levels: Option<u32>,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self {
            resolution: None,
            sigma: srbf::PAPER_SIGMA,
            cut: CutSettings::default(),
            force_trace: false,
            cell_deg: None,
            refine: RefineSettings::default(),
            boundary_levels: None,
        }
    }
}

/// Decision (d)'s probes spread over the surface by area ([`decisions::CELL_PROBES`]).
const CELL_AREA_PROBES: usize = decisions::CELL_PROBES / 2;

/// Points baked per batch ([`Baker::bake_points`]): a batch's cuts are the only unpacked ones alive
/// (~8 MiB of them), and its end costs the threads one wait.
const BATCH: usize = 1 << 14;

/// Points whose first passes are planned together and their rays traced in one call
/// ([`Tracer::occluded_grouped`]: one stream where Embree traces, else each point's in
/// packets): consecutive in Morton order, so neighbours.
const GROUP: usize = 16;

/// Indices of `points` sorted by the Morton code (21 bits per axis over their bounding box) of
/// their positions, ties and `None`s in index order (the `None`s last).
fn morton_order(points: &[Option<(DVec3, DVec3)>]) -> Vec<u32> {
    let (lo, hi) = points.iter().flatten().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (p, _)| (lo.min(*p), hi.max(*p)),
    );
    let scale = DVec3::splat((1u64 << 21) as f64 - 1.0) / (hi - lo).max(DVec3::splat(1e-30));
    // Spreads the low 21 bits of x to every third bit.
    let spread = |x: u64| {
        let mut x = x & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, point)| {
            let key = point.map_or(u64::MAX, |(p, _)| {
                let q =
                    ((p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat((1u64 << 21) as f64 - 1.0));
                spread(q.x as u64) | (spread(q.y as u64) << 1) | (spread(q.z as u64) << 2)
            });
            (key, i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("the scene has no vertices to bake")]
    EmptyMesh,
    #[error("bake settings: {0}")]
    Sphere(#[from] SphereError),
    #[error("bake settings: {0}")]
    Settings(String),
    #[error("bake: {0}")]
    Refine(#[from] refine::RefineError),
}

/// Bake statistics.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeStats {
    pub vertices: usize,
    pub triangles: usize,
    pub rays_traced: u64,
    pub mean_cut_size: f64,
    pub max_cut_size: usize,
    /// Vertices whose cut hit the cap, so ε was relaxed for them.
    pub capped_vertices: usize,
    pub seconds: f64,
    /// Seconds spent on the decisions (BVH build, occlusion test, resolution probes).
    pub decision_seconds: f64,
    pub bytes: usize,
    pub bytes_per_vertex: f64,
    /// What traced the rays ([`tracer::Backend::name`]; empty in bakes written before it was
    /// recorded).
    #[serde(default)]
    pub tracer: String,
    /// Where the time after the decisions went, stage by stage in the order they ran (empty in
    /// bakes written before it was recorded). What they leave of `seconds − decision_seconds` is
    /// the refinement's setup, a last check that splits nothing, and the final bookkeeping.
    #[serde(default)]
    pub stages: Vec<BakeStage>,
}

/// One stage of a bake after its decisions ([`BakeStats::stages`]): the vertices it finished, the
/// rays it cast and its wall-clock seconds, summed over [`Baker::bake_set`]'s calls.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeStage {
    /// `sampled` (vertex sampling's sampled vertices, level by level, [`sparse::Levels`]),
    /// `interpolated` (rule 2 of [`sparse`], no rays), `traced` (the others; every vertex where
    /// vertex sampling is off), `refinement round R` (the edges judged and the new vertices
    /// baked, decision (e)).
    pub stage: String,
    pub vertices: usize,
    pub rays: u64,
    pub seconds: f64,
}

impl BakeStage {
    /// The stages as one line for people, e.g. `sampled: 13334 vertices, 8.0 M rays, 1.44 s; …`.
    pub fn summary(stages: &[BakeStage]) -> String {
        stages
            .iter()
            .map(|s| {
                let rays = match s.rays {
                    0 => "no rays".to_string(),
                    r => format!("{:.1} M rays", r as f64 * 1e-6),
                };
                format!(
                    "{}: {} vertices, {rays}, {:.2} s",
                    s.stage, s.vertices, s.seconds
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// A finished bake.
#[derive(Debug, Clone)]
pub struct Bake {
    pub settings: BakeSettings,
    pub decisions: Decisions,
    /// Cuts of every vertex of the baked mesh: the scene's mesh, refined by `refinement`.
    pub cuts: Cuts,
    pub stats: BakeStats,
    /// How the baked mesh was refined from the scene's (empty: not refined).
    pub refinement: Refinement,
}

impl Bake {
    /// The mesh the cuts belong to: the scene's mesh with the refinement replayed.
    pub fn mesh(&self, scene_mesh: &crate::scene::Mesh) -> Result<crate::scene::Mesh, BakeError> {
        Ok(self.refinement.apply(scene_mesh)?)
    }

    /// `scene` with its mesh replaced by the baked mesh (cameras and bounds are unchanged: the
    /// refinement does not move the surface).
    pub fn scene(&self, scene: &Scene) -> Result<Scene, BakeError> {
        let mut out = scene.clone();
        if !self.refinement.is_empty() {
            out.mesh = self.mesh(&scene.mesh)?;
        }
        Ok(out)
    }
}

/// Everything needed to bake vertices, built once (BVH, tree, decisions).
pub struct Baker<'a> {
    scene: &'a Scene,
    pub settings: BakeSettings,
    pub decisions: Decisions,
    pub set: DirectionSet,
    pub tree: LightTree,
    pub tracer: Tracer,
    /// Whether the first passes of neighbouring vertices are planned and their rays traced in one
    /// call per 16 ([`cuts::plan_first_pass`]); the same cuts either way. Set by default: a
    /// planned first pass is not built where boundary refinement follows ([`cuts`] rule 9), and
    /// where Embree traces the group's rays go as one stream. Tests set it both ways.
    pub group_points: bool,
    /// Tangents for the shading frames (decision (b)).
    pub tangents: Option<Vec<Vec4>>,
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    offset: f64,
    decision_seconds: f64,
    /// The rotation-worst light that refinement (e), vertex sampling (f) and the boundary
    /// refinement's budget weigh visibility by ([`refine::RingLight`]).
    ring: refine::RingLight,
    /// Which visibility cells border which (boundary refinement, [`CutSettings::boundary_levels`]).
    cell_neighbours: cuts::CellNeighbours,
    /// The visibility cells, in leaf order ([`cuts::Prior::cells`]).
    cells: Vec<(u32, u32, u32)>,
    /// How many vertices the mesh had when imported: their cuts' root cone test is decision (a)'s
    /// test of the hemisphere ([`cuts::Prior::root_hemisphere`]).
    imported_vertices: usize,
    /// The range of `cells` under each tree node ([`cuts::Prior::cell_ranges`]).
    cell_ranges: Vec<(u32, u32)>,
    /// Vertex sampling (decision (f)): each vertex's neighbours and whether it is always traced;
    /// empty when every vertex is traced.
    vertex_neighbours: Vec<Vec<u32>>,
    sampled: Vec<bool>,
    /// The levels of the sampled vertices, traced top level first ([`sparse::Levels`]).
    levels: sparse::Levels,
}

impl<'a> Baker<'a> {
    /// Builds the BVH and makes the decisions; the rays go through [`tracer::Backend::best`].
    pub fn new(scene: &'a Scene, env: &EnvMap, settings: BakeSettings) -> Result<Self, BakeError> {
        Self::with_backend(scene, env, settings, tracer::Backend::best())
    }

    /// [`Baker::new`] with the rays traced by `backend` (to compare tracers in whole bakes).
    pub fn with_backend(
        scene: &'a Scene,
        env: &EnvMap,
        settings: BakeSettings,
        backend: tracer::Backend,
    ) -> Result<Self, BakeError> {
        let start = std::time::Instant::now();
        let mesh = &scene.mesh;
        if mesh.positions.is_empty() {
            return Err(BakeError::EmptyMesh);
        }
        if !(settings.cut.epsilon >= 0.0 && settings.cut.epsilon.is_finite()) {
            return Err(BakeError::Settings(format!(
                "epsilon must be finite and >= 0, not {}",
                settings.cut.epsilon
            )));
        }
        let reach = settings.refine.take_reach;
        if !(reach >= 0.0 && reach.is_finite()) {
            return Err(BakeError::Settings(format!(
                "the reach for taking neighbours' cells must be finite and >= 0, not {reach}"
            )));
        }
        if let Some(deg) = settings.cell_deg.filter(|d| !(*d >= 0.0 && d.is_finite())) {
            return Err(BakeError::Settings(format!(
                "the visibility cell size must be finite and >= 0 degrees, not {deg}"
            )));
        }
        let lambda = srbf::lambda_from_sigma(settings.sigma)?;
        // The environment split once (clamped base and excess samples) for every decision below.
        let source = crate::light::LightSource::new(env);
        let positions: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let imported_vertices = positions.len();
        let normals: Vec<DVec3> = mesh
            .normals
            .iter()
            .map(|n| n.as_dvec3().try_normalize().unwrap_or(DVec3::Y))
            .collect();
        let offset = settings.cut.ray_offset * scene.bounds.diagonal().max(1e-12) as f64;
        // The light's decision (c) and the geometry's (BVH, decision (a)) need nothing of each
        // other: run side by side, so that the serial parts of each overlap.
        let (light, geometry) = rayon::join(
            || -> Result<_, BakeError> {
                let resolved = match settings.resolution {
                    Some(n) => decisions::Resolution {
                        per_side: n,
                        reason: format!(
                            "set explicitly to {n} per side ({} directions)",
                            6 * n * n
                        ),
                        probe_errors: Vec::new(),
                        radiance: None,
                    },
                    None => decisions::decide_resolution(&source, lambda),
                };
                let set = DirectionSet::cube(resolved.per_side)?;
                let tree = LightTree::build(&set);
                Ok((resolved, set, tree))
            },
            || {
                let tracer = Tracer::with_backend(mesh, backend);
                let occlusion = decisions::decide_occlusion(&positions, &normals, offset, &tracer);
                (tracer, occlusion)
            },
        );
        let (resolved, set, tree) = light?;
        let decisions::Resolution {
            per_side: resolution,
            reason: resolution_reason,
            probe_errors,
            radiance: probed_radiance,
        } = resolved;
        let (tracer, (needs_trace, mut trace_reason)) = geometry;
        let mut settings = settings;
        let trace_visibility = needs_trace || settings.force_trace;
        if settings.force_trace && !needs_trace {
            trace_reason.push_str(" (traced anyway: force_trace)");
        }
        // Decision (d) traces probes; the tangents (b), the refinement's weights and the vertex
        // sampling set (f) need nothing of it: side by side.
        let interpolate = trace_visibility && settings.refine.interpolate;
        let (
            ((cell_deg, cell_reason, mut cell_decision), ring),
            ((frame_source, tangents, frame_reason), (vertex_neighbours, sampled, levels)),
        ) = rayon::join(
            || {
                // The environment's radiance per texel, as (c)'s probes integrated it where they
                // integrated this set (the same values either way), which (d) reads too; and the
                // rotation-worst light per leaf made from it: what refinement (e), vertex sampling
                // (f) and the boundary refinement's budget weigh visibility by.
                let (radiance, ring) = if trace_visibility {
                    let radiance = probed_radiance
                        .unwrap_or_else(|| crate::light::texel_radiance_from(&source, &set, 0.0));
                    let ring = refine::RingLight::new(&tree, &tree.in_leaf_order(&radiance));
                    (radiance, ring)
                } else {
                    (Vec::new(), refine::RingLight::default())
                };
                let cell = match settings.cell_deg {
                    Some(deg) => (
                        deg,
                        format!(
                            "set explicitly to {deg}° ({})",
                            decisions::cell_size_words(
                                &tree,
                                decisions::cell_leaves(resolution, deg)
                            )
                        ),
                        None,
                    ),
                    None if !trace_visibility => {
                        let deg = decisions::CELL_CANDIDATES[0].0;
                        (
                            deg,
                            format!(
                                "{deg}°: no visibility is traced, so the cell size does not matter"
                            ),
                            None,
                        )
                    }
                    None => {
                        let origins: Vec<(DVec3, DVec3)> = positions
                            .iter()
                            .zip(&normals)
                            .map(|(p, n)| (*p + *n * offset, *n))
                            .collect();
                        let area = decisions::area_probes(mesh, CELL_AREA_PROBES, offset);
                        let d = decisions::decide_cell(
                            &radiance,
                            &set,
                            &tree,
                            &origins,
                            &area,
                            &tracer,
                            &settings.cut,
                            &ring,
                        );
                        (d.deg, d.reason.clone(), Some(d))
                    }
                };
                (cell, ring)
            },
            || {
                let frames = decisions::decide_frames(mesh);
                let sampling = if interpolate {
                    let neighbours =
                        sparse::vertex_neighbours(mesh.positions.len(), &mesh.triangles);
                    let sampled = sparse::sampled_vertices(&neighbours);
                    let levels = sparse::Levels::new(&neighbours, &sampled);
                    (neighbours, sampled, levels)
                } else {
                    (Vec::new(), Vec::new(), sparse::Levels::default())
                };
                (frames, sampling)
            },
        );
        settings.cut.cell_leaves = decisions::cell_leaves(resolution, cell_deg);
        let (boundary_levels, boundary_reason) = decisions::decide_boundary(
            settings.boundary_levels,
            settings.cell_deg.is_some(),
            trace_visibility,
            cell_decision.as_ref(),
        );
        settings.cut.boundary_levels = boundary_levels;
        settings.boundary_levels = Some(boundary_levels);
        settings.cell_deg = Some(cell_deg);
        // A decided cell size is `cell_deg`; only explicit boundary levels can differ from (d)'s.
        let decided_neighbours = cell_decision
            .as_mut()
            .filter(|d| d.levels == boundary_levels)
            .map(|d| std::mem::take(&mut d.neighbours));
        let cell_neighbours = if let Some(decided) = decided_neighbours {
            decided
        } else if trace_visibility {
            cuts::CellNeighbours::new(
                &set,
                &tree,
                settings.cut.cell_leaves,
                settings.cut.boundary_levels,
            )
        } else {
            cuts::CellNeighbours::default()
        };
        let decisions = Decisions {
            trace_visibility,
            trace_reason,
            anisotropic: frame_source != FrameSource::None,
            frame_source,
            frame_reason,
            resolution,
            resolution_reason,
            resolution_probe_errors: probe_errors,
            cell_deg,
            cell_reason,
            cell_probe_errors: cell_decision.map(|d| d.errors).unwrap_or_default(),
            boundary_levels,
            boundary_reason,
            refine_reason: String::new(),
            refined_vertices: 0,
            sampling_reason: String::new(),
            interpolated_vertices: 0,
        };
        let cells = if trace_visibility {
            cuts::Prior::cells(&tree, settings.cut.cell_leaves)
        } else {
            Vec::new()
        };
        let cell_ranges = cuts::Prior::cell_ranges(&tree, &cells);
        Ok(Self {
            scene,
            settings,
            decisions,
            set,
            tree,
            group_points: true,
            tracer,
            tangents,
            positions,
            normals,
            offset,
            decision_seconds: start.elapsed().as_secs_f64(),
            ring,
            cell_neighbours,
            cell_ranges,
            cells,
            imported_vertices,
            vertex_neighbours,
            sampled,
            levels,
        })
    }

    /// Decision (f) in words, given how many vertices were interpolated.
    fn sampling_reason(&self, interpolated: usize) -> String {
        let n = self.positions.len();
        if !self.decisions.trace_visibility {
            return "no visibility is traced: nothing to sample".into();
        }
        if self.sampled.len() != n {
            return "every vertex traced (vertex sampling off)".into();
        }
        let sampled = self.sampled.iter().filter(|&&s| s).count();
        let top = self.levels.top_count();
        format!(
            "{interpolated} of {n} vertices interpolated from traced neighbours: edges shorter than {:.4} of the diagonal, neighbours' visibility within {} of the irradiance of each other, normals within {}°; {sampled} sampled vertices (every other vertex's neighbour) and {} others traced (those with edges within {reach:.4} of the diagonal taking from their sampled neighbours every visibility cell they agree on); the sampled ones in levels, {top} at the top traced whole, each other taking the cells its sampled neighbours of the level above agree on where they lie within {reach:.4} of the diagonal of it",
            self.settings.refine.min_edge,
            self.settings.refine.threshold,
            sparse::MAX_NORMAL_DEG,
            n - sampled - interpolated,
            reach = self.settings.refine.take_reach,
        )
    }

    /// (ray origin, unit normal) of vertex v: the point rays start from (offset along the normal).
    pub fn ray_origin(&self, v: usize) -> Option<(DVec3, DVec3)> {
        let (p, n) = (self.positions.get(v)?, self.normals.get(v)?);
        Some((*p + *n * self.offset, *n))
    }

    /// How far ray origins sit off the surface along the normal (world units).
    pub fn ray_offset(&self) -> f64 {
        self.offset
    }

    /// The scene being baked.
    pub fn scene(&self) -> &Scene {
        self.scene
    }

    /// Cuts of the given vertices (in parallel), in the order given. `progress` is called with the
    /// number of vertices finished so far (from any thread).
    pub fn bake_vertices(
        &self,
        vertices: &[u32],
        progress: &(dyn Fn(usize) + Sync),
    ) -> Vec<VertexCut> {
        let mut out = vec![VertexCut::default(); vertices.len()];
        self.bake_points(
            &self.points_of(vertices),
            Some(vertices),
            None,
            false,
            progress,
            &mut |batch, cuts| {
                for (&i, cut) in batch.iter().zip(cuts) {
                    out[i as usize] = cut;
                }
            },
        );
        out
    }

    /// Cuts at arbitrary surface points — (position on the smooth surface, unit normal) — traced
    /// with this bake's cells, boundary refinement and light budget, each on its own (no
    /// neighbours' help): the per-pixel visibility of a traced frame
    /// ([`crate::render::traced`]). Point i's cut is row i; with the rays cast.
    pub fn point_cuts(&self, points: &[(DVec3, DVec3)]) -> (Cuts, u64) {
        let points: Vec<Option<(DVec3, DVec3)>> = points.iter().copied().map(Some).collect();
        let mut cuts = Cuts::with_vertices(points.len());
        let mut rays = 0u64;
        self.bake_points(
            &points,
            None,
            None,
            false,
            &|_| {},
            &mut |batch, batch_cuts| {
                // Packed in parallel, as the bake's batches are ([`Cuts::set_many`]).
                rays += batch_cuts.iter().map(|c| c.rays).sum::<u64>();
                let ids: Vec<usize> = batch.iter().map(|&i| i as usize).collect();
                let entries: Vec<&[(u32, f32)]> =
                    batch_cuts.iter().map(|c| c.entries.as_slice()).collect();
                cuts.set_many(&ids, &entries);
            },
        );
        (cuts, rays)
    }

    /// (position, unit normal) of each vertex, `None` for an index out of range.
    fn points_of(&self, vertices: &[u32]) -> Vec<Option<(DVec3, DVec3)>> {
        vertices
            .iter()
            .map(|&v| {
                self.positions
                    .get(v as usize)
                    .copied()
                    .zip(self.normals.get(v as usize).copied())
            })
            .collect()
    }

    /// Cuts at the given (position, unit normal) points (in parallel), handed to `store` a batch
    /// at a time as each finishes (the batch's indices in `points`, and their cuts in that order);
    /// `None` gives an empty cut. `agreed(i)`, where
    /// given, is what point i takes from its traced neighbours and `record` whether each records
    /// what it knows for others ([`cuts::Prior`]).
    fn bake_points(
        &self,
        points: &[Option<(DVec3, DVec3)>],
        ids: Option<&[u32]>,
        agreed: Option<&(dyn Fn(usize) -> Vec<[u64; 2]> + Sync)>,
        record: bool,
        progress: &(dyn Fn(usize) + Sync),
        store: &mut dyn FnMut(&[u32], Vec<VertexCut>),
    ) {
        let done = std::sync::atomic::AtomicUsize::new(0);
        // Traced in Morton order of their positions: each thread takes a contiguous block of that
        // order, so consecutive vertices' rays cross the same BVH nodes and triangles, which stay
        // in its caches. Each cut depends on its own point alone, so the order changes the time
        // only. Batches of that order are stored as they finish: only a batch's cuts are ever
        // unpacked at once.
        let order = morton_order(points);
        // An imported vertex's first cone test is decision (a)'s test of its hemisphere.
        let root_hemisphere = |i: u32| {
            ids.and_then(|ids| ids.get(i as usize))
                .is_some_and(|&v| (v as usize) < self.imported_vertices)
        };
        let tick = || {
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            if n.is_multiple_of(256) || n == points.len() {
                progress(n);
            }
        };
        let grouped = self.decisions.trace_visibility && self.group_points;
        for batch in order.chunks(BATCH) {
            let scratch =
                || CutScratch::new(self.tree.leaf_count(), self.settings.cut.boundary_levels);
            let cuts: Vec<VertexCut> = if grouped {
                // Consecutive points in Morton order are neighbours: their first passes' rays go
                // to the tracer together (`Tracer::occluded_grouped`).
                let groups: Vec<Vec<VertexCut>> = batch
                    .par_chunks(GROUP)
                    .map_init(
                        || (scratch(), cuts::GroupRays::default()),
                        |(scratch, rays), group| {
                            let known: Vec<Vec<[u64; 2]>> = group
                                .iter()
                                .map(|&i| agreed.map(|f| f(i as usize)).unwrap_or_default())
                                .collect();
                            let prior = |j: usize| cuts::Prior {
                                cells: &self.cells,
                                cell_ranges: &self.cell_ranges,
                                agreed: &known[j],
                                record,
                                root_hemisphere: root_hemisphere(group[j]),
                            };
                            rays.clear();
                            let plans: Vec<Option<cuts::Planned>> = group
                                .iter()
                                .enumerate()
                                .map(|(j, &i)| {
                                    let (p, n) = points[i as usize]?;
                                    Some(cuts::plan_first_pass(
                                        p,
                                        n,
                                        self.offset,
                                        &self.tree,
                                        &self.tracer,
                                        &self.settings.cut,
                                        scratch,
                                        prior(j),
                                        rays,
                                    ))
                                })
                                .collect();
                            rays.trace(&self.tracer);
                            let rays = &*rays;
                            group
                                .iter()
                                .zip(plans)
                                .enumerate()
                                .map(|(j, (&i, plan))| {
                                    let cut = self.point_cut(
                                        points[i as usize],
                                        prior(j),
                                        plan.map(|p| (p, rays)),
                                        scratch,
                                    );
                                    tick();
                                    cut
                                })
                                .collect()
                        },
                    )
                    .collect();
                groups.into_iter().flatten().collect()
            } else {
                batch
                    .par_iter()
                    .map_init(scratch, |scratch, &i| {
                        let known = agreed.map(|f| f(i as usize)).unwrap_or_default();
                        let prior = cuts::Prior {
                            cells: &self.cells,
                            cell_ranges: &self.cell_ranges,
                            agreed: &known,
                            record,
                            root_hemisphere: root_hemisphere(i),
                        };
                        let cut = self.point_cut(points[i as usize], prior, None, scratch);
                        tick();
                        cut
                    })
                    .collect()
            };
            store(batch, cuts);
        }
    }

    /// The cut at one point of [`Baker::bake_points`], with what it takes from its neighbours and,
    /// where its first pass was traced ahead, that pass's rays.
    fn point_cut(
        &self,
        point: Option<(DVec3, DVec3)>,
        prior: cuts::Prior,
        planned: Option<(cuts::Planned, &cuts::GroupRays)>,
        scratch: &mut CutScratch,
    ) -> VertexCut {
        if !self.decisions.trace_visibility {
            // No ray can hit: V = 1 over the whole upper hemisphere, the root covers it.
            return VertexCut {
                entries: vec![(0, 1.0)],
                rays: 0,
                epsilon_used: self.settings.cut.epsilon,
                interpolated: false,
                cell_bits: Vec::new(),
            };
        }
        let Some((p, n)) = point else {
            return VertexCut::default();
        };
        cuts::vertex_cut(
            p,
            n,
            self.offset,
            &self.tree,
            &self.tracer,
            &self.settings.cut,
            &self.cell_neighbours,
            scratch,
            prior,
            Some(self.ring.gate(n)),
            planned,
        )
    }

    /// Cuts of every vertex of the scene's mesh; `order` (e.g. the fit view's vertices first) only
    /// changes which finish first, not the result.
    pub fn bake_base(
        &self,
        order: Option<&[u32]>,
        progress: &(dyn Fn(usize) + Sync),
    ) -> PartialBake {
        let n = self.positions.len();
        let default_order: Vec<u32> = (0..n as u32).collect();
        let order = order.unwrap_or(&default_order);
        let mut state = PartialBake::new(n);
        self.bake_set(order, &mut state, progress);
        state
    }

    /// Bakes the vertices of `vertices` not yet baked into `state` (of the scene's vertex count),
    /// with vertex sampling (decision (f), [`sparse`]): the sampled vertices among them and the
    /// sampled neighbours the others need are traced first, level by level from the top with the
    /// vertices of the level above that each takes cells from ([`sparse::Levels`]), then each other
    /// vertex is interpolated
    /// where the rule allows and traced where it does not. The result does not depend on how the
    /// vertices are split between calls or ordered. `progress` gets the number of vertices finished
    /// in this call.
    pub fn bake_set(
        &self,
        vertices: &[u32],
        state: &mut PartialBake,
        progress: &(dyn Fn(usize) + Sync),
    ) {
        let n = self.positions.len().min(state.vertex_count());
        let todo: Vec<u32> = vertices
            .iter()
            .copied()
            .filter(|&v| (v as usize) < n && !state.baked[v as usize])
            .collect();
        let stage = state.start_stage();
        if self.sampled.len() != n {
            self.bake_points(
                &self.points_of(&todo),
                Some(&todo),
                None,
                false,
                progress,
                &mut |batch, cuts| {
                    let ids: Vec<usize> =
                        batch.iter().map(|&i| todo[i as usize] as usize).collect();
                    state.store_many(&ids, cuts);
                },
            );
            state.end_stage("traced", todo.len(), stage);
            return;
        }
        // 1. The sampled vertices: those of `todo`, then the sampled neighbours of the others.
        let mut first: Vec<u32> = todo
            .iter()
            .copied()
            .filter(|&v| self.sampled[v as usize])
            .collect();
        let own = first.len();
        let mut wanted = vec![false; n];
        first.iter().for_each(|&v| wanted[v as usize] = true);
        for &v in &todo {
            for &u in &self.vertex_neighbours[v as usize] {
                if self.sampled[u as usize] && !state.baked[u as usize] && !wanted[u as usize] {
                    wanted[u as usize] = true;
                    first.push(u);
                }
            }
        }
        // Level by level from the top, with the vertices of the level above that each takes cells
        // from (rule 5); each recording what it knows of every visibility cell, for the vertices
        // traced after it.
        let max_edge = self.settings.refine.min_edge * self.scene.bounds.diagonal() as f64;
        // Rules 4 and 5 take cells within their own reach; rule 2 interpolates within `min_edge`.
        let reach = self.settings.refine.take_reach * self.scene.bounds.diagonal() as f64;
        let mut by_level: Vec<Vec<(u32, Option<Vec<u32>>)>> = Vec::new();
        let mut queue = first;
        while !queue.is_empty() {
            let found: Vec<Option<Vec<u32>>> = queue
                .par_iter()
                .map(|&v| {
                    self.levels.anchors(
                        v as usize,
                        &self.positions,
                        &self.normals,
                        &self.vertex_neighbours,
                        reach,
                    )
                })
                .collect();
            let mut above = Vec::new();
            for (v, anchors) in queue.into_iter().zip(found) {
                for &u in anchors.iter().flatten() {
                    if !state.baked[u as usize] && !wanted[u as usize] {
                        wanted[u as usize] = true;
                        above.push(u);
                    }
                }
                let level = self.levels.level[v as usize] as usize;
                if by_level.len() <= level {
                    by_level.resize(level + 1, Vec::new());
                }
                by_level[level].push((v, anchors));
            }
            queue = above;
        }
        let mut finished = 0;
        let sampled_count = by_level.iter().map(Vec::len).sum();
        for list in by_level.into_iter().rev() {
            let (vertices, anchors): (Vec<u32>, Vec<Option<Vec<u32>>>) = list.into_iter().unzip();
            self.bake_assisted(&vertices, &anchors, true, state, &|k| {
                progress((finished + k).min(own))
            });
            finished += vertices.len();
        }
        state.end_stage("sampled", sampled_count, stage);
        let stage = state.start_stage();
        // 2. The others: interpolated, or traced.
        let rest: Vec<u32> = todo
            .iter()
            .copied()
            .filter(|&v| !state.baked[v as usize])
            .collect();
        let threshold = self.settings.refine.threshold;
        let epsilon = self.settings.cut.epsilon;
        let mut traced = Vec::new();
        let mut interpolated = 0;
        for batch in rest.chunks(BATCH) {
            let blended: Vec<Option<VertexCut>> = {
                let cuts = &state.cuts;
                batch
                    .par_iter()
                    .map(|&v| {
                        let v = v as usize;
                        // The cuts of the sampled neighbours it may be interpolated from (none
                        // where rule 2's geometry fails: then nothing is read back), once each.
                        let anchors = sparse::anchors(
                            v,
                            &self.positions,
                            &self.normals,
                            &self.vertex_neighbours,
                            &self.sampled,
                            max_edge,
                        )?;
                        let around: Vec<(u32, Vec<(u32, f32)>)> = anchors
                            .into_iter()
                            .map(|u| (u, cuts.cut(u as usize).collect()))
                            .collect();
                        let cut_of = |u: usize| {
                            around
                                .iter()
                                .find(|(w, _)| *w as usize == u)
                                .map_or(&[][..], |(_, c)| c.as_slice())
                        };
                        let weights = sparse::interpolation_weights(
                            v,
                            &self.positions,
                            &self.normals,
                            &self.vertex_neighbours,
                            &self.sampled,
                            max_edge,
                            threshold,
                            &self.tree,
                            &self.ring.prefix,
                            &cut_of,
                        )?;
                        let cuts: Vec<&[(u32, f32)]> =
                            weights.iter().map(|&(u, _)| cut_of(u as usize)).collect();
                        let w: Vec<f64> = weights.iter().map(|&(_, w)| w).collect();
                        let (mut cut, uncovered) = sparse::blend_cuts(
                            &self.tree,
                            &cuts,
                            &w,
                            self.normals[v],
                            &self.ring.prefix,
                            self.ring.totals.at(self.normals[v]),
                        );
                        cut.epsilon_used = epsilon;
                        (uncovered <= threshold).then_some(cut)
                    })
                    .collect()
            };
            let (mut ids, mut cuts) = (Vec::new(), Vec::new());
            for (&v, cut) in batch.iter().zip(blended) {
                match cut {
                    Some(cut) => {
                        ids.push(v as usize);
                        cuts.push(cut);
                    }
                    None => traced.push(v),
                }
            }
            interpolated += ids.len();
            state.store_many(&ids, cuts);
        }
        let done = own + interpolated;
        state.end_stage("interpolated", interpolated, stage);
        let stage = state.start_stage();
        progress(done);
        // Where a traced vertex's sampled neighbours all agree on a cell, it takes their
        // visibility (rule 4).
        let anchors: Vec<Option<Vec<u32>>> = traced
            .par_iter()
            .map(|&v| {
                sparse::anchors(
                    v as usize,
                    &self.positions,
                    &self.normals,
                    &self.vertex_neighbours,
                    &self.sampled,
                    reach,
                )
            })
            .collect();
        self.bake_assisted(&traced, &anchors, false, state, &|k| progress(done + k));
        state.end_stage("traced", traced.len(), stage);
    }

    /// Traces `vertices` into `state`, vertex i taking every visibility cell that all of
    /// `anchors[i]` (baked, with their cell bits) know alike ([`sparse::agreed_cells`]), and
    /// recording its own cell bits where `record`. The sampled vertices' cell bits stay in `state`
    /// until the refinement (128 bytes a vertex at 11.25°, 512 at 5.625°), so that a later
    /// [`Baker::bake_set`] call finds them too.
    fn bake_assisted(
        &self,
        vertices: &[u32],
        anchors: &[Option<Vec<u32>>],
        record: bool,
        state: &mut PartialBake,
        progress: &(dyn Fn(usize) + Sync),
    ) {
        let bits = std::mem::take(&mut state.cell_bits);
        let agreed = |i: usize| -> Vec<[u64; 2]> {
            match anchors.get(i) {
                Some(Some(anchors)) => {
                    let of: Vec<&[[u64; 2]]> = anchors
                        .iter()
                        .map(|&u| bits.get(u as usize).map_or(&[][..], Vec::as_slice))
                        .collect();
                    sparse::agreed_cells(&of)
                }
                _ => Vec::new(),
            }
        };
        self.bake_points(
            &self.points_of(vertices),
            Some(vertices),
            Some(&agreed),
            record,
            progress,
            &mut |batch, cuts| {
                let ids: Vec<usize> = batch
                    .iter()
                    .map(|&i| vertices[i as usize] as usize)
                    .collect();
                state.store_many(&ids, cuts);
            },
        );
        let new = std::mem::replace(&mut state.cell_bits, bits);
        for (v, b) in new.into_iter().enumerate() {
            if !b.is_empty() {
                if state.cell_bits.len() <= v {
                    state.cell_bits.resize(v + 1, Vec::new());
                }
                state.cell_bits[v] = b;
            }
        }
    }

    /// Bakes every vertex of the scene's mesh as it is (no refinement); `order` only changes which
    /// finish first, not the result.
    pub fn bake_all(&self, order: Option<&[u32]>, progress: &(dyn Fn(usize) + Sync)) -> Bake {
        let start = std::time::Instant::now();
        let state = self.bake_base(order, progress);
        self.finish(state, Refinement::default(), self.decisions.clone(), start)
    }

    /// Bakes every vertex, then refines the mesh where visibility changes between vertices
    /// ([`refine`], decision (e)) and bakes the new vertices: what `glint bake` and the app do. The
    /// result's cuts belong to [`Bake::mesh`].
    pub fn bake_refined(&self, order: Option<&[u32]>, progress: &(dyn Fn(usize) + Sync)) -> Bake {
        let start = std::time::Instant::now();
        let base = self.bake_base(order, progress);
        self.refine(base, start)
    }

    /// The refinement rounds over `base` (the cuts of every vertex of the scene's mesh).
    pub fn refine(&self, base: PartialBake, start: std::time::Instant) -> Bake {
        let r = self.settings.refine;
        let mut decisions = self.decisions.clone();
        let base_count = base.vertex_count();
        if !self.decisions.trace_visibility || r.rounds == 0 || self.ring.prefix.is_empty() {
            decisions.refine_reason = if r.rounds == 0 {
                "refinement off (0 rounds)".into()
            } else {
                "no visibility is traced, so it is the same at every vertex: nothing to refine"
                    .into()
            };
            decisions.refined_vertices = base_count;
            return self.finish(base, Refinement::default(), decisions, start);
        }
        let mut mesh = self.scene.mesh.clone();
        let mut state = base;
        // (The sampled vertices' cell bits served the base mesh's vertices only.)
        state.cell_bits = Vec::new();
        // Each new vertex as a blend of at most three imported vertices (the corners of the
        // imported triangle it lies in), so that its rays start on the smooth surface the imported
        // normals describe, as the imported vertices' do, not on the flat facet below it (which
        // would see the neighbouring facets at grazing angles: the shadow-terminator problem).
        let mut blends: Vec<Vec<(u32, f64)>> = Vec::new();
        let mut parents_all: Vec<[u32; 2]> = Vec::new();
        let min_length = (r.min_edge * self.scene.bounds.diagonal() as f64) as f32;
        let mut rounds_done = 0;
        let mut split_total = 0;
        // Edges between vertices that were there in an earlier round were judged then, on the same
        // cuts: each round looks only at edges with an end added by the round before.
        let mut since = 0u32;
        for round in 1..=r.rounds {
            let stage = state.start_stage();
            let edges = refine::long_edges(&mesh, min_length);
            let marked: Vec<(u32, u32)> = edges
                .par_iter()
                .copied()
                .filter(|&(_, b)| b >= since)
                .map_init(
                    || (Vec::new(), Vec::new()),
                    |(ca, cb), (a, b)| {
                        state.cuts.cut_into(a as usize, ca);
                        state.cuts.cut_into(b as usize, cb);
                        let n = (mesh.normals[a as usize] + mesh.normals[b as usize])
                            .as_dvec3()
                            .try_normalize()
                            .unwrap_or(DVec3::Y);
                        let differ =
                            refine::visibility_difference(&self.tree, &self.ring.prefix, ca, cb, n)
                                > r.threshold;
                        differ.then_some((a, b))
                    },
                )
                .flatten()
                .collect();
            if marked.is_empty() {
                break;
            }
            let parents = refine::split_marked(&mut mesh, &marked);
            let first_new = state.vertex_count();
            since = first_new as u32;
            for &[a, b] in &parents {
                refine::push_midpoint_blend(&mut blends, base_count, a, b);
            }
            let points: Vec<Option<(DVec3, DVec3)>> = (first_new..mesh.positions.len())
                .map(|v| {
                    let flat = mesh.positions[v].as_dvec3();
                    let blend = refine::blend_of(&blends, base_count, v as u32);
                    // An edge lies in one imported triangle, so a blend has at most three corners.
                    let p = if blend.len() <= 3 {
                        crate::scene::smooth_surface_point(&self.scene.mesh, &blend, flat)
                    } else {
                        flat
                    };
                    Some((
                        p,
                        mesh.normals[v]
                            .as_dvec3()
                            .try_normalize()
                            .unwrap_or(DVec3::Y),
                    ))
                })
                .collect();
            self.bake_points(&points, None, None, false, &|_| {}, &mut |batch, cuts| {
                let ids: Vec<usize> = batch.iter().map(|&i| first_new + i as usize).collect();
                state.store_many(&ids, cuts);
            });
            state.end_stage(&format!("refinement round {round}"), points.len(), stage);
            split_total += parents.len();
            parents_all.extend(parents);
            rounds_done += 1;
        }
        decisions.refined_vertices = mesh.positions.len();
        decisions.refine_reason = if parents_all.is_empty() {
            format!(
                "no edge longer than {:.4} of the diagonal has ends whose visibility differs by more than {} of the irradiance: not refined",
                r.min_edge, r.threshold
            )
        } else {
            format!(
                "{split_total} edges split in {rounds_done} round(s) where the ends' visibility differs by more than {} of the irradiance (edges longer than {:.4} of the diagonal): {base_count} → {} vertices",
                r.threshold,
                r.min_edge,
                mesh.positions.len()
            )
        };
        let refinement = if parents_all.is_empty() {
            Refinement::default()
        } else {
            Refinement {
                parents: parents_all,
                triangles: mesh.triangles,
            }
        };
        self.finish(state, refinement, decisions, start)
    }

    fn finish(
        &self,
        state: PartialBake,
        refinement: Refinement,
        mut decisions: Decisions,
        start: std::time::Instant,
    ) -> Bake {
        let PartialBake {
            mut cuts,
            records,
            stages,
            ..
        } = state;
        let n = cuts.vertex_count();
        let interpolated = records.iter().filter(|r| r.interpolated).count();
        decisions.interpolated_vertices = interpolated;
        decisions.sampling_reason = self.sampling_reason(interpolated);
        let rays_traced = records.iter().map(|r| r.rays).sum();
        let capped_vertices = records
            .iter()
            .filter(|r| r.epsilon_used > self.settings.cut.epsilon)
            .count();
        let max_cut_size = (0..n).map(|v| cuts.cut_len(v)).max().unwrap_or(0);
        cuts.shrink_to_fit();
        let bytes = cuts.bytes() + refinement.parents.len() * 8 + refinement.triangles.len() * 12;
        let stats = BakeStats {
            vertices: n,
            triangles: if refinement.is_empty() {
                self.scene.mesh.triangles.len()
            } else {
                refinement.triangles.len()
            },
            rays_traced,
            mean_cut_size: cuts.mean_cut_size(),
            max_cut_size,
            capped_vertices,
            seconds: start.elapsed().as_secs_f64() + self.decision_seconds,
            decision_seconds: self.decision_seconds,
            bytes,
            bytes_per_vertex: bytes as f64 / n.max(1) as f64,
            tracer: self.tracer.backend().name().to_string(),
            stages,
        };
        Bake {
            settings: self.settings,
            decisions,
            cuts,
            stats,
            refinement,
        }
    }
}

/// One call: decisions, BVH, every vertex, the refinement ([`Baker::bake_refined`]).
pub fn bake(
    scene: &Scene,
    env: &EnvMap,
    settings: BakeSettings,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Bake, BakeError> {
    let baker = Baker::new(scene, env, settings)?;
    Ok(baker.bake_refined(None, progress))
}
