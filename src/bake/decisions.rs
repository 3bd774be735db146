//! What the scene calls for, decided before tracing and reported with reasons.
//!
//! - (a) [`decide_occlusion`]: must visibility be traced at all? Exact test: for every vertex, is
//!   the cone of all directions above its tangent plane free of geometry ([`Tracer::cone_free`])?
//!   If so no ray from any vertex can hit the scene (a convex object), nothing is traced and Ṽ =
//!   max(cos, 0). The test stops at the first vertex that sees geometry.
//! - (b) [`decide_frames`]: is there a tangent field for an anisotropic p(h)? glTF TANGENT, else
//!   MikkTSpace tangents from TEXCOORD_0, else none — and then the fit must be isotropic.
//! - (c) [`decide_resolution`]: how fine must the direction set be for this environment? Probe
//!   lobes with the BRDF's width in wi-space (λ/4 for a half-vector lobe of sharpness λ) are
//!   integrated against the environment on cube maps of 16, 32 and 64 texels per side and on a 128
//!   reference; the coarsest whose worst probe error is below 1 % of the brightest probe is what
//!   the light needs. A sun concentrates energy at high frequency and pushes the choice up. The
//!   BRDF adds its own floor ([`brdf_resolution`]: texels at most σ/2 wide); the finer of the two
//!   wins.
//! - (d) [`decide_cell`]: how large may a visibility cell (one ray, V ∈ {0, 1} over the cell) be
//!   for this scene under this environment, and are cells at shadow edges traced again finer?
//!   Measured at probe vertices on the cuts the bake would make there: the irradiance with each
//!   candidate (11.25° cells; 11.25° cells refined at shadow edges where a light's visibility
//!   changes; 5.625° cells refined likewise) against the irradiance with a
//!   ray per direction. Per kind of probe (vertices, area points) the cheapest within
//!   [`CELL_TOLERANCE`] (2 %) wins, else the cheapest within [`CELL_NEAR`] (1.2×) of the closest
//!   one's error; the finer of the two kinds' picks is used. Small bright lights (a
//!   studio's softboxes, a window) whose visibility a coarse cell gets wrong push it finer; a broad
//!   sky does not.
//! - (e) and (f) are made while baking, from the traced cuts: the mesh refinement
//!   ([`super::refine`]) and the vertex sampling ([`super::sparse`]); their reasons are stored here
//!   too.
//!
//! Inputs: the mesh, the tracer, the environment, the direction set's tree. Outputs: decisions with
//! reasons (serialisable, stored in the bake). No IO.

use super::cuts::{CellNeighbours, CutScratch, CutSettings, Prior, vertex_cut};
use super::tracer::Tracer;
use crate::light::{LightSource, texel_radiance_from};
use crate::scene::Mesh;
use crate::sphere::lobes::fibonacci_hemisphere;
use crate::sphere::{DirectionSet, LightTree, srbf};
use glam::{DVec3, Vec3A, Vec4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where the shading frames' tangents come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FrameSource {
    /// glTF TANGENT attribute.
    GltfTangents,
    /// MikkTSpace tangents generated from TEXCOORD_0.
    MikktspaceFromUvs,
    /// No tangent field: only isotropic lobes are meaningful.
    None,
}

/// The decisions of one bake, each with its reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decisions {
    /// (a) Whether visibility rays are traced.
    pub trace_visibility: bool,
    pub trace_reason: String,
    /// (b) Whether an anisotropic p(h) is possible.
    pub anisotropic: bool,
    pub frame_source: FrameSource,
    pub frame_reason: String,
    /// (c) Direction-set resolution (texels per cube-face side).
    pub resolution: usize,
    pub resolution_reason: String,
    /// (candidate resolution, worst probe error relative to the brightest probe).
    pub resolution_probe_errors: Vec<(usize, f64)>,
    /// (d) Visibility cell size (degrees; 0 = a ray per direction).
    pub cell_deg: f64,
    pub cell_reason: String,
    /// (candidate cell size in degrees, its boundary levels, relative RMS irradiance error at the
    /// probe vertices), per candidate of [`CELL_CANDIDATES`].
    pub cell_probe_errors: Vec<(f64, u32, f64)>,
    /// (d) Boundary refinement of the cells: how many times a cell beside a cell of the other
    /// visibility is traced again as cells half as wide, and why.
    #[serde(default)]
    pub boundary_levels: u32,
    #[serde(default)]
    pub boundary_reason: String,
    /// (e) Adaptive refinement of the mesh: why, and the vertex count after it.
    #[serde(default)]
    pub refine_reason: String,
    #[serde(default)]
    pub refined_vertices: usize,
    /// (f) Vertex sampling: why, and how many of the scene's vertices were interpolated, not
    ///     traced.
    #[serde(default)]
    pub sampling_reason: String,
    #[serde(default)]
    pub interpolated_vertices: usize,
}

impl Decisions {
    /// Each decision and its reason, as `glint bake` prints them (`refined`: the mesh was refined).
    pub fn summary(&self, refined: bool) -> Vec<(String, &str)> {
        let boundary = if self.boundary_levels > 0 {
            format!("{} boundary level(s)", self.boundary_levels)
        } else {
            "no boundary refinement".into()
        };
        vec![
            (
                (if self.trace_visibility {
                    "trace visibility"
                } else {
                    "no ray tracing"
                })
                .into(),
                self.trace_reason.as_str(),
            ),
            (
                (if self.anisotropic {
                    "anisotropic frame"
                } else {
                    "isotropic fit"
                })
                .into(),
                &self.frame_reason,
            ),
            (
                format!(
                    "{} directions ({} per face)",
                    6 * self.resolution * self.resolution,
                    self.resolution
                ),
                &self.resolution_reason,
            ),
            (
                format!("visibility cells of {}°", self.cell_deg),
                &self.cell_reason,
            ),
            (boundary, &self.boundary_reason),
            (
                (if refined {
                    "refined mesh"
                } else {
                    "mesh as it is"
                })
                .into(),
                &self.refine_reason,
            ),
            (
                (if self.interpolated_vertices > 0 {
                    "vertex sampling"
                } else {
                    "every vertex traced"
                })
                .into(),
                &self.sampling_reason,
            ),
        ]
    }
}

/// (a): (trace?, reason). The test stops at the first vertex (in the mesh's order) that sees
/// geometry above its tangent plane: the other vertices' tests are made where their cuts need them
/// ([`hemisphere_free`], [`super::cuts::Prior::root_hemisphere`]), and only at the vertices that
/// are traced (on dragon_100k split twice, 350 K of 800 K).
pub fn decide_occlusion(
    positions: &[DVec3],
    normals: &[DVec3],
    offset: f64,
    tracer: &Tracer,
) -> (bool, String) {
    let blocked = positions
        .par_iter()
        .zip(normals)
        .position_first(|(p, n)| !hemisphere_free(tracer, *p, *n, offset));
    let reason = match blocked {
        None => format!(
            "no vertex of {} sees geometry above its tangent plane (a convex object): no ray can hit the scene, visibility is the cosine alone",
            positions.len()
        ),
        Some(v) => format!(
            "vertex {v} of {} sees geometry above its tangent plane (the first in the mesh's order): visibility is ray traced",
            positions.len()
        ),
    };
    (blocked.is_some(), reason)
}

/// Whether nothing lies above the tangent plane of the vertex at `position` with unit `normal`
/// (the cone of all directions above it, from the ray origin `offset` along the normal): decision
/// (a)'s test, which also answers a cut's first cone test, the root's.
pub fn hemisphere_free(tracer: &Tracer, position: DVec3, normal: DVec3, offset: f64) -> bool {
    let apex: Vec3A = (position + normal * offset).as_vec3().into();
    let nf: Vec3A = normal.as_vec3().into();
    tracer.cone_free(apex, nf, nf, 0.0)
}

/// (b): tangents for the shading frames, with the decision.
pub fn decide_frames(mesh: &Mesh) -> (FrameSource, Option<Vec<Vec4>>, String) {
    if let Some(t) = &mesh.tangents {
        return (
            FrameSource::GltfTangents,
            Some(t.clone()),
            "the glTF file has TANGENT: anisotropic lobes follow it".into(),
        );
    }
    if let Some(uvs) = &mesh.uvs {
        if let Some(t) = mikktspace_tangents(mesh, uvs) {
            return (
                FrameSource::MikktspaceFromUvs,
                Some(t),
                "no TANGENT but TEXCOORD_0 is present: MikkTSpace tangents generated from the UVs"
                    .into(),
            );
        }
        return (FrameSource::None, None, "TEXCOORD_0 is present but MikkTSpace could not build tangents from it (degenerate UVs): the fit must be isotropic".into());
    }
    (FrameSource::None, None, "no TANGENT and no TEXCOORD_0: no consistent tangent field exists, so the fit must be isotropic".into())
}

struct MikkMesh<'a> {
    mesh: &'a Mesh,
    uvs: &'a [glam::Vec2],
    out: Vec<Vec4>,
}

impl bevy_mikktspace::Geometry for MikkMesh<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.triangles.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.mesh.triangles[face][vert] as usize;
        self.mesh
            .positions
            .get(i)
            .map_or([0.0; 3], |p| p.to_array())
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.mesh.triangles[face][vert] as usize;
        self.mesh
            .normals
            .get(i)
            .map_or([0.0, 0.0, 1.0], |n| n.to_array())
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let i = self.mesh.triangles[face][vert] as usize;
        self.uvs.get(i).map_or([0.0; 2], |t| t.to_array())
    }
    fn set_tangent(
        &mut self,
        tangent_space: Option<bevy_mikktspace::TangentSpace>,
        face: usize,
        vert: usize,
    ) {
        let i = self.mesh.triangles[face][vert] as usize;
        if let (Some(ts), Some(slot)) = (tangent_space, self.out.get_mut(i)) {
            *slot = Vec4::from_array(ts.tangent_encoded());
        }
    }
}

/// Per-vertex MikkTSpace tangents (xyz, w = handedness). Vertices shared by faces whose tangents
/// differ keep the last one written (glint does not split vertices; seams keep the importer's
/// vertex split).
fn mikktspace_tangents(mesh: &Mesh, uvs: &[glam::Vec2]) -> Option<Vec<Vec4>> {
    let mut geometry = MikkMesh {
        mesh,
        uvs,
        out: vec![Vec4::ZERO; mesh.positions.len()],
    };
    bevy_mikktspace::generate_tangents(&mut geometry).ok()?;
    let usable = geometry
        .out
        .iter()
        .filter(|t| t.truncate().length_squared() > 0.5)
        .count();
    (usable * 2 >= geometry.out.len()).then_some(geometry.out)
}

/// Candidate resolutions and the reference.
pub const RESOLUTION_CANDIDATES: [usize; 3] = [16, 32, 64];
pub const RESOLUTION_REFERENCE: usize = 128;
/// Worst probe error (relative to the brightest probe) that a resolution may have.
pub const RESOLUTION_TOLERANCE: f64 = 0.01;

/// The coarsest candidate whose texels (90°/n across) are at most σ/2 wide, so that the transfer
/// can evaluate the BRDF at one direction per texel: n ≥ π/σ. Measured (tests/it/transfer.rs,
/// suzanne): T is 1.03 % off direct integration at n = 32 and 0.59 % at n = 64 for σ = π/40.
pub fn brdf_resolution(lambda: f64) -> usize {
    let sigma = srbf::sigma_from_lambda(lambda).unwrap_or(0.08);
    let needed = std::f64::consts::PI / sigma;
    [16, 32, 64, 128, 256]
        .into_iter()
        .find(|&n| n as f64 >= needed)
        .unwrap_or(256)
}

/// (c): the resolution, the reason and the probe errors, with the environment's radiance per
/// texel of the chosen set (unrotated, [`texel_radiance_from`]), which the ring light and (d) read
/// too. `lambda` is the half-vector lobe sharpness the BRDF will use. The result is the finer of
/// what the environment needs (probe lobes) and what the BRDF needs ([`brdf_resolution`]).
pub fn decide_resolution(env: &LightSource, lambda: f64) -> Resolution {
    let light = light_resolution(env, lambda);
    let n_brdf = brdf_resolution(lambda);
    let (per_side, reason) = if n_brdf > light.per_side {
        let reason = format!(
            "{n_brdf} per side ({} directions): the BRDF's lobes (σ = {:.4}) need texels at most σ/2 wide; the environment alone would need {} ({})",
            6 * n_brdf * n_brdf,
            srbf::sigma_from_lambda(lambda).unwrap_or(0.0),
            light.per_side,
            light.reason
        );
        (n_brdf, reason)
    } else {
        (light.per_side, light.reason)
    };
    // The probes integrated the chosen set, unless the BRDF asks for one finer than the reference.
    let radiance = light
        .integrated
        .into_iter()
        .find(|(n, _)| *n == per_side)
        .map(|(_, r)| r);
    Resolution {
        per_side,
        reason,
        probe_errors: light.probe_errors,
        radiance,
    }
}

/// What decision (c) found.
#[derive(Debug, Clone)]
pub struct Resolution {
    /// Texels per cube-face side.
    pub per_side: usize,
    pub reason: String,
    /// (candidate resolution, worst probe error relative to the brightest probe).
    pub probe_errors: Vec<(usize, f64)>,
    /// The environment's radiance per texel of the chosen set at rotation 0, where the probes
    /// integrated that set (`None`: compute it with [`texel_radiance_from`]).
    pub radiance: Option<Vec<[f64; 3]>>,
}

/// The environment's part of (c), as [`light_resolution`] found it.
struct LightResolution {
    per_side: usize,
    reason: String,
    probe_errors: Vec<(usize, f64)>,
    /// Every set the probes integrated, with its per-texel radiance.
    integrated: Vec<(usize, Vec<[f64; 3]>)>,
}

/// The environment's part of (c).
fn light_resolution(env: &LightSource, lambda: f64) -> LightResolution {
    let lambda_wi = lambda / 4.0;
    // Probe axes over the whole sphere (two Fibonacci hemispheres).
    let mut probes = fibonacci_hemisphere(64);
    probes.extend(
        fibonacci_hemisphere(64)
            .into_iter()
            .map(|d| DVec3::new(d.x, d.y, -d.z)),
    );
    let mut integrated = Vec::new();
    let mut integrate = |n: usize| -> Vec<f64> {
        let Ok(set) = DirectionSet::cube(n) else {
            return vec![0.0; probes.len()];
        };
        let radiance = texel_radiance_from(env, &set, 0.0);
        let cut = srbf::support_cosine(lambda_wi, 30.0);
        let values = probes
            .par_iter()
            .map(|xi| {
                set.directions()
                    .iter()
                    .zip(set.solid_angles())
                    .zip(&radiance)
                    .filter_map(|((d, w), l)| {
                        let x = d.dot(*xi);
                        (x > cut)
                            .then(|| w * srbf::gaussian(x, lambda_wi) * (l[0] + l[1] + l[2]) / 3.0)
                    })
                    .sum()
            })
            .collect();
        integrated.push((n, radiance));
        values
    };
    let reference = integrate(RESOLUTION_REFERENCE);
    let scale = reference
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let mut errors = Vec::new();
    for n in RESOLUTION_CANDIDATES {
        let values = integrate(n);
        let worst = values
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f64, f64::max)
            / scale;
        errors.push((n, worst));
        if worst <= RESOLUTION_TOLERANCE {
            let reason = format!(
                "lobes of the BRDF's width (λ = {lambda:.1}, {lambda_wi:.1} in wi-space) integrate this environment within {:.2} % of a {RESOLUTION_REFERENCE}-per-side reference at {n} per side ({} directions)",
                worst * 100.0,
                6 * n * n
            );
            return LightResolution {
                per_side: n,
                reason,
                probe_errors: errors,
                integrated,
            };
        }
    }
    let reason = format!(
        "this environment keeps energy at high frequency (a sun or sharp features): even 64 per side is {:.2} % off, so the {RESOLUTION_REFERENCE}-per-side set is used",
        errors.last().map_or(0.0, |e| e.1) * 100.0
    );
    LightResolution {
        per_side: RESOLUTION_REFERENCE,
        reason,
        probe_errors: errors,
        integrated,
    }
}

/// Candidate visibility cells for (d), cheapest first: (cell size in degrees, boundary levels).
///
/// 22.5° is not a candidate: on studio_1k it put the bunny's frame 7.5 % off the Monte Carlo truth
/// (`glint study`), and the specular part, which the irradiance probe does not see, suffers first.
/// Where 11.25° cells miss shadows, they are refined at shadow edges three times, to 5.625°,
/// 2.8125° and 1.40625° ([`crate::bake::CutSettings::boundary_levels`]), under the light budget
/// ([`crate::bake::CutSettings::boundary_budget`]): a shadow edge is refined where a light's
/// visibility changes, not where the map is dark under every rotation. On dragon_100k under
/// studio_1k (every vertex traced, `render_studies bake_error`) this takes 34 M rays against
/// 134 M for 5.625° cells refined twice without the budget, at 0.27–1.29 % of a ray per
/// direction's irradiance (four rotations) against 0.10–0.55 %. 5.625° cells refined twice (with
/// the budget) stay the last candidate, for a scene where 11.25° cells are too coarse even to
/// find the shadow edges.
pub const CELL_CANDIDATES: [(f64, u32); 3] = [(11.25, 0), (11.25, 3), (5.625, 2)];
/// Largest relative RMS irradiance error at the probe vertices that a cell choice may cause.
pub const CELL_TOLERANCE: f64 = 0.02;
/// Where no candidate of (d) is within [`CELL_TOLERANCE`], the cheapest within this factor of the
/// closest one's error is taken: the cost should follow the error it buys.
pub const CELL_NEAR: f64 = 1.2;
/// Probes for (d): half of them vertices spread evenly over the vertex list, half points spread
/// over the surface by area ([`area_probes`]); each group picks a candidate, the finer pick is used.
/// Vertices alone follow the mesh's density: the brushed sphere's ground is two triangles, so its
/// shadow edges never voted, the sphere's vertices chose unrefined 11.25° cells, and the ground's
/// pixels were 5 % off (what a picture weighs is area, not vertices).
pub const CELL_PROBES: usize = 128;

/// `count` points spread over the mesh's surface by area (stratified over the triangles' running
/// area, a Hammersley point inside each stratum's triangle), each lifted onto the smooth surface
/// the normals describe ([`crate::scene::smooth_surface_point`]) and offset along its normal by
/// `offset`: (ray origin, unit normal), as [`decide_cell`]'s vertex origins are.
pub fn area_probes(mesh: &crate::scene::Mesh, count: usize, offset: f64) -> Vec<(DVec3, DVec3)> {
    let p = |v: u32| mesh.positions[v as usize].as_dvec3();
    let areas: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length())
        .collect();
    let total: f64 = areas.iter().sum();
    if !(total > 0.0) || count == 0 {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(count);
    let (mut k, mut below) = (0usize, 0.0f64);
    for i in 0..count {
        let target = (i as f64 + 0.5) / count as f64 * total;
        while k + 1 < areas.len() && below + areas[k] < target {
            below += areas[k];
            k += 1;
        }
        // Where in the triangle: the stratum's offset along its area and the radical inverse of
        // i, mapped uniformly onto the triangle.
        let u = ((target - below) / areas[k].max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        let w = (i as u32).reverse_bits() as f64 / 4_294_967_296.0;
        let su = u.sqrt();
        let b = [1.0 - su, su * (1.0 - w), su * w];
        let t = mesh.triangles[k];
        let corners = [(t[0], b[0]), (t[1], b[1]), (t[2], b[2])];
        let flat: DVec3 = corners.iter().map(|&(v, x)| p(v) * x).sum();
        let Some(n) = corners
            .iter()
            .map(|&(v, x)| mesh.normals[v as usize].as_dvec3() * x)
            .sum::<DVec3>()
            .try_normalize()
        else {
            continue;
        };
        let point = crate::scene::smooth_surface_point(mesh, &corners, flat);
        out.push((point + n * offset, n));
    }
    out
}

/// Leaves per visibility cell of `deg` degrees on a cube direction set of `resolution` per side:
/// (n · deg / 90°)², at least 1 (so 0° means a ray per direction).
pub fn cell_leaves(resolution: usize, deg: f64) -> usize {
    let per_side = (resolution as f64 * deg / 90.0).max(1.0);
    (per_side * per_side).round().max(1.0) as usize
}

/// The cells of at most `max_leaves` leaves in words: the tree's largest nodes that small, e.g. "48
/// directions each" for at most 64 on a 6×64² set, whose node sizes are 3·2^k.
pub fn cell_size_words(tree: &LightTree, max_leaves: usize) -> String {
    let sizes: Vec<u32> = nodes_of_at_most(tree, max_leaves as u32, 0)
        .iter()
        .map(|&k| tree.nodes()[k].count)
        .collect();
    let (lo, hi) = (
        sizes.iter().copied().min().unwrap_or(0),
        sizes.iter().copied().max().unwrap_or(0),
    );
    if lo == hi {
        format!("{hi} directions each")
    } else {
        format!("{lo}–{hi} directions each")
    }
}

/// A candidate of (d) in words: "11.25° cells" or "11.25° cells, 2 boundary levels".
fn cell_words(deg: f64, levels: u32) -> String {
    if levels == 0 {
        format!("{deg}° cells")
    } else {
        format!("{deg}° cells, {levels} boundary levels")
    }
}

/// The sizes boundary refinement traces cells of `deg` degrees at, `levels` times halved: "5.625°,
/// 2.8125° and 1.40625°".
fn refined_sizes(deg: f64, levels: u32) -> String {
    let sizes: Vec<String> = (1..=levels)
        .map(|l| format!("{}°", deg / f64::from(1u32 << l)))
        .collect();
    match sizes.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        Some((last, _)) => last.clone(),
        None => String::new(),
    }
}

/// What decision (d) chose: the visibility cell size and its boundary refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct CellDecision {
    /// Cell size in degrees.
    pub deg: f64,
    /// Boundary levels ([`crate::bake::CutSettings::boundary_levels`]).
    pub levels: u32,
    pub reason: String,
    /// Per candidate of [`CELL_CANDIDATES`]: (degrees, levels, relative RMS irradiance error at the
    /// probe vertices).
    pub errors: Vec<(f64, u32, f64)>,
    /// The chosen cells' neighbours (built for the probes), for the bake to take rather than build
    /// again.
    pub neighbours: CellNeighbours,
}

/// Per leaf (tree order), the mean of the three channels of its texel's radiance.
pub fn leaf_grey(tree: &LightTree, texel_radiance: &[[f64; 3]]) -> Vec<f64> {
    tree.leaf_texels()
        .iter()
        .map(|&t| texel_radiance[t as usize].iter().sum::<f64>() / 3.0)
        .collect()
}

/// Σ over a cut's nodes (k, V_k) of V_k Σ_{ℓ∈k} L_ℓ max(Ω_ℓ d_ℓ·n, 0): the irradiance of the
/// per-leaf radiance `radiance` (tree order) that the cut sees about unit normal `n`.
pub fn cut_irradiance(
    tree: &LightTree,
    cut: impl Iterator<Item = (u32, f32)>,
    radiance: &[f64],
    n: DVec3,
) -> f64 {
    let nodes = tree.nodes();
    cut.map(|(k, v)| {
        let node = nodes[k as usize];
        let range = node.first as usize..(node.first + node.count) as usize;
        v as f64
            * range
                .map(|l| radiance[l] * tree.leaf_moments()[l].dot(n).max(0.0))
                .sum::<f64>()
    })
    .sum()
}

/// (d): the visibility cell size and its boundary levels.
///
/// At [`CELL_PROBES`] probes — vertices (ray origins and normals in `origins`) and points spread
/// by area (`area`, [`area_probes`]), half and half — the irradiance of the environment's
/// luminance (at rotation 0; `texel_radiance`, per texel of `set`, [`texel_radiance_from`]) is
/// summed over the cut the bake would make there (the settings `cut`:
/// ε, the cap, the cone tests) with a ray per direction (the reference) and with each candidate of
/// [`CELL_CANDIDATES`], where one ray along a cell's mean direction decides V for the whole cell
/// and, with boundary levels, cells at a shadow edge are traced again finer. Each group of probes
/// (vertices, points by area) picks the first (cheapest) candidate whose relative RMS error over it
/// is within [`CELL_TOLERANCE`] or, if none is, the cheapest within [`CELL_NEAR`] of the one it
/// measures closest; the finer of the two picks is chosen, and the reason says how far off it
/// stays. A candidate's reported error is the larger of its two groups'.
#[allow(clippy::too_many_arguments)] // the light, the directions, both probe sets and the tracer
pub fn decide_cell(
    texel_radiance: &[[f64; 3]],
    set: &DirectionSet,
    tree: &LightTree,
    origins: &[(DVec3, DVec3)],
    area: &[(DVec3, DVec3)],
    tracer: &Tracer,
    cut: &CutSettings,
    ring: &super::refine::RingLight,
) -> CellDecision {
    let luminance = leaf_grey(tree, texel_radiance);
    let resolution = set.resolution();
    // The reference (a ray per direction), then the candidates.
    // (Built side by side: at 128 directions a side each table takes ~0.05 s on one core.)
    let mut configs: Vec<(CutSettings, CellNeighbours)> = std::iter::once((0.0, 0))
        .chain(CELL_CANDIDATES)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|(deg, levels)| {
            let leaves = cell_leaves(resolution, deg);
            // The reference (cells of one direction) cone-tests down to REFERENCE_CONE_LEAVES:
            // the same cut, without a ray into each direction of open sky.
            let settings = CutSettings {
                cell_leaves: leaves,
                boundary_levels: levels,
                cone_leaves: if leaves == 1 {
                    REFERENCE_CONE_LEAVES
                } else {
                    cut.cone_leaves
                },
                ..*cut
            };
            (settings, CellNeighbours::new(set, tree, leaves, levels))
        })
        .collect();
    let max_levels = CELL_CANDIDATES.iter().map(|c| c.1).max().unwrap_or(0);
    let area = &area[..area.len().min(CELL_PROBES / 2)];
    let vertex_count = origins.len().min(CELL_PROBES - area.len());
    let probes: Vec<(DVec3, DVec3)> = (0..vertex_count)
        .map(|i| origins[(2 * i + 1) * origins.len() / (2 * vertex_count)])
        .chain(area.iter().copied())
        .collect();
    let count = probes.len();
    // Per probe: the irradiance of the reference and of each candidate.
    let sums: Vec<Vec<f64>> = probes
        .par_iter()
        .map_init(
            || CutScratch::new(tree.leaf_count(), max_levels),
            |scratch, &(origin, normal)| {
                configs
                    .iter()
                    .map(|(settings, neighbours)| {
                        let prior = Prior {
                            cells: &[],
                            cell_ranges: &[],
                            agreed: &[],
                            root_hemisphere: false,
                            record: false,
                        };
                        let made = vertex_cut(
                            origin,
                            normal,
                            0.0,
                            tree,
                            tracer,
                            settings,
                            neighbours,
                            scratch,
                            prior,
                            Some(ring.gate(normal)),
                            None,
                        );
                        cut_irradiance(tree, made.entries.iter().copied(), &luminance, normal)
                    })
                    .collect()
            },
        )
        .collect();
    // Relative RMS error of candidate c over a group of probes (0 for an empty group).
    let group_error = |group: &[Vec<f64>], c: usize| -> f64 {
        let denominator: f64 = group
            .iter()
            .map(|s| s[0] * s[0])
            .sum::<f64>()
            .max(f64::MIN_POSITIVE);
        let squared: f64 = group.iter().map(|s| (s[c + 1] - s[0]).powi(2)).sum();
        (squared / denominator).sqrt()
    };
    let (by_vertex, by_area) = sums.split_at(vertex_count);
    let per_group: [Vec<f64>; 2] = [by_vertex, by_area].map(|group| {
        (0..CELL_CANDIDATES.len())
            .map(|c| group_error(group, c))
            .collect()
    });
    let errors: Vec<(f64, u32, f64)> = CELL_CANDIDATES
        .iter()
        .enumerate()
        .map(|(c, &(deg, levels))| (deg, levels, per_group[0][c].max(per_group[1][c])))
        .collect();
    let listed = errors
        .iter()
        .map(|&(d, l, e)| format!("{} {:.2} %", cell_words(d, l), e * 100.0))
        .collect::<Vec<_>>()
        .join("; ");
    // Each group picks the cheapest candidate within tolerance or, where none is, the cheapest
    // within [`CELL_NEAR`] of its closest; the finer of the two picks is taken. Finer cells are
    // closer on average, but not always at the probes (teapot under interior_1k: 11.25° 3.3 %,
    // 5.625° 3.5 %), and where they are by a hair (the bunny under interior_1k: 2.46 % against
    // 2.45 %, for 2× the rays) the extra rays buy nothing. Picking per group, not on the larger
    // error, keeps an error no candidate reduces in one group (a point where an occluder smaller
    // than any cell hides light: the dragon_100k patch under interior_1k, 7.5 % by area for all
    // three) from overruling what the other group needs (0.70 % at the vertices with refined
    // cells, 7.3 % without).
    let pick = |errors: &[f64]| -> (usize, bool) {
        match errors.iter().position(|&e| e <= CELL_TOLERANCE) {
            Some(c) => (c, true),
            None => {
                let best = errors.iter().copied().fold(f64::INFINITY, f64::min);
                let c = errors.iter().position(|&e| e <= CELL_NEAR * best);
                (c.unwrap_or(0), false)
            }
        }
    };
    let (vertex_pick, area_pick) = (pick(&per_group[0]), pick(&per_group[1]));
    let c = vertex_pick.0.max(area_pick.0);
    let chosen = (vertex_pick.1 && area_pick.1).then_some(c);
    let (deg, levels, _) = errors[c];
    let cells = cell_size_words(tree, cell_leaves(resolution, deg));
    let edges = if levels > 0 {
        format!(
            ", cells at shadow edges traced again at {}",
            refined_sizes(deg, levels)
        )
    } else {
        String::new()
    };
    let reason = match chosen {
        Some(_) => format!(
            "{deg}° cells ({cells}){edges}: the cheapest whose irradiance at {count} probes (vertices and points by area) is within {:.0} % (RMS) of a ray per direction ({listed})",
            CELL_TOLERANCE * 100.0
        ),
        None => format!(
            "{deg}° cells ({cells}){edges}: at {count} probes (vertices and points by area) no candidate is within {:.0} % of a ray per direction at both (small bright lights make cells miss their shadows, occluders smaller than a cell hide light), so each kind of probe took the cheapest within tolerance or within {:.0} % of its closest, and the finer of the two is used ({listed})",
            CELL_TOLERANCE * 100.0,
            (CELL_NEAR - 1.0) * 100.0
        ),
    };
    CellDecision {
        deg,
        levels,
        reason,
        errors,
        neighbours: configs.swap_remove(c + 1).1,
    }
}

/// [`CutSettings::cone_leaves`] of decision (d)'s reference, a ray per direction: the same cuts
/// (`tests/it/bake_visibility.rs`), open sky settled by cone tests on nodes of more than 256
/// directions. Deciding the 15 mesh × map pairs of `cargo bench --bench bake -- matrix` took
/// 18.2 s without them and 15.9 s with them (interior_1k, 128 directions a side: 1.2–2.5 s →
/// 1.2–2.3 s); 16, 64, 256 and 1024 leaves measured alike within the machine's noise.
const REFERENCE_CONE_LEAVES: usize = 256;

/// (d), second part: how many times cells at a shadow edge are traced again as cells half as wide
/// ([`crate::bake::CutSettings::boundary_levels`]), and why: as set, or as [`decide_cell`] decided
/// with the cell size (`decided`: its levels and reason). One ray per cell point-samples
/// visibility, so a shadow edge that crosses a cell moves to the cell's border, and the error does
/// not average out over a light as the irradiance's does: a sharp lobe's highlight sees it whole.
pub fn decide_boundary(
    explicit: Option<u32>,
    cell_explicit: bool,
    traced: bool,
    decided: Option<&CellDecision>,
) -> (u32, String) {
    if let Some(levels) = explicit {
        return (
            levels,
            format!("boundary refinement set explicitly to {levels} level(s)"),
        );
    }
    if !traced {
        return (0, "no boundary refinement: no visibility is traced".into());
    }
    if cell_explicit {
        return (0, "no boundary refinement: the cell size was set explicitly (set the levels too to refine)".into());
    }
    let Some(d) = decided else {
        return (0, "no boundary refinement".into());
    };
    let (deg0, _, error0) = d.errors.first().copied().unwrap_or((d.deg, 0, 0.0));
    if d.levels == 0 {
        return (
            0,
            format!(
                "no boundary refinement: {deg0}° cells are within {:.0} % at the probes, so the light is soft and shadow edges blur over a cell",
                CELL_TOLERANCE * 100.0
            ),
        );
    }
    (
        d.levels,
        format!(
            "cells at shadow edges traced again at {}, where they gate light: {deg0}° cells missed {:.1} % of the irradiance at the probes, so small bright lights cast sharp shadows, which a ray per cell moves to the cells' borders",
            refined_sizes(d.deg, d.levels),
            error0 * 100.0
        ),
    )
}

/// The largest nodes under `root` covering at most `max_leaves` leaves (leaves always qualify), in
/// leaf order: the visibility cells of that size.
pub(crate) fn nodes_of_at_most(tree: &LightTree, max_leaves: u32, root: usize) -> Vec<usize> {
    let nodes = tree.nodes();
    let (mut out, mut stack) = (Vec::new(), vec![root]);
    while let Some(k) = stack.pop() {
        let node = nodes[k];
        if node.count <= max_leaves || node.is_leaf() {
            out.push(k);
        } else {
            stack.push(node.right as usize);
            stack.push(node.left as usize);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decided(deg: f64, levels: u32, errors: &[(f64, u32, f64)]) -> CellDecision {
        CellDecision {
            deg,
            levels,
            reason: String::new(),
            errors: errors.to_vec(),
            neighbours: CellNeighbours::default(),
        }
    }

    #[test]
    fn boundary_refinement_follows_the_cell_decision() {
        // The coarsest cells missed shadows: sharp lights, the finer cells refined as decided.
        let missed = decided(
            11.25,
            3,
            &[
                (11.25, 0, 2.0 * CELL_TOLERANCE),
                (11.25, 3, 0.5 * CELL_TOLERANCE),
                (5.625, 2, 0.4 * CELL_TOLERANCE),
            ],
        );
        let (levels, reason) = decide_boundary(None, false, true, Some(&missed));
        assert_eq!(levels, 3);
        assert!(
            reason.contains("5.625°, 2.8125° and 1.40625°") && reason.contains("4.0 %"),
            "{reason}"
        );
        assert_eq!(refined_sizes(5.625, 2), "2.8125° and 1.40625°");
        assert_eq!(refined_sizes(8.0, 1), "4°");
        // Within tolerance at the coarsest: soft light, no refinement.
        let soft = decided(11.25, 0, &[(11.25, 0, 0.5 * CELL_TOLERANCE)]);
        assert_eq!(decide_boundary(None, false, true, Some(&soft)).0, 0);
        // Explicit levels win; no tracing or an explicit cell (no probe) means none.
        assert_eq!(decide_boundary(Some(1), false, true, Some(&soft)).0, 1);
        assert_eq!(decide_boundary(None, false, false, None).0, 0);
        assert_eq!(decide_boundary(None, true, true, None).0, 0);
    }
}
