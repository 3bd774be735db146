//! The preview sphere that material-only files carry, so a viewer (and a validator) sees the
//! material used by something.
//!
//! Inputs: a radius and a subdivision. Output: a [`SceneMesh`] UV sphere about +Y with unit
//! normals, tangents along increasing u (w = +1) and TEXCOORD_0 (u = φ/2π, v = θ/π from the +Y
//! pole). Invariants: counter-clockwise seen from outside, no degenerate triangles (pole rows emit
//! one triangle per slice), deterministic.

use crate::material::SceneMesh;
use std::f64::consts::PI;

/// Slices (around Y) and stacks (pole to pole) of the preview sphere.
pub const PREVIEW_SLICES: usize = 32;
pub const PREVIEW_STACKS: usize = 16;

/// A UV sphere of `radius` (metres) about the origin, Y up.
pub fn uv_sphere(radius: f32, slices: usize, stacks: usize) -> SceneMesh {
    let (slices, stacks) = (slices.max(3), stacks.max(2));
    let mut m = SceneMesh {
        tangents: Some(Vec::new()),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    for i in 0..=stacks {
        let theta = PI * i as f64 / stacks as f64;
        for j in 0..=slices {
            let phi = 2.0 * PI * j as f64 / slices as f64;
            let n = [
                theta.sin() * phi.sin(),
                theta.cos(),
                theta.sin() * phi.cos(),
            ];
            let n = if i == 0 {
                [0.0, 1.0, 0.0]
            } else if i == stacks {
                [0.0, -1.0, 0.0]
            } else {
                n
            };
            m.positions.push([
                (radius as f64 * n[0]) as f32,
                (radius as f64 * n[1]) as f32,
                (radius as f64 * n[2]) as f32,
            ]);
            m.normals.push([n[0] as f32, n[1] as f32, n[2] as f32]);
            if let Some(t) = m.tangents.as_mut() {
                t.push([phi.cos() as f32, 0.0, -phi.sin() as f32, 1.0]);
            }
            if let Some(uv) = m.uvs.as_mut() {
                uv.push([
                    (j as f64 / slices as f64) as f32,
                    (i as f64 / stacks as f64) as f32,
                ]);
            }
        }
    }
    let row = slices + 1;
    for i in 0..stacks {
        for j in 0..slices {
            let a = (i * row + j) as u32;
            let b = ((i + 1) * row + j) as u32;
            let c = b + 1;
            let d = a + 1;
            if i != stacks - 1 {
                m.indices.extend_from_slice(&[a, b, c]);
            }
            if i != 0 {
                m.indices.extend_from_slice(&[a, c, d]);
            }
        }
    }
    m
}

/// The preview sphere material-only files use.
pub fn preview_sphere() -> SceneMesh {
    uv_sphere(1.0, PREVIEW_SLICES, PREVIEW_STACKS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_is_closed_outward_and_valid() {
        let m = preview_sphere();
        assert!(m.validated().is_ok());
        assert_eq!(
            m.indices.len() / 3,
            2 * PREVIEW_SLICES * (PREVIEW_STACKS - 1)
        );
        // Outward winding: the geometric normal agrees with the vertex normals; no degenerate
        // triangle.
        for t in m.indices.chunks(3) {
            let p = |k: usize| m.positions[t[k] as usize].map(|x| x as f64);
            let (a, b, c) = (p(0), p(1), p(2));
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let g = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let centre = [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]];
            let area2 = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            assert!(area2 > 1e-6);
            assert!(g[0] * centre[0] + g[1] * centre[1] + g[2] * centre[2] > 0.0);
        }
    }
}
