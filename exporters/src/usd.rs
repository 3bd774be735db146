//! USD text (`<name>.usda`): a UsdShade Material with a UsdPreviewSurface fallback and a glint
//! shader carrying the lobe table, bound to the caller's mesh or to a preview sphere.
//!
//! Inputs: a validated [`MaterialDesc`] and an optional [`SceneMesh`]. Outputs: the text
//! ([`encode_usda`]) and the exporter ([`UsdExporter`]), which also writes the `<name>_ph.exr`
//! table the stage references. Layout:
//!
//! ```text
//! /Root (Xform, defaultPrim, kind = component; stage: upAxis Y, metersPerUnit 1)
//!   /Root/Looks/<Mat> (Material; customData.glint: provenance, fallback_relative_error (the
//!                      UsdPreviewSurface's), fallback_uniform_relative_error, fallback_weighting,
//!                      gltf_fallback_relative_error, and when the
//!                      fallback is anisotropic fallback_anisotropy = {strength, rotation, convention}:
//!                      UsdPreviewSurface has no anisotropy input, so the KHR_materials_anisotropy
//!                      values the glTF carries are kept here rather than lost)
//!     outputs:surface       -> PreviewSurface.outputs:surface
//!     outputs:mtlx:surface  -> OpenPbrSurface.outputs:out   (render context "mtlx")
//!     outputs:glint:surface -> GlintDbrdf.outputs:surface   (render context "glint")
//!     PreviewSurface (Shader, UsdPreviewSurface: clearcoat, clearcoatRoughness, diffuseColor,
//!                     metallic, roughness, useSpecularWorkflow, and specularColor in the specular
//!                     workflow)
//!     OpenPbrSurface (Shader, info:id ND_open_pbr_surface_surfaceshader: the inputs of
//!                     `crate::mtlx::open_pbr_inputs`, for MaterialX-aware renderers)
//!     GlintDbrdf (Shader with no info:id: data for glint-aware readers and renderers, which no
//!                 Sdr registry knows; inputs: model, version, conventions, lambda, sigma, layout,
//!                 isotropic, centres double3[], coefficients_r/g/b double[], rho_d color3d, f0,
//!                 table asset, table_resolution, parameterisation token + formula,
//!                 brdf_convention (the formula for this layout), frame_convention)
//!   /Root/<Mesh> (Mesh: points, faceVertexCounts, faceVertexIndices, primvars:normals (vertex),
//!                 primvars:st when UVs are given, primvars:tangents + primvars:tangentSigns (vertex)
//!                 when the mesh has a tangent field, extent; MaterialBindingAPI) — or a Sphere preview
//!   /Root/<Camera> (Camera, when the scene carries one: the view glint renders — a rigid
//!                 xformOp:transform, focalLength and apertures giving its vertical field of view,
//!                 clippingRange)
//! ```
//!
//! Why the glint shader has no `info:id` and no Sdr definition: an unregistered `info:id` fails
//! `UsdUtils.ComplianceChecker` ("invalid shader node") and the UsdValidation validators; a
//! `sourceAsset` definition resolves, but usd-core's shader-definition parser first tries the
//! node's hashed identifier as a prim name and warns "Invalid prim name" on stderr every time the
//! node is resolved. A shader without an identifier is valid, passes both checkers and prints
//! nothing. The exact meaning of every input is docs/conventions.md.
//!
//! Invariants: the lobe table's numbers are doubles written shortest round-trip (`{:?}` of f64), so
//! a reader recovers them exactly; geometry is f32 (`{:?}` of f32); strings are escaped; prim names
//! are sanitised identifiers; no timestamps or hash-map order, so equal inputs give equal bytes.
//! usd-core's checks pass (tested by `python/check_usd.py`).

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::exr::{encode_ph_exr, ph_exr_file_name};
use crate::material::{CONVENTIONS_DOC, MaterialDesc, SceneMesh};
use crate::table::{PARAMETERISATION, PARAMETERISATION_FORMULA};
use std::fmt::Write as _;
use std::path::Path;

/// The render context of the Material's output that connects the glint shader.
pub const RENDER_CONTEXT: &str = "glint";

/// What `customData.glint.fallback_anisotropy` means (written beside the numbers).
pub const ANISOTROPY_CONVENTION: &str = "KHR_materials_anisotropy of the fallback: strength in [0, 1]; rotation in radians, counter-clockwise from the tangent (local x) towards the bitangent; alpha_t = mix(roughness^2, 1, strength^2), alpha_b = roughness^2";

/// f32 shortest round-trip text (`1.0`, `0.1`, `1e-7`).
fn num(x: f64) -> String {
    format!("{:?}", x as f32)
}

/// f64 shortest round-trip text.
fn dnum(x: f64) -> String {
    format!("{x:?}")
}

fn dvec3(v: [f64; 3]) -> String {
    format!("({}, {}, {})", dnum(v[0]), dnum(v[1]), dnum(v[2]))
}

fn num32(x: f32) -> String {
    format!("{x:?}")
}

fn vec3(v: [f64; 3]) -> String {
    format!("({}, {}, {})", num(v[0]), num(v[1]), num(v[2]))
}

/// A USD string literal.
fn quote(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if c.is_control() => out.push_str(&format!("\\x{:02x}", c as u32 & 0xff)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A valid prim name from a material name: `[A-Za-z_][A-Za-z0-9_]*`.
pub fn prim_name(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

fn list<T>(items: &[T], f: impl Fn(&T) -> String) -> String {
    let mut out = String::with_capacity(items.len() * 12 + 2);
    out.push('[');
    for (i, x) in items.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str(&f(x));
    }
    out.push(']');
    out
}

/// The `.usda` text for a validated description and mesh (a preview sphere when `scene` is `None`).
pub fn encode_usda(desc: &MaterialDesc, scene: Option<&SceneMesh>) -> Result<String, ExportError> {
    desc.validate()?;
    let mesh = scene.map(|s| s.validated()).transpose()?;
    let mat = prim_name(&desc.name);
    let mat_path = format!("/Root/Looks/{mat}");
    let fb = &desc.fallback;
    let ps = &desc.preview_surface;
    let mut inputs: Vec<(&str, &str, String)> = vec![
        ("string", "brdf_convention", quote(&desc.brdf_convention)),
        ("double3[]", "centres", list(&desc.centres, |c| dvec3(*c))),
        (
            "double[]",
            "coefficients_r",
            list(&desc.coefficients[0], |x| dnum(*x)),
        ),
        (
            "double[]",
            "coefficients_g",
            list(&desc.coefficients[1], |x| dnum(*x)),
        ),
        (
            "double[]",
            "coefficients_b",
            list(&desc.coefficients[2], |x| dnum(*x)),
        ),
        ("string", "conventions", quote(CONVENTIONS_DOC)),
        ("double", "f0", dnum(desc.f0)),
        ("string", "frame_convention", quote(&desc.frame_convention)),
        (
            "bool",
            "isotropic",
            (if desc.isotropic { "1" } else { "0" }).to_string(),
        ),
        ("double", "lambda", dnum(desc.lambda)),
        ("token", "layout", quote(&desc.layout)),
        ("token", "model", quote(&desc.model)),
        ("token", "parameterisation", quote(PARAMETERISATION)),
        (
            "string",
            "parameterisation_formula",
            quote(PARAMETERISATION_FORMULA),
        ),
        ("color3d", "rho_d", dvec3(desc.rho_d)),
        ("double", "sigma", dnum(desc.sigma)),
        (
            "asset",
            "table",
            format!("@./{}@", ph_exr_file_name(&desc.name)),
        ),
        ("int", "table_resolution", desc.table.resolution.to_string()),
        (
            "int",
            "version",
            desc.version.min(i32::MAX as u32).to_string(),
        ),
    ];
    inputs.sort_by(|a, b| a.1.cmp(b.1));
    let mut o = String::new();
    // Writing to a String cannot fail; the results are ignored below.
    let _ = writeln!(o, "#usda 1.0");
    let _ = writeln!(o, "(");
    let _ = writeln!(o, "    defaultPrim = \"Root\"");
    let _ = writeln!(
        o,
        "    doc = {}",
        quote(&format!(
            "glint material '{}' ({} v{}), written by glint-exporters {}",
            desc.name,
            desc.model,
            desc.version,
            env!("CARGO_PKG_VERSION")
        ))
    );
    let _ = writeln!(o, "    metersPerUnit = 1");
    let _ = writeln!(o, "    upAxis = \"Y\"");
    let _ = writeln!(o, ")");
    let _ = writeln!(o);
    let _ = writeln!(o, "def Xform \"Root\" (\n    kind = \"component\"\n)\n{{");
    let _ = writeln!(o, "    def Scope \"Looks\"\n    {{");
    let _ = writeln!(o, "        def Material \"{mat}\" (");
    let _ = writeln!(o, "            customData = {{");
    let _ = writeln!(o, "                dictionary glint = {{");
    if let Some((strength, rotation)) = fb.anisotropy {
        let _ = writeln!(o, "                    dictionary fallback_anisotropy = {{");
        let _ = writeln!(
            o,
            "                        string convention = {}",
            quote(ANISOTROPY_CONVENTION)
        );
        let _ = writeln!(o, "                        double rotation = {rotation:?}");
        let _ = writeln!(o, "                        double strength = {strength:?}");
        let _ = writeln!(o, "                    }}");
    }
    let _ = writeln!(
        o,
        "                    double fallback_relative_error = {:?}",
        ps.relative_error
    );
    let _ = writeln!(
        o,
        "                    double fallback_uniform_relative_error = {:?}",
        ps.uniform_relative_error
    );
    let _ = writeln!(
        o,
        "                    token fallback_weighting = {}",
        quote(fb.weighting.name())
    );
    let _ = writeln!(
        o,
        "                    double gltf_fallback_relative_error = {:?}",
        fb.relative_error
    );
    let _ = writeln!(o, "                    dictionary provenance = {{");
    for (k, v) in &desc.provenance {
        let _ = writeln!(
            o,
            "                        string {} = {}",
            quote(k),
            quote(v)
        );
    }
    let _ = writeln!(o, "                    }}");
    let _ = writeln!(o, "                }}");
    let _ = writeln!(o, "            }}");
    let _ = writeln!(o, "        )\n        {{");
    let _ = writeln!(
        o,
        "            token outputs:{RENDER_CONTEXT}:surface.connect = <{mat_path}/GlintDbrdf.outputs:surface>"
    );
    let _ = writeln!(
        o,
        "            token outputs:mtlx:surface.connect = <{mat_path}/OpenPbrSurface.outputs:out>"
    );
    let _ = writeln!(
        o,
        "            token outputs:surface.connect = <{mat_path}/PreviewSurface.outputs:surface>"
    );
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "            def Shader \"OpenPbrSurface\"\n            {{"
    );
    let _ = writeln!(
        o,
        "                uniform token info:id = \"{}\"",
        crate::mtlx::OPEN_PBR_NODEDEF
    );
    for input in crate::mtlx::open_pbr_inputs(desc) {
        if input.value.len() == 3 {
            let v = [input.value[0], input.value[1], input.value[2]];
            let _ = writeln!(
                o,
                "                color3f inputs:{} = {}",
                input.name,
                vec3(v)
            );
        } else {
            let _ = writeln!(
                o,
                "                float inputs:{} = {}",
                input.name,
                num(input.value[0])
            );
        }
    }
    let _ = writeln!(o, "                token outputs:out");
    let _ = writeln!(o, "            }}");
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "            def Shader \"PreviewSurface\"\n            {{"
    );
    let _ = writeln!(
        o,
        "                uniform token info:id = \"UsdPreviewSurface\""
    );
    let mut preview = vec![
        format!("float inputs:clearcoat = {}", num(ps.clearcoat)),
        format!(
            "float inputs:clearcoatRoughness = {}",
            num(ps.clearcoat_roughness)
        ),
        format!("color3f inputs:diffuseColor = {}", vec3(ps.diffuse_color)),
        format!("float inputs:metallic = {}", num(ps.metallic)),
        format!("float inputs:roughness = {}", num(ps.roughness)),
    ];
    if ps.use_specular_workflow {
        preview.push(format!(
            "color3f inputs:specularColor = {}",
            vec3(ps.specular_color)
        ));
    }
    preview.push(format!(
        "int inputs:useSpecularWorkflow = {}",
        u8::from(ps.use_specular_workflow)
    ));
    for line in preview {
        let _ = writeln!(o, "                {line}");
    }
    let _ = writeln!(o, "                token outputs:surface");
    let _ = writeln!(o, "            }}");
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "            def Shader \"GlintDbrdf\" (\n                doc = {}\n            )\n            {{",
        quote(&format!(
            "glint's BRDF ({}): {}",
            desc.model, desc.brdf_convention
        ))
    );
    for (kind, name, value) in &inputs {
        let _ = writeln!(o, "                {kind} inputs:{name} = {value}");
    }
    let _ = writeln!(o, "                token outputs:surface");
    let _ = writeln!(o, "            }}");
    let _ = writeln!(o, "        }}");
    let _ = writeln!(o, "    }}");
    let _ = writeln!(o);
    match &mesh {
        Some(m) => {
            let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            for p in &m.positions {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let v3 = |p: &[f32; 3]| format!("({}, {}, {})", num32(p[0]), num32(p[1]), num32(p[2]));
            let _ = writeln!(
                o,
                "    def Mesh \"{}\" (\n        prepend apiSchemas = [\"MaterialBindingAPI\"]\n    )\n    {{",
                prim_name(&format!("{}_mesh", desc.name))
            );
            let _ = writeln!(o, "        float3[] extent = [{}, {}]", v3(&lo), v3(&hi));
            let _ = writeln!(
                o,
                "        int[] faceVertexCounts = {}",
                list(&vec![3u8; m.indices.len() / 3], |x| x.to_string())
            );
            let _ = writeln!(
                o,
                "        int[] faceVertexIndices = {}",
                list(&m.indices, |x| x.to_string())
            );
            let _ = writeln!(o, "        rel material:binding = <{mat_path}>");
            let _ = writeln!(o, "        point3f[] points = {}", list(&m.positions, v3));
            let _ = writeln!(
                o,
                "        normal3f[] primvars:normals = {} (\n            interpolation = \"vertex\"\n        )",
                list(&m.normals, v3)
            );
            if let Some(uv) = &m.uvs {
                // USD's st has v up; glTF's TEXCOORD_0 has v down.
                let st = |t: &[f32; 2]| format!("({}, {})", num32(t[0]), num32(1.0 - t[1]));
                let _ = writeln!(
                    o,
                    "        texCoord2f[] primvars:st = {} (\n            interpolation = \"vertex\"\n        )",
                    list(uv, st)
                );
            }
            if let Some(t) = &m.tangents {
                let xyz =
                    |t: &[f32; 4]| format!("({}, {}, {})", num32(t[0]), num32(t[1]), num32(t[2]));
                let _ = writeln!(
                    o,
                    "        float3[] primvars:tangents = {} (\n            interpolation = \"vertex\"\n        )",
                    list(t, xyz)
                );
                let _ = writeln!(
                    o,
                    "        float[] primvars:tangentSigns = {} (\n            interpolation = \"vertex\"\n        )",
                    list(t, |t| num32(t[3]))
                );
            }
            let _ = writeln!(o, "        uniform token subdivisionScheme = \"none\"");
            let _ = writeln!(o, "    }}");
        }
        None => {
            let _ = writeln!(
                o,
                "    def Sphere \"PreviewSphere\" (\n        prepend apiSchemas = [\"MaterialBindingAPI\"]\n    )\n    {{"
            );
            let _ = writeln!(o, "        float3[] extent = [(-1, -1, -1), (1, 1, 1)]");
            let _ = writeln!(o, "        rel material:binding = <{mat_path}>");
            let _ = writeln!(o, "        double radius = 1");
            let _ = writeln!(o, "    }}");
        }
    }
    if let Some(camera) = scene.and_then(|s| s.camera.as_ref()) {
        write_camera(&mut o, camera);
    }
    let _ = writeln!(o, "}}");
    Ok(o)
}

/// A `Camera` prim for glint's view: USD cameras look down −Z with +Y up, as glint's do; the
/// transform's rows are the camera's +X, +Y, +Z and eye (USD's row-vector convention); the vertical
/// aperture over the focal length is 2 tan(yfov/2).
fn write_camera(o: &mut String, camera: &crate::view::SceneCamera) {
    let (r, u, f, e) = (camera.right(), camera.up, camera.forward, camera.eye);
    let vertical = 24.0;
    let focal = 0.5 * vertical / (0.5 * camera.yfov_rad).tan();
    let horizontal = vertical * camera.width as f64 / camera.height as f64;
    let far = camera.zfar.unwrap_or(camera.znear * 1e7);
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "    def Camera \"{}\" (\n        doc = \"the view glint renders (docs/conventions.md section 4): {}x{} pixels, vertical field of view {:?} degrees\"\n    )\n    {{",
        prim_name(&format!("{}_camera", camera.name)),
        camera.width,
        camera.height,
        camera.yfov_rad.to_degrees()
    );
    let _ = writeln!(
        o,
        "        float2 clippingRange = ({}, {})",
        num(camera.znear),
        num(far)
    );
    let _ = writeln!(o, "        float focalLength = {}", num(focal));
    let _ = writeln!(o, "        float horizontalAperture = {}", num(horizontal));
    let _ = writeln!(o, "        token projection = \"perspective\"");
    let _ = writeln!(o, "        float verticalAperture = {}", num(vertical));
    let _ = writeln!(
        o,
        "        matrix4d xformOp:transform = ({}, {}, {}, {})",
        row4(r, 0.0),
        row4(u, 0.0),
        row4([-f[0], -f[1], -f[2]], 0.0),
        row4(e, 1.0)
    );
    let _ = writeln!(
        o,
        "        uniform token[] xformOpOrder = [\"xformOp:transform\"]"
    );
    let _ = writeln!(o, "    }}");
}

fn row4(v: [f64; 3], w: f64) -> String {
    format!(
        "({}, {}, {}, {})",
        dnum(v[0]),
        dnum(v[1]),
        dnum(v[2]),
        dnum(w)
    )
}

/// Writes `<name>.usda` and the `<name>_ph.exr` it references.
#[derive(Debug, Clone, Copy, Default)]
pub struct UsdExporter;

impl Exporter for UsdExporter {
    fn name(&self) -> &'static str {
        "usd"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["usda", "exr"]
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        let text = encode_usda(desc, scene)?;
        Ok(vec![
            OutputFile {
                path: dir.join(format!("{}.usda", desc.name)),
                bytes: text.into_bytes(),
            },
            OutputFile {
                path: dir.join(ph_exr_file_name(&desc.name)),
                bytes: encode_ph_exr(desc)?,
            },
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_strings_are_safe() {
        assert_eq!(prim_name("bunny-v2.final"), "bunny_v2_final");
        assert_eq!(prim_name("2x"), "_2x");
        assert_eq!(quote("a\"b\\c\nd"), "\"a\\\"b\\\\c\\nd\"");
        assert_eq!(num(0.1), "0.1");
        assert_eq!(num(1.0), "1.0");
        assert_eq!(
            "1e-7".parse::<f32>().unwrap(),
            num(1e-7).parse::<f32>().unwrap()
        );
    }
}
