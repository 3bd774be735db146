//! File loading: OpenEXR via the `exr` crate, Radiance RGBE via `image`.
//!
//! Both paths read the header first and refuse oversized images before any pixel memory is
//! allocated. The EXR decoder runs single-threaded inside `catch_unwind`, so that a decoder panic
//! on a malformed file becomes an [`EnvError::Decode`] instead of aborting the process (a panic in
//! the exr crate's own thread pool would abort).

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use exr::prelude::{ReadChannels, ReadLayers, ReadSpecificChannel, Vec2};
use image::ImageDecoder;
use image::codecs::hdr::HdrDecoder;

use super::{EnvError, EnvMap, check_size};

/// Loads an equirectangular environment map, choosing the decoder by extension
/// (case-insensitive): `.exr` (OpenEXR: any compression the `exr` crate supports, including ZIP,
/// PIZ and DWAB; half, float or uint channels; the first layer with R, G, B channels, else the
/// first with a Y channel, read as grey) or `.hdr` (Radiance RGBE).
///
/// The map is sanitised (see [`EnvMap::from_rgb`]); its [`EnvMap::source`] is the file name.
pub fn load(path: &Path) -> Result<EnvMap, EnvError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (width, height, texels) = match ext.as_str() {
        "exr" => load_exr(path)?,
        "hdr" => load_hdr(path)?,
        _ => {
            return Err(EnvError::UnsupportedExtension {
                path: path.to_path_buf(),
                ext,
            });
        }
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    EnvMap::from_rgb(width, height, texels, name)
}

type Decoded = (usize, usize, Vec<[f32; 3]>);

fn io_error(path: &Path, source: std::io::Error) -> EnvError {
    EnvError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn decode_error(path: &Path, message: impl Into<String>) -> EnvError {
    EnvError::Decode {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_string()
    }
}

// ---------------------------------------------------------------------------------------------
// OpenEXR

/// Which channels of the chosen layer are read.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ExrChannels {
    Rgb,
    Grey,
}

/// Pixel storage handed to the exr reader. `create` checks the size again (it must agree with the
/// header check) and allocates nothing when it is out of limits.
struct ExrPixels {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
}

impl ExrPixels {
    fn new(size: Vec2<usize>) -> Self {
        let (width, height) = (size.width(), size.height());
        let within = check_size(PathBuf::new(), width as u64, height as u64).is_ok();
        let texels = if within {
            vec![[0.0; 3]; width * height]
        } else {
            Vec::new()
        };
        ExrPixels {
            width,
            height,
            texels,
        }
    }

    fn set(&mut self, pos: Vec2<usize>, rgb: [f32; 3]) {
        if pos.x() < self.width
            && let Some(t) = self.texels.get_mut(pos.y() * self.width + pos.x())
        {
            *t = rgb;
        }
    }
}

fn load_exr(path: &Path) -> Result<Decoded, EnvError> {
    let mut file = File::open(path).map_err(|e| io_error(path, e))?;

    // 1. Header only: choose the layer and check its size before any pixel allocation.
    let meta = catch_unwind(AssertUnwindSafe(|| {
        exr::meta::MetaData::read_from_buffered(BufReader::new(&mut file), false)
    }))
    .map_err(|p| decode_error(path, format!("decoder panicked: {}", panic_message(&*p))))?
    .map_err(|e| decode_error(path, format!("invalid OpenEXR header: {e}")))?;

    let has =
        |h: &exr::meta::header::Header, name: &str| h.channels.list.iter().any(|c| c.name.eq(name));
    let flat = || meta.headers.iter().filter(|h| !h.deep);
    let (header, mode) = if let Some(h) = flat().find(|h| has(h, "R") && has(h, "G") && has(h, "B"))
    {
        (h, ExrChannels::Rgb)
    } else if let Some(h) = flat().find(|h| has(h, "Y")) {
        (h, ExrChannels::Grey)
    } else {
        let mut channels: Vec<String> = Vec::new();
        for h in &meta.headers {
            for c in &h.channels.list {
                let name = c.name.to_string();
                if !channels.contains(&name) {
                    channels.push(name);
                }
            }
        }
        return Err(EnvError::NoRgbChannels {
            path: path.to_path_buf(),
            channels,
        });
    };
    let (width, height) = (header.layer_size.width(), header.layer_size.height());
    check_size(path.to_path_buf(), width as u64, height as u64)?;
    if width == 0 || height == 0 {
        return Err(EnvError::Empty {
            name: path.display().to_string(),
            width,
            height,
        });
    }

    // 2. Pixels: the first layer with the chosen channels, which is the header chosen above.
    file.seek(SeekFrom::Start(0))
        .map_err(|e| io_error(path, e))?;
    let reader = BufReader::new(file);
    let decoded = catch_unwind(AssertUnwindSafe(move || read_exr_pixels(reader, mode)))
        .map_err(|p| decode_error(path, format!("decoder panicked: {}", panic_message(&*p))))?
        .map_err(|e| {
            decode_error(
                path,
                format!("invalid OpenEXR pixel data (truncated or corrupt?): {e}"),
            )
        })?;

    if decoded.width != width || decoded.height != height || decoded.texels.len() != width * height
    {
        return Err(decode_error(
            path,
            format!(
                "decoded layer is {}x{} but the header declares {width}x{height}",
                decoded.width, decoded.height
            ),
        ));
    }
    Ok((width, height, decoded.texels))
}

fn read_exr_pixels(
    reader: BufReader<File>,
    mode: ExrChannels,
) -> Result<ExrPixels, exr::error::Error> {
    let builder = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level();
    let pixels = match mode {
        ExrChannels::Rgb => {
            builder
                .specific_channels()
                .required("R")
                .required("G")
                .required("B")
                .collect_pixels(
                    |size, _| ExrPixels::new(size),
                    |px: &mut ExrPixels, pos, (r, g, b): (f32, f32, f32)| px.set(pos, [r, g, b]),
                )
                .first_valid_layer()
                .all_attributes()
                .non_parallel()
                .from_buffered(reader)?
                .layer_data
                .channel_data
                .pixels
        }
        ExrChannels::Grey => {
            builder
                .specific_channels()
                .required("Y")
                .collect_pixels(
                    |size, _| ExrPixels::new(size),
                    |px: &mut ExrPixels, pos, (y,): (f32,)| px.set(pos, [y, y, y]),
                )
                .first_valid_layer()
                .all_attributes()
                .non_parallel()
                .from_buffered(reader)?
                .layer_data
                .channel_data
                .pixels
        }
    };
    Ok(pixels)
}

// ---------------------------------------------------------------------------------------------
// Radiance RGBE

fn load_hdr(path: &Path) -> Result<Decoded, EnvError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let mut reader = BufReader::new(file);

    // Peek at the signature: "#?RADIANCE" is decoded strictly; other "#?" programs (e.g. "#?RGBE")
    // leniently; anything else is not a Radiance file.
    let mut magic = [0u8; 10];
    let mut filled = 0;
    while filled < magic.len() {
        match reader.read(&mut magic[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io_error(path, e)),
        }
    }
    if !magic[..filled].starts_with(b"#?") {
        return Err(decode_error(
            path,
            "not a Radiance HDR file (no \"#?\" signature)",
        ));
    }
    let strict = magic[..filled] == *b"#?RADIANCE";
    reader
        .seek(SeekFrom::Start(0))
        .map_err(|e| io_error(path, e))?;

    let decoder = HdrDecoder::with_strictness(reader, strict)
        .map_err(|e| decode_error(path, format!("invalid Radiance header: {e}")))?;
    let (w, h) = decoder.dimensions();
    check_size(path.to_path_buf(), u64::from(w), u64::from(h))?;
    let (width, height) = (w as usize, h as usize);
    if width == 0 || height == 0 {
        return Err(EnvError::Empty {
            name: path.display().to_string(),
            width,
            height,
        });
    }
    // Rgb32F: 12 bytes per texel, native-endian f32 (`image` guarantees the layout).
    let total = decoder.total_bytes();
    if total != (width * height * 12) as u64 {
        return Err(decode_error(
            path,
            format!("unexpected decoded size {total} bytes for {width}x{height} RGB f32"),
        ));
    }
    let mut bytes = vec![0u8; width * height * 12];
    decoder.read_image(&mut bytes).map_err(|e| {
        decode_error(
            path,
            format!("invalid Radiance pixel data (truncated or corrupt?): {e}"),
        )
    })?;
    let texels = bytes
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f32::from_ne_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
            [f(0), f(4), f(8)]
        })
        .collect();
    Ok((width, height, texels))
}
