//! Reading a material back from glint's own exports: the lobe table of a `.glb` (its material's
//! `extras.glint`) or of a `.usda` (the `GlintDbrdf` shader's inputs), as the JSON object
//! [`MaterialDesc::lobe_table_json`](crate::MaterialDesc::lobe_table_json) writes — the shape of
//! glint's material JSON, with `layout` by name.
//!
//! Inputs: a file path. Outputs: [`read_lobe_table`] → `serde_json::Value`. The caller (glint)
//! turns it into its material type and validates the numbers against the layout.
//!
//! Invariants: only the named file is read — the USD text is parsed as one layer
//! (`openusd::usda::parse`, no composition, so no sublayer, reference or payload is opened) and the
//! table a file names is not opened, but its path must stay inside the file's folder (relative, no
//! `..`, no scheme); files over [`MAX_FILE_BYTES`] and arrays over [`MAX_LOBES`] entries are
//! refused before they are parsed or copied; every failure is one line ([`ExportError::Import`]).

use crate::error::ExportError;
use crate::material::MODEL;
use serde_json::{Value, json};
use std::path::Path;

/// Largest material file read back (a glTF with a million-vertex mesh is ~60 MB).
pub const MAX_FILE_BYTES: u64 = 1 << 30;
/// Most lobes a material may have (glint's layouts refuse more).
pub const MAX_LOBES: usize = 100_000;

fn bad(path: &Path, reason: impl Into<String>) -> ExportError {
    ExportError::Import {
        path: path.to_path_buf(),
        reason: reason.into().replace(['\n', '\r'], " "),
    }
}

/// The lobe table of a `.glb`, `.gltf` or `.usda` glint wrote (by extension).
pub fn read_lobe_table(path: &Path) -> Result<Value, ExportError> {
    let ext = extension(path);
    let bytes = read_capped(path)?;
    match ext.as_str() {
        "glb" | "gltf" => from_gltf(path, &bytes),
        "usda" | "usd" => from_usda(path, &bytes),
        _ => Err(bad(
            path,
            "not a material file glint reads back (.json, .glb, .gltf or .usda)",
        )),
    }
}

/// The file's extension, lower-case ("" when it has none).
fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default()
}

fn read_capped(path: &Path) -> Result<Vec<u8>, ExportError> {
    use std::io::Read;
    let read_err = |source| ExportError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(read_err)?;
    let len = file.metadata().map_err(read_err)?.len();
    if len > MAX_FILE_BYTES {
        return Err(bad(
            path,
            format!("{len} bytes is larger than the {MAX_FILE_BYTES} a material file may be"),
        ));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(read_err)?;
    Ok(bytes)
}

/// A table path must name a file in the material's folder (or below it).
fn check_relative(path: &Path, uri: &str) -> Result<(), ExportError> {
    let trimmed = uri.strip_prefix("./").unwrap_or(uri);
    let escapes = trimmed.is_empty()
        || trimmed.starts_with('/')
        || trimmed.starts_with('\\')
        || trimmed.contains(':')
        || trimmed.split(['/', '\\']).any(|c| c == "..")
        || trimmed.contains('\0');
    if escapes {
        return Err(bad(
            path,
            format!(
                "the table path '{}' leaves the material's folder (a relative path inside it is required)",
                uri.escape_debug()
            ),
        ));
    }
    Ok(())
}

/// The JSON of a `.glb` (its first chunk) or a `.gltf`.
fn gltf_root(path: &Path, bytes: &[u8]) -> Result<Value, ExportError> {
    let json_bytes: &[u8] = if bytes.starts_with(b"glTF") {
        let word = |at: usize| {
            bytes
                .get(at..at + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        let (Some(version), Some(total), Some(chunk), Some(kind)) =
            (word(4), word(8), word(12), word(16))
        else {
            return Err(bad(path, "truncated GLB header"));
        };
        if version != 2 {
            return Err(bad(
                path,
                format!("GLB version {version}; glint reads version 2"),
            ));
        }
        if total as usize != bytes.len() {
            return Err(bad(
                path,
                format!(
                    "the GLB header says {total} bytes but the file has {} (truncated or padded)",
                    bytes.len()
                ),
            ));
        }
        if kind != u32::from_le_bytes(*b"JSON") {
            return Err(bad(path, "the GLB's first chunk is not JSON"));
        }
        bytes
            .get(20..20 + chunk as usize)
            .ok_or_else(|| bad(path, "the GLB's JSON chunk runs past the end of the file"))?
    } else {
        bytes
    };
    serde_json::from_slice(json_bytes)
        .map_err(|e| bad(path, format!("the glTF JSON is invalid: {e}")))
}

fn from_gltf(path: &Path, bytes: &[u8]) -> Result<Value, ExportError> {
    let root = gltf_root(path, bytes)?;
    let materials = root
        .get("materials")
        .and_then(Value::as_array)
        .ok_or_else(|| bad(path, "the glTF has no materials"))?;
    let glint = materials
        .iter()
        .find_map(|m| m.get("extras").and_then(|e| e.get("glint")))
        .ok_or_else(|| {
            bad(
                path,
                "no material of this glTF carries extras.glint (not a glint export)",
            )
        })?;
    if let Some(uri) = glint.get("table").and_then(|t| t.get("uri")) {
        let uri = uri
            .as_str()
            .ok_or_else(|| bad(path, "extras.glint.table.uri is not a string"))?;
        check_relative(path, uri)?;
    }
    let table = lobe_fields(path, glint)?;
    Ok(table)
}

/// The fallback a glint export carries, as JSON: for a `.glb`/`.gltf`, the glint material's
/// object (`pbrMetallicRoughness`, `extensions`); for a `.usda`, `{"UsdPreviewSurface": {input:
/// value}}` with the numbers of the material's preview shader (`info:id = "UsdPreviewSurface"`).
/// The same reading rules as [`read_lobe_table`].
pub fn read_fallback(path: &Path) -> Result<Value, ExportError> {
    let ext = extension(path);
    let bytes = read_capped(path)?;
    match ext.as_str() {
        "glb" | "gltf" => {
            let root = gltf_root(path, &bytes)?;
            root.get("materials")
                .and_then(Value::as_array)
                .and_then(|ms| {
                    ms.iter()
                        .find(|m| m.get("extras").and_then(|e| e.get("glint")).is_some())
                })
                .cloned()
                .ok_or_else(|| {
                    bad(
                        path,
                        "no material of this glTF carries extras.glint (not a glint export)",
                    )
                })
        }
        "usda" | "usd" => preview_surface(path, &bytes),
        _ => Err(bad(
            path,
            "not an exported fallback glint reads (.glb, .gltf or .usda)",
        )),
    }
}

fn preview_surface(path: &Path, bytes: &[u8]) -> Result<Value, ExportError> {
    use openusd::sdf;
    let data = parse_usda(path, bytes)?;
    let mut shader: Option<String> = None;
    for (p, spec) in data.iter() {
        if spec.ty == sdf::SpecType::Attribute
            && let Some(prim) = p.as_str().strip_suffix(".info:id")
            && matches!(spec.get("default"), Some(sdf::Value::Token(t)) if t.as_str() == "UsdPreviewSurface")
        {
            if shader.is_some() {
                return Err(bad(path, "more than one UsdPreviewSurface in the stage"));
            }
            shader = Some(prim.to_string());
        }
    }
    let shader = shader.ok_or_else(|| bad(path, "no UsdPreviewSurface shader in the stage"))?;
    let mut inputs = serde_json::Map::new();
    for (p, spec) in data.iter() {
        let Some(name) = p
            .as_str()
            .strip_prefix(shader.as_str())
            .and_then(|rest| rest.strip_prefix(".inputs:"))
        else {
            continue;
        };
        let value = match spec.get("default") {
            Some(sdf::Value::Float(x)) => json!(*x as f64),
            Some(sdf::Value::Double(x)) => json!(*x),
            Some(sdf::Value::Int(x)) => json!(*x),
            Some(sdf::Value::Vec3f(c)) => json!([c.x as f64, c.y as f64, c.z as f64]),
            Some(sdf::Value::Vec3d(c)) => json!([c.x, c.y, c.z]),
            _ => continue,
        };
        inputs.insert(name.to_string(), value);
    }
    Ok(json!({ "UsdPreviewSurface": inputs }))
}

/// The lobe-table fields of a JSON object, checked for presence, type and size.
fn lobe_fields(path: &Path, g: &Value) -> Result<Value, ExportError> {
    let get = |key: &str| {
        g.get(key)
            .ok_or_else(|| bad(path, format!("the glint material lacks '{key}'")))
    };
    let model = get("model")?
        .as_str()
        .ok_or_else(|| bad(path, "'model' is not a string"))?;
    if model != MODEL {
        return Err(bad(
            path,
            format!("material model '{}' is not '{MODEL}'", model.escape_debug()),
        ));
    }
    let centres = get("centres")?
        .as_array()
        .ok_or_else(|| bad(path, "'centres' is not an array"))?;
    if centres.len() > MAX_LOBES {
        return Err(bad(
            path,
            format!(
                "{} centres is more than the {MAX_LOBES} lobes a material may have",
                centres.len()
            ),
        ));
    }
    let coefficients = get("coefficients")?
        .as_array()
        .ok_or_else(|| bad(path, "'coefficients' is not an array"))?;
    if coefficients.len() != 3
        || coefficients
            .iter()
            .any(|c| c.as_array().is_none_or(|c| c.len() != centres.len()))
    {
        return Err(bad(
            path,
            format!(
                "'coefficients' must be 3 arrays of {} numbers (one per centre)",
                centres.len()
            ),
        ));
    }
    let numbers = |v: &Value, n: Option<usize>| {
        v.as_array()
            .is_some_and(|a| n.is_none_or(|n| a.len() == n) && a.iter().all(Value::is_number))
    };
    for key in ["lambda", "sigma", "f0"] {
        if !get(key)?.is_number() {
            return Err(bad(path, format!("'{key}' is not a number")));
        }
    }
    if !get("version")?.is_u64() {
        return Err(bad(path, "'version' is not a non-negative integer"));
    }
    if !get("layout")?.is_string() || !get("isotropic")?.is_boolean() {
        return Err(bad(
            path,
            "'layout' must be a string and 'isotropic' a boolean",
        ));
    }
    if !numbers(get("rho_d")?, Some(3)) {
        return Err(bad(path, "'rho_d' is not 3 numbers"));
    }
    if !centres.iter().all(|c| numbers(c, Some(3))) {
        return Err(bad(path, "'centres' must hold 3 numbers per centre"));
    }
    if !coefficients.iter().all(|c| numbers(c, None)) {
        return Err(bad(path, "'coefficients' must hold numbers"));
    }
    let mut out = serde_json::Map::new();
    for key in [
        "model",
        "version",
        "lambda",
        "sigma",
        "layout",
        "isotropic",
        "centres",
        "coefficients",
        "rho_d",
        "f0",
    ] {
        out.insert(key.into(), get(key)?.clone());
    }
    Ok(Value::Object(out))
}

/// One USD text layer, parsed alone.
fn parse_usda(path: &Path, bytes: &[u8]) -> Result<openusd::sdf::Data, ExportError> {
    let text = std::str::from_utf8(bytes).map_err(|_| {
        bad(
            path,
            "not UTF-8 text (glint reads its own .usda, not binary .usdc)",
        )
    })?;
    if !text.starts_with("#usda 1.0") {
        return Err(bad(
            path,
            "not a USD text layer (it must start with '#usda 1.0')",
        ));
    }
    // The parser is a third party's: a panic in it on hostile text is reported as a refusal.
    let parsed = std::panic::catch_unwind(|| openusd::usda::parse(text))
        .map_err(|_| bad(path, "USD parse error: the parser failed on this text"))?;
    parsed.map_err(|e| {
        bad(
            path,
            format!(
                "USD parse error: {}",
                format!("{e:#}").lines().next().unwrap_or("")
            ),
        )
    })
}

fn from_usda(path: &Path, bytes: &[u8]) -> Result<Value, ExportError> {
    use openusd::sdf;
    let data = parse_usda(path, bytes)?;
    let mut shader: Option<String> = None;
    for (p, spec) in data.iter() {
        if spec.ty == sdf::SpecType::Attribute
            && let Some(prim) = p.as_str().strip_suffix(".inputs:model")
            && matches!(spec.get("default"), Some(sdf::Value::Token(t)) if t.as_str() == MODEL)
        {
            if shader.is_some() {
                return Err(bad(
                    path,
                    "more than one glint shader (inputs:model = \"dbrdf-srbf\") in the stage",
                ));
            }
            shader = Some(prim.to_string());
        }
    }
    let shader = shader.ok_or_else(|| {
        bad(
            path,
            "no shader with inputs:model = \"dbrdf-srbf\" (not a glint export)",
        )
    })?;
    let input = |name: &str| -> Result<&sdf::Value, ExportError> {
        let attr = sdf::Path::new(&format!("{shader}.inputs:{name}"))
            .map_err(|e| bad(path, e.to_string()))?;
        data.spec(&attr)
            .and_then(|s| s.get("default"))
            .ok_or_else(|| {
                bad(
                    path,
                    format!("the glint shader {shader} has no value for inputs:{name}"),
                )
            })
    };
    let wrong = |name: &str, v: &sdf::Value| {
        bad(
            path,
            format!("inputs:{name} has the wrong type ({})", value_kind(v)),
        )
    };
    let scalar = |name: &str| -> Result<f64, ExportError> {
        match input(name)? {
            sdf::Value::Double(x) => Ok(*x),
            sdf::Value::Float(x) => Ok(*x as f64),
            v => Err(wrong(name, v)),
        }
    };
    let array = |name: &str| -> Result<Vec<f64>, ExportError> {
        let v = match input(name)? {
            sdf::Value::DoubleVec(x) => x.clone(),
            sdf::Value::FloatVec(x) => x.iter().map(|&f| f as f64).collect(),
            v => return Err(wrong(name, v)),
        };
        if v.len() > MAX_LOBES {
            return Err(bad(
                path,
                format!(
                    "inputs:{name} has {} values, more than the {MAX_LOBES} lobes a material may have",
                    v.len()
                ),
            ));
        }
        Ok(v)
    };
    let text_of = |name: &str| -> Result<String, ExportError> {
        match input(name)? {
            sdf::Value::Token(t) => Ok(t.as_str().to_string()),
            sdf::Value::String(s) => Ok(s.clone()),
            v => Err(wrong(name, v)),
        }
    };
    let centres: Vec<[f64; 3]> = match input("centres")? {
        sdf::Value::Vec3dVec(v) => v.iter().map(|c| [c.x, c.y, c.z]).collect(),
        sdf::Value::Vec3fVec(v) => v
            .iter()
            .map(|c| [c.x as f64, c.y as f64, c.z as f64])
            .collect(),
        v => return Err(wrong("centres", v)),
    };
    if centres.len() > MAX_LOBES {
        return Err(bad(
            path,
            format!(
                "{} centres is more than the {MAX_LOBES} lobes a material may have",
                centres.len()
            ),
        ));
    }
    let rho_d = match input("rho_d")? {
        sdf::Value::Vec3d(c) => [c.x, c.y, c.z],
        sdf::Value::Vec3f(c) => [c.x as f64, c.y as f64, c.z as f64],
        v => return Err(wrong("rho_d", v)),
    };
    let isotropic = match input("isotropic")? {
        sdf::Value::Bool(b) => *b,
        v => return Err(wrong("isotropic", v)),
    };
    let version = match input("version")? {
        sdf::Value::Int(i) => *i,
        v => return Err(wrong("version", v)),
    };
    match input("table")? {
        sdf::Value::AssetPath(a) => check_relative(path, &a.authored_path)?,
        v => return Err(wrong("table", v)),
    }
    let coefficients = [
        array("coefficients_r")?,
        array("coefficients_g")?,
        array("coefficients_b")?,
    ];
    let g = json!({
        "model": text_of("model")?,
        "version": version,
        "lambda": scalar("lambda")?,
        "sigma": scalar("sigma")?,
        "layout": text_of("layout")?,
        "isotropic": isotropic,
        "centres": centres,
        "coefficients": coefficients,
        "rho_d": rho_d,
        "f0": scalar("f0")?,
    });
    lobe_fields(path, &g)
}

fn value_kind(v: &openusd::sdf::Value) -> String {
    let d = format!("{v:?}");
    d.split(['(', ' ', '{']).next().unwrap_or("?").to_string()
}
