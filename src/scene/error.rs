//! The one error type of glTF import, [`ImportError`].
//!
//! Inputs: none (plain data). Outputs: error values. Invariants: every message is one line, starts
//! with the file it concerns (the scene file, or for [`ImportError::Io`] the file that failed) and
//! states the cause; URIs are quoted with `{:?}` (so control characters stay escaped) and shortened
//! to [`MAX_URI_CHARS`] characters in messages (the fields keep them whole).

use std::path::PathBuf;

/// URIs longer than this many characters are shortened (with `…`) in error messages.
pub const MAX_URI_CHARS: usize = 120;

/// Shortens `uri` for a message: at most [`MAX_URI_CHARS`] characters, then `…`.
pub(crate) fn short(uri: &str) -> String {
    if uri.chars().count() <= MAX_URI_CHARS {
        uri.to_owned()
    } else {
        let mut s: String = uri.chars().take(MAX_URI_CHARS).collect();
        s.push('…');
        s
    }
}

/// Everything that can go wrong importing a glTF 2.0 file. Every variant names the file; the
/// `Display` message is one line.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A file (the scene, or an external buffer) could not be opened or read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The scene file (or an external buffer) is larger than glint accepts.
    #[error("{}: file is {size} bytes; glint refuses files over {limit} bytes", path.display())]
    FileTooLarge {
        path: PathBuf,
        size: u64,
        limit: u64,
    },
    /// Neither the GLB magic `glTF` nor a JSON object.
    #[error("{}: not a glTF file (no GLB magic \"glTF\" and not a JSON object)", path.display())]
    NotGltf { path: PathBuf },
    /// A GLB container with a version other than 2.
    #[error("{}: GLB container version {version} is not supported (glint reads version 2)", path.display())]
    GlbVersion { path: PathBuf, version: u32 },
    /// The file ends before the byte count its GLB header (or the fixed header size) requires.
    #[error("{}: truncated: {what} needs {needed} bytes but the file has {available}", path.display())]
    Truncated {
        path: PathBuf,
        what: String,
        needed: u64,
        available: u64,
    },
    /// A GLB chunk declares more bytes than remain in the container.
    #[error(
        "{}: GLB chunk {chunk} declares {declared} bytes but only {available} remain in the container",
        path.display()
    )]
    ChunkLength {
        path: PathBuf,
        chunk: usize,
        declared: u64,
        available: u64,
    },
    /// Any other malformation of the GLB container (chunk order, alignment, stray bytes).
    #[error("{}: malformed GLB container: {message}", path.display())]
    Glb { path: PathBuf, message: String },
    /// The JSON is not valid JSON or does not have the shape of a glTF document.
    #[error("{}: invalid glTF JSON: {message}", path.display())]
    Json { path: PathBuf, message: String },
    /// The glTF document breaks a rule of the specification (bad index, missing field, …).
    #[error("{}: invalid glTF: {message}", path.display())]
    Validation { path: PathBuf, message: String },
    /// `extensionsRequired` lists an extension glint does not implement.
    #[error("{}: requires glTF extension {extension}, which glint does not implement", path.display())]
    RequiredExtension { path: PathBuf, extension: String },
    /// A buffer URI that leaves the scene file's folder (`..`, or a symlink pointing out).
    #[error(
        "{}: buffer URI {:?} points outside the scene file's folder; refused",
        path.display(),
        short(uri)
    )]
    BufferUriOutsideFolder { path: PathBuf, uri: String },
    /// A buffer URI that is an absolute path (`/…`, `\…`, `C:…`).
    #[error(
        "{}: buffer URI {:?} is an absolute path; only paths relative to the scene file are allowed",
        path.display(),
        short(uri)
    )]
    AbsoluteUri { path: PathBuf, uri: String },
    /// A buffer URI with a scheme other than `data:` (`http:`, `file:`, …).
    #[error(
        "{}: buffer URI {:?} uses the {scheme:?} scheme; only relative paths and data: URIs are allowed",
        path.display(),
        short(uri)
    )]
    UnsupportedUriScheme {
        path: PathBuf,
        uri: String,
        scheme: String,
    },
    /// A `data:` URI that cannot be decoded.
    #[error("{}: buffer {buffer}: bad data: URI: {message}", path.display())]
    BadDataUri {
        path: PathBuf,
        buffer: usize,
        message: String,
    },
    /// A buffer whose file does not exist (or, in a GLB, a buffer without URI and no BIN chunk).
    #[error("{}: buffer {buffer}: {:?} not found", path.display(), short(uri))]
    MissingBuffer {
        path: PathBuf,
        buffer: usize,
        uri: String,
    },
    /// Buffer data shorter than the buffer's declared `byteLength`.
    #[error(
        "{}: buffer {buffer} declares {declared} bytes but its data has only {actual}",
        path.display()
    )]
    BufferTooShort {
        path: PathBuf,
        buffer: usize,
        declared: u64,
        actual: u64,
    },
    /// An accessor with a bad count, offset, stride, type or sparse part, or bad data.
    #[error("{}: accessor {accessor}: {message}", path.display())]
    Accessor {
        path: PathBuf,
        accessor: usize,
        message: String,
    },
    /// A vertex index that is not below the primitive's vertex count.
    #[error(
        "{}: mesh {mesh:?}: vertex index {index} is out of range (the primitive has {vertices} vertices)",
        path.display()
    )]
    IndexOutOfRange {
        path: PathBuf,
        mesh: String,
        index: u32,
        vertices: usize,
    },
    /// The default scene holds no triangle (only points or lines, or nothing).
    #[error("{}: the scene contains no triangles", path.display())]
    NoTriangles { path: PathBuf },
    /// The document has no scene to show.
    #[error("{}: the glTF document has no scene", path.display())]
    NoScene { path: PathBuf },
    /// Instancing or node nesting would produce more than glint accepts.
    #[error("{}: scene too large: {message}", path.display())]
    SceneTooLarge { path: PathBuf, message: String },
}
