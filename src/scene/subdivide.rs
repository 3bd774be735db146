//! Midpoint subdivision: every triangle split into four at its edge midpoints, the new vertices
//! shared between the two triangles of an edge (so the mesh stays watertight where it was).
//!
//! Used to sample visibility more densely on coarse meshes: the surface is unchanged (the new
//! vertices lie on the old flat triangles), and attributes are interpolated as the renderers
//! interpolate them across a triangle — normals and tangents normalised, UVs linear, handedness
//! kept from the first end.
//!
//! Inputs: a [`Mesh`]. Output: a [`Mesh`] with V + E vertices and 4T triangles; the first V vertices
//! are the input's, in order. Invariants: deterministic (new vertices in order of first use); no IO.

use super::Mesh;
use glam::{Vec3, Vec4};
use std::collections::HashMap;

/// One level of midpoint subdivision.
pub fn subdivide_midpoint(mesh: &Mesh) -> Mesh {
    let mut out = Mesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        tangents: mesh.tangents.clone(),
        uvs: mesh.uvs.clone(),
        triangles: Vec::with_capacity(mesh.triangles.len() * 4),
    };
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.triangles.len() * 3 / 2);
    let mut midpoint = |out: &mut Mesh, a: u32, b: u32| -> u32 {
        let key = (a.min(b), a.max(b));
        *midpoints.entry(key).or_insert_with(|| {
            let (i, j) = (key.0 as usize, key.1 as usize);
            out.positions.push((out.positions[i] + out.positions[j]) * 0.5);
            let n = (out.normals[i] + out.normals[j]).normalize_or_zero();
            out.normals.push(if n == Vec3::ZERO { out.normals[i] } else { n });
            if let Some(t) = out.tangents.as_mut() {
                let (ti, tj) = (t[i], t[j]);
                let xyz = (ti.truncate() + tj.truncate()).normalize_or_zero();
                t.push(Vec4::new(xyz.x, xyz.y, xyz.z, ti.w));
            }
            if let Some(uv) = out.uvs.as_mut() {
                uv.push((uv[i] + uv[j]) * 0.5);
            }
            (out.positions.len() - 1) as u32
        })
    };
    for &[a, b, c] in &mesh.triangles {
        let ab = midpoint(&mut out, a, b);
        let bc = midpoint(&mut out, b, c);
        let ca = midpoint(&mut out, c, a);
        out.triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quad_splits_into_eight_triangles_with_shared_midpoints() {
        let (mesh, _) = crate::raster::tests::unit_quad_scene();
        let s = subdivide_midpoint(&mesh);
        // 4 corners + 5 edges (4 sides and the diagonal), 2 → 8 triangles.
        assert_eq!((s.positions.len(), s.triangles.len()), (9, 8));
        assert_eq!(&s.positions[..4], &mesh.positions[..]);
        // Area is kept and every new vertex lies on an old edge's midpoint.
        let area = |m: &Mesh| -> f32 { m.triangles.iter().map(|t| (m.positions[t[1] as usize] - m.positions[t[0] as usize]).cross(m.positions[t[2] as usize] - m.positions[t[0] as usize]).length() * 0.5).sum() };
        assert!((area(&s) - area(&mesh)).abs() < 1e-6);
        // Every edge of the result is used by at most two triangles (watertight where the input was).
        let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &s.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(uses.values().all(|&u| u <= 2));
        assert_eq!(uses.values().filter(|&&u| u == 2).count(), 8, "16 edges (Euler, a disc: V − E + F = 1), 8 on the boundary");
    }
}
