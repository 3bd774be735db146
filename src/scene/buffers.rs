//! Loading the bytes of every glTF buffer.
//!
//! Inputs: the validated document, the GLB BIN chunk (if any) and the scene file's path.
//! Outputs: [`Buffers`], each buffer's bytes cut to exactly its declared `byteLength`.
//!
//! Invariants:
//! * a buffer without `uri` is the GLB BIN chunk; `data:` URIs are decoded (base64 or
//!   percent-encoded); every other URI must be a relative path, which is percent-decoded and
//!   resolved against the scene file's folder;
//! * **reading a glTF never touches files outside its folder**: absolute paths (`/…`, `\…`, drive
//!   letters) and other schemes (`http:`, `file:`, …) are refused without touching the file system;
//!   a path whose `..` components climb above the folder is refused before any file-system call; a
//!   path that exists is canonicalised and refused unless it lies inside the canonicalised folder
//!   (symlinks pointing out); only then is the file opened, and at most `byteLength` bytes are
//!   read;
//! * data shorter than the declared `byteLength` is [`ImportError::BufferTooShort`].

use std::io::Read;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use percent_encoding::percent_decode_str;

use super::container::MAX_FILE_BYTES;
use super::error::ImportError;

/// The bytes of every buffer of a document, indexed like `document.buffers()`.
#[derive(Debug)]
pub(crate) struct Buffers {
    bin: Vec<u8>,
    /// `None`: this buffer is (a prefix of) the BIN chunk.
    data: Vec<Option<Vec<u8>>>,
    /// Declared byte lengths.
    lengths: Vec<usize>,
}

impl Buffers {
    /// The bytes of buffer `index`, exactly its declared length long; `None` if there is no such
    /// buffer.
    pub fn get(&self, index: usize) -> Option<&[u8]> {
        let len = *self.lengths.get(index)?;
        match self.data.get(index)? {
            Some(bytes) => bytes.get(..len),
            None => self.bin.get(..len),
        }
    }
}

/// Loads every buffer of `root`; `scene_path` is the scene file.
pub(crate) fn load(
    scene_path: &Path,
    root: &gltf::json::Root,
    bin: Option<Vec<u8>>,
) -> Result<Buffers, ImportError> {
    let mut folder: Option<PathBuf> = None; // canonicalised lazily: only needed for file URIs
    let mut data = Vec::with_capacity(root.buffers.len());
    let mut lengths = Vec::with_capacity(root.buffers.len());
    for (index, buffer) in root.buffers.iter().enumerate() {
        let declared = buffer.byte_length.0;
        let too_short = |actual: u64| ImportError::BufferTooShort {
            path: scene_path.to_path_buf(),
            buffer: index,
            declared,
            actual,
        };
        let Ok(declared_usize) = usize::try_from(declared) else {
            return Err(too_short(0));
        };
        if declared > MAX_FILE_BYTES {
            return Err(ImportError::FileTooLarge {
                path: scene_path.to_path_buf(),
                size: declared,
                limit: MAX_FILE_BYTES,
            });
        }
        let bytes = match buffer.uri.as_deref() {
            None => {
                let Some(bin) = bin.as_ref() else {
                    return Err(ImportError::MissingBuffer {
                        path: scene_path.to_path_buf(),
                        buffer: index,
                        uri: "(GLB BIN chunk)".into(),
                    });
                };
                if bin.len() < declared_usize {
                    return Err(too_short(bin.len() as u64));
                }
                None
            }
            Some(uri) => {
                let bytes = if has_scheme(uri, "data") {
                    decode_data_uri(scene_path, index, uri)?
                } else {
                    let folder = match &folder {
                        Some(f) => f.clone(),
                        None => {
                            let f = scene_folder(scene_path)?;
                            folder = Some(f.clone());
                            f
                        }
                    };
                    read_relative(scene_path, &folder, index, uri, declared)?
                };
                if bytes.len() < declared_usize {
                    return Err(too_short(bytes.len() as u64));
                }
                Some(bytes)
            }
        };
        data.push(bytes);
        lengths.push(declared_usize);
    }
    Ok(Buffers {
        bin: bin.unwrap_or_default(),
        data,
        lengths,
    })
}

/// The canonicalised folder holding the scene file.
fn scene_folder(scene_path: &Path) -> Result<PathBuf, ImportError> {
    let parent = match scene_path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    parent.canonicalize().map_err(|source| ImportError::Io {
        path: parent.to_path_buf(),
        source,
    })
}

/// The URI scheme (RFC 3986: a letter, then letters, digits, `+`, `-`, `.`, then `:`), if any.
fn scheme(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let s = uri.get(..colon)?;
    let mut chars = s.chars();
    let first = chars.next()?;
    (first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(s)
}

fn has_scheme(uri: &str, name: &str) -> bool {
    scheme(uri).is_some_and(|s| s.eq_ignore_ascii_case(name))
}

/// `/x`, `\x`, `C:…` (a one-letter "scheme" is a Windows drive letter).
fn is_absolute(s: &str) -> bool {
    s.starts_with('/')
        || s.starts_with('\\')
        || scheme(s).is_some_and(|sch| sch.len() == 1)
        || Path::new(s).is_absolute()
}

fn decode_data_uri(scene_path: &Path, index: usize, uri: &str) -> Result<Vec<u8>, ImportError> {
    let bad = |message: String| ImportError::BadDataUri {
        path: scene_path.to_path_buf(),
        buffer: index,
        message,
    };
    // "data:" is 5 ASCII bytes (has_scheme checked it), so slicing at 5 is on a char boundary.
    let rest = uri.get(5..).unwrap_or("");
    let Some((header, payload)) = rest.split_once(',') else {
        return Err(bad("no ',' separating the media type from the data".into()));
    };
    if header
        .rsplit(';')
        .next()
        .is_some_and(|last| last.eq_ignore_ascii_case("base64"))
    {
        let cleaned: String = payload
            .chars()
            .filter(|c| !c.is_ascii_whitespace())
            .collect();
        let engine = base64::engine::GeneralPurpose::new(
            &base64::alphabet::STANDARD,
            base64::engine::GeneralPurposeConfig::new()
                .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
        );
        engine
            .decode(cleaned.as_bytes())
            .map_err(|e| bad(format!("invalid base64: {e}")))
    } else {
        Ok(percent_decode_str(payload).collect())
    }
}

/// Resolves a relative buffer URI inside `folder` and reads at most `declared` bytes of it.
fn read_relative(
    scene_path: &Path,
    folder: &Path,
    index: usize,
    uri: &str,
    declared: u64,
) -> Result<Vec<u8>, ImportError> {
    let absolute = || ImportError::AbsoluteUri {
        path: scene_path.to_path_buf(),
        uri: uri.to_owned(),
    };
    let outside = || ImportError::BufferUriOutsideFolder {
        path: scene_path.to_path_buf(),
        uri: uri.to_owned(),
    };
    let missing = || ImportError::MissingBuffer {
        path: scene_path.to_path_buf(),
        buffer: index,
        uri: uri.to_owned(),
    };
    if is_absolute(uri) {
        return Err(absolute());
    }
    if let Some(s) = scheme(uri) {
        return Err(ImportError::UnsupportedUriScheme {
            path: scene_path.to_path_buf(),
            uri: uri.to_owned(),
            scheme: s.to_owned(),
        });
    }
    // Query and fragment are not part of a file path.
    let path_part = uri.split(['?', '#']).next().unwrap_or("");
    let Ok(decoded) = percent_decode_str(path_part).decode_utf8() else {
        return Err(ImportError::Validation {
            path: scene_path.to_path_buf(),
            message: format!(
                "buffer {index}: URI {:?} is not UTF-8 after percent-decoding",
                super::error::short(uri)
            ),
        });
    };
    if is_absolute(&decoded) {
        return Err(absolute());
    }
    if decoded.is_empty() || decoded.contains('\0') {
        return Err(missing());
    }
    // Lexical check first: no file-system call for a path that climbs out of the folder.
    let mut depth = 0usize;
    for part in decoded.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => depth = depth.checked_sub(1).ok_or_else(outside)?,
            _ => depth += 1,
        }
    }
    let candidate = folder.join(&*decoded);
    let resolved = match candidate.canonicalize() {
        Ok(r) => r,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(missing()),
        Err(source) => {
            return Err(ImportError::Io {
                path: candidate,
                source,
            });
        }
    };
    if !resolved.starts_with(folder) {
        return Err(outside());
    }
    if !resolved.is_file() {
        return Err(missing());
    }
    let io = |source| ImportError::Io {
        path: resolved.clone(),
        source,
    };
    let file = std::fs::File::open(&resolved).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(declared).read_to_end(&mut bytes).map_err(io)?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemes_and_absolute_paths() {
        assert_eq!(scheme("http://x/y.bin"), Some("http"));
        assert_eq!(
            scheme("data:application/octet-stream;base64,AAAA"),
            Some("data")
        );
        assert_eq!(scheme("a.bin"), None);
        assert_eq!(scheme("dir/a:b.bin"), None);
        assert_eq!(scheme("1a:b"), None);
        assert!(is_absolute("/etc/passwd"));
        assert!(is_absolute("\\\\server\\share"));
        assert!(is_absolute("C:\\x.bin"));
        assert!(is_absolute("c:x.bin"));
        assert!(!is_absolute("x.bin"));
    }

    #[test]
    fn data_uris() {
        let p = Path::new("x.gltf");
        assert_eq!(
            decode_data_uri(p, 0, "data:application/octet-stream;base64,AQID").unwrap(),
            vec![1, 2, 3]
        );
        assert_eq!(
            decode_data_uri(p, 0, "data:application/gltf-buffer;base64,AQIDBA").unwrap(),
            vec![1, 2, 3, 4]
        );
        assert_eq!(decode_data_uri(p, 0, "data:,%01%02").unwrap(), vec![1, 2]);
        assert!(matches!(
            decode_data_uri(p, 0, "data:application/octet-stream;base64,*&^"),
            Err(ImportError::BadDataUri { .. })
        ));
        assert!(matches!(
            decode_data_uri(p, 0, "data:nothing"),
            Err(ImportError::BadDataUri { .. })
        ));
    }
}
