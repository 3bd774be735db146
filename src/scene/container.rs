//! Reading a scene file into a validated glTF document plus the GLB `BIN` chunk.
//!
//! Inputs: the scene file's path. Outputs: a [`gltf::Document`] that passed the gltf crate's
//! validation, and the `BIN` chunk bytes when the file is a GLB that has one.
//!
//! Invariants and order of checks:
//! * files over [`MAX_FILE_BYTES`] are refused before they are read;
//! * a file starting with the magic `glTF` is parsed as a GLB container here (not by the gltf
//!   crate), so that truncation and lying chunk lengths give precise errors: header version 2,
//!   declared total length equal to the file length, a JSON chunk first, an optional BIN chunk
//!   second, every chunk length within the remaining bytes and a multiple of 4;
//! * anything else must be a JSON object (after optional whitespace and a UTF-8 byte order mark);
//! * `asset.version` must be 2.x, and every entry of `extensionsRequired` must be in
//!   [`IGNORABLE_REQUIRED_EXTENSIONS`] (or start with one of [`IGNORABLE_REQUIRED_PREFIXES`]),
//!   otherwise the file is refused naming the extension (this is checked before the gltf crate
//!   sees the JSON);
//! * parts the importer ignores (materials, textures, images, samplers, animations) are removed
//!   before validation, so that a defect in them cannot refuse a file whose geometry is fine;
//! * mesh attribute accessor indices are range-checked before validation (the gltf crate's
//!   validation indexes `accessors[POSITION]` without a check).

use std::io::Read;
use std::path::Path;

use serde_json::Value;

use super::error::ImportError;

/// Largest scene or buffer file glint reads, in bytes (2 GiB).
pub const MAX_FILE_BYTES: u64 = 2 * 1024 * 1024 * 1024;

/// Required extensions that glint accepts without implementing them, because they concern only
/// materials, textures, lights or metadata, all of which the importer ignores; ignoring them cannot
/// change the geometry. Every other required extension — `KHR_draco_mesh_compression`,
/// `EXT_meshopt_compression`, `KHR_mesh_quantization`, `EXT_mesh_gpu_instancing`, … — changes how
/// geometry must be decoded and is refused with [`ImportError::RequiredExtension`].
pub const IGNORABLE_REQUIRED_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "MSFT_texture_dds",
    "KHR_lights_punctual",
    "KHR_xmp_json_ld",
];

/// Prefixes of required extensions accepted for the same reason as
/// [`IGNORABLE_REQUIRED_EXTENSIONS`]: every `KHR_materials_*` extension only changes materials.
pub const IGNORABLE_REQUIRED_PREFIXES: &[&str] = &["KHR_materials_"];

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// A parsed scene file: the validated document and the GLB BIN chunk, if any.
pub(crate) struct Parsed {
    pub document: gltf::Document,
    pub bin: Option<Vec<u8>>,
}

/// Reads at most `limit` bytes of `path`, refusing larger files before reading them.
pub(crate) fn read_limited(path: &Path, limit: u64) -> Result<Vec<u8>, ImportError> {
    let io = |source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size > limit {
        return Err(ImportError::FileTooLarge {
            path: path.to_path_buf(),
            size,
            limit,
        });
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    // Read one byte more than the limit so that a file that grew since `metadata` is still caught.
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    let read = bytes.len() as u64;
    if read > limit {
        return Err(ImportError::FileTooLarge {
            path: path.to_path_buf(),
            size: read,
            limit,
        });
    }
    Ok(bytes)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]])) // `b` has exactly 4 bytes: cannot panic
}

/// Byte ranges of the JSON and BIN chunks inside a GLB file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct GlbChunks {
    pub json: std::ops::Range<usize>,
    pub bin: Option<std::ops::Range<usize>>,
}

/// Parses the GLB container structure of `bytes` (which start with the `glTF` magic).
pub(crate) fn parse_glb(path: &Path, bytes: &[u8]) -> Result<GlbChunks, ImportError> {
    let p = || path.to_path_buf();
    let available = bytes.len() as u64;
    let (Some(version), Some(total)) = (u32_at(bytes, 4), u32_at(bytes, 8)) else {
        return Err(ImportError::Truncated {
            path: p(),
            what: "the 12-byte GLB header".into(),
            needed: 12,
            available,
        });
    };
    if version != 2 {
        return Err(ImportError::GlbVersion { path: p(), version });
    }
    let total = u64::from(total);
    if total > available {
        return Err(ImportError::Truncated {
            path: p(),
            what: "the GLB container (length from its header)".into(),
            needed: total,
            available,
        });
    }
    if total < available {
        return Err(ImportError::Glb {
            path: p(),
            message: format!(
                "header declares {total} bytes but the file has {available} (trailing data)"
            ),
        });
    }
    // total == bytes.len(), so every offset below that is <= total fits in usize.
    let end = bytes.len();
    let mut offset = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0usize;
    while offset < end {
        let remaining = end - offset; // offset < end
        if remaining < 8 {
            return Err(ImportError::Glb {
                path: p(),
                message: format!(
                    "{remaining} stray bytes after chunk {} (a chunk header needs 8)",
                    chunk.saturating_sub(1)
                ),
            });
        }
        let (Some(len), Some(kind)) = (u32_at(bytes, offset), u32_at(bytes, offset + 4)) else {
            // Cannot happen: remaining >= 8 was checked above.
            return Err(ImportError::Glb {
                path: p(),
                message: "unreadable chunk header".into(),
            });
        };
        let body = remaining - 8; // remaining >= 8 checked above
        let len_usize = usize::try_from(len).unwrap_or(usize::MAX);
        if len_usize > body {
            return Err(ImportError::ChunkLength {
                path: p(),
                chunk,
                declared: u64::from(len),
                available: body as u64,
            });
        }
        if !len.is_multiple_of(4) {
            return Err(ImportError::Glb {
                path: p(),
                message: format!(
                    "chunk {chunk} length {len} is not a multiple of 4 (chunks must stay 4-byte aligned)"
                ),
            });
        }
        let start = offset + 8;
        let range = start..start + len_usize; // len_usize <= body, so within `end`
        match (chunk, kind) {
            (0, CHUNK_JSON) => json = Some(range),
            (0, _) => {
                return Err(ImportError::Glb {
                    path: p(),
                    message: format!("first chunk has type 0x{kind:08x}, expected JSON"),
                });
            }
            (1, CHUNK_BIN) => bin = Some(range),
            (_, CHUNK_JSON) => {
                return Err(ImportError::Glb {
                    path: p(),
                    message: format!("chunk {chunk} is a second JSON chunk"),
                });
            }
            (_, CHUNK_BIN) => {
                return Err(ImportError::Glb {
                    path: p(),
                    message: format!("chunk {chunk} is a BIN chunk; BIN must be chunk 1"),
                });
            }
            // Unknown chunk types are skipped, as the specification requires.
            _ => {}
        }
        offset = start + len_usize;
        chunk += 1;
    }
    let Some(json) = json else {
        return Err(ImportError::Glb {
            path: p(),
            message: "no JSON chunk".into(),
        });
    };
    Ok(GlbChunks { json, bin })
}

/// Reads and validates the scene file at `path`.
pub(crate) fn read_document(path: &Path) -> Result<Parsed, ImportError> {
    let mut bytes = read_limited(path, MAX_FILE_BYTES)?;
    let (value, bin) = if bytes.starts_with(GLB_MAGIC) {
        let chunks = parse_glb(path, &bytes)?;
        let json_bytes = bytes.get(chunks.json.clone()).unwrap_or(&[]);
        let value = parse_json(path, json_bytes, true)?;
        let bin = match chunks.bin {
            Some(range) => {
                // Reuse the file's allocation for the BIN chunk instead of copying it.
                bytes.truncate(range.end);
                bytes.drain(..range.start);
                Some(bytes)
            }
            None => None,
        };
        (value, bin)
    } else {
        (parse_json(path, &bytes, false)?, None)
    };
    let root = prepare_root(path, value)?;
    let document = gltf::Document::from_json(root).map_err(|e| ImportError::Validation {
        path: path.to_path_buf(),
        message: describe_gltf_error(e),
    })?;
    Ok(Parsed { document, bin })
}

fn describe_gltf_error(e: gltf::Error) -> String {
    match e {
        gltf::Error::Validation(list) => {
            let mut parts: Vec<String> = list
                .iter()
                .take(4)
                .map(|(path, err)| format!("{path}: {err}"))
                .collect();
            if list.len() > 4 {
                parts.push(format!("and {} more", list.len() - 4));
            }
            parts.join("; ")
        }
        other => other.to_string().replace('\n', " "),
    }
}

/// Parses JSON text. `in_glb`: trailing NUL padding is tolerated (some writers pad with 0, not
/// spaces). Outside a GLB, text that does not start with `{` is "not glTF".
fn parse_json(path: &Path, bytes: &[u8], in_glb: bool) -> Result<Value, ImportError> {
    let mut text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    while let [rest @ .., 0 | b' ' | b'\t' | b'\r' | b'\n'] = text {
        text = rest;
    }
    let first = text
        .iter()
        .find(|b| !matches!(b, b' ' | b'\t' | b'\r' | b'\n'));
    if first != Some(&b'{') {
        return Err(if in_glb {
            ImportError::Json {
                path: path.to_path_buf(),
                message: "the JSON chunk does not hold a JSON object".into(),
            }
        } else {
            ImportError::NotGltf {
                path: path.to_path_buf(),
            }
        });
    }
    serde_json::from_slice(text).map_err(|e| ImportError::Json {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn is_ignorable_extension(name: &str) -> bool {
    IGNORABLE_REQUIRED_EXTENSIONS.contains(&name)
        || IGNORABLE_REQUIRED_PREFIXES
            .iter()
            .any(|prefix| name.starts_with(prefix))
}

/// Checks version and required extensions, removes ignored parts, deserialises and range-checks
/// what the gltf crate's validation would index unchecked.
fn prepare_root(path: &Path, mut value: Value) -> Result<gltf::json::Root, ImportError> {
    let json_err = |message: String| ImportError::Json {
        path: path.to_path_buf(),
        message,
    };
    let invalid = |message: String| ImportError::Validation {
        path: path.to_path_buf(),
        message,
    };
    let Some(object) = value.as_object_mut() else {
        return Err(json_err("top level is not a JSON object".into()));
    };

    // asset.version (and minVersion) must be 2.x. A missing asset is reported by deserialisation.
    if let Some(asset) = object.get("asset").and_then(Value::as_object) {
        for key in ["version", "minVersion"] {
            if let Some(v) = asset.get(key) {
                let Some(s) = v.as_str() else {
                    return Err(json_err(format!("asset.{key} is not a string")));
                };
                let major = s.split('.').next().unwrap_or("");
                if major != "2" {
                    return Err(invalid(format!(
                        "asset.{key} is {s:?}; glint reads glTF 2.x only"
                    )));
                }
            }
        }
    }

    if let Some(required) = object.remove("extensionsRequired") {
        let Some(list) = required.as_array() else {
            return Err(json_err("extensionsRequired is not an array".into()));
        };
        for entry in list {
            let Some(name) = entry.as_str() else {
                return Err(json_err(
                    "extensionsRequired holds a value that is not a string".into(),
                ));
            };
            if !is_ignorable_extension(name) {
                return Err(ImportError::RequiredExtension {
                    path: path.to_path_buf(),
                    extension: name.to_owned(),
                });
            }
        }
        // The remaining (ignorable) entries are dropped: the gltf crate would refuse those it
        // does not know, and the importer ignores what they concern anyway.
    }

    for key in ["materials", "textures", "images", "samplers", "animations"] {
        object.remove(key);
    }
    if let Some(meshes) = object.get_mut("meshes").and_then(Value::as_array_mut) {
        for mesh in meshes {
            if let Some(prims) = mesh.get_mut("primitives").and_then(Value::as_array_mut) {
                for prim in prims {
                    if let Some(prim) = prim.as_object_mut() {
                        prim.remove("material");
                    }
                }
            }
        }
    }

    let root: gltf::json::Root =
        serde_json::from_value(value).map_err(|e| json_err(e.to_string()))?;

    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= accessors {
                    return Err(invalid(format!(
                        "meshes[{m}].primitives[{p}].attributes[{}] refers to accessor {} but there are {accessors}",
                        semantic_name(semantic),
                        index.value()
                    )));
                }
            }
        }
    }
    Ok(root)
}

fn semantic_name(s: &gltf::json::validation::Checked<gltf::json::mesh::Semantic>) -> String {
    match s {
        gltf::json::validation::Checked::Valid(s) => s.to_string(),
        gltf::json::validation::Checked::Invalid => "?".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        let mut j = json.to_vec();
        while !j.len().is_multiple_of(4) {
            j.push(b' ');
        }
        out.extend_from_slice(&(j.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        out.extend_from_slice(&j);
        if let Some(bin) = bin {
            let mut b = bin.to_vec();
            while !b.len().is_multiple_of(4) {
                b.push(0);
            }
            out.extend_from_slice(&(b.len() as u32).to_le_bytes());
            out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
            out.extend_from_slice(&b);
        }
        let n = out.len() as u32;
        out[8..12].copy_from_slice(&n.to_le_bytes());
        out
    }

    #[test]
    fn glb_chunks_found() {
        let bytes = glb(b"{}", Some(&[1, 2, 3, 4, 5]));
        let c = parse_glb(Path::new("x.glb"), &bytes).unwrap();
        assert_eq!(c.json, 20..24);
        assert_eq!(c.bin, Some(32..40));
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let bytes = glb(br#"{"asset":{"version":"2.0"}}"#, Some(&[7; 20]));
        for cut in 0..bytes.len() {
            let b = &bytes[..cut];
            if cut >= 4 {
                assert!(parse_glb(Path::new("x.glb"), b).is_err(), "cut at {cut}");
            }
            // With a header length that agrees with the cut file: an error or the JSON chunk alone.
            if cut >= 12 {
                let mut b = b.to_vec();
                let n = b.len() as u32;
                b[8..12].copy_from_slice(&n.to_le_bytes());
                if let Ok(c) = parse_glb(Path::new("x.glb"), &b) {
                    assert_eq!(c.bin, None);
                }
            }
        }
    }

    #[test]
    fn lying_chunk_length() {
        let mut bytes = glb(b"{}  ", None);
        bytes[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        match parse_glb(Path::new("x.glb"), &bytes) {
            Err(ImportError::ChunkLength {
                chunk: 0,
                declared,
                available: 4,
                ..
            }) => assert_eq!(declared, u64::from(u32::MAX)),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn version_and_required_extensions() {
        let p = Path::new("x.gltf");
        let v: Value = serde_json::from_str(r#"{"asset":{"version":"1.0"}}"#).unwrap();
        assert!(matches!(
            prepare_root(p, v),
            Err(ImportError::Validation { .. })
        ));
        let v: Value = serde_json::from_str(
            r#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_materials_clearcoat","KHR_texture_transform"]}"#,
        )
        .unwrap();
        assert!(prepare_root(p, v).is_ok());
        let v: Value = serde_json::from_str(
            r#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_texture_transform","EXT_meshopt_compression"]}"#,
        )
        .unwrap();
        match prepare_root(p, v) {
            Err(ImportError::RequiredExtension { extension, .. }) => {
                assert_eq!(extension, "EXT_meshopt_compression")
            }
            Err(other) => panic!("{other}"),
            Ok(_) => panic!("accepted"),
        }
    }
}
