//! What the scene calls for, decided before tracing and reported with reasons.
//!
//! - (a) [`decide_occlusion`]: must visibility be traced at all? Exact test: for every vertex, is the
//!   cone of all directions above its tangent plane free of geometry ([`Tracer::cone_free`])? If so no
//!   ray from any vertex can hit the scene (a convex object), nothing is traced and Ṽ = max(cos, 0).
//! - (b) [`decide_frames`]: is there a tangent field for an anisotropic p(h)? glTF TANGENT, else
//!   MikkTSpace tangents from TEXCOORD_0, else none — and then the fit must be isotropic.
//! - (c) [`decide_resolution`]: how fine must the direction set be for this environment? Probe lobes
//!   with the BRDF's width in wi-space (λ/4 for a half-vector lobe of sharpness λ) are integrated against
//!   the environment on cube maps of 16, 32 and 64 texels per side and on a 128 reference; the coarsest
//!   whose worst probe error is below 1 % of the brightest probe is what the light needs. A sun
//!   concentrates energy at high frequency and pushes the choice up. The BRDF adds its own floor
//!   ([`brdf_resolution`]: texels at most σ/2 wide); the finer of the two wins.
//!
//! Inputs: the mesh, the tracer, the environment. Outputs: decisions with reasons (serialisable, stored
//! in the bake). No IO.

use super::tracer::Tracer;
use crate::env::EnvMap;
use crate::light::texel_radiance;
use crate::scene::Mesh;
use crate::sphere::lobes::fibonacci_hemisphere;
use crate::sphere::{DirectionSet, srbf};
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
}

/// (a): (trace?, reason).
pub fn decide_occlusion(positions: &[DVec3], normals: &[DVec3], offset: f64, tracer: &Tracer) -> (bool, String) {
    let blocked = positions
        .par_iter()
        .zip(normals)
        .filter(|(p, n)| {
            let apex: Vec3A = (**p + **n * offset).as_vec3().into();
            let nf: Vec3A = n.as_vec3().into();
            !tracer.cone_free(apex, nf, nf, 0.0)
        })
        .count();
    if blocked == 0 {
        (
            false,
            format!(
                "no vertex of {} sees geometry above its tangent plane (a convex object): no ray can hit the scene, visibility is the cosine alone",
                positions.len()
            ),
        )
    } else {
        (true, format!("{blocked} of {} vertices see geometry above their tangent plane: visibility is ray traced", positions.len()))
    }
}

/// (b): tangents for the shading frames, with the decision.
pub fn decide_frames(mesh: &Mesh) -> (FrameSource, Option<Vec<Vec4>>, String) {
    if let Some(t) = &mesh.tangents {
        return (FrameSource::GltfTangents, Some(t.clone()), "the glTF file has TANGENT: anisotropic lobes follow it".into());
    }
    if let Some(uvs) = &mesh.uvs {
        if let Some(t) = mikktspace_tangents(mesh, uvs) {
            return (
                FrameSource::MikktspaceFromUvs,
                Some(t),
                "no TANGENT but TEXCOORD_0 is present: MikkTSpace tangents generated from the UVs".into(),
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
        self.mesh.positions.get(i).map_or([0.0; 3], |p| p.to_array())
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.mesh.triangles[face][vert] as usize;
        self.mesh.normals.get(i).map_or([0.0, 0.0, 1.0], |n| n.to_array())
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let i = self.mesh.triangles[face][vert] as usize;
        self.uvs.get(i).map_or([0.0; 2], |t| t.to_array())
    }
    fn set_tangent(&mut self, tangent_space: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
        let i = self.mesh.triangles[face][vert] as usize;
        if let (Some(ts), Some(slot)) = (tangent_space, self.out.get_mut(i)) {
            *slot = Vec4::from_array(ts.tangent_encoded());
        }
    }
}

/// Per-vertex MikkTSpace tangents (xyz, w = handedness). Vertices shared by faces whose tangents differ
/// keep the last one written (glint does not split vertices; seams keep the importer's vertex split).
fn mikktspace_tangents(mesh: &Mesh, uvs: &[glam::Vec2]) -> Option<Vec<Vec4>> {
    let mut geometry = MikkMesh { mesh, uvs, out: vec![Vec4::ZERO; mesh.positions.len()] };
    bevy_mikktspace::generate_tangents(&mut geometry).ok()?;
    let usable = geometry.out.iter().filter(|t| t.truncate().length_squared() > 0.5).count();
    (usable * 2 >= geometry.out.len()).then_some(geometry.out)
}

/// Candidate resolutions and the reference.
pub const RESOLUTION_CANDIDATES: [usize; 3] = [16, 32, 64];
pub const RESOLUTION_REFERENCE: usize = 128;
/// Worst probe error (relative to the brightest probe) that a resolution may have.
pub const RESOLUTION_TOLERANCE: f64 = 0.01;

/// The coarsest candidate whose texels (90°/n across) are at most σ/2 wide, so that the transfer can
/// evaluate the BRDF at one direction per texel: n ≥ π/σ. Measured (tests/transfer.rs, suzanne): T is
/// 1.03 % off direct integration at n = 32 and 0.59 % at n = 64 for σ = π/40.
pub fn brdf_resolution(lambda: f64) -> usize {
    let sigma = srbf::sigma_from_lambda(lambda).unwrap_or(0.08);
    let needed = std::f64::consts::PI / sigma;
    [16, 32, 64, 128, 256].into_iter().find(|&n| n as f64 >= needed).unwrap_or(256)
}

/// (c): (resolution, reason, probe errors). `lambda` is the half-vector lobe sharpness the BRDF will use.
/// The result is the finer of what the environment needs (probe lobes) and what the BRDF needs
/// ([`brdf_resolution`]).
pub fn decide_resolution(env: &EnvMap, lambda: f64) -> (usize, String, Vec<(usize, f64)>) {
    let (n_light, light_reason, errors) = light_resolution(env, lambda);
    let n_brdf = brdf_resolution(lambda);
    if n_brdf > n_light {
        let reason = format!(
            "{n_brdf} per side ({} directions): the BRDF's lobes (σ = {:.4}) need texels at most σ/2 wide; the environment alone would need {n_light} ({light_reason})",
            6 * n_brdf * n_brdf,
            srbf::sigma_from_lambda(lambda).unwrap_or(0.0)
        );
        return (n_brdf, reason, errors);
    }
    (n_light, light_reason, errors)
}

/// The environment's part of (c).
fn light_resolution(env: &EnvMap, lambda: f64) -> (usize, String, Vec<(usize, f64)>) {
    let lambda_wi = lambda / 4.0;
    // Probe axes over the whole sphere (two Fibonacci hemispheres).
    let mut probes = fibonacci_hemisphere(64);
    probes.extend(fibonacci_hemisphere(64).into_iter().map(|d| DVec3::new(d.x, d.y, -d.z)));
    let integrate = |n: usize| -> Vec<f64> {
        let Ok(set) = DirectionSet::cube(n) else { return vec![0.0; probes.len()] };
        let radiance = texel_radiance(env, &set, 0.0);
        let cut = srbf::support_cosine(lambda_wi, 30.0);
        probes
            .par_iter()
            .map(|xi| {
                set.directions()
                    .iter()
                    .zip(set.solid_angles())
                    .zip(&radiance)
                    .filter_map(|((d, w), l)| {
                        let x = d.dot(*xi);
                        (x > cut).then(|| w * srbf::gaussian(x, lambda_wi) * (l[0] + l[1] + l[2]) / 3.0)
                    })
                    .sum()
            })
            .collect()
    };
    let reference = integrate(RESOLUTION_REFERENCE);
    let scale = reference.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    let mut errors = Vec::new();
    for n in RESOLUTION_CANDIDATES {
        let values = integrate(n);
        let worst = values.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max) / scale;
        errors.push((n, worst));
        if worst <= RESOLUTION_TOLERANCE {
            let reason = format!(
                "lobes of the BRDF's width (λ = {lambda:.1}, {lambda_wi:.1} in wi-space) integrate this environment within {:.2} % of a {RESOLUTION_REFERENCE}-per-side reference at {n} per side ({} directions)",
                worst * 100.0,
                6 * n * n
            );
            return (n, reason, errors);
        }
    }
    let reason = format!(
        "this environment keeps energy at high frequency (a sun or sharp features): even 64 per side is {:.2} % off, so the {RESOLUTION_REFERENCE}-per-side set is used",
        errors.last().map_or(0.0, |e| e.1) * 100.0
    );
    (RESOLUTION_REFERENCE, reason, errors)
}
