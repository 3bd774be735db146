//! A PRT frame whose visibility is traced at the covered pixels themselves: the still frame for
//! views where visibility changes inside the mesh's triangles.
//!
//! The default PRT frame ([`super::prt`]) shades every covered pixel at its own surface point but
//! blends its triangle's three corner cuts for V. Where a shadow edge crosses a triangle — a sphere's
//! shadow on a two-triangle ground, a teapot's spout over its body — no blend of the corners'
//! visibility is the visibility inside it, and no refinement of the bake short of one vertex per
//! pixel removes that. Here each covered pixel whose corners' cuts differ gets a cut of its own,
//! traced by the bake's own cut algorithm ([`Baker::point_cuts`]: the same visibility cells,
//! boundary refinement and light budget) from the pixel's point on the smooth surface, where the
//! Monte Carlo reference starts its shadow rays (docs/conventions.md §6). Every pixel's normal,
//! tangent and ray origin are the imported mesh's (a refined triangle's corners mapped back onto
//! its imported triangle), as the reference's are: normalised midpoint normals interpolate to a
//! slightly different normal, which a sharp lobe sees (the teapot under courtyard_1k, one sharp
//! lobe: 2.63 → 2.27 % off Monte Carlo less noise). Pixels whose corners agree
//! take that cut as it is (the blend of three equal cuts). Everything after the cuts — the light
//! runs, the BRDF, grazing tiers, resolved leaves — is the PRT frame's: the covered pixels become
//! the vertices of a point mesh that [`Prt`] shades one by one, with one change: inside the leaves
//! a grazing point resolves ([`PrtSettings::resolve_leaves`]) each cell that carries light
//! ([`super::prt::CELL_SHARE`]) has its visibility from a ray of its own from the pixel's origin
//! ([`CellVisibility`]), not its run's V. A cut's V is a cosine-weighted mean, so near the
//! horizon — where a sharp lobe seen at a grazing angle reflects — it is merged over wide nodes,
//! and a lobe a few degrees wide falls on directions that V = 1 says are open and a neighbouring
//! face blocks (the teapot under studio_1k turned 90°, orbit view, one sharp lobe, where vertex
//! normals lean 17–31° from the faces: 2.27 → 1.51 % off 4096 × 2 spp less its noise, at
//! 128×96).
//!
//! Inputs: a [`Baker`] over the mesh the bake's cuts belong to (its tree is the light sums'), the
//! mesh, its cuts and tangents, the light, camera, image size, the material, [`PrtSettings`]
//! (`per_pixel` is implied). Output: an [`Image`] and [`TracedStats`]. Invariants: no IO; the same
//! result for any thread count (each pixel's cut depends on its point alone); the ray tracing
//! happens here, in the bake's code, not in the PRT renderer.

use super::image::Image;
use super::prt::{CellVisibility, Prt, PrtSettings, Shading, ShadingPoint};
use crate::bake::refine::base_blends;
use crate::bake::{BakeSettings, Baker, Cuts, Decisions};
use crate::light::LightSums;
use crate::raster::rasterize;
use crate::scene::{Camera, Mesh, smooth_surface_point};
use glam::{DVec3, Vec3, Vec3A, Vec4};
use std::sync::atomic::{AtomicU64, Ordering};

/// Pixels shaded per block: a block's cuts and their leaf ranges are the only ones held at once
/// (about 2 KiB a pixel).
const BLOCK: usize = 1 << 15;

/// The fewest boundary levels a traced frame refines its pixels' cells by: decision (d) may leave
/// a bake's 11.25° cells unrefined where its probes see no shadow edge, and a pixel's own cut is
/// cheap next to the picture it fixes (the teapot under courtyard_1k, default view, one sharp lobe,
/// 128×96: 8.8 % off Monte Carlo by default, 9.3 % traced with unrefined cells, 2.7 % with three
/// levels at 0.48 M rays, less the reference's noise).
pub const TRACED_BOUNDARY_LEVELS: u32 = 3;

/// How a traced frame refines its pixels' visibility cells at shadow edges (`glint render
/// --trace-levels`, `--trace-budget`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracing {
    /// Boundary levels, at least ([`TRACED_BOUNDARY_LEVELS`] by default).
    pub levels: u32,
    /// The light budget β of the boundary refinement ([`crate::bake::CutSettings::boundary_budget`]);
    /// `None`: the bake's. The bake's budget leaves unrefined the shadow edges of lights too dim
    /// to move a vertex's irradiance, but a sharp lobe can take all its light from one: 0 refines
    /// every shadow edge (the teapot under interior_1k, default view, one sharp lobe: 2.52 → 1.01 %
    /// off Monte Carlo, 0.61 → 1.10 s at 128×96).
    pub budget: Option<f64>,
}

impl Default for Tracing {
    fn default() -> Self {
        Self {
            levels: TRACED_BOUNDARY_LEVELS,
            budget: None,
        }
    }
}

/// The settings a [`Baker`] traces a frame's pixels with, from a bake's settings and decisions:
/// its direction set, cell size and light budget (or `tracing`'s), cells at shadow edges traced
/// again at least `tracing.levels` times, and no vertex sampling (each pixel is traced on its
/// own).
pub fn tracing_settings(
    bake: BakeSettings,
    decisions: &Decisions,
    tracing: Tracing,
) -> BakeSettings {
    let mut settings = bake;
    settings.resolution = Some(decisions.resolution);
    settings.cell_deg = Some(decisions.cell_deg);
    settings.boundary_levels = Some(decisions.boundary_levels.max(tracing.levels));
    settings.force_trace = decisions.trace_visibility;
    settings.refine.interpolate = false;
    if let Some(budget) = tracing.budget {
        settings.cut.boundary_budget = budget;
    }
    settings
}

/// What a traced frame did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TracedStats {
    /// Covered pixels.
    pub pixels: usize,
    /// Pixels whose corners' cuts differ, traced on their own.
    pub traced: usize,
    /// Occlusion rays cast: the traced pixels' cuts and, at every pixel, the cells inside the
    /// leaves it resolves.
    pub rays: u64,
}

/// The frame: eq. 22 at every covered pixel's surface point, with that point's own traced cut
/// where its triangle's corners disagree (module docs). `baker` must trace the surface of `mesh`
/// (the mesh `cuts` belong to) over the tree `light` was summed for; `parents` is how the bake
/// refined it ([`crate::bake::Refinement::parents`], empty if not), so that rays start from the
/// imported mesh's smooth surface, as the reference's and the bake's do.
#[allow(clippy::too_many_arguments)] // the bake's parts, the light, the view and the material
pub fn render_traced(
    baker: &Baker,
    mesh: &Mesh,
    cuts: &Cuts,
    parents: &[[u32; 2]],
    tangents: Option<&[Vec4]>,
    light: &LightSums,
    camera: &Camera,
    (width, height): (u32, u32),
    shading: &Shading,
    settings: PrtSettings,
) -> (Image, TracedStats) {
    let settings = PrtSettings {
        per_pixel: true,
        ..settings
    };
    let base_count = mesh.positions.len().saturating_sub(parents.len());
    let blends = base_blends(base_count, parents);
    let fragments = rasterize(mesh, camera, width, height);
    let eye = camera.eye().as_dvec3();
    let mut image = Image::new(width, height);
    let mut stats = TracedStats {
        pixels: fragments.len(),
        ..TracedStats::default()
    };
    for block in fragments.chunks(BLOCK) {
        let mut points = Mesh {
            positions: Vec::with_capacity(block.len()),
            normals: Vec::with_capacity(block.len()),
            tangents: None,
            uvs: None,
            triangles: Vec::new(),
        };
        let mut point_tangents: Vec<Vec4> = Vec::new();
        // Per pixel: the corner whose cut it takes, or None where it is traced.
        let mut agreed: Vec<Option<u32>> = Vec::with_capacity(block.len());
        let mut origins: Vec<(DVec3, DVec3)> = Vec::new();
        // Every pixel's shadow-ray origin, for the cells inside its resolved leaves.
        let mut apexes: Vec<Vec3A> = Vec::with_capacity(block.len());
        for f in block {
            let Some(&tri) = mesh.triangles.get(f.triangle as usize) else {
                // Not a triangle of the mesh: a degenerate point, shaded black as by the PRT.
                points.positions.push(Vec3::ZERO);
                points.normals.push(Vec3::ZERO);
                point_tangents.push(Vec4::ZERO);
                agreed.push(Some(0));
                apexes.push(Vec3A::ZERO);
                continue;
            };
            let b = f.bary.map(|x| x as f64);
            let corners = [(tri[0], b[0]), (tri[1], b[1]), (tri[2], b[2])];
            let position: DVec3 = corners
                .iter()
                .map(|&(v, w)| mesh.positions[v as usize].as_dvec3() * w)
                .sum();
            // The point's normal, tangent and ray origin as the imported mesh gives them (the
            // reference's): a refined triangle's normalised midpoint normals interpolate to a
            // slightly different normal, which a sharp lobe sees.
            let imported = imported_corners(&blends, base_count, &corners);
            let surface: &[(u32, f64)] = imported.as_deref().unwrap_or(&corners);
            let normal = surface
                .iter()
                .map(|&(v, w)| mesh.normals[v as usize].as_dvec3() * w)
                .sum::<DVec3>()
                .normalize_or_zero();
            points.positions.push(position.as_vec3());
            points.normals.push(normal.as_vec3());
            if let Some(t) = tangents {
                point_tangents.push(surface.iter().map(|&(v, w)| t[v as usize] * w as f32).sum());
            }
            let same = |a: u32, b: u32| {
                let (a, b) = (a as usize, b as usize);
                cuts.nodes_of(a) == cuts.nodes_of(b) && cuts.quantised(a) == cuts.quantised(b)
            };
            let origin = smooth_surface_point(mesh, surface, position);
            apexes.push((origin + normal * baker.ray_offset()).as_vec3().into());
            if same(tri[0], tri[1]) && same(tri[0], tri[2]) {
                agreed.push(Some(tri[0]));
            } else {
                agreed.push(None);
                origins.push((origin, normal));
            }
        }
        let (traced, rays) = baker.point_cuts(&origins);
        stats.traced += origins.len();
        stats.rays += rays;
        let mut point_cuts = Cuts::with_vertices(block.len());
        let (mut row, mut entries) = (0, Vec::new());
        for (i, corner) in agreed.iter().enumerate() {
            match corner {
                Some(v) => cuts.cut_into(*v as usize, &mut entries),
                None => {
                    traced.cut_into(row, &mut entries);
                    row += 1;
                }
            }
            point_cuts.set(i, &entries);
        }
        let prt = Prt::new(
            &points,
            &point_cuts,
            &baker.tree,
            tangents.map(|_| point_tangents.as_slice()),
            settings,
        );
        let shading_points: Vec<ShadingPoint> = (0..block.len() as u32)
            .map(|i| ShadingPoint {
                corners: [i; 3],
                bary: [1.0, 0.0, 0.0],
            })
            .collect();
        let cell_rays = AtomicU64::new(0);
        let visible: &CellVisibility<'_> = &|i: u32, dir: DVec3| {
            cell_rays.fetch_add(1, Ordering::Relaxed);
            !baker
                .tracer
                .occluded(apexes[i as usize], dir.as_vec3().into())
        };
        // Where no ray can hit (decision (a)) every cell is open: V = 1, as the cuts say.
        let cells = baker.decisions.trace_visibility.then_some(visible);
        let radiance = prt.shade_points_with(&shading_points, light, eye, shading, cells);
        stats.rays += cell_rays.into_inner();
        for (f, rgb) in block.iter().zip(&radiance) {
            image.set(f.x, f.y, rgb.map(|x| x as f32));
        }
    }
    (image, stats)
}

/// A point of the refined mesh (its triangle's corners with barycentrics) as a blend of the imported
/// mesh's vertices (`blends[v - base_count]` for a midpoint; the first `base_count` vertices are the
/// imported ones): its imported triangle's corners, whose normals and smooth surface
/// ([`smooth_surface_point`]) the reference and the bake use. `None` where the blend spans more
/// than three (not within one imported triangle: a non-conforming refinement).
fn imported_corners(
    blends: &[Vec<(u32, f64)>],
    base_count: usize,
    corners: &[(u32, f64); 3],
) -> Option<Vec<(u32, f64)>> {
    let mut base: Vec<(u32, f64)> = Vec::with_capacity(3);
    for &(v, w) in corners {
        let own = [(v, 1.0)];
        let blend = match (v as usize).checked_sub(base_count) {
            Some(k) => blends.get(k).map_or(&own[..], Vec::as_slice),
            None => &own[..],
        };
        for &(u, x) in blend {
            match base.iter_mut().find(|(b, _)| *b == u) {
                Some(entry) => entry.1 += w * x,
                None => base.push((u, w * x)),
            }
        }
    }
    (base.len() <= 3).then_some(base)
}
