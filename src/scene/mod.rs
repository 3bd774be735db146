//! glTF 2.0 import into plain data: one merged world-space triangle mesh, per-part information,
//! cameras and bounds.
//!
//! Inputs: a `.gltf` (JSON, with external or `data:` buffers) or `.glb` file. Outputs: a [`Scene`]
//! or an [`ImportError`] whose one-line message names the file and the cause.
//!
//! What [`import`] does, in order:
//! 1. reads the file (refusing files over 2 GiB) and, for GLB, checks the container itself
//!    (header, total length, chunk lengths and order) — see `container.rs`;
//! 2. refuses any `extensionsRequired` entry glint does not implement, naming it; only extensions
//!    that concern materials, textures, lights or metadata are accepted, and ignored
//!    ([`IGNORABLE_REQUIRED_EXTENSIONS`], [`IGNORABLE_REQUIRED_PREFIXES`]); materials, textures,
//!    images, samplers and animations are dropped unread;
//! 3. validates the document with the gltf crate;
//! 4. loads buffers: the GLB BIN chunk, `data:` URIs, or files **inside the scene file's folder**
//!    (nothing outside it is ever opened) — see `buffers.rs`;
//! 5. checks every accessor before reading it (types, count, byte ranges, sparse parts) —
//!    see `accessor.rs`;
//! 6. walks the default scene (else scene 0) composing node transforms, bakes every triangle
//!    primitive (TRIANGLES; strips and fans converted; points and lines skipped and counted) into
//!    world space and merges them — see `geometry.rs`;
//! 7. collects perspective cameras (orthographic ones are skipped with a warning) and, when there
//!    is none, adds a default camera framing the bounds — see `camera.rs`.
//!
//! Invariants of a returned [`Scene`]: at least one triangle; every index is below
//! `mesh.positions.len()`; positions are finite; normals are unit length (generated where missing
//! or unusable); `mesh.tangents`/`mesh.uvs` are `Some` only when every part has them, and then have
//! one entry per vertex; vertices are not welded (counts are the sums of the instanced primitives'
//! POSITION counts); at least one camera. No input makes `import` panic.
//!
//! Limits: [`MAX_FILE_BYTES`] per file, [`MAX_ELEMENTS`] per accessor, [`MAX_SCENE_VERTICES`] and
//! [`MAX_SCENE_TRIANGLES`] after instancing, [`MAX_NODE_INSTANCES`] node visits. Skins and morph
//! targets are ignored (the bind pose / base shape is used, with a warning).

mod accessor;
mod buffers;
mod camera;
mod container;
mod error;
mod geometry;
mod subdivide;
pub mod view;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use serde::Serialize;

pub use accessor::MAX_ELEMENTS;
pub use camera::{
    Bounds, Camera, DEFAULT_ELEVATION_DEG, DEFAULT_HEIGHT, DEFAULT_WIDTH, DEFAULT_YFOV_DEG,
    default_camera, orbit_camera,
};
pub use container::{IGNORABLE_REQUIRED_EXTENSIONS, IGNORABLE_REQUIRED_PREFIXES, MAX_FILE_BYTES};
pub use error::ImportError;
pub use geometry::angle_weighted_normals;
pub use subdivide::{push_midpoint, smooth_surface_point, split_edges, subdivide_midpoint};

/// Largest number of vertices in a scene after instancing (64 Mi).
pub const MAX_SCENE_VERTICES: usize = 64 * 1024 * 1024;
/// Largest number of triangles in a scene after instancing (128 Mi).
pub const MAX_SCENE_TRIANGLES: usize = 128 * 1024 * 1024;
/// Largest number of node instances visited while walking the scene graph (1 Mi).
pub const MAX_NODE_INSTANCES: usize = 1024 * 1024;
/// At most this many warnings are kept; further ones are counted in a final line.
const MAX_WARNINGS: usize = 100;

/// A triangle mesh in world space.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Unit length, one per position.
    pub normals: Vec<Vec3>,
    /// xyz unit (or zero where the source tangent was unusable), w = ±1; one per position.
    pub tangents: Option<Vec<Vec4>>,
    pub uvs: Option<Vec<Vec2>>,
    /// Counter-clockwise seen from the side the normals point to (glTF's convention).
    pub triangles: Vec<[u32; 3]>,
}

/// Where a vertex attribute of a part came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AttributeSource {
    /// Read from the file.
    Present,
    /// Computed by glint (normals only).
    Generated,
    /// Not in the file and not generated.
    Absent,
}

/// One instanced primitive of the merged mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartInfo {
    /// The glTF mesh's name, else `mesh N`.
    pub mesh_name: String,
    /// The instancing node's name, else `node N`.
    pub node_name: String,
    /// Index of the primitive within its mesh.
    pub primitive: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub normals: AttributeSource,
    pub tangents: AttributeSource,
    pub uvs: AttributeSource,
}

/// An imported glTF scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The path given to [`import`].
    pub source: PathBuf,
    /// All parts merged, in world space.
    pub mesh: Mesh,
    /// One entry per baked primitive instance, in merge order.
    pub parts: Vec<PartInfo>,
    /// Number of distinct glTF meshes instanced by the scene's nodes.
    pub mesh_count: usize,
    /// Perspective cameras of the scene, or one default camera.
    pub cameras: Vec<Camera>,
    /// Bounds of `mesh.positions`.
    pub bounds: Bounds,
    /// Primitive instances skipped: POINTS, LINES, LINE_LOOP, LINE_STRIP, or no POSITION.
    pub skipped_primitives: usize,
    /// Vertices whose normal was generated by a fallback (no valid triangle, cancelling faces) or
    /// whose normal in the file was unusable (NaN, infinite, zero) and was replaced.
    pub normal_fallbacks: usize,
    /// Human-readable notes on what was skipped or ignored (orthographic cameras, skipped
    /// primitives, skins, morph targets).
    pub warnings: Vec<String>,
}

struct Warnings {
    list: Vec<String>,
    dropped: usize,
}

impl Warnings {
    fn push(&mut self, w: String) {
        if self.list.len() < MAX_WARNINGS {
            self.list.push(w);
        } else {
            self.dropped += 1;
        }
    }

    fn finish(mut self) -> Vec<String> {
        if self.dropped > 0 {
            self.list
                .push(format!("… and {} more warnings", self.dropped));
        }
        self.list
    }
}

/// A node's local transform: its matrix, or translation · rotation · scale. The rotation is
/// normalised (identity if it has zero length or is not finite).
fn local_matrix(node: &gltf::json::scene::Node) -> Mat4 {
    if let Some(m) = node.matrix {
        return Mat4::from_cols_array(&m);
    }
    let t = node.translation.map_or(Vec3::ZERO, Vec3::from_array);
    let s = node.scale.map_or(Vec3::ONE, Vec3::from_array);
    let q = node.rotation.map_or(Quat::IDENTITY, |r| {
        let v = Vec4::from_array(r.0);
        match v.try_normalize() {
            Some(v) => Quat::from_vec4(v),
            None => Quat::IDENTITY,
        }
    });
    Mat4::from_scale_rotation_translation(s, q, t)
}

/// Imports the glTF 2.0 file at `path` (`.gltf` or `.glb`; the content decides, not the name).
pub fn import(path: &Path) -> Result<Scene, ImportError> {
    let parsed = container::read_document(path)?;
    let root = parsed.document.as_json();
    let buffers = buffers::load(path, root, parsed.bin)?;
    let reader = accessor::AccessorReader {
        path,
        root,
        buffers: &buffers,
    };
    let invalid = |message: String| ImportError::Validation {
        path: path.to_path_buf(),
        message,
    };
    let too_large = |message: String| ImportError::SceneTooLarge {
        path: path.to_path_buf(),
        message,
    };

    let scene_index = match root.scene {
        Some(s) => s.value(),
        None if !root.scenes.is_empty() => 0,
        None => {
            return Err(ImportError::NoScene {
                path: path.to_path_buf(),
            });
        }
    };
    let Some(gscene) = root.scenes.get(scene_index) else {
        return Err(ImportError::NoScene {
            path: path.to_path_buf(),
        });
    };

    // Walk the node graph iteratively. A path longer than the node count must repeat a node, so
    // depth > nodes.len() proves a cycle; the instance cap bounds DAGs that share children.
    let mut warnings = Warnings {
        list: Vec::new(),
        dropped: 0,
    };
    let mut instances: Vec<(usize, usize, Mat4)> = Vec::new(); // (node, mesh, world)
    let mut cameras = Vec::new();
    let mut stack: Vec<(usize, Mat4, usize)> = gscene
        .nodes
        .iter()
        .rev()
        .map(|n| (n.value(), Mat4::IDENTITY, 1))
        .collect();
    let mut pushed = stack.len();
    let mut warned_skin = false;
    while let Some((ni, parent, depth)) = stack.pop() {
        if pushed > MAX_NODE_INSTANCES {
            return Err(too_large(format!(
                "the node graph expands to more than {MAX_NODE_INSTANCES} node instances"
            )));
        }
        if depth > root.nodes.len() {
            return Err(invalid(format!(
                "the node hierarchy has a cycle (through node {ni})"
            )));
        }
        let Some(node) = root.nodes.get(ni) else {
            return Err(invalid(format!("node {ni} does not exist")));
        };
        let world = parent * local_matrix(node);
        if !world.is_finite() {
            return Err(invalid(format!(
                "node {ni} has a non-finite world transform"
            )));
        }
        if let Some(mesh) = node.mesh {
            instances.push((ni, mesh.value(), world));
            if node.skin.is_some() && !warned_skin {
                warned_skin = true;
                warnings.push(
                    "skins are ignored: skinned meshes are imported in their bind pose".into(),
                );
            }
        }
        if let Some(cam) = node.camera {
            match camera::from_gltf(root, cam.value(), node.name.as_deref(), &world) {
                Ok(c) => cameras.push(c),
                Err(w) => warnings.push(w),
            }
        }
        if let Some(children) = &node.children {
            pushed = pushed.saturating_add(children.len());
            if pushed > MAX_NODE_INSTANCES {
                return Err(too_large(format!(
                    "the node graph expands to more than {MAX_NODE_INSTANCES} node instances"
                )));
            }
            stack.extend(children.iter().rev().map(|c| (c.value(), world, depth + 1)));
        }
    }

    // Decode every instanced mesh once.
    let mut decoded: HashMap<usize, Vec<geometry::Decoded>> = HashMap::new();
    let mut mesh_ids: HashSet<usize> = HashSet::new();
    for &(_, mi, _) in &instances {
        if !mesh_ids.insert(mi) {
            continue;
        }
        let Some(mesh) = root.meshes.get(mi) else {
            return Err(invalid(format!("mesh {mi} does not exist")));
        };
        let name = mesh.name.clone().unwrap_or_else(|| format!("mesh {mi}"));
        let prims = mesh
            .primitives
            .iter()
            .map(|p| geometry::decode_primitive(&reader, &name, p))
            .collect::<Result<Vec<_>, _>>()?;
        if mesh.primitives.iter().any(|p| p.targets.is_some()) {
            warnings.push(format!(
                "mesh {name:?}: morph targets are ignored (the base shape is used)"
            ));
        }
        decoded.insert(mi, prims);
    }

    // Bake and merge.
    let mut out = Mesh {
        tangents: Some(Vec::new()),
        uvs: Some(Vec::new()),
        ..Mesh::default()
    };
    let mut parts = Vec::new();
    let mut skipped = 0usize;
    let mut fallbacks = 0usize;
    for &(ni, mi, world) in &instances {
        let (Some(prims), Some(mesh)) = (decoded.get(&mi), root.meshes.get(mi)) else {
            continue; // every instanced mesh was decoded above
        };
        let mesh_name = mesh.name.clone().unwrap_or_else(|| format!("mesh {mi}"));
        let node_name = root
            .nodes
            .get(ni)
            .and_then(|n| n.name.clone())
            .unwrap_or_else(|| format!("node {ni}"));
        for (pi, prim) in prims.iter().enumerate() {
            let local = match prim {
                geometry::Decoded::Triangles(local) => local,
                geometry::Decoded::Skipped(why) => {
                    skipped += 1;
                    warnings.push(format!(
                        "mesh {mesh_name:?} primitive {pi} at node {node_name:?}: skipped ({why})"
                    ));
                    continue;
                }
            };
            let base = out.positions.len();
            if base + local.positions.len() > MAX_SCENE_VERTICES
                || out.triangles.len() + local.triangles.len() > MAX_SCENE_TRIANGLES
            {
                return Err(too_large(format!(
                    "more than {MAX_SCENE_VERTICES} vertices or {MAX_SCENE_TRIANGLES} triangles after instancing"
                )));
            }
            let Some(part) = geometry::bake(local, &world) else {
                return Err(invalid(format!(
                    "node {node_name:?}: transformed positions of mesh {mesh_name:?} overflow f32"
                )));
            };
            let base = base as u32; // <= MAX_SCENE_VERTICES < u32::MAX
            parts.push(PartInfo {
                mesh_name: mesh_name.clone(),
                node_name: node_name.clone(),
                primitive: pi,
                vertices: part.positions.len(),
                triangles: part.triangles.len(),
                normals: part.normal_source,
                tangents: if part.tangents.is_some() {
                    AttributeSource::Present
                } else {
                    AttributeSource::Absent
                },
                uvs: if part.uvs.is_some() {
                    AttributeSource::Present
                } else {
                    AttributeSource::Absent
                },
            });
            fallbacks += part.fallbacks;
            out.positions.extend_from_slice(&part.positions);
            out.normals.extend_from_slice(&part.normals);
            out.triangles
                .extend(part.triangles.iter().map(|t| t.map(|i| i + base)));
            match (&mut out.tangents, &part.tangents) {
                (Some(all), Some(t)) => all.extend_from_slice(t),
                _ => out.tangents = None,
            }
            match (&mut out.uvs, &part.uvs) {
                (Some(all), Some(u)) => all.extend_from_slice(u),
                _ => out.uvs = None,
            }
        }
    }
    if out.triangles.is_empty() {
        return Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
        });
    }
    let Some(bounds) = Bounds::from_points(&out.positions) else {
        return Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
        });
    };
    if cameras.is_empty() {
        cameras.push(default_camera(&bounds));
    }
    Ok(Scene {
        source: path.to_path_buf(),
        mesh: out,
        parts,
        mesh_count: mesh_ids.len(),
        cameras,
        bounds,
        skipped_primitives: skipped,
        normal_fallbacks: fallbacks,
        warnings: warnings.finish(),
    })
}
