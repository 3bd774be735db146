//! Primitive decoding (local space) and baking into world space, with normal generation.
//!
//! Inputs: a glTF mesh primitive (through the checked [`AccessorReader`]) and, for baking, the
//! node's world matrix. Outputs: [`LocalPrimitive`] (decoded, triangle list, indices checked) and
//! [`BakedPart`] (world space, unit normals).
//!
//! Invariants:
//! * TRIANGLES need a multiple of 3 indices; TRIANGLE_STRIP and TRIANGLE_FAN are converted to a
//!   triangle list (keeping the strip's alternating winding) and their degenerate triangles (a
//!   repeated index, as used for strip restarts) are dropped; POINTS and LINES* are skipped;
//! * every index is below the primitive's vertex count ([`ImportError::IndexOutOfRange`]), and all
//!   present attributes have as many elements as POSITION;
//! * baking: positions by the world matrix; normals by its cofactor matrix (the inverse transpose
//!   times the determinant, which stays defined for singular matrices) times the determinant's
//!   sign, then normalised; tangents' xyz by the world matrix, normalised (zero if that fails), w
//!   set to ±1 and negated when the determinant is negative; a negative determinant also reverses
//!   every triangle's winding, so the face normals of the output agree with its vertex normals;
//! * every output normal is unit length: missing normals are generated
//!   ([`angle_weighted_normals`]), and present normals that are NaN, infinite or zero after the
//!   transform are replaced by generated ones and counted as fallbacks; UVs that are not finite
//!   become 0.

use glam::{DVec3, Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::json;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::AttributeSource;
use super::accessor::{AccessorReader, Role};
use super::error::ImportError;

/// A decoded primitive in its mesh's local space, as a triangle list.
#[derive(Debug, Clone)]
pub(crate) struct LocalPrimitive {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec4>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
}

/// What became of a primitive.
#[derive(Debug, Clone)]
pub(crate) enum Decoded {
    Triangles(LocalPrimitive),
    /// Not triangle-shaped (or no POSITION); the string says why.
    Skipped(String),
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// Decodes one primitive. `mesh_name` is used in errors.
pub(crate) fn decode_primitive(
    reader: &AccessorReader<'_>,
    mesh_name: &str,
    prim: &json::mesh::Primitive,
) -> Result<Decoded, ImportError> {
    let Checked::Valid(mode) = prim.mode else {
        return Err(ImportError::Validation {
            path: reader.path.to_path_buf(),
            message: format!("mesh {mesh_name:?}: invalid primitive mode"),
        });
    };
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(Decoded::Skipped(format!("mode {}", mode_name(mode))));
    }
    let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
    let Some(pos_index) = attr(Semantic::Positions) else {
        return Ok(Decoded::Skipped("no POSITION attribute".into()));
    };
    let positions = reader.vec3(pos_index, Role::Position)?;
    let n = positions.len();
    let check_len = |index: usize, name: &str, len: usize| {
        if len == n {
            Ok(())
        } else {
            Err(ImportError::Accessor {
                path: reader.path.to_path_buf(),
                accessor: index,
                message: format!("{name} has {len} elements but POSITION has {n}"),
            })
        }
    };
    let normals = match attr(Semantic::Normals) {
        Some(i) => {
            let v = reader.vec3(i, Role::Normal)?;
            check_len(i, "NORMAL", v.len())?;
            Some(v)
        }
        None => None,
    };
    let tangents = match attr(Semantic::Tangents) {
        Some(i) => {
            let v = reader.vec4(i, Role::Tangent)?;
            check_len(i, "TANGENT", v.len())?;
            Some(v)
        }
        None => None,
    };
    let uvs = match attr(Semantic::TexCoords(0)) {
        Some(i) => {
            let v = reader.vec2(i, Role::TexCoord)?;
            check_len(i, "TEXCOORD_0", v.len())?;
            Some(v)
        }
        None => None,
    };

    // n <= MAX_ELEMENTS < u32::MAX, so vertex numbers fit in u32.
    let (indices, index_accessor) = match prim.indices {
        Some(i) => (reader.indices(i.value())?, i.value()),
        None => ((0..n as u32).collect(), pos_index),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= n) {
        return Err(ImportError::IndexOutOfRange {
            path: reader.path.to_path_buf(),
            mesh: mesh_name.to_owned(),
            index: bad,
            vertices: n,
        });
    }
    let distinct = |t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    let triangles: Vec<[u32; 3]> = match mode {
        Mode::Triangles => {
            if !indices.len().is_multiple_of(3) {
                return Err(ImportError::Accessor {
                    path: reader.path.to_path_buf(),
                    accessor: index_accessor,
                    message: format!(
                        "TRIANGLES primitive of mesh {mesh_name:?} has {} indices, not a multiple of 3",
                        indices.len()
                    ),
                });
            }
            indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]]) // chunks of exactly 3
                .collect()
        }
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                // windows of exactly 3
                if i.is_multiple_of(2) {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .filter(distinct)
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest
                .windows(2)
                .map(|w| [first, w[0], w[1]]) // windows of exactly 2
                .filter(distinct)
                .collect(),
            None => Vec::new(),
        },
        _ => Vec::new(), // excluded above
    };
    Ok(Decoded::Triangles(LocalPrimitive {
        positions,
        normals,
        tangents,
        uvs,
        triangles,
    }))
}

/// A primitive instance baked into world space.
#[derive(Debug, Clone)]
pub(crate) struct BakedPart {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub tangents: Option<Vec<Vec4>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
    pub normal_source: AttributeSource,
    /// Vertices whose normal is a fallback (see [`angle_weighted_normals`]) or a replaced bad one.
    pub fallbacks: usize,
}

/// Bakes `local` with the world matrix `world` (which must be finite). Returns `None` if a
/// transformed position is not finite (the matrix overflowed `f32`).
pub(crate) fn bake(local: &LocalPrimitive, world: &Mat4) -> Option<BakedPart> {
    let linear = Mat3::from_mat4(*world);
    let det = linear.determinant();
    let mirrored = det < 0.0;
    let positions: Vec<Vec3> = local
        .positions
        .iter()
        .map(|&p| world.transform_point3(p))
        .collect();
    if positions.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let triangles: Vec<[u32; 3]> = if mirrored {
        local.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect()
    } else {
        local.triangles.clone()
    };

    let (normals, normal_source, fallbacks) = match &local.normals {
        Some(src) => {
            let (a0, a1, a2) = (linear.x_axis, linear.y_axis, linear.z_axis);
            let sign = if mirrored { -1.0 } else { 1.0 };
            let cofactor = Mat3::from_cols(a1.cross(a2), a2.cross(a0), a0.cross(a1)) * sign;
            let mut normals: Vec<Option<Vec3>> = src.iter().map(|&n| unit(cofactor * n)).collect();
            let bad = normals.iter().filter(|n| n.is_none()).count();
            if bad > 0 {
                let (generated, _) = angle_weighted_normals(&positions, &triangles);
                for (n, g) in normals.iter_mut().zip(generated) {
                    n.get_or_insert(g);
                }
            }
            let normals = normals.into_iter().map(|n| n.unwrap_or(Vec3::Y)).collect();
            (normals, AttributeSource::Present, bad)
        }
        None => {
            let (normals, fallbacks) = angle_weighted_normals(&positions, &triangles);
            (normals, AttributeSource::Generated, fallbacks)
        }
    };

    let tangents = local.tangents.as_ref().map(|src| {
        src.iter()
            .map(|t| {
                let xyz = unit(linear * t.truncate()).unwrap_or(Vec3::ZERO);
                let w = if t.w < 0.0 { -1.0 } else { 1.0 };
                xyz.extend(if mirrored { -w } else { w })
            })
            .collect()
    });
    let uvs = local.uvs.as_ref().map(|src| {
        src.iter()
            .map(|&uv| if uv.is_finite() { uv } else { Vec2::ZERO })
            .collect()
    });
    Some(BakedPart {
        positions,
        normals,
        tangents,
        uvs,
        triangles,
        normal_source,
        fallbacks,
    })
}

/// `v` normalised, or `None` if it is zero, tiny or not finite.
fn unit(v: Vec3) -> Option<Vec3> {
    let len = v.length();
    (len.is_finite() && len > 1e-20).then(|| v / len)
}

/// Angle-weighted vertex normals of a triangle list: every non-degenerate triangle adds its unit
/// face normal (right-hand rule over its winding) times its corner angle to each of its three
/// vertices; the sums are normalised. Degenerate (zero-area) triangles add nothing.
///
/// A vertex whose sum vanishes (no valid triangle, or faces that cancel, |sum| below 1e-6 of the
/// summed angles) gets the face normal of the first valid triangle containing it, or +Y if there is
/// none; the second value counts these fallbacks. Triangles with an index out of range are ignored
/// (callers check indices first).
pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<Vec3>, usize) {
    let n = positions.len();
    let mut sum = vec![DVec3::ZERO; n];
    let mut weight = vec![0.0f64; n];
    let mut first: Vec<Option<DVec3>> = vec![None; n];
    for tri in triangles {
        let [a, b, c] = tri.map(|i| i as usize);
        let (Some(pa), Some(pb), Some(pc)) = (positions.get(a), positions.get(b), positions.get(c))
        else {
            continue;
        };
        let (pa, pb, pc) = (pa.as_dvec3(), pb.as_dvec3(), pc.as_dvec3());
        let face = (pb - pa).cross(pc - pa);
        let len = face.length();
        if !(len.is_finite() && len > 0.0) {
            continue;
        }
        let unit_face = face / len;
        for (v, p, q, r) in [(a, pa, pb, pc), (b, pb, pc, pa), (c, pc, pa, pb)] {
            let (e1, e2) = (q - p, r - p);
            let angle = e1.cross(e2).length().atan2(e1.dot(e2));
            // v < n: all three were found by `get` above.
            if let (Some(s), Some(w), Some(f)) =
                (sum.get_mut(v), weight.get_mut(v), first.get_mut(v))
            {
                *s += unit_face * angle;
                *w += angle;
                f.get_or_insert(unit_face);
            }
        }
    }
    let mut fallbacks = 0;
    let normals = sum
        .iter()
        .zip(&weight)
        .zip(&first)
        .map(|((s, &w), f)| {
            let len = s.length();
            if len.is_finite() && w > 0.0 && len > 1e-6 * w {
                (*s / len).as_vec3()
            } else {
                fallbacks += 1;
                f.map_or(Vec3::Y, |f| f.as_vec3())
            }
        })
        .collect();
    (normals, fallbacks)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tetrahedron_corner_normal() {
        // Three right-angled faces meeting at the origin, each weighted by π/2.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let t = [[0, 2, 1], [0, 1, 3], [0, 3, 2]];
        let (n, fb) = angle_weighted_normals(&p, &t);
        assert_eq!(fb, 0);
        let e = -Vec3::ONE.normalize();
        assert!((n[0] - e).length() < 1e-6, "{:?}", n[0]);
    }

    #[test]
    fn degenerate_and_unreferenced_vertices_fall_back() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::Z];
        let (n, fb) = angle_weighted_normals(&p, &[[0, 1, 2]]);
        assert_eq!(fb, 4);
        assert!(n.iter().all(|&v| v == Vec3::Y));
    }

    #[test]
    fn singular_matrix_does_not_produce_nan() {
        let local = LocalPrimitive {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: Some(vec![Vec3::Z; 3]),
            tangents: Some(vec![Vec4::new(1.0, 0.0, 0.0, 1.0); 3]),
            uvs: None,
            triangles: vec![[0, 1, 2]],
        };
        let flat = Mat4::from_scale(Vec3::new(1.0, 1.0, 0.0));
        let baked = bake(&local, &flat).unwrap();
        assert!(
            baked
                .normals
                .iter()
                .all(|n| (n.length() - 1.0).abs() < 1e-6)
        );
        let zero = Mat4::from_scale(Vec3::ZERO);
        let baked = bake(&local, &zero).unwrap();
        assert!(
            baked
                .normals
                .iter()
                .all(|n| (n.length() - 1.0).abs() < 1e-6)
        );
        assert_eq!(baked.fallbacks, 3);
    }
}
