//! CPU rasterisation: which triangle covers each pixel centre, with perspective-correct
//! barycentrics.
//!
//! Inputs: a world-space [`Mesh`], a [`Camera`], an image size (any; the camera's aspect is used
//! for the projection, as a render target of another size would). Output: per covered pixel
//! (row-major, origin top-left, pixel centres at +½) the triangle, its barycentrics and depth.
//! Depth tested (nearest wins); back faces are kept (a single-sided test would drop thin or open
//! geometry). Triangles with a vertex at or behind the camera plane are skipped (objects are framed
//! in front of the camera).
//!
//! Invariants: barycentrics sum to 1 and are ≥ 0 (within rounding); deterministic (the same
//! fragments whatever the thread count); no IO.

use crate::scene::{Camera, Mesh};
use glam::{Vec3, Vec4Swizzles};
use rayon::prelude::*;

/// One covered pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fragment {
    pub x: u32,
    pub y: u32,
    pub triangle: u32,
    /// Perspective-correct barycentrics of the triangle's three vertices.
    pub bary: [f32; 3],
    /// NDC depth (0 near .. 1 far).
    pub depth: f32,
}

/// Rasterises every triangle; returns the visible fragment of each covered pixel, row-major.
pub fn rasterize(mesh: &Mesh, camera: &Camera, width: u32, height: u32) -> Vec<Fragment> {
    rasterize_triangles(&mesh.positions, &mesh.triangles, camera, width, height)
}

/// [`rasterize`] over bare positions and triangles (e.g. a subdivided shading mesh). The triangles
/// are split into one chunk per thread, each rasterised into its own depth buffer, and the buffers
/// merged nearest first with ties to the lower triangle index: the result of one sequential pass.
pub fn rasterize_triangles(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    camera: &Camera,
    width: u32,
    height: u32,
) -> Vec<Fragment> {
    let clip_from_world = camera.clip_from_world();
    let clip: Vec<glam::Vec4> = positions
        .par_iter()
        .map(|p| clip_from_world * p.extend(1.0))
        .collect();
    let chunk = triangles
        .len()
        .div_ceil(rayon::current_num_threads().max(1))
        .max(4096);
    let buffers: Vec<Vec<Option<Fragment>>> = triangles
        .par_chunks(chunk)
        .enumerate()
        .map(|(c, tris)| rasterize_chunk(&clip, tris, c * chunk, width, height))
        .collect();
    let mut buffers = buffers.into_iter();
    let Some(mut best) = buffers.next() else {
        return Vec::new();
    };
    for other in buffers {
        for (b, o) in best.iter_mut().zip(other) {
            if let Some(o) = o {
                match b {
                    // Later chunks hold higher triangle indices: on a tie the earlier one stays.
                    Some(f) if f.depth <= o.depth => {}
                    _ => *b = Some(o),
                }
            }
        }
    }
    best.into_iter().flatten().collect()
}

/// The nearest fragment per pixel of `triangles` (indices from `first`) over clip-space positions.
fn rasterize_chunk(
    clip: &[glam::Vec4],
    triangles: &[[u32; 3]],
    first: usize,
    width: u32,
    height: u32,
) -> Vec<Option<Fragment>> {
    let (w, h) = (width as usize, height as usize);
    let mut depth = vec![f32::INFINITY; w * h];
    let mut best: Vec<Option<Fragment>> = vec![None; w * h];
    for (t, tri) in triangles.iter().enumerate() {
        let t = first + t;
        let (Some(&c0), Some(&c1), Some(&c2)) = (
            clip.get(tri[0] as usize),
            clip.get(tri[1] as usize),
            clip.get(tri[2] as usize),
        ) else {
            continue;
        };
        let c = [c0, c1, c2];
        if c.iter()
            .any(|v| v.w.is_nan() || v.w <= 1e-6 || !v.is_finite())
        {
            continue;
        }
        // Screen positions (pixels) and 1/w.
        let s: [Vec3; 3] = c.map(|v| {
            let ndc = v.xyz() / v.w;
            Vec3::new(
                (ndc.x + 1.0) * 0.5 * width as f32,
                (1.0 - ndc.y) * 0.5 * height as f32,
                ndc.z,
            )
        });
        let inv_w = [1.0 / c[0].w, 1.0 / c[1].w, 1.0 / c[2].w];
        let area = edge(s[0], s[1], s[2]);
        if area.abs() < 1e-12 {
            continue;
        }
        let min_x = s
            .iter()
            .map(|p| p.x)
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let max_x = s
            .iter()
            .map(|p| p.x)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil()
            .min(width as f32) as usize;
        let min_y = s
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let max_y = s
            .iter()
            .map(|p| p.y)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil()
            .min(height as f32) as usize;
        for py in min_y..max_y {
            for px in min_x..max_x {
                let p = Vec3::new(px as f32 + 0.5, py as f32 + 0.5, 0.0);
                let l0 = edge(s[1], s[2], p) / area;
                let l1 = edge(s[2], s[0], p) / area;
                let l2 = 1.0 - l0 - l1;
                if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                    continue;
                }
                let z = l0 * s[0].z + l1 * s[1].z + l2 * s[2].z;
                if !(0.0..=1.0).contains(&z) {
                    continue;
                }
                let k = py * w + px;
                if z < depth[k] {
                    depth[k] = z;
                    let pc = [l0 * inv_w[0], l1 * inv_w[1], l2 * inv_w[2]];
                    let sum = pc[0] + pc[1] + pc[2];
                    best[k] = Some(Fragment {
                        x: px as u32,
                        y: py as u32,
                        triangle: t as u32,
                        bary: [pc[0] / sum, pc[1] / sum, pc[2] / sum],
                        depth: z,
                    });
                }
            }
        }
    }
    best
}

/// The vertices of the triangles that cover at least one pixel of the view, ascending: what must be
/// baked before the view can be fitted ("first fit fast").
pub fn visible_vertices(mesh: &Mesh, camera: &Camera, width: u32, height: u32) -> Vec<u32> {
    let mut seen = vec![false; mesh.positions.len()];
    for f in rasterize(mesh, camera, width, height) {
        if let Some(tri) = mesh.triangles.get(f.triangle as usize) {
            for &i in tri {
                if let Some(s) = seen.get_mut(i as usize) {
                    *s = true;
                }
            }
        }
    }
    seen.iter()
        .enumerate()
        .filter(|(_, s)| **s)
        .map(|(i, _)| i as u32)
        .collect()
}

/// Twice the signed area of (a, b, p) in screen space.
#[inline]
fn edge(a: Vec3, b: Vec3, p: Vec3) -> f32 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::{Bounds, orbit_camera};

    /// A unit square at z = 0 (two triangles) and a 200×200 camera on +Z looking at it.
    pub(crate) fn unit_quad_scene() -> (Mesh, Camera) {
        let mesh = Mesh {
            positions: vec![
                Vec3::new(-0.5, -0.5, 0.0),
                Vec3::new(0.5, -0.5, 0.0),
                Vec3::new(0.5, 0.5, 0.0),
                Vec3::new(-0.5, 0.5, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            tangents: None,
            uvs: None,
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        let bounds = Bounds {
            min: Vec3::new(-1.0, -1.0, -0.1),
            max: Vec3::new(1.0, 1.0, 0.1),
        };
        (mesh, orbit_camera(&bounds, 0.0, 0.0, 0.0, 200, 200))
    }

    #[test]
    fn chunked_rasterisation_equals_one_sequential_pass() {
        // 20,000 random overlapping triangles, each drawn twice (exact depth ties), so the chunks
        // overlap everywhere: the fragments with 1 and 3 threads are identical, and every tie goes
        // to the lower triangle index (even ones: each pair is (2i, 2i + 1)).
        let mut rng = crate::math::Rng::new(5);
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..10_000u32 {
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
            let t = [3 * i, 3 * i + 1, 3 * i + 2];
            triangles.push(t);
            triangles.push(t);
        }
        let (_, camera) = unit_quad_scene();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| rasterize_triangles(&positions, &triangles, &camera, 96, 80))
        };
        let (one, three) = (run(1), run(3));
        assert!(one.len() > 800, "{}", one.len());
        assert_eq!(one, three);
        assert!(one.iter().all(|f| f.triangle % 2 == 0));
    }

    #[test]
    fn a_quad_facing_the_camera_covers_its_projected_area() {
        // A unit square at z = 0 seen from +Z: its pixel count matches the projected area, and the
        // barycentric-interpolated positions land where the camera ray through the pixel meets z =
        // 0.
        let (mesh, camera) = unit_quad_scene();
        let frags = rasterize(&mesh, &camera, 200, 200);
        let eye = camera.eye();
        let dist = eye.z;
        let half_height_px = 100.0;
        let px_per_unit = half_height_px / (dist * (camera.yfov_rad * 0.5).tan());
        let expected = (px_per_unit * 1.0).powi(2);
        assert!(
            ((frags.len() as f32 - expected) / expected).abs() < 0.03,
            "{} vs {expected}",
            frags.len()
        );
        let inv = camera.clip_from_world().inverse();
        for f in frags.iter().step_by(97) {
            let tri = mesh.triangles[f.triangle as usize];
            let p: Vec3 = (0..3)
                .map(|i| mesh.positions[tri[i] as usize] * f.bary[i])
                .sum();
            // Unproject the pixel centre to a ray and intersect z = 0.
            let ndc_x = (f.x as f32 + 0.5) / 100.0 - 1.0;
            let ndc_y = 1.0 - (f.y as f32 + 0.5) / 100.0;
            let far = inv * glam::Vec4::new(ndc_x, ndc_y, 0.5, 1.0);
            let far = far.xyz() / far.w;
            let dir = (far - eye).normalize();
            let hit = eye + dir * (-eye.z / dir.z);
            assert!((hit - p).length() < 1e-4, "{hit} vs {p}");
        }
    }
}
