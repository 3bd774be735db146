//! The bake file: versioned, checksummed, written atomically.
//!
//! Layout of `bake.glint` (little-endian): `b"GLINTBAK"` · u32 format version · u32 header length ·
//! header (JSON: [`BakeHeader`]) · u32 × (V + 1) offsets · u32 × E nodes · u16 × E visibility
//! (padded to 4 bytes) · the refinement (u32 P · P × u32 pair of parent vertices · u32 T · T × u32
//! triple of refined triangles; P = T = 0 when the mesh was not refined) · u64 FNV-1a of every byte
//! before it. A `bake.json` beside it repeats the header for people.
//!
//! Inputs: a [`BakeHeader`], [`Cuts`] and the [`Refinement`]. Outputs: the file, or the parsed
//! bake. Invariants: a file that is truncated, corrupt (checksum), of another format version, or
//! internally inconsistent is refused with a one-line reason — the caller rebuilds; a write never
//! leaves a half-written file.

use super::{BakeSettings, BakeStats, Cuts, Decisions, Refinement};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Current format version; bump on any change of layout or meaning, or of how the same inputs are
/// baked (so that a bake made the old way is rebuilt, not reused). 6: vertices traced after all
/// take their sampled neighbours' agreed visibility cells.
pub const FORMAT_VERSION: u32 = 7;
const MAGIC: &[u8; 8] = b"GLINTBAK";

/// What a bake was made from and how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BakeHeader {
    pub format_version: u32,
    pub glint_version: String,
    /// Absolute paths of the inputs when baked.
    pub scene_file: PathBuf,
    pub env_file: PathBuf,
    /// FNV-1a 64 of the input files' bytes, hex.
    pub scene_hash: String,
    pub env_hash: String,
    pub settings: BakeSettings,
    pub decisions: Decisions,
    pub stats: BakeStats,
    pub vertex_count: usize,
}

/// Why a bake file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum BakeFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a glint bake (bad magic bytes)")]
    NotABake { path: PathBuf },
    #[error("{path}: bake format version {found}, this glint reads version {expected}")]
    Version {
        path: PathBuf,
        found: u32,
        expected: u32,
    },
    #[error("{path}: truncated ({what})")]
    Truncated { path: PathBuf, what: String },
    #[error("{path}: checksum mismatch (the file is corrupt)")]
    Checksum { path: PathBuf },
    #[error("{path}: bad header: {message}")]
    Header { path: PathBuf, message: String },
    #[error("{path}: inconsistent bake: {message}")]
    Inconsistent { path: PathBuf, message: String },
    #[error("{0}")]
    Write(#[from] glint_exporters::AtomicWriteError),
}

pub use crate::math::fnv1a64;

/// Hex FNV-1a of a file's bytes.
pub fn hash_file(path: &Path) -> Result<String, BakeFileError> {
    let bytes = std::fs::read(path).map_err(|source| BakeFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(format!("{:016x}", fnv1a64(&bytes)))
}

/// Serialises header, cuts and refinement.
pub fn encode(header: &BakeHeader, cuts: &Cuts, refinement: &Refinement) -> Vec<u8> {
    let json = serde_json::to_vec(header).unwrap_or_default();
    let mut out = Vec::with_capacity(24 + json.len() + cuts.bytes() + 16);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    // In vertex order, however the cuts lie in memory.
    let mut offset = 0u32;
    out.extend_from_slice(&offset.to_le_bytes());
    for v in 0..cuts.vertex_count() {
        offset += cuts.cut_len(v) as u32;
        out.extend_from_slice(&offset.to_le_bytes());
    }
    for v in 0..cuts.vertex_count() {
        cuts.nodes_of(v)
            .iter()
            .for_each(|n| out.extend_from_slice(&n.to_le_bytes()));
    }
    for v in 0..cuts.vertex_count() {
        cuts.quantised(v)
            .iter()
            .for_each(|q| out.extend_from_slice(&q.to_le_bytes()));
    }
    if cuts.node_count() % 2 == 1 {
        out.extend_from_slice(&[0, 0]);
    }
    out.extend_from_slice(&(refinement.parents.len() as u32).to_le_bytes());
    for x in refinement.parents.iter().flatten() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&(refinement.triangles.len() as u32).to_le_bytes());
    for x in refinement.triangles.iter().flatten() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Writes `bake.glint` and `bake.json` into `dir` (created if missing), atomically.
pub fn write(
    dir: &Path,
    header: &BakeHeader,
    cuts: &Cuts,
    refinement: &Refinement,
) -> Result<PathBuf, BakeFileError> {
    std::fs::create_dir_all(dir).map_err(|source| BakeFileError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join("bake.glint");
    glint_exporters::write_atomic(&path, &encode(header, cuts, refinement))?;
    let json = serde_json::to_vec_pretty(header).unwrap_or_default();
    glint_exporters::write_atomic(&dir.join("bake.json"), &json)?;
    Ok(path)
}

/// Reads and checks a bake file (`bake.glint`, or a folder holding one).
pub fn read(path: &Path) -> Result<(BakeHeader, Cuts, Refinement), BakeFileError> {
    let path = if path.is_dir() {
        path.join("bake.glint")
    } else {
        path.to_path_buf()
    };
    let bytes = std::fs::read(&path).map_err(|source| BakeFileError::Io {
        path: path.clone(),
        source,
    })?;
    decode(&path, &bytes)
}

/// Parses bytes of a bake file (see [`read`]).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<(BakeHeader, Cuts, Refinement), BakeFileError> {
    let p = || path.to_path_buf();
    let truncated = |what: &str| BakeFileError::Truncated {
        path: p(),
        what: what.into(),
    };
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(if bytes.len() < 8 {
            truncated("no header")
        } else {
            BakeFileError::NotABake { path: p() }
        });
    }
    let u32_at = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let version = u32_at(8).ok_or_else(|| truncated("no version"))?;
    if version != FORMAT_VERSION {
        return Err(BakeFileError::Version {
            path: p(),
            found: version,
            expected: FORMAT_VERSION,
        });
    }
    if bytes.len() < 24 {
        return Err(truncated("shorter than the fixed header"));
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let stored = u64::from_le_bytes([
        sum[0], sum[1], sum[2], sum[3], sum[4], sum[5], sum[6], sum[7],
    ]);
    let header_len = u32_at(12).ok_or_else(|| truncated("no header length"))? as usize;
    let header_end = 16usize
        .checked_add(header_len)
        .filter(|&e| e <= body.len())
        .ok_or_else(|| truncated("header"))?;
    if fnv1a64(body) != stored {
        return Err(BakeFileError::Checksum { path: p() });
    }
    let header: BakeHeader =
        serde_json::from_slice(&body[16..header_end]).map_err(|e| BakeFileError::Header {
            path: p(),
            message: e.to_string(),
        })?;
    let v = header.vertex_count;
    let offsets_end = (v + 1)
        .checked_mul(4)
        .and_then(|n| n.checked_add(header_end))
        .filter(|&e| e <= body.len())
        .ok_or_else(|| truncated("offsets"))?;
    let offsets: Vec<u32> = body[header_end..offsets_end]
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let e = offsets.last().copied().unwrap_or(0) as usize;
    if offsets.first() != Some(&0) || offsets.windows(2).any(|w| w[0] > w[1]) {
        return Err(BakeFileError::Inconsistent {
            path: p(),
            message: "offsets are not ascending from 0".into(),
        });
    }
    let padded = e * 2 + (e % 2) * 2;
    let cuts_end = offsets_end + e * 4 + padded;
    if body.len() < cuts_end {
        return Err(truncated("cut data"));
    }
    let nodes: Vec<u32> = body[offsets_end..offsets_end + e * 4]
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let vis_start = offsets_end + e * 4;
    let visibility: Vec<u16> = body[vis_start..vis_start + e * 2]
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let node_count = 2 * 6 * header.decisions.resolution * header.decisions.resolution;
    if nodes.iter().any(|&n| n as usize >= node_count) {
        return Err(BakeFileError::Inconsistent {
            path: p(),
            message: "a cut names a node outside the light tree".into(),
        });
    }
    let cuts = Cuts::from_rows(&offsets, nodes, visibility).ok_or_else(|| {
        BakeFileError::Inconsistent {
            path: p(),
            message: "the cut offsets do not match the cut data".into(),
        }
    })?;
    // The refinement: a count, then that many groups of `width` u32s.
    let mut at = cuts_end;
    let mut groups = |width: usize, what: &str| -> Result<Vec<u32>, BakeFileError> {
        let count = u32_at(at)
            .filter(|_| at + 4 <= body.len())
            .ok_or_else(|| truncated(what))? as usize;
        let end = count
            .checked_mul(4 * width)
            .and_then(|n| n.checked_add(at + 4))
            .filter(|&e| e <= body.len())
            .ok_or_else(|| truncated(what))?;
        let out = body[at + 4..end]
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        at = end;
        Ok(out)
    };
    let parents: Vec<[u32; 2]> = groups(2, "refinement vertices")?
        .chunks_exact(2)
        .map(|c| [c[0], c[1]])
        .collect();
    let triangles: Vec<[u32; 3]> = groups(3, "refinement triangles")?
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    if at != body.len() {
        return Err(BakeFileError::Inconsistent {
            path: p(),
            message: format!("{} bytes after the refinement", body.len() - at),
        });
    }
    let refinement = Refinement { parents, triangles };
    // Every vertex of the refined mesh has a cut.
    if !refinement.is_empty() && header.vertex_count < refinement.parents.len() {
        return Err(BakeFileError::Inconsistent {
            path: p(),
            message: format!(
                "{} cuts for {} refinement vertices",
                header.vertex_count,
                refinement.parents.len()
            ),
        });
    }
    Ok((header, cuts, refinement))
}

/// What [`bake_or_reuse`] did.
pub struct BakeOutcome {
    /// The header of the bake now on disk.
    pub header: BakeHeader,
    /// Whether a matching bake was already there (nothing was traced).
    pub reused: bool,
    /// Why an existing bake was not reused (other inputs or settings, or unreadable), in words.
    pub rebuild_reason: Option<String>,
}

/// Why [`bake_or_reuse`] failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeRunError {
    #[error(transparent)]
    File(#[from] BakeFileError),
    #[error(transparent)]
    Bake(#[from] super::BakeError),
}

/// Bakes `scene` under `env` into `dir/bake.glint` (and `bake.json`), unless a bake there was made
/// from files with the same hashes and the same settings (and `force` is off): then it is reused.
/// `scene_path` and `env_path` are the files `scene` and `env` were read from (their hashes and
/// absolute paths go into the header). `progress` receives the number of vertices baked.
#[allow(clippy::too_many_arguments)] // the inputs of a bake, each needed and of a different kind
pub fn bake_or_reuse(
    scene: &crate::scene::Scene,
    env: &crate::env::EnvMap,
    scene_path: &Path,
    env_path: &Path,
    dir: &Path,
    settings: BakeSettings,
    force: bool,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<BakeOutcome, BakeRunError> {
    let scene_hash = hash_file(scene_path)?;
    let env_hash = hash_file(env_path)?;
    let existing = dir.join("bake.glint");
    let mut rebuild_reason = None;
    if existing.exists() && !force {
        match read(&existing) {
            Ok((header, _, _))
                if header.scene_hash == scene_hash
                    && header.env_hash == env_hash
                    && header.settings == settings =>
            {
                return Ok(BakeOutcome {
                    header,
                    reused: true,
                    rebuild_reason: None,
                });
            }
            Ok(_) => {
                rebuild_reason = Some(format!(
                    "{} was made from other inputs or settings; rebuilding",
                    existing.display()
                ))
            }
            Err(e) => rebuild_reason = Some(format!("{e}; rebuilding")),
        }
    }
    let baker = super::Baker::new(scene, env, settings)?;
    let bake = baker.bake_refined(None, progress);
    let header = BakeHeader {
        format_version: FORMAT_VERSION,
        glint_version: env!("CARGO_PKG_VERSION").into(),
        scene_file: std::path::absolute(scene_path).unwrap_or_else(|_| scene_path.to_path_buf()),
        env_file: std::path::absolute(env_path).unwrap_or_else(|_| env_path.to_path_buf()),
        scene_hash,
        env_hash,
        settings,
        decisions: bake.decisions.clone(),
        stats: bake.stats.clone(),
        vertex_count: bake.cuts.vertex_count(),
    };
    write(dir, &header, &bake.cuts, &bake.refinement)?;
    Ok(BakeOutcome {
        header,
        reused: false,
        rebuild_reason,
    })
}
