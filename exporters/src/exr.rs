//! The p(h) table as OpenEXR: `<name>_ph.exr`, RGB 32-bit float (linear), one part, scan lines,
//! uncompressed, with glint's metadata as header attributes.
//!
//! Inputs: a validated [`MaterialDesc`] (its [`PhTable`] and lobe-table scalars). Outputs: the file
//! bytes ([`encode_ph_exr`]), the exporter ([`ExrExporter`]), and a reader through the `exr` crate
//! ([`read_ph_exr`], [`read_ph_exr_attributes`]) that the tests use as an independent decoder.
//!
//! Attributes (besides the required ones): `glint.model`, `glint.name`, `glint.layout`,
//! `glint.parameterisation` (name and formula), `glint.frame_convention`, `glint.brdf_convention`,
//! `glint.conventions` (where the exact conventions are stated: docs/conventions.md),
//! `glint.provenance` (JSON, ASCII with `\\uXXXX` escapes) — strings; `glint.version`,
//! `glint.isotropic` (0/1), `glint.lobe_count` — int; `glint.lambda`, `glint.sigma`, `glint.f0` —
//! double; `glint.rho_d` — v3d (three doubles), and again as the floats `glint.rho_d_r`, `_g`, `_b`
//! (Mitsuba's EXR reader drops v3d attributes).
//!
//! Invariants: the header is written by hand, attributes sorted by name, so equal inputs give equal
//! bytes (the `exr` crate keeps custom attributes in a `HashMap` and would write them in a random
//! order); texel (x, y) is pixel (x, y), row y = 0 the first scan line (INCREASING_Y); strings are
//! ASCII (other characters escaped as `\u{…}`).

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::material::{CONVENTIONS_DOC, MaterialDesc, SceneMesh};
use crate::table::{PARAMETERISATION_FORMULA, PhTable};
use std::collections::BTreeMap;
use std::path::Path;

/// File name of a material's table.
pub fn ph_exr_file_name(name: &str) -> String {
    format!("{name}_ph.exr")
}

/// A header attribute value as [`read_ph_exr_attributes`] returns it.
#[derive(Debug, Clone, PartialEq)]
pub enum AttrValue {
    Text(String),
    Int(i32),
    Double(f64),
    Float(f32),
    Vec3([f64; 3]),
    /// Any other type: its type name.
    Other(String),
}

/// Escapes everything outside printable ASCII as `\u{…}` (EXR strings are byte strings; the `exr`
/// crate accepts only chars < 256).
pub(crate) fn ascii(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_ascii() && (!c.is_ascii_control() || c == '\t') {
            out.push(c);
        } else {
            out.push_str(&format!("\\u{{{:x}}}", c as u32));
        }
    }
    out
}

/// Compact JSON with every non-ASCII character as a `\uXXXX` escape (still valid JSON, pure ASCII).
pub(crate) fn json_ascii(value: &serde_json::Value) -> String {
    let text = value.to_string();
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{:04x}", u));
            }
        }
    }
    out
}

pub(crate) struct Header {
    pub(crate) attrs: Vec<(String, &'static str, Vec<u8>)>,
}

impl Header {
    pub(crate) fn add(&mut self, name: &str, kind: &'static str, bytes: Vec<u8>) {
        self.attrs.push((name.to_string(), kind, bytes));
    }
    pub(crate) fn text(&mut self, name: &str, value: &str) {
        self.add(name, "string", ascii(value).into_bytes());
    }
    fn double(&mut self, name: &str, value: f64) {
        self.add(name, "double", value.to_le_bytes().to_vec());
    }
}

/// The bytes of `<name>_ph.exr` (the description is validated first).
pub fn encode_ph_exr(desc: &MaterialDesc) -> Result<Vec<u8>, ExportError> {
    desc.validate()?;
    let r = desc.table.resolution as usize;
    let mut h = Header { attrs: Vec::new() };
    h.text("glint.model", &desc.model);
    h.text("glint.name", &desc.name);
    h.text("glint.layout", &desc.layout);
    h.add(
        "glint.version",
        "int",
        (desc.version.min(i32::MAX as u32) as i32)
            .to_le_bytes()
            .to_vec(),
    );
    h.double("glint.lambda", desc.lambda);
    h.double("glint.sigma", desc.sigma);
    h.double("glint.f0", desc.f0);
    h.add(
        "glint.rho_d",
        "v3d",
        desc.rho_d.iter().flat_map(|v| v.to_le_bytes()).collect(),
    );
    // The same scalars as plain attributes, for readers that drop vector types (Mitsuba's EXR
    // reader).
    for (k, channel) in ["r", "g", "b"].iter().enumerate() {
        h.add(
            &format!("glint.rho_d_{channel}"),
            "float",
            (desc.rho_d[k] as f32).to_le_bytes().to_vec(),
        );
    }
    h.add(
        "glint.isotropic",
        "int",
        i32::from(desc.isotropic).to_le_bytes().to_vec(),
    );
    h.add(
        "glint.lobe_count",
        "int",
        (desc.centres.len().min(i32::MAX as usize) as i32)
            .to_le_bytes()
            .to_vec(),
    );
    h.text("glint.conventions", CONVENTIONS_DOC);
    h.text("glint.parameterisation", PARAMETERISATION_FORMULA); // starts with the name, "hemi-octahedral:"
    h.text("glint.frame_convention", &desc.frame_convention);
    h.text("glint.brdf_convention", &desc.brdf_convention);
    h.text(
        "glint.provenance",
        &json_ascii(&serde_json::json!(desc.provenance)),
    );
    Ok(encode_rgb_exr(r, r, &desc.table.texels, h))
}

/// An RGB 32-bit float image as uncompressed scan-line OpenEXR, with the given extra attributes
/// (`width`, `height` ≥ 1; `texels` row-major, `width × height`, row 0 the first scan line).
pub(crate) fn encode_rgb_exr(
    width: usize,
    height: usize,
    texels: &[[f32; 3]],
    mut h: Header,
) -> Vec<u8> {
    // Required attributes.
    let mut chlist = Vec::new();
    for ch in [b'B', b'G', b'R'] {
        chlist.extend_from_slice(&[ch, 0]);
        chlist.extend_from_slice(&2i32.to_le_bytes()); // FLOAT
        chlist.extend_from_slice(&[0, 0, 0, 0]); // pLinear, reserved
        chlist.extend_from_slice(&1i32.to_le_bytes());
        chlist.extend_from_slice(&1i32.to_le_bytes());
    }
    chlist.push(0);
    h.add("channels", "chlist", chlist);
    h.add("compression", "compression", vec![0]);
    let mut window = Vec::new();
    for v in [0i32, 0, width as i32 - 1, height as i32 - 1] {
        window.extend_from_slice(&v.to_le_bytes());
    }
    h.add("dataWindow", "box2i", window.clone());
    h.add("displayWindow", "box2i", window);
    h.add("lineOrder", "lineOrder", vec![0]);
    h.add("pixelAspectRatio", "float", 1f32.to_le_bytes().to_vec());
    h.add(
        "screenWindowCenter",
        "v2f",
        [0f32.to_le_bytes(), 0f32.to_le_bytes()].concat(),
    );
    h.add("screenWindowWidth", "float", 1f32.to_le_bytes().to_vec());
    h.attrs.sort_by(|a, b| a.0.cmp(&b.0));

    let long_names = h.attrs.iter().any(|(n, k, _)| n.len() > 31 || k.len() > 31);
    let mut out = Vec::with_capacity(1024 + height * 8 + height * (8 + 12 * width));
    out.extend_from_slice(&20000630i32.to_le_bytes());
    out.extend_from_slice(&(2u32 | if long_names { 0x400 } else { 0 }).to_le_bytes());
    for (name, kind, bytes) in &h.attrs {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(bytes.len() as i32).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    out.push(0);
    // Offset table: one block per scan line (uncompressed).
    let line_bytes = 12 * width;
    let first = out.len() + 8 * height;
    for y in 0..height {
        out.extend_from_slice(&((first + y * (8 + line_bytes)) as u64).to_le_bytes());
    }
    for y in 0..height {
        out.extend_from_slice(&(y as i32).to_le_bytes());
        out.extend_from_slice(&(line_bytes as i32).to_le_bytes());
        let row = &texels[y * width..(y + 1) * width];
        for k in [2, 1, 0] {
            for t in row {
                out.extend_from_slice(&t[k].to_le_bytes());
            }
        }
    }
    out
}

/// Writes `<name>_ph.exr`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ExrExporter;

impl Exporter for ExrExporter {
    fn name(&self) -> &'static str {
        "exr"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["exr"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        _scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        Ok(vec![OutputFile {
            path: dir.join(ph_exr_file_name(&desc.name)),
            bytes: encode_ph_exr(desc)?,
        }])
    }
}

fn exr_error(path: &Path, reason: impl std::fmt::Display) -> ExportError {
    ExportError::Exr {
        path: path.to_path_buf(),
        reason: reason.to_string().replace(['\n', '\r'], " "),
    }
}

fn read_with_attributes(
    path: &Path,
) -> Result<(PhTable, BTreeMap<String, AttrValue>), ExportError> {
    use exr::prelude::*;
    if !path.is_file() {
        return Err(ExportError::Read {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size, _| (size.width(), vec![[0f32; 3]; size.width() * size.height()]),
            |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b): (f32, f32, f32)| {
                px[pos.y() * *w + pos.x()] = [r, g, b]
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| exr_error(path, e))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    if w != h || w == 0 {
        return Err(exr_error(path, format!("the table is {w}x{h}, not square")));
    }
    let texels = layer.channel_data.pixels.1.clone();
    let mut attrs = BTreeMap::new();
    for (name, value) in layer
        .attributes
        .other
        .iter()
        .chain(image.attributes.other.iter())
    {
        let name = name.to_string();
        if !name.starts_with("glint.") {
            continue;
        }
        let v = match value {
            AttributeValue::Text(t) => {
                AttrValue::Text(String::from_utf8_lossy(t.bytes()).into_owned())
            }
            AttributeValue::I32(i) => AttrValue::Int(*i),
            AttributeValue::F64(d) => AttrValue::Double(*d),
            AttributeValue::F32(f) => AttrValue::Float(*f),
            AttributeValue::Custom { kind, bytes }
                if kind.bytes() == b"v3d" && bytes.len() == 24 =>
            {
                let d = |i: usize| {
                    f64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().unwrap_or([0; 8]))
                };
                AttrValue::Vec3([d(0), d(1), d(2)])
            }
            AttributeValue::Custom { kind, .. }
            | AttributeValue::Bytes {
                type_hint: kind, ..
            } => AttrValue::Other(kind.to_string()),
            other => AttrValue::Other(format!("{other:?}").chars().take(40).collect()),
        };
        attrs.insert(name, v);
    }
    Ok((
        PhTable {
            resolution: w as u32,
            texels,
        },
        attrs,
    ))
}

/// Reads a p(h) table (any EXR with R, G, B channels and a square data window) with the `exr`
/// crate.
pub fn read_ph_exr(path: &Path) -> Result<PhTable, ExportError> {
    read_with_attributes(path).map(|(t, _)| t)
}

/// The `glint.*` header attributes of an EXR table.
pub fn read_ph_exr_attributes(path: &Path) -> Result<BTreeMap<String, AttrValue>, ExportError> {
    read_with_attributes(path).map(|(_, a)| a)
}
