//! The CPU PRT renderer: eq. 22 per vertex over its visibility cut, then raster interpolation
//! (method.md §7). The reference the wgpu preview is compared with.
//!
//! B(v, wo) = Σ_runs V_run · P_run · (ρd/π + p̃(h_run) s(ω_run, wo)), where the *runs* are the
//! vertex's cut nodes split by a *render partition* (light-tree nodes at most `partition_deg`
//! wide), and per run:
//! - P_run (RGB) = Σ_leaves L_leaf ∫_leaf max(ω·n, 0) dω — exact for a run wholly above the
//!   vertex's horizon (the radiance-weighted moment · n, [`LightSums::radiant_moment`]); where it
//!   straddles it, a walk down the tree ([`LightTree::split_by_horizon`]) takes the sub-ranges
//!   above by their moments and clips the nodes of ≤ [`HORIZON_LEAVES`] leaves that the horizon
//!   cuts whole (a disc model at their mean radiance; `horizon_leaves: 0` clips leaf by leaf by a
//!   linear rule, ~1e-3 of each such leaf's share, as the wgpu preview does): the diffuse part is
//!   exact up to that clip, per-leaf constant radiance and V's bake;
//! - ω_run = the direction of the run's luminance-weighted moment (where its light comes from: a
//!   sun inside a large run is seen where it is), and its spread v_ω = 1 − |moment|/power;
//! - p̃ = p pre-filtered by that spread in half-vector space ([`PhPyramid::lookup_filtered`]), so
//!   coarse runs do not alias sharp lobes; `prefilter: false` evaluates p at ω_run alone. Isotropic
//!   tables are read from their polar profiles ([`PhPyramid::lookup_profile_filtered`]) unless
//!   `texel_lookups`. Shaded per pixel, the spread is the ellipse's peak-matched one
//!   ([`half_vector_spread`]), points seen at grazing angles use finer partitions
//!   ([`GRAZING_TIERS`]), and below [`RESOLVE_BELOW`] the runs that carry the point's specular
//!   are integrated inside their leaves over the map's own radiance ([`PrtSettings::resolve_leaves`],
//!   [`crate::light::InsideLight`]); the vertex modes keep the wgpu preview's geometric-mean spread
//!   and one partition.
//!
//! With `merge_runs` (the default) the runs of one render-partition node are summed first — Σ V·P,
//! Σ V·moment and Σ V·power — and the BRDF is evaluated once per node at that visible light's
//! direction and spread: cuts refined at shadow edges split a node into many small runs that the
//! node's angle does not need apart (the frame moves by < 0.2 %, `tests/it/render.rs`). The wgpu
//! preview sums per run.
//!
//! Shading points: by default (`per_pixel`) eq. 22 is evaluated at every covered pixel's own
//! surface point (the fragment's barycentrics). Otherwise at the mesh's vertices (`max_edge_px: 0`,
//! the app's preview and the wgpu preview) or also at the vertices of a uniformly subdivided copy
//! of its visible triangles ([`ShadingMesh`]), whose radiance is then rasterised and interpolated.
//! A point inside a triangle blends its three corners' cuts (V = Σ bᵢ Vᵢ over the merged leaf
//! ranges) and interpolates the normal and tangent, as the transfer does per pixel.
//!
//! Inputs: mesh, cuts, light tree, tangents (or none), [`LightSums`] for the rotation, the eye, the
//! material's ρd and F0, and p as a table or as the exact lobe sum — or a standard material (an
//! exported fallback, [`Specular::Standard`]) evaluated whole per light run. Output: RGB radiance
//! per shading point, and an [`Image`] with per-pixel interpolation (perspective-correct
//! barycentrics from [`crate::raster`]).
//!
//! Invariants: no ray tracing and no IO; vertices are independent (rayon), so results do not depend
//! on the thread count; f64 sums.

use super::image::Image;
use super::table::{PhPyramid, filtered_exact};
use crate::bake::{Cuts, Span, for_each_run};
use crate::brdf::dbrdf::{half_vector_cosines, static_term, static_term_parts};
use crate::brdf::standard::StandardMaterial;
use crate::light::LightSums;
use crate::light::{LUMINANCE, luminance, spread};
use crate::raster::{rasterize, rasterize_triangles};
use crate::scene::{Camera, Mesh};
use crate::sphere::light_tree::Partition;
use crate::sphere::{Frame, LightTree, LobeSet};
use glam::{DVec3, Vec3, Vec4};
use rayon::prelude::*;
use std::collections::HashMap;

/// A run at a grazing point ([`Prt::shade_resolved`]): its leaves [a, z), V, its specular estimate
/// and the luminance that selects it for integration inside its leaves.
type EstimatedRun = ((usize, usize), f64, [f64; 3], f64);

/// A shading point's distinct corners with their weights, how many, position, normal and frame.
type PointGeometry = ([(u32, f64); 3], usize, DVec3, DVec3, Frame);

/// Whether vertex `v` of the renderer's mesh sees along the unit world direction `dir`: where a
/// point's leaves are resolved ([`PrtSettings::resolve_leaves`]), the visibility of each cell
/// inside them in place of its run's V, the cut's cosine-weighted mean over the leaves
/// ([`crate::bake::cuts`]). A sharp lobe seen at a grazing angle reflects into a few cells near
/// the horizon, where that mean weighs visibility by a small cosine and so merges it over wide
/// nodes. The caller traces it ([`super::traced`]); the renderer casts no rays.
pub type CellVisibility<'a> = dyn Fn(u32, DVec3) -> bool + Sync + 'a;

/// Knobs of the PRT renderer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrtSettings {
    /// Largest half-angle (degrees) of a render-partition node: cut nodes wider than this are
    /// split.
    pub partition_deg: f64,
    /// Pre-filter p by each run's angular spread.
    pub prefilter: bool,
    /// With `per_pixel` off: largest projected edge (pixels) of a shading triangle: coarse meshes
    /// are subdivided (uniformly, so no T-junctions) until 90 % of the visible triangles' edges are
    /// this short; 0 shades the mesh's own vertices only.
    pub max_edge_px: f64,
    /// Nodes of at most this many leaves that the horizon cuts are clipped as a whole
    /// ([`LightTree::split_by_horizon`]'s disc model) instead of leaf by leaf; ≤ 1 clips every
    /// leaf.
    pub horizon_leaves: u32,
    /// Read p from the table's 2D texels even where it has a polar profile (isotropic lobes): what
    /// the wgpu preview reads, for comparing the two. Off: the profile, which is faster and has no
    /// 2D interpolation error.
    pub texel_lookups: bool,
    /// Shade every covered pixel at its own surface point (the fragment's perspective-correct
    /// barycentrics, corner cuts blended as the transfer does) instead of interpolating a shading
    /// mesh; `max_edge_px` is then unused. Never more points than the 1-pixel shading mesh (which
    /// has up to 2 per pixel), and no interpolation of sharp highlights between points.
    pub per_pixel: bool,
    /// Sum the runs of one render-partition node before the BRDF: their visible light (V-weighted
    /// radiant cosine integrals, luminance moments and powers) is added and the BRDF evaluated once
    /// at its direction, pre-filtered by its spread, instead of once per run. Cuts refined at
    /// shadow edges split a node into many small runs; the BRDF does not need them (the node is
    /// what its angle resolves). Off: once per run, as the wgpu preview does.
    pub merge_runs: bool,
    /// With `per_pixel`: points seen at grazing angles are summed over finer render partitions
    /// ([`GRAZING_TIERS`]): a lobe σ wide in half-vector space covers only about 2σ·(wo·h) of wi
    /// across the plane of wi and wo, far less than a node of `partition_deg` there, and no
    /// isotropic pre-filter of a node's light stands in for that. Off: one partition for
    /// every point.
    pub grazing_tiers: bool,
    /// With `per_pixel`: at points seen at wo·n < `resolve_below`, the runs that carry more than
    /// [`RESOLVE_SHARE`] of the point's specular estimate are integrated inside their leaves, over
    /// the cells of [`LightSums::inside`] (the map's own radiance, up to 4×4 cells a leaf) with
    /// the BRDF unfiltered at each cell, instead of once per run at its light's direction and
    /// spread. There a sharp lobe covers about 2σ·(wo·h) of wi across the plane of wi and wo,
    /// less than a leaf, so neither a leaf's mean radiance nor any pre-filter of it stands in for
    /// the light the lobe sees. Off (or sums without inside light): the runs alone. The bunny's
    /// sharp lobe at an orbit view, map turned 90°: 5.92 → 2.33 % off Monte Carlo (2.15 % of it
    /// the reference's noise), frame +6–39 % (`cargo bench --bench render`).
    pub resolve_leaves: bool,
    /// The view cosine below which `resolve_leaves` integrates inside leaves ([`RESOLVE_BELOW`]).
    pub resolve_below: f64,
}

impl Default for PrtSettings {
    /// Chosen by measurement at 160×120 (tests/it/render.rs, `diagnose`): against the per-pixel
    /// transfer render the bunny's PRT frame is 12.5 % off with vertex shading only, 5.6 % at
    /// 2-pixel and 2.1 % at 1-pixel shading triangles, and 0.44 % shaded per pixel (the default,
    /// which is also the fastest of the three at the same picture). The partition angle
    /// matters little thanks to the radiance-weighted run directions and pre-filtering: PRT vs
    /// Monte Carlo at 4° / 8° / 16° is 5.28 / 5.29 / 5.31 %
    /// (bunny) and 20.09 / 20.06 / 20.27 % (teapot), PRT vs transfer 1.10 / 1.15 / 1.35 % (teapot);
    /// the frame takes 2.3× less time at 8° than at 4° (bench), and 16° only 1.2–1.7× less again.
    fn default() -> Self {
        Self {
            partition_deg: 8.0,
            prefilter: true,
            max_edge_px: 1.0,
            horizon_leaves: HORIZON_LEAVES,
            texel_lookups: false,
            per_pixel: true,
            merge_runs: true,
            grazing_tiers: true,
            resolve_leaves: true,
            resolve_below: RESOLVE_BELOW,
        }
    }
}

/// The finer render partitions of grazing views ([`PrtSettings::grazing_tiers`]): (largest node
/// half-angle in degrees, the view cosine wo·n below which a point uses it), finest first; a point
/// at or above the last cosine uses `partition_deg`. The angles are those of the transfer's tiers
/// for the paper's σ = π/40 (σ/4 and σ/2). Measured on the grazing sharp-lobe case (bunny,
/// studio_1k, orbit 20,15,2.5, environment turned 90°, one sharp ring lobe along n, 160×120): see
/// `tests/it/render.rs`, `sharp_lobe_at_grazing_views_against_monte_carlo`.
pub const GRAZING_TIERS: [(f64, f64); 2] = [(1.125, 0.3), (2.25, 0.6)];

/// [`PrtSettings::resolve_leaves`]: the view cosine wo·n below which a point's brightest runs are
/// integrated inside their leaves. A lobe σ = π/40 wide covers 2σ·(wo·h) ≈ 4.5° of wi there, a
/// leaf's width at most: one sharp lobe against Monte Carlo at 4096 × 2 spp, 128×96, traced
/// visibility, 0.3 → 0.5: the teapot under studio_1k turned 90°, default view, 2.31 → 1.43 %
/// (1.02 % the reference's noise), the brushed sphere the same 3.21 → 1.98 %; 0.7 and 1.0 change
/// neither.
pub const RESOLVE_BELOW: f64 = 0.5;

/// [`PrtSettings::resolve_leaves`]: a run is integrated inside its leaves where its specular
/// estimate exceeds this share of the point's (luminance), so at most 1/share runs a point.
pub const RESOLVE_SHARE: f64 = 1e-3;

/// [`CellVisibility`]: a cell inside a resolved leaf is asked for its own visibility where its
/// light through the BRDF exceeds this share of the point's specular estimate (luminance), else
/// it takes its run's V. The teapot under studio_1k, 12 views and materials of the accuracy
/// matrix, traced: 34.4 M → 5.6 M rays, 13.1 → 6.3 s, no error moved by more than 0.01 points (a
/// share of 10⁻² lost 0.15 points on the sharp lobe at the orbit, turned 90°).
pub const CELL_SHARE: f64 = 1e-3;

/// A render-partition node's light under one rotation: per channel its radiant moment, and the
/// luminance of its power. Read once per frame (a few hundred nodes) instead of four prefix-sum
/// entries per run: 77 % of a frame's runs are whole partition nodes (dragon_100k, 16°), and the
/// prefix sums (2.4 MB at 64 texels per side) miss the caches when read at random.
#[derive(Debug, Clone, Copy)]
struct NodeLight {
    radiant: [DVec3; 3],
    lum_power: f64,
}

/// The spread of a run's light in half-vector space (per-axis variance, rad²) for p's pre-filter.
/// `v_omega`: the light's spread around wi (per axis, isotropic); wo_h = wo·h; lambda: the lobes'
/// sharpness.
///
/// The map wi → h scales a jitter by 1/2 in the plane of wi and wo and by 1/(2 wo·h) across it, so
/// the light's footprint in h is an ellipse of variances a = v_ω/4 and b = v_ω/(4 (wo·h)²). With
/// `anisotropic` off the pre-filter takes the geometric mean √(ab) = v_ω/(4 wo·h) (what the wgpu
/// preview and the transfer's ring filter use): right where the footprint is much wider than the
/// lobe on both axes. At grazing views b ≫ σ² ≳ a, and a lobe (variance σ² = 1/(2λ) per axis)
/// filtered by that ellipse peaks at σ²/√((σ² + a)(σ² + b)), well below the geometric mean's
/// σ²/(σ² + √(ab)): with `anisotropic` the isotropic spread with that same peak,
/// √((σ² + a)(σ² + b)) − σ², which is √(ab) again where a, b ≫ σ² and a = b = v_ω/4 at normal
/// incidence (the grazing case: the bunny's sharp lobe at grazing views, 28.8 → 17.9 % off Monte
/// Carlo with one 8° partition).
#[inline]
pub fn half_vector_spread(v_omega: f64, wo_h: f64, lambda: f64, anisotropic: bool) -> f64 {
    let c = wo_h.max(1e-3);
    if !anisotropic {
        return v_omega / (4.0 * c);
    }
    let s2 = 0.5 / lambda.max(1e-12);
    let a = 0.25 * v_omega;
    let b = a / (c * c);
    ((s2 + a) * (s2 + b)).sqrt() - s2
}

/// Default of [`PrtSettings::horizon_leaves`]: nodes of ≤ 16 leaves (about 5.6° across at 64 per
/// side) astride the horizon are clipped whole. Measured on dragon_100k under courtyard, 640×480
/// vertex shading: frame 0.72 → 0.43 s, 5.0e-4 relative RMSE against clipping every leaf (4 leaves:
/// 0.58 s, 1.0e-4; 64: 0.37 s, 2.5e-3); the irradiance of a uniform sky is then within 4.6e-4 of π.
pub const HORIZON_LEAVES: u32 = crate::sphere::light_tree::COARSE_HORIZON_LEAVES;

/// How p(h) is evaluated.
#[derive(Debug, Clone, Copy)]
pub enum Specular<'a> {
    /// No specular term (diffuse only).
    None,
    /// The tabulated p (what frames use).
    Table(&'a PhPyramid),
    /// The exact lobe sum (closed form, pre-filtered the same way): the table's reference.
    Exact {
        lobes: &'a LobeSet,
        coefficients: [&'a [f64]; 3],
    },
    /// A standard material (an exported fallback), evaluated whole at each run's direction, less
    /// the [`Shading::rho_d`] term (set it to [`StandardMaterial::back_facing_rho`]); not
    /// pre-filtered.
    Standard(&'a StandardMaterial),
}

/// The material as the renderer needs it.
#[derive(Debug, Clone, Copy)]
pub struct Shading<'a> {
    pub rho_d: [f64; 3],
    pub f0: f64,
    pub specular: Specular<'a>,
}

/// A point where eq. 22 is evaluated: a triangle's corner vertices and barycentrics (a mesh vertex
/// is `[v, v, v]` with `[1, 0, 0]`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadingPoint {
    pub corners: [u32; 3],
    pub bary: [f32; 3],
}

impl ShadingPoint {
    /// The mesh vertex this point is, if it is one (all weight on one corner).
    #[inline]
    pub fn as_vertex(&self) -> Option<u32> {
        let c = self.corners;
        if c[0] == c[1] && c[1] == c[2] {
            return Some(c[0]);
        }
        (0..3).find(|&i| self.bary[i] >= 1.0).map(|i| c[i])
    }
}

/// One cached run: V · ∫ L max(ω·n, 0) dω (RGB), the unit direction its light comes from, its
/// spread.
#[derive(Debug, Clone, Copy)]
struct CachedRun {
    vis_cos_power: [f32; 3],
    dir: [f32; 3],
    v_omega: f32,
}

#[derive(Debug, Clone, Default)]
struct CachedVertex {
    irradiance: [f64; 3],
    runs: Vec<CachedRun>,
}

/// The view- and material-independent part of eq. 22 at mesh vertices for one light and one set of
/// cuts ([`Prt::render_cached`]): per vertex its irradiance and, per run, V·∫L max(cos, 0), the
/// light's direction and spread (28 bytes a run). A new view or a new material then costs the BRDF
/// per run only; a rotated light or new cuts need a new cache. Filled lazily, for the vertices
/// frames shade.
#[derive(Debug, Clone, Default)]
pub struct VertexLight {
    vertices: Vec<Option<CachedVertex>>,
}

impl VertexLight {
    /// An empty cache for a mesh of `vertices` vertices.
    pub fn new(vertices: usize) -> Self {
        Self {
            vertices: vec![None; vertices],
        }
    }

    /// Vertices cached so far.
    pub fn cached_vertices(&self) -> usize {
        self.vertices.iter().filter(|v| v.is_some()).count()
    }

    /// Bytes held (runs and irradiance).
    pub fn bytes(&self) -> usize {
        self.vertices
            .iter()
            .flatten()
            .map(|v| 24 + v.runs.len() * std::mem::size_of::<CachedRun>())
            .sum()
    }
}

/// The visible triangles of a view, subdivided `subdivision` times per edge, with their shading
/// points.
#[derive(Debug, Clone, Default)]
pub struct ShadingMesh {
    pub points: Vec<ShadingPoint>,
    /// World position of each point.
    pub positions: Vec<Vec3>,
    /// Sub-triangles over `points`.
    pub triangles: Vec<[u32; 3]>,
    pub subdivision: u32,
    /// With `subdivision` 1, the view's fragments with `triangle` indexing `triangles`: what
    /// [`interpolate`] would rasterise again (the same fragments: the visible triangles in the
    /// mesh's order); empty otherwise.
    pub fragments: Vec<crate::raster::Fragment>,
    /// The image size the fragments are for.
    pub fragment_size: [u32; 2],
}

/// Upper bound on shading points per frame, as a multiple of the image's pixels.
const MAX_POINTS_PER_PIXEL: usize = 2;

/// The shading mesh of a view: the triangles that cover a pixel, each split into k² sub-triangles
/// with k chosen from the 90th percentile of their projected edge lengths (k = 1 keeps the mesh's
/// vertices). Edge points are shared between neighbours, so the sub-mesh is watertight.
pub fn shading_mesh(
    mesh: &Mesh,
    camera: &Camera,
    width: u32,
    height: u32,
    max_edge_px: f64,
) -> ShadingMesh {
    let fragments = rasterize(mesh, camera, width, height);
    let mut visible = vec![false; mesh.triangles.len()];
    for f in &fragments {
        visible[f.triangle as usize] = true;
    }
    let tris: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .zip(&visible)
        .filter(|(_, v)| **v)
        .map(|(t, _)| *t)
        .collect();
    let k = subdivision(mesh, camera, width, height, &tris, max_edge_px);
    let mut out = ShadingMesh {
        subdivision: k,
        ..ShadingMesh::default()
    };
    let mut vertex_point: HashMap<u32, u32> = HashMap::new();
    let mut edge_point: HashMap<(u32, u32, u32), u32> = HashMap::new();
    let push = |out: &mut ShadingMesh, corners: [u32; 3], bary: [f32; 3]| -> u32 {
        let p: Vec3 = (0..3)
            .map(|i| mesh.positions[corners[i] as usize] * bary[i])
            .sum();
        out.points.push(ShadingPoint { corners, bary });
        out.positions.push(p);
        (out.points.len() - 1) as u32
    };
    if k == 1 {
        // The triangles themselves over their vertices (the app's preview): the same points, in the
        // same order, as the grid below gives, with a table instead of hash maps (dragon_100k at
        // 640×480: 11 → 5 ms).
        let mut point_of = vec![u32::MAX; mesh.positions.len()];
        let mut shading_triangle = vec![u32::MAX; mesh.triangles.len()];
        let mut next = 0u32;
        for (t, slot) in visible.iter().zip(shading_triangle.iter_mut()) {
            if *t {
                *slot = next;
                next += 1;
            }
        }
        out.fragments = fragments;
        out.fragment_size = [width, height];
        for f in &mut out.fragments {
            f.triangle = shading_triangle[f.triangle as usize];
        }
        for tri in &tris {
            let mut corners = [0u32; 3];
            for (slot, &v) in corners.iter_mut().zip(tri) {
                if point_of[v as usize] == u32::MAX {
                    point_of[v as usize] = push(&mut out, [v, v, v], [1.0, 0.0, 0.0]);
                }
                *slot = point_of[v as usize];
            }
            out.triangles.push(corners);
        }
        return out;
    }
    let kf = k as f32;
    for tri in &tris {
        let [v0, v1, v2] = *tri;
        // Point (i, j): barycentrics ((k − i − j)/k, i/k, j/k).
        let mut grid = vec![0u32; ((k + 1) * (k + 2) / 2) as usize];
        let at = |i: u32, j: u32| -> usize {
            (j * (k + 1) - j * (j.saturating_sub(1)) / 2 + i) as usize
        };
        for j in 0..=k {
            for i in 0..=(k - j) {
                let corner = if i == 0 && j == 0 {
                    Some(v0)
                } else if i == k {
                    Some(v1)
                } else if j == k {
                    Some(v2)
                } else {
                    None
                };
                let index = if let Some(v) = corner {
                    *vertex_point
                        .entry(v)
                        .or_insert_with(|| push(&mut out, [v, v, v], [1.0, 0.0, 0.0]))
                } else {
                    // On an edge: (from, to, step from `from`).
                    let edge = if j == 0 {
                        Some((v0, v1, i))
                    } else if i == 0 {
                        Some((v0, v2, j))
                    } else if i + j == k {
                        Some((v1, v2, j))
                    } else {
                        None
                    };
                    match edge {
                        Some((a, b, step)) => {
                            let key = if a < b {
                                (a, b, step)
                            } else {
                                (b, a, k - step)
                            };
                            *edge_point.entry(key).or_insert_with(|| {
                                let t = key.2 as f32 / kf;
                                push(&mut out, [key.0, key.1, key.1], [1.0 - t, t, 0.0])
                            })
                        }
                        None => push(
                            &mut out,
                            [v0, v1, v2],
                            [(k - i - j) as f32 / kf, i as f32 / kf, j as f32 / kf],
                        ),
                    }
                };
                grid[at(i, j)] = index;
            }
        }
        for j in 0..k {
            for i in 0..(k - j) {
                out.triangles
                    .push([grid[at(i, j)], grid[at(i + 1, j)], grid[at(i, j + 1)]]);
                if i + j + 1 < k {
                    out.triangles.push([
                        grid[at(i + 1, j)],
                        grid[at(i + 1, j + 1)],
                        grid[at(i, j + 1)],
                    ]);
                }
            }
        }
    }
    out
}

fn subdivision(
    mesh: &Mesh,
    camera: &Camera,
    width: u32,
    height: u32,
    tris: &[[u32; 3]],
    max_edge_px: f64,
) -> u32 {
    if max_edge_px <= 0.0 || tris.is_empty() {
        return 1;
    }
    let clip_from_world = camera.clip_from_world();
    let screen = |v: u32| -> Option<(f64, f64)> {
        let c = clip_from_world * mesh.positions[v as usize].extend(1.0);
        (c.w > 1e-6).then(|| {
            (
                ((c.x / c.w) as f64 + 1.0) * 0.5 * width as f64,
                (1.0 - (c.y / c.w) as f64) * 0.5 * height as f64,
            )
        })
    };
    let mut edges: Vec<f64> = tris
        .iter()
        .filter_map(|t| {
            let s = [screen(t[0])?, screen(t[1])?, screen(t[2])?];
            Some(
                (0..3)
                    .map(|i| {
                        ((s[i].0 - s[(i + 1) % 3].0).powi(2) + (s[i].1 - s[(i + 1) % 3].1).powi(2))
                            .sqrt()
                    })
                    .fold(0.0, f64::max),
            )
        })
        .collect();
    if edges.is_empty() {
        return 1;
    }
    edges.sort_by(f64::total_cmp);
    let p90 = edges[(edges.len() * 9 / 10).min(edges.len() - 1)];
    let mut k = ((p90 / max_edge_px).ceil() as u32).clamp(1, 64);
    let budget = MAX_POINTS_PER_PIXEL * (width as usize * height as usize).max(1);
    while k > 1 && tris.len() * ((k as usize + 1) * (k as usize + 2) / 2) / 2 > budget {
        k -= 1;
    }
    k
}

/// What stays fixed across frames: the cuts as leaf ranges and the render partition.
pub struct Prt<'a> {
    mesh: &'a Mesh,
    tree: &'a LightTree,
    tangents: Option<&'a [Vec4]>,
    span_offsets: Vec<u32>,
    spans: Vec<Span>,
    partition: Partition,
    /// [`GRAZING_TIERS`]' partitions with their view cosines (empty unless `per_pixel` and
    /// `grazing_tiers`).
    tiers: Vec<(Partition, f64)>,
    settings: PrtSettings,
}

impl<'a> Prt<'a> {
    /// Prepares the cuts of every vertex and the render partition.
    pub fn new(
        mesh: &'a Mesh,
        cuts: &Cuts,
        tree: &'a LightTree,
        tangents: Option<&'a [Vec4]>,
        settings: PrtSettings,
    ) -> Self {
        let mut span_offsets = Vec::with_capacity(cuts.vertex_count() + 1);
        let mut spans = Vec::with_capacity(cuts.node_count());
        span_offsets.push(0);
        for v in 0..cuts.vertex_count() {
            spans.extend(cuts.spans(v, tree));
            span_offsets.push(spans.len() as u32);
        }
        let partition = tree.partition(settings.partition_deg.to_radians().max(1e-6));
        let tiers = if settings.per_pixel && settings.grazing_tiers {
            GRAZING_TIERS
                .iter()
                .filter(|&&(deg, _)| deg < settings.partition_deg)
                .map(|&(deg, below)| (tree.partition(deg.to_radians()), below))
                .collect()
        } else {
            Vec::new()
        };
        Self {
            mesh,
            tree,
            tangents,
            span_offsets,
            spans,
            partition,
            tiers,
            settings,
        }
    }

    /// Nodes in the render partition (whole sphere).
    pub fn partition_nodes(&self) -> usize {
        self.partition.ranges.len()
    }

    /// The settings this renderer was built with.
    pub fn settings(&self) -> PrtSettings {
        self.settings
    }

    fn vertex_spans(&self, v: u32) -> &[Span] {
        let v = v as usize;
        match (self.span_offsets.get(v), self.span_offsets.get(v + 1)) {
            (Some(&a), Some(&b)) => &self.spans[a as usize..b as usize],
            _ => &[],
        }
    }

    /// The point's distinct corners with positive weight (a vertex point has one), its position,
    /// normal and shading frame; `None` for a degenerate point.
    fn point_geometry(&self, point: &ShadingPoint) -> Option<PointGeometry> {
        let mut corners: [(u32, f64); 3] = [(0, 0.0); 3];
        let mut count = 0;
        for i in 0..3 {
            let (v, b) = (point.corners[i], point.bary[i] as f64);
            if b <= 0.0 || v as usize >= self.mesh.positions.len() {
                continue;
            }
            if let Some(c) = corners[..count].iter_mut().find(|c| c.0 == v) {
                c.1 += b;
            } else {
                corners[count] = (v, b);
                count += 1;
            }
        }
        if count == 0 {
            return None;
        }
        let position: DVec3 = corners[..count]
            .iter()
            .map(|&(v, b)| self.mesh.positions[v as usize].as_dvec3() * b)
            .sum();
        let n = corners[..count]
            .iter()
            .map(|&(v, b)| self.mesh.normals[v as usize].as_dvec3() * b)
            .sum::<DVec3>()
            .try_normalize()?;
        let frame = match self.tangents {
            Some(t) => {
                let tw: Vec4 = corners[..count]
                    .iter()
                    .map(|&(v, b)| t[v as usize] * b as f32)
                    .sum();
                Frame::from_normal_tangent(
                    n,
                    tw.truncate().as_dvec3(),
                    if tw.w < 0.0 { -1.0 } else { 1.0 },
                )
            }
            None => Frame::from_normal(n),
        };
        Some((corners, count, position, n, frame))
    }

    /// The view- and material-independent part of eq. 22 per run at a point with these corners and
    /// normal: `f(V · ∫_run L max(ω·n, 0) dω (RGB), the run's luminance-weighted moment, its spread
    /// v_ω = 1 − |moment| / power)` for every run with light above the horizon (v_ω only when
    /// `spreads`, else 0).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn for_each_lit_run(
        &self,
        partition: &Partition,
        corners: &[(u32, f64)],
        n: DVec3,
        light: &LightSums,
        node_light: Option<&[NodeLight]>,
        spreads: bool,
        mut f: impl FnMut([f64; 3], DVec3, f64),
    ) {
        if !self.settings.merge_runs {
            return self.for_each_lit_piece(
                partition,
                corners,
                n,
                light,
                node_light,
                spreads,
                |_, _, _, vis_cos_power, lum_moment, lum_power| {
                    f(vis_cos_power, lum_moment, spread(lum_moment, lum_power))
                },
            );
        }
        // The runs of one partition node arrive consecutively: (node, Σ V·cos power, Σ V·moment, Σ
        // V·power).
        let mut pending: Option<(usize, [f64; 3], DVec3, f64)> = None;
        self.for_each_lit_piece(
            partition,
            corners,
            n,
            light,
            node_light,
            spreads,
            |si, _, vis, vis_cos_power, lum_moment, lum_power| match pending.as_mut() {
                Some(p) if p.0 == si => {
                    for (sum, x) in p.1.iter_mut().zip(vis_cos_power) {
                        *sum += x;
                    }
                    p.2 += vis * lum_moment;
                    p.3 += vis * lum_power;
                }
                _ => {
                    if let Some((_, cos_power, moment, power)) =
                        pending.replace((si, vis_cos_power, vis * lum_moment, vis * lum_power))
                    {
                        f(cos_power, moment, spread(moment, power));
                    }
                }
            },
        );
        if let Some((_, cos_power, moment, power)) = pending {
            f(cos_power, moment, spread(moment, power));
        }
    }

    /// [`Self::for_each_lit_run`] per run: `f(partition node, the run's leaves [a, z), V, V·cos
    /// power, luminance moment, luminance power)` (the power only when `spreads`, else 0).
    /// `node_light`: the partition nodes' light ([`Self::node_light`]) for runs that are whole
    /// nodes, or `None` to read every run's from the prefix sums.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn for_each_lit_piece(
        &self,
        partition: &Partition,
        corners: &[(u32, f64)],
        n: DVec3,
        light: &LightSums,
        node_light: Option<&[NodeLight]>,
        spreads: bool,
        mut f: impl FnMut(usize, (usize, usize), f64, [f64; 3], DVec3, f64),
    ) {
        let lists: [&[Span]; 3] = std::array::from_fn(|i| {
            corners
                .get(i)
                .map_or(&[][..], |&(v, _)| self.vertex_spans(v))
        });
        let weights: [f64; 3] = std::array::from_fn(|i| corners.get(i).map_or(0.0, |c| c.1));
        let count = corners.len().min(3);
        let (ranges, nodes) = (&partition.ranges, &partition.nodes);
        let leaves = self.tree.leaf_count() as u32;
        for_each_run(
            &lists[..count],
            &weights[..count],
            ranges,
            leaves,
            |a, z, vis, si| {
                let cone = self.tree.corner_cone(nodes[si] as usize);
                // A partition node wholly below the horizon contributes nothing. (angle(axis, n) ≥
                // 90° + the half-angle: cos ≤ −sin of the half-angle, no square root.)
                let cb = cone.axis.dot(n);
                if cone.cos >= 0.0 && cb <= -cone.sin {
                    return;
                }
                let whole = node_light
                    .filter(|_| ranges[si] == (a as u32, z as u32))
                    .map(|nl| nl[si]);
                let moment = whole.map_or_else(|| light.radiant_moment(a, z), |nl| nl.radiant);
                // ∫ L max(ω·n, 0) dω over the run: the radiant moment · n where the run lies wholly
                // above the horizon (exact up to per-leaf constant radiance), else split by walking
                // down the tree (sub-ranges above by their moments, nodes astride the horizon
                // clipped). A partition node wholly above the horizon (its corner cone) settles
                // every run in it.
                let cos_power: [f64; 3] = if cone.cos > 0.0 && cb > cone.sin {
                    std::array::from_fn(|c| moment[c].dot(n))
                } else {
                    light.clipped_cosine_power(
                        self.tree,
                        nodes[si] as usize,
                        a,
                        z,
                        n,
                        self.settings.horizon_leaves,
                        &moment,
                    )
                };
                if cos_power.iter().all(|&x| x <= 0.0) {
                    return;
                }
                let lum_moment =
                    moment[0] * LUMINANCE[0] + moment[1] * LUMINANCE[1] + moment[2] * LUMINANCE[2];
                let lum_power = match (spreads, whole) {
                    (false, _) => 0.0,
                    (true, Some(nl)) => nl.lum_power,
                    (true, None) => luminance(light.power(a, z)),
                };
                f(
                    si,
                    (a, z),
                    vis,
                    cos_power.map(|x| vis * x),
                    lum_moment,
                    lum_power,
                );
            },
        );
    }

    /// s(ω, wo) and p̃(h) of one run whose light comes from `lum_moment`'s direction with spread
    /// `v_omega`; `None` when that direction is below the horizon or undefined, or there is no
    /// specular term.
    #[inline]
    #[allow(clippy::too_many_arguments)] // one run's light moments and the point's frame: plain numbers
    fn run_specular(
        &self,
        lum_moment: DVec3,
        v_omega: f64,
        frame: &Frame,
        wo: DVec3,
        wo_world: DVec3,
        f0: f64,
        specular: Specular,
    ) -> Option<(f64, [f64; 3])> {
        let dir = lum_moment.try_normalize()?;
        if let Specular::Standard(m) = specular {
            let wi = frame.to_local(dir);
            if wi.z <= 0.0 {
                return None;
            }
            let (f, rho) = (m.eval(wi, wo), m.back_facing_rho());
            return Some((
                1.0,
                std::array::from_fn(|c| f[c] - rho[c] / std::f64::consts::PI),
            ));
        }
        if let Specular::Table(t) = specular
            && !self.settings.texel_lookups
            && t.has_profile()
        {
            // An isotropic table needs only cos θh ([`half_vector_cosines`]: no local frame).
            let k1 = dir.dot(frame.normal);
            let (wo_h, cos_h) = half_vector_cosines(k1, wo.z, dir.dot(wo_world))?;
            let s = static_term_parts(k1, wo.z, wo_h, f0);
            if !(s > 0.0) {
                return None;
            }
            let spread = if self.settings.prefilter {
                half_vector_spread(v_omega, wo_h, t.lambda(), self.settings.per_pixel)
            } else {
                0.0
            };
            let h = DVec3::new(0.0, 0.0, cos_h);
            return t.lookup_profile_filtered(h, spread).map(|p| (s, p));
        }
        let wi = frame.to_local(dir);
        if wi.z <= 0.0 {
            return None;
        }
        let h = (wi + wo).try_normalize()?;
        let s = static_term(wi, wo, f0);
        if s <= 0.0 {
            return None;
        }
        let lambda = match specular {
            Specular::Table(t) => t.lambda(),
            Specular::Exact { lobes, .. } => lobes.lambda(),
            Specular::None | Specular::Standard(_) => return None,
        };
        let spread = if self.settings.prefilter {
            half_vector_spread(v_omega, wo.dot(h), lambda, self.settings.per_pixel)
        } else {
            0.0
        };
        let p = match specular {
            Specular::Table(t) => match (
                self.settings.texel_lookups,
                t.lookup_profile_filtered(h, spread),
            ) {
                (false, Some(p)) => p,
                _ if spread > 0.0 => t.lookup_filtered(h, spread),
                _ => t.lookup(h),
            },
            Specular::Exact {
                lobes,
                coefficients,
            } => filtered_exact(lobes, coefficients, h, spread),
            Specular::None | Specular::Standard(_) => return None,
        };
        Some((s, p))
    }

    /// Outgoing radiance at a shading point seen from `eye`.
    pub fn shade_point(
        &self,
        point: &ShadingPoint,
        light: &LightSums,
        eye: DVec3,
        shading: &Shading,
    ) -> [f64; 3] {
        self.shade_point_with(point, light, None, &[], eye, shading, None)
    }

    /// The partition nodes' light under `light` (for [`Self::for_each_lit_piece`]).
    fn node_light(&self, light: &LightSums) -> Vec<NodeLight> {
        Self::partition_light(&self.partition, light)
    }

    /// The nodes' light of a partition under `light`.
    fn partition_light(partition: &Partition, light: &LightSums) -> Vec<NodeLight> {
        partition
            .ranges
            .iter()
            .map(|&(a, z)| {
                let (a, z) = (a as usize, z as usize);
                NodeLight {
                    radiant: light.radiant_moment(a, z),
                    lum_power: luminance(light.power(a, z)),
                }
            })
            .collect()
    }

    /// The tiers' node light ([`Self::partition_light`]) for each of `self.tiers`.
    fn tier_light(&self, light: &LightSums) -> Vec<Vec<NodeLight>> {
        self.tiers
            .iter()
            .map(|(p, _)| Self::partition_light(p, light))
            .collect()
    }

    /// `tier_light`: [`Self::tier_light`], or empty to read the tiers' runs from the prefix sums.
    /// `cells`: where given, the visibility of the cells inside resolved leaves
    /// ([`CellVisibility`]).
    #[allow(clippy::too_many_arguments)] // the point, its light and view, the material
    fn shade_point_with(
        &self,
        point: &ShadingPoint,
        light: &LightSums,
        node_light: Option<&[NodeLight]>,
        tier_light: &[Vec<NodeLight>],
        eye: DVec3,
        shading: &Shading,
        cells: Option<&CellVisibility<'_>>,
    ) -> [f64; 3] {
        let Some((corners, count, position, n, frame)) = self.point_geometry(point) else {
            return [0.0; 3];
        };
        let wo_world = (eye - position).try_normalize().unwrap_or(n);
        let wo = frame.to_local(wo_world);
        // Where the shading normal faces away from the eye only the diffuse term is kept.
        let specular = if wo.z > 0.0 {
            shading.specular
        } else {
            Specular::None
        };
        let has_specular = !matches!(specular, Specular::None);
        // A grazing view: a finer partition (only where there is a specular term to resolve).
        let (partition, node_light) = match self
            .tiers
            .iter()
            .position(|&(_, below)| has_specular && wo.z < below)
        {
            Some(t) => (&self.tiers[t].0, tier_light.get(t).map(|l| l.as_slice())),
            None => (&self.partition, node_light),
        };
        if has_specular
            && self.settings.per_pixel
            && self.settings.resolve_leaves
            && wo.z < self.settings.resolve_below
            && let Some(inside) = light.inside()
        {
            return self.shade_resolved(
                partition,
                &corners[..count],
                n,
                &frame,
                wo,
                wo_world,
                light,
                node_light,
                inside,
                shading,
                cells.zip(point.as_vertex()),
            );
        }
        let (mut e, mut spec) = ([0.0f64; 3], [0.0f64; 3]);
        self.for_each_lit_run(
            partition,
            &corners[..count],
            n,
            light,
            node_light,
            has_specular && self.settings.prefilter,
            |vis_cos_power, lum_moment, v_omega| {
                for c in 0..3 {
                    e[c] += vis_cos_power[c];
                }
                if has_specular
                    && let Some((s, p)) = self.run_specular(
                        lum_moment, v_omega, &frame, wo, wo_world, shading.f0, specular,
                    )
                {
                    for c in 0..3 {
                        spec[c] += vis_cos_power[c] * s * p[c];
                    }
                }
            },
        );
        std::array::from_fn(|c| shading.rho_d[c] / std::f64::consts::PI * e[c] + spec[c])
    }

    /// Eq. 22 at a point seen at a grazing angle ([`PrtSettings::resolve_leaves`]): every run's
    /// specular estimate as [`Self::shade_point_with`] makes it, then the runs whose estimate
    /// exceeds [`RESOLVE_SHARE`] of the point's — or, astride the horizon with their light's
    /// direction below it, whose estimate at that direction lifted above it does — summed again
    /// over the cells inside their leaves: V · Σ_cells Ω·L · max(ω·n, 0) · s(ω, wo) · p(h), p
    /// unfiltered. The diffuse term is the runs' as everywhere.
    #[allow(clippy::too_many_arguments)] // the point's geometry and light: plain data
    fn shade_resolved(
        &self,
        partition: &Partition,
        corners: &[(u32, f64)],
        n: DVec3,
        frame: &Frame,
        wo: DVec3,
        wo_world: DVec3,
        light: &LightSums,
        node_light: Option<&[NodeLight]>,
        inside: &crate::light::InsideLight,
        shading: &Shading,
        cells: Option<(&CellVisibility<'_>, u32)>,
    ) -> [f64; 3] {
        let specular = shading.specular;
        let estimate = |vis_cos_power: [f64; 3], dir: DVec3, v_omega: f64| {
            self.run_specular(dir, v_omega, frame, wo, wo_world, shading.f0, specular)
                .map_or([0.0; 3], |(s, p)| {
                    std::array::from_fn(|c| vis_cos_power[c] * s * p[c])
                })
        };
        let mut runs: Vec<EstimatedRun> = Vec::new();
        let mut e = [0.0f64; 3];
        self.for_each_lit_piece(
            partition,
            corners,
            n,
            light,
            node_light,
            self.settings.prefilter,
            |_, leaves, vis, vis_cos_power, lum_moment, lum_power| {
                for c in 0..3 {
                    e[c] += vis_cos_power[c];
                }
                let v_omega = spread(lum_moment, lum_power);
                let est = estimate(vis_cos_power, lum_moment, v_omega);
                // Light astride the horizon whose direction is below it: judged at that direction
                // lifted just above it.
                let select = if est == [0.0; 3] && lum_moment.dot(n) <= 0.0 {
                    let lifted =
                        lum_moment.normalize_or_zero().reject_from_normalized(n) + n * 1e-3;
                    luminance(estimate(vis_cos_power, lifted, v_omega))
                } else {
                    luminance(est)
                };
                runs.push((leaves, vis, est, select));
            },
        );
        let total: f64 = runs.iter().map(|r| luminance(r.2)).sum();
        let threshold = RESOLVE_SHARE * total;
        let cell_threshold = CELL_SHARE * total;
        let leaf_texels = self.tree.leaf_texels();
        let mut spec = [0.0f64; 3];
        for ((a, z), vis, est, select) in runs {
            if !(select > threshold) {
                for c in 0..3 {
                    spec[c] += est[c];
                }
                continue;
            }
            for &t in &leaf_texels[a..z] {
                for (dir, power) in inside.texel(t as usize) {
                    let dir = dir.as_dvec3();
                    let cos = dir.dot(n);
                    if cos <= 0.0 || power == [0.0; 3] {
                        continue;
                    }
                    if let Some((s, p)) =
                        self.run_specular(dir, 0.0, frame, wo, wo_world, shading.f0, specular)
                    {
                        let light: [f64; 3] =
                            std::array::from_fn(|c| power[c] as f64 * cos * s * p[c]);
                        let v = match cells {
                            Some((visible, point)) if luminance(light) > cell_threshold => {
                                f64::from(u8::from(visible(point, dir)))
                            }
                            _ => vis,
                        };
                        for c in 0..3 {
                            spec[c] += v * light[c];
                        }
                    }
                }
            }
        }
        std::array::from_fn(|c| shading.rho_d[c] / std::f64::consts::PI * e[c] + spec[c])
    }

    /// Fills `cache` with the light of the vertex points among `points` that it lacks (in
    /// parallel).
    pub fn fill_vertex_light(
        &self,
        cache: &mut VertexLight,
        points: &[ShadingPoint],
        light: &LightSums,
    ) {
        if cache.vertices.len() != self.mesh.positions.len() {
            *cache = VertexLight::new(self.mesh.positions.len());
        }
        let node_light = self.node_light(light);
        let mut missing: Vec<u32> = points
            .iter()
            .filter_map(|p| p.as_vertex())
            .filter(|&v| cache.vertices[v as usize].is_none())
            .collect();
        missing.sort_unstable();
        missing.dedup();
        let filled: Vec<(u32, CachedVertex)> = missing
            .par_iter()
            .map(|&v| {
                let point = ShadingPoint {
                    corners: [v; 3],
                    bary: [1.0, 0.0, 0.0],
                };
                let mut entry = CachedVertex::default();
                if let Some((corners, count, _, n, _)) = self.point_geometry(&point) {
                    self.for_each_lit_run(
                        &self.partition,
                        &corners[..count],
                        n,
                        light,
                        Some(&node_light),
                        self.settings.prefilter,
                        |vis_cos_power, lum_moment, v_omega| {
                            for c in 0..3 {
                                entry.irradiance[c] += vis_cos_power[c];
                            }
                            if let Some(dir) = lum_moment.try_normalize() {
                                entry.runs.push(CachedRun {
                                    vis_cos_power: vis_cos_power.map(|x| x as f32),
                                    dir: dir.as_vec3().to_array(),
                                    v_omega: v_omega as f32,
                                });
                            }
                        },
                    );
                }
                (v, entry)
            })
            .collect();
        for (v, entry) in filled {
            cache.vertices[v as usize] = Some(entry);
        }
    }

    /// Outgoing radiance at a vertex point from its cached light (`None` when the point is not a
    /// vertex or the vertex is not cached): the BRDF per run only.
    fn shade_cached(
        &self,
        point: &ShadingPoint,
        cache: &VertexLight,
        eye: DVec3,
        shading: &Shading,
    ) -> Option<[f64; 3]> {
        let v = point.as_vertex()?;
        let entry = cache.vertices.get(v as usize)?.as_ref()?;
        let Some((_, _, position, n, frame)) = self.point_geometry(point) else {
            return Some([0.0; 3]);
        };
        let wo_world = (eye - position).try_normalize().unwrap_or(n);
        let wo = frame.to_local(wo_world);
        let specular = if wo.z > 0.0 {
            shading.specular
        } else {
            Specular::None
        };
        let mut spec = [0.0f64; 3];
        if !matches!(specular, Specular::None) {
            for run in &entry.runs {
                let dir = glam::Vec3::from_array(run.dir).as_dvec3();
                if let Some((s, p)) = self.run_specular(
                    dir,
                    run.v_omega as f64,
                    &frame,
                    wo,
                    wo_world,
                    shading.f0,
                    specular,
                ) {
                    for c in 0..3 {
                        spec[c] += run.vis_cos_power[c] as f64 * s * p[c];
                    }
                }
            }
        }
        Some(std::array::from_fn(|c| {
            shading.rho_d[c] / std::f64::consts::PI * entry.irradiance[c] + spec[c]
        }))
    }

    /// A frame as [`Prt::render`], reading each shaded vertex's light from `cache` (filled first
    /// for the vertices this view shades and the cache lacks). The cache holds for one light
    /// (rotation) and these cuts: the caller keeps it across views and materials and drops it when
    /// either changes. Points inside triangles (`max_edge_px > 0`) are shaded directly.
    pub fn render_cached(
        &self,
        cache: &mut VertexLight,
        light: &LightSums,
        camera: &Camera,
        width: u32,
        height: u32,
        shading: &Shading,
    ) -> Image {
        if self.settings.per_pixel {
            // Every point is inside a triangle: nothing to cache.
            return self.render(light, camera, width, height, shading);
        }
        self.render_cached_mesh(
            cache,
            &self.shading_mesh(camera, width, height),
            light,
            camera,
            width,
            height,
            shading,
        )
    }

    /// [`Prt::render_cached`] over a shading mesh made before for this view and size
    /// ([`Prt::shading_mesh`]; a caller whose view has not changed keeps it). Not for `per_pixel`.
    #[allow(clippy::too_many_arguments)]
    pub fn render_cached_mesh(
        &self,
        cache: &mut VertexLight,
        sm: &ShadingMesh,
        light: &LightSums,
        camera: &Camera,
        width: u32,
        height: u32,
        shading: &Shading,
    ) -> Image {
        self.fill_vertex_light(cache, &sm.points, light);
        let eye = camera.eye().as_dvec3();
        let cache = &*cache;
        let node_light = self.node_light(light);
        let radiance: Vec<[f64; 3]> = sm
            .points
            .par_iter()
            .map(|p| {
                self.shade_cached(p, cache, eye, shading)
                    .unwrap_or_else(|| {
                        self.shade_point_with(p, light, Some(&node_light), &[], eye, shading, None)
                    })
            })
            .collect();
        interpolate(sm, &radiance, camera, width, height)
    }

    /// Radiance of the given shading points (in parallel), in order.
    pub fn shade_points(
        &self,
        points: &[ShadingPoint],
        light: &LightSums,
        eye: DVec3,
        shading: &Shading,
    ) -> Vec<[f64; 3]> {
        self.shade_points_with(points, light, eye, shading, None)
    }

    /// [`Self::shade_points`] with, where given, each vertex point's visibility of the cells inside
    /// the leaves it resolves ([`CellVisibility`]) in place of its runs' V.
    pub fn shade_points_with(
        &self,
        points: &[ShadingPoint],
        light: &LightSums,
        eye: DVec3,
        shading: &Shading,
        cells: Option<&CellVisibility<'_>>,
    ) -> Vec<[f64; 3]> {
        let node_light = self.node_light(light);
        let tier_light = self.tier_light(light);
        points
            .par_iter()
            .map(|p| {
                self.shade_point_with(
                    p,
                    light,
                    Some(&node_light),
                    &tier_light,
                    eye,
                    shading,
                    cells,
                )
            })
            .collect()
    }

    /// The shading mesh this renderer would use for a view. With `per_pixel`, its points are the
    /// covered pixels' surface points (no triangles; `subdivision` 0).
    pub fn shading_mesh(&self, camera: &Camera, width: u32, height: u32) -> ShadingMesh {
        if self.settings.per_pixel {
            let (_, points) = self.pixel_points(camera, width, height);
            let positions = points
                .iter()
                .map(|p| {
                    (0..3)
                        .map(|i| self.mesh.positions[p.corners[i] as usize] * p.bary[i])
                        .sum()
                })
                .collect();
            return ShadingMesh {
                points,
                positions,
                triangles: Vec::new(),
                subdivision: 0,
                fragments: Vec::new(),
                fragment_size: [0, 0],
            };
        }
        shading_mesh(self.mesh, camera, width, height, self.settings.max_edge_px)
    }

    /// The visible fragment of each covered pixel and its surface point.
    fn pixel_points(
        &self,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> (Vec<crate::raster::Fragment>, Vec<ShadingPoint>) {
        let fragments = rasterize(self.mesh, camera, width, height);
        let points = fragments
            .iter()
            .map(|f| match self.mesh.triangles.get(f.triangle as usize) {
                Some(&corners) => ShadingPoint {
                    corners,
                    bary: f.bary,
                },
                None => ShadingPoint {
                    corners: [0; 3],
                    bary: [1.0, 0.0, 0.0],
                },
            })
            .collect();
        (fragments, points)
    }

    /// A frame: shade the points of the view's shading mesh, interpolate per pixel (or, with
    /// `per_pixel`, shade each covered pixel's own point). Pixels off the object stay black and
    /// uncovered (see [`Image::fill_background`]).
    pub fn render(
        &self,
        light: &LightSums,
        camera: &Camera,
        width: u32,
        height: u32,
        shading: &Shading,
    ) -> Image {
        if self.settings.per_pixel {
            let (fragments, points) = self.pixel_points(camera, width, height);
            let radiance = self.shade_points(&points, light, camera.eye().as_dvec3(), shading);
            let mut image = Image::new(width, height);
            for (f, rgb) in fragments.iter().zip(&radiance) {
                image.set(f.x, f.y, rgb.map(|x| x as f32));
            }
            return image;
        }
        self.render_mesh(
            &self.shading_mesh(camera, width, height),
            light,
            camera,
            width,
            height,
            shading,
        )
    }

    /// [`Prt::render`] over a shading mesh made before for this view and size
    /// ([`Prt::shading_mesh`]): a new light changes no shading point, so a caller whose view has
    /// not changed keeps the mesh (its rasterisation is ~10 % of the dragon's frame at 640×480).
    /// Not for `per_pixel`.
    pub fn render_mesh(
        &self,
        sm: &ShadingMesh,
        light: &LightSums,
        camera: &Camera,
        width: u32,
        height: u32,
        shading: &Shading,
    ) -> Image {
        let radiance = self.shade_points(&sm.points, light, camera.eye().as_dvec3(), shading);
        interpolate(sm, &radiance, camera, width, height)
    }
}

/// Rasterises a shading mesh and interpolates its points' radiance per pixel. `camera`, `width` and
/// `height` are those the shading mesh was made for (a mesh of the triangles themselves brings its
/// fragments along and is not rasterised again).
pub fn interpolate(
    sm: &ShadingMesh,
    radiance: &[[f64; 3]],
    camera: &Camera,
    width: u32,
    height: u32,
) -> Image {
    let mut image = Image::new(width, height);
    let rasterized;
    // The shading mesh's own fragments when it has them for this size (it is made for one view).
    let fragments = if !sm.fragments.is_empty() && sm.fragment_size == [width, height] {
        &sm.fragments
    } else {
        rasterized = rasterize_triangles(&sm.positions, &sm.triangles, camera, width, height);
        &rasterized
    };
    for f in fragments {
        let tri = sm.triangles[f.triangle as usize];
        let mut rgb = [0.0f64; 3];
        for i in 0..3 {
            let r = radiance[tri[i] as usize];
            for c in 0..3 {
                rgb[c] += f.bary[i] as f64 * r[c];
            }
        }
        image.set(f.x, f.y, rgb.map(|x| x as f32));
    }
    image
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shading_mesh_of_the_triangles_keeps_the_fragments_a_new_rasterisation_gives() {
        // 4,000 random overlapping triangles (many hidden): the fragments the k = 1 shading mesh
        // brings along equal rasterising its own points and triangles again, and interpolating from
        // them equals interpolating from a rasterisation.
        let mut rng = crate::math::Rng::new(11);
        let (mut positions, mut triangles) = (Vec::new(), Vec::new());
        for i in 0..4_000u32 {
            let c = Vec3::new(
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 * 0.2 - 0.1,
            );
            for _ in 0..3 {
                positions.push(
                    c + Vec3::new(
                        rng.next_f64() as f32 * 0.2 - 0.1,
                        rng.next_f64() as f32 * 0.2 - 0.1,
                        rng.next_f64() as f32 * 0.02,
                    ),
                );
            }
            triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let normals = vec![Vec3::Z; positions.len()];
        let mesh = Mesh {
            positions,
            normals,
            tangents: None,
            uvs: None,
            triangles,
        };
        let (_, camera) = crate::raster::tests::unit_quad_scene();
        let sm = shading_mesh(&mesh, &camera, 160, 120, 0.0);
        assert_eq!(sm.subdivision, 1);
        assert!(
            sm.triangles.len() < mesh.triangles.len() && sm.fragments.len() > 2_000,
            "{} {}",
            sm.triangles.len(),
            sm.fragments.len()
        );
        let again = rasterize_triangles(&sm.positions, &sm.triangles, &camera, 160, 120);
        assert_eq!(sm.fragments, again);
        let radiance: Vec<[f64; 3]> = (0..sm.points.len())
            .map(|i| [i as f64, 1.0, (i % 7) as f64])
            .collect();
        let bare = ShadingMesh {
            fragments: Vec::new(),
            ..sm.clone()
        };
        let (a, b) = (
            interpolate(&sm, &radiance, &camera, 160, 120),
            interpolate(&bare, &radiance, &camera, 160, 120),
        );
        assert_eq!((a.pixels, a.covered), (b.pixels, b.covered));
    }

    #[test]
    fn subdivided_shading_mesh_is_watertight_and_covers_the_same_pixels() {
        let (mesh, camera) = crate::raster::tests::unit_quad_scene();
        let coarse = shading_mesh(&mesh, &camera, 200, 200, 0.0);
        assert_eq!(
            (
                coarse.subdivision,
                coarse.points.len(),
                coarse.triangles.len()
            ),
            (1, 4, 2)
        );
        let fine = shading_mesh(&mesh, &camera, 200, 200, 10.0);
        let k = fine.subdivision as usize;
        assert!(k > 5, "k = {k}");
        // A k×k grid per triangle with shared edges: (k + 1)² points over the square, 2k²
        // triangles.
        assert_eq!(fine.points.len(), (k + 1) * (k + 1));
        assert_eq!(fine.triangles.len(), 2 * k * k);
        let a = rasterize(&mesh, &camera, 200, 200).len();
        let b = rasterize_triangles(&fine.positions, &fine.triangles, &camera, 200, 200).len();
        assert_eq!(
            a, b,
            "the sub-mesh covers exactly the pixels the mesh covers"
        );
        // Every point's position is its barycentric blend.
        for (p, pos) in fine.points.iter().zip(&fine.positions) {
            let want: Vec3 = (0..3)
                .map(|i| mesh.positions[p.corners[i] as usize] * p.bary[i])
                .sum();
            assert!((want - *pos).length() < 1e-6);
        }
    }
}
