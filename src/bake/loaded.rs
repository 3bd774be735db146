//! A bake read back with the inputs it was made from: what `glint fit`, `render` and `export
//! --bake` start from.
//!
//! Inputs: a `bake.glint` (or its folder). Output: [`LoadedBake`] — the header, the cuts, the scene
//! with its mesh refined as the bake refined it, the environment and the tangent frames.
//! Invariants: the scene and environment files are the ones baked (their hashes are checked: a
//! changed input is an error that says to bake again); the cuts match the mesh vertex for vertex.

use super::Cuts;
use super::file::{self, BakeFileError, BakeHeader};
use crate::env::{EnvError, EnvMap};
use crate::scene::{ImportError, Scene};
use crate::sphere::{DirectionSet, LightTree, SphereError};
use glam::Vec4;
use std::path::{Path, PathBuf};

/// A bake and its inputs, checked unchanged.
pub struct LoadedBake {
    pub header: BakeHeader,
    pub cuts: Cuts,
    /// The scene, its mesh refined as the bake refined it (the cuts belong to this mesh).
    pub scene: Scene,
    pub env: EnvMap,
    /// The tangent frames of the refined mesh (`None`: isotropic only).
    pub tangents: Option<Vec<Vec4>>,
    /// How the refined mesh's new vertices were made ([`super::Refinement::parents`]): the
    /// imported mesh is its first vertices, so a point of the refined mesh can be placed on it.
    pub parents: Vec<[u32; 2]>,
}

/// Why a bake cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadBakeError {
    #[error(transparent)]
    File(#[from] BakeFileError),
    #[error(transparent)]
    Scene(#[from] ImportError),
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error("the {what} {} changed since the bake; run glint bake again", path.display())]
    Changed { what: &'static str, path: PathBuf },
    #[error("{}: {message}; run glint bake again", path.display())]
    Mismatch { path: PathBuf, message: String },
}

impl LoadedBake {
    /// Reads `path` (a `bake.glint` or its folder) and the scene and environment it names.
    pub fn open(path: &Path) -> Result<Self, LoadBakeError> {
        let (header, cuts, refinement) = file::read(path)?;
        for (input, hash, what) in [
            (&header.scene_file, &header.scene_hash, "scene"),
            (&header.env_file, &header.env_hash, "environment"),
        ] {
            if &file::hash_file(input)? != hash {
                return Err(LoadBakeError::Changed {
                    what,
                    path: input.clone(),
                });
            }
        }
        let scene = crate::scene::import(&header.scene_file)?;
        let env = crate::env::load(&header.env_file)?;
        Self::assemble(path, header, cuts, refinement, scene, env)
    }

    /// Reads `path` with the scene and environment it was made from already in memory (as
    /// [`file::bake_or_reuse`] leaves them, having checked their hashes): nothing is imported
    /// again.
    pub fn with_inputs(path: &Path, scene: Scene, env: EnvMap) -> Result<Self, LoadBakeError> {
        let (header, cuts, refinement) = file::read(path)?;
        Self::assemble(path, header, cuts, refinement, scene, env)
    }

    fn assemble(
        path: &Path,
        header: BakeHeader,
        cuts: Cuts,
        refinement: super::Refinement,
        mut scene: Scene,
        env: EnvMap,
    ) -> Result<Self, LoadBakeError> {
        let mismatch = |message: String| LoadBakeError::Mismatch {
            path: path.to_path_buf(),
            message,
        };
        // The cuts belong to the baked (refined) mesh; the surface is the same.
        scene.mesh = refinement
            .apply(&scene.mesh)
            .map_err(|e| mismatch(e.to_string()))?;
        if scene.mesh.positions.len() != cuts.vertex_count() {
            return Err(mismatch(format!(
                "the bake has {} cuts for a mesh of {} vertices",
                cuts.vertex_count(),
                scene.mesh.positions.len()
            )));
        }
        let (_, tangents, _) = super::decisions::decide_frames(&scene.mesh);
        Ok(Self {
            header,
            cuts,
            scene,
            env,
            tangents,
            parents: refinement.parents,
        })
    }

    /// The direction set and light tree the cuts index.
    pub fn light_tree(&self) -> Result<(DirectionSet, LightTree), SphereError> {
        let set = DirectionSet::cube(self.header.decisions.resolution)?;
        let tree = LightTree::build(&set);
        Ok((set, tree))
    }
}
