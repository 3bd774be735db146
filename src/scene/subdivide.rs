//! Midpoint subdivision: every triangle split into four at its edge midpoints, the new vertices
//! shared between the two triangles of an edge (so the mesh stays watertight where it was).
//!
//! Used to sample visibility more densely on coarse meshes: the surface is unchanged (the new
//! vertices lie on the old flat triangles), and attributes are interpolated as the renderers
//! interpolate them across a triangle — normals and tangents normalised, UVs linear, handedness
//! kept from the first end.
//!
//! [`split_edges`] splits only chosen edges (the bake's adaptive refinement, where visibility
//! changes across an edge), conformingly, so no T-junction is left.
//!
//! Inputs: a [`Mesh`]. Output: a [`Mesh`] with V + E vertices and 4T triangles (or, for
//! [`split_edges`], one more vertex per chosen edge); the first V vertices are the input's, in
//! order. Invariants: deterministic (new vertices in order of first use); no IO.

use super::Mesh;
use glam::{Vec3, Vec4};
use std::collections::HashMap;

/// The point on the smooth surface the vertex normals describe, above a point `position` of a flat
/// triangle with barycentrics `corners` ((vertex, weight), weights summing to 1) (Hanika, "Hacking
/// the shadow terminator", Ray Tracing Gems II, ch. 4): the point is projected onto each corner's
/// tangent plane where it lies below it, and the projections are blended by the weights. Where the
/// mesh is convex this lifts the point off the facet, so rays above the shading normal's horizon do
/// not hit the facet they start from; where it is concave it stays. The Monte Carlo reference
/// starts its rays there, and the bake traces a refined mesh's midpoints from there.
pub fn smooth_surface_point(
    mesh: &Mesh,
    corners: &[(u32, f64)],
    position: glam::DVec3,
) -> glam::DVec3 {
    let mut lifted = position;
    for &(v, w) in corners {
        let (Some(p), Some(n)) = (mesh.positions.get(v as usize), mesh.normals.get(v as usize))
        else {
            continue;
        };
        let n = n.as_dvec3().try_normalize().unwrap_or(glam::DVec3::ZERO);
        let below = (position - p.as_dvec3()).dot(n).min(0.0);
        lifted -= w * below * n;
    }
    lifted
}

/// Appends the midpoint of edge (a, b) to `mesh` (position halfway, normal and tangent the
/// normalised sums, UV halfway, handedness from `a`) and returns its index. `a` and `b` must be
/// vertices of `mesh`.
pub fn push_midpoint(mesh: &mut Mesh, a: u32, b: u32) -> u32 {
    let (i, j) = (a as usize, b as usize);
    mesh.positions
        .push((mesh.positions[i] + mesh.positions[j]) * 0.5);
    let n = (mesh.normals[i] + mesh.normals[j]).normalize_or_zero();
    mesh.normals
        .push(if n == Vec3::ZERO { mesh.normals[i] } else { n });
    if let Some(t) = mesh.tangents.as_mut() {
        let (ti, tj) = (t[i], t[j]);
        let xyz = (ti.truncate() + tj.truncate()).normalize_or_zero();
        t.push(Vec4::new(xyz.x, xyz.y, xyz.z, ti.w));
    }
    if let Some(uv) = mesh.uvs.as_mut() {
        uv.push((uv[i] + uv[j]) * 0.5);
    }
    (mesh.positions.len() - 1) as u32
}

/// One level of midpoint subdivision.
pub fn subdivide_midpoint(mesh: &Mesh) -> Mesh {
    let mut out = Mesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        tangents: mesh.tangents.clone(),
        uvs: mesh.uvs.clone(),
        triangles: Vec::with_capacity(mesh.triangles.len() * 4),
    };
    let mut midpoints: HashMap<(u32, u32), u32> =
        HashMap::with_capacity(mesh.triangles.len() * 3 / 2);
    let mut midpoint = |out: &mut Mesh, a: u32, b: u32| -> u32 {
        let key = (a.min(b), a.max(b));
        *midpoints
            .entry(key)
            .or_insert_with(|| push_midpoint(out, key.0, key.1))
    };
    for &[a, b, c] in &mesh.triangles {
        let ab = midpoint(&mut out, a, b);
        let bc = midpoint(&mut out, b, c);
        let ca = midpoint(&mut out, c, a);
        out.triangles
            .extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    out
}

/// Splits the edges `split` says to split (keyed (min, max) of the end vertices), conformingly: a
/// triangle with one such edge becomes two, with two becomes three (the new diagonal is the shorter
/// one), with three becomes four. New vertices are appended in order of first use, each the
/// midpoint of its edge ([`push_midpoint`]); returns their edges (min, max). Orientation is kept.
pub fn split_edges(mesh: &mut Mesh, split: &impl Fn(u32, u32) -> bool) -> Vec<[u32; 2]> {
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut parents = Vec::new();
    let old = std::mem::take(&mut mesh.triangles);
    let mut triangles = Vec::with_capacity(old.len() * 2);
    for t in old {
        let mut mid = [u32::MAX; 3];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            if split(key.0, key.1) {
                mid[k] = *midpoints.entry(key).or_insert_with(|| {
                    parents.push([key.0, key.1]);
                    push_midpoint(mesh, key.0, key.1)
                });
            }
        }
        let marked = mid.iter().filter(|&&m| m != u32::MAX).count();
        match marked {
            0 => triangles.push(t),
            3 => {
                let [a, b, c] = t;
                let [ab, bc, ca] = mid;
                triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
            }
            1 => {
                // Rotate so that the split edge is (a, b).
                let k = mid.iter().position(|&m| m != u32::MAX).unwrap_or(0);
                let (a, b, c, m) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3], mid[k]);
                triangles.extend([[a, m, c], [m, b, c]]);
            }
            _ => {
                // Rotate so that the unsplit edge is (c, a): edges (a, b) and (b, c) are split.
                let k = mid.iter().position(|&m| m == u32::MAX).unwrap_or(0);
                let (c, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let (ab, bc) = (mid[(k + 1) % 3], mid[(k + 2) % 3]);
                triangles.push([ab, b, bc]);
                let p = |v: u32| mesh.positions[v as usize];
                if (p(a) - p(bc)).length_squared() <= (p(c) - p(ab)).length_squared() {
                    triangles.extend([[a, ab, bc], [a, bc, c]]);
                } else {
                    triangles.extend([[a, ab, c], [ab, bc, c]]);
                }
            }
        }
    }
    mesh.triangles = triangles;
    parents
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
        let area = |m: &Mesh| -> f32 {
            m.triangles
                .iter()
                .map(|t| {
                    (m.positions[t[1] as usize] - m.positions[t[0] as usize])
                        .cross(m.positions[t[2] as usize] - m.positions[t[0] as usize])
                        .length()
                        * 0.5
                })
                .sum()
        };
        assert!((area(&s) - area(&mesh)).abs() < 1e-6);
        // Every edge of the result is used by at most two triangles (watertight where the input
        // was).
        let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &s.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(uses.values().all(|&u| u <= 2));
        assert_eq!(
            uses.values().filter(|&&u| u == 2).count(),
            8,
            "16 edges (Euler, a disc: V − E + F = 1), 8 on the boundary"
        );
    }
}
