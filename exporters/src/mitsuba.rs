//! A Mitsuba 3 scene (`<name>_mitsuba.xml`) that renders the material as glint does: the mesh, the
//! environment in Mitsuba's orientation, a sensor equal to glint's camera, the `glint` BSDF and the
//! `glint_direct` integrator of the plugin in `exporters/python/glint_mitsuba`.
//!
//! Inputs: a validated [`MaterialDesc`] and a [`SceneMesh`] with a camera and an environment.
//! Outputs ([`MitsubaExporter`]): `<name>_mitsuba.xml`; `<name>_mesh.ply` (binary little-endian: `x
//! y z nx ny nz`, `u v` when the mesh has UVs, `tangent_x tangent_y tangent_z handedness_0` when it
//! has a tangent field — Mitsuba loads those as the mesh attributes `vertex_tangent` and
//! `vertex_handedness`); `<name>_env.exr` (the environment resampled for Mitsuba's `envmap`, see
//! below); `<name>_ph.exr` (the table) and `<name>_lobes.json` (the exact lobe table, the glTF
//! extras' object), either of which the BSDF reads.
//!
//! The environment (docs/conventions.md §5): Mitsuba's `envmap` has u = atan2(x, −z)/2π, half a
//! turn from glint's, texel centres at u = (i + 0.5)/W, and rows at v = j/(H′ − 1). The map written
//! has W columns shifted by half a turn and H′ = 2H + 1 rows, row j′ holding glint's bilinear
//! lookup at v = j′/(2H): glint's bilinear function is linear between its row centres, which are
//! every other row of the new map, so Mitsuba's bilinear lookup of it equals glint's exactly (and
//! in u too when W is even). The emitter's `to_world` is R_y(rotation).
//!
//! The sensor: `perspective`, `fov_axis` y, `lookat` from the camera's eye along its forward with
//! its up, the camera's near and far planes, a W × H RGBA `hdrfilm` with a box filter. Mitsuba
//! jitters samples over each pixel; the `glint_direct` integrator moves them to the pixel centre,
//! as glint shades (its `pixel_centres` parameter), and starts shadow rays from the smooth surface,
//! offset by `ray_offset` = 1e-4 × the mesh's bounding-box diagonal (docs/conventions.md §6).
//!
//! Invariants: equal inputs give equal bytes; numbers are shortest round-trip; every file is built
//! in memory before any is written; file names inside the XML are relative (the folder moves as a
//! whole).

use crate::error::ExportError;
use crate::exporter::{Exporter, OutputFile};
use crate::exr::{Header, encode_ph_exr, encode_rgb_exr, ph_exr_file_name};
use crate::material::{CONVENTIONS_DOC, CleanMesh, MaterialDesc, SceneMesh};
use crate::view::{SceneCamera, SceneEnvironment};
use std::fmt::Write as _;
use std::path::Path;

/// Samples per pixel the scene asks for unless the caller overrides `spp`.
pub const DEFAULT_SPP: u32 = 64;
/// The shadow-ray offset as a fraction of the mesh's bounding-box diagonal (glint's reference).
pub const RAY_OFFSET_FRACTION: f64 = 1e-4;

/// File names of a material's Mitsuba scene: (scene, mesh, environment, lobes).
pub fn file_names(name: &str) -> [String; 4] {
    [
        format!("{name}_mitsuba.xml"),
        format!("{name}_mesh.ply"),
        format!("{name}_env.exr"),
        format!("{name}_lobes.json"),
    ]
}

/// The environment resampled for Mitsuba's `envmap`: W × (2H + 1), row-major (see the module doc).
pub fn mitsuba_environment(env: &SceneEnvironment) -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h) = (env.width, 2 * env.height + 1);
    let mut texels = Vec::with_capacity(w * h);
    for j in 0..h {
        let v = j as f64 / (2 * env.height) as f64;
        for i in 0..w {
            // Mitsuba's u' = (i + 0.5)/W is glint's u = u' + 0.5.
            let u = (i as f64 + 0.5) / w as f64 + 0.5;
            let c = env.lookup_bilinear(u, v);
            texels.push([c[0] as f32, c[1] as f32, c[2] as f32]);
        }
    }
    (w, h, texels)
}

/// The binary PLY of a validated mesh.
fn encode_ply(mesh: &CleanMesh) -> Vec<u8> {
    let n = mesh.positions.len();
    let mut names: Vec<&str> = vec!["x", "y", "z", "nx", "ny", "nz"];
    if mesh.uvs.is_some() {
        names.extend(["u", "v"]);
    }
    if mesh.tangents.is_some() {
        names.extend(["tangent_x", "tangent_y", "tangent_z", "handedness_0"]);
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment glint mesh; frame and tangents: {CONVENTIONS_DOC}\nelement vertex {n}"
    );
    for p in &names {
        let _ = writeln!(out, "property float {p}");
    }
    let _ = writeln!(
        out,
        "element face {}\nproperty list uchar int vertex_indices\nend_header",
        mesh.indices.len() / 3
    );
    let mut bytes = out.into_bytes();
    bytes.reserve(n * names.len() * 4 + mesh.indices.len() / 3 * 13);
    for i in 0..n {
        let mut push = |x: f32| bytes.extend_from_slice(&x.to_le_bytes());
        mesh.positions[i].iter().for_each(|&x| push(x));
        mesh.normals[i].iter().for_each(|&x| push(x));
        if let Some(uv) = &mesh.uvs {
            uv[i].iter().for_each(|&x| push(x));
        }
        if let Some(t) = &mesh.tangents {
            t[i].iter().for_each(|&x| push(x));
        }
    }
    for tri in mesh.indices.chunks_exact(3) {
        bytes.push(3);
        for &i in tri {
            bytes.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    bytes
}

/// An XML attribute value (the names written are plain; this escapes the rest).
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn v3(v: [f64; 3]) -> String {
    format!("{:?}, {:?}, {:?}", v[0], v[1], v[2])
}

/// The mesh's bounding-box diagonal (f32 bounds, as glint computes them).
fn diagonal(mesh: &CleanMesh) -> f64 {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let d: [f32; 3] = std::array::from_fn(|k| hi[k] - lo[k]);
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() as f64
}

/// The scene XML.
pub fn encode_scene_xml(
    desc: &MaterialDesc,
    camera: &SceneCamera,
    env: &SceneEnvironment,
    ray_offset: f64,
) -> String {
    let [_, ply, env_file, _] = file_names(&desc.name);
    let target = std::array::from_fn(|k| camera.eye[k] + camera.forward[k]);
    let far = camera.zfar.unwrap_or(camera.znear * 1e7);
    let mut o = String::new();
    let _ = writeln!(o, "<?xml version=\"1.0\" encoding=\"utf-8\"?>");
    let _ = writeln!(
        o,
        "<!-- glint material '{}' ({} v{}, layout {}) on its mesh under {}, seen from camera '{}'.",
        xml_escape(&desc.name),
        xml_escape(&desc.model),
        desc.version,
        xml_escape(&desc.layout),
        xml_escape(&env.source),
        xml_escape(&camera.name)
    );
    let _ = writeln!(
        o,
        "     Render: python -m glint_mitsuba render {}_mitsuba.xml -o out.exr  (pip install exporters/python/glint_mitsuba).",
        xml_escape(&desc.name)
    );
    let _ = writeln!(
        o,
        "     Conventions (camera, environment, shadow-ray origins, BRDF): {CONVENTIONS_DOC}. -->"
    );
    let _ = writeln!(o, "<scene version=\"3.0.0\">");
    let _ = writeln!(o, "    <default name=\"spp\" value=\"{DEFAULT_SPP}\"/>");
    let _ = writeln!(o, "    <integrator type=\"glint_direct\">");
    let _ = writeln!(
        o,
        "        <float name=\"ray_offset\" value=\"{ray_offset:?}\"/>"
    );
    let _ = writeln!(
        o,
        "        <boolean name=\"pixel_centres\" value=\"true\"/>"
    );
    let _ = writeln!(o, "    </integrator>");
    let _ = writeln!(o, "    <sensor type=\"perspective\">");
    let _ = writeln!(o, "        <string name=\"fov_axis\" value=\"y\"/>");
    let _ = writeln!(
        o,
        "        <float name=\"fov\" value=\"{:?}\"/>",
        camera.yfov_rad.to_degrees()
    );
    let _ = writeln!(
        o,
        "        <float name=\"near_clip\" value=\"{:?}\"/>",
        camera.znear
    );
    let _ = writeln!(o, "        <float name=\"far_clip\" value=\"{far:?}\"/>");
    let _ = writeln!(o, "        <transform name=\"to_world\">");
    let _ = writeln!(
        o,
        "            <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>",
        v3(camera.eye),
        v3(target),
        v3(camera.up)
    );
    let _ = writeln!(o, "        </transform>");
    let _ = writeln!(o, "        <sampler type=\"independent\">");
    let _ = writeln!(
        o,
        "            <integer name=\"sample_count\" value=\"$spp\"/>"
    );
    let _ = writeln!(o, "        </sampler>");
    let _ = writeln!(o, "        <film type=\"hdrfilm\">");
    let _ = writeln!(
        o,
        "            <integer name=\"width\" value=\"{}\"/>",
        camera.width
    );
    let _ = writeln!(
        o,
        "            <integer name=\"height\" value=\"{}\"/>",
        camera.height
    );
    let _ = writeln!(
        o,
        "            <string name=\"pixel_format\" value=\"rgba\"/>"
    );
    let _ = writeln!(o, "            <rfilter type=\"box\"/>");
    let _ = writeln!(o, "        </film>");
    let _ = writeln!(o, "    </sensor>");
    let _ = writeln!(o, "    <emitter type=\"envmap\">");
    let _ = writeln!(
        o,
        "        <string name=\"filename\" value=\"{}\"/>",
        xml_escape(&env_file)
    );
    let _ = writeln!(o, "        <transform name=\"to_world\">");
    let _ = writeln!(
        o,
        "            <rotate y=\"1\" angle=\"{:?}\"/>",
        env.rotation_rad.to_degrees()
    );
    let _ = writeln!(o, "        </transform>");
    let _ = writeln!(o, "    </emitter>");
    let _ = writeln!(o, "    <shape type=\"ply\">");
    let _ = writeln!(
        o,
        "        <string name=\"filename\" value=\"{}\"/>",
        xml_escape(&ply)
    );
    let _ = writeln!(o, "        <bsdf type=\"glint\">");
    let _ = writeln!(
        o,
        "            <string name=\"filename\" value=\"{}\"/>",
        xml_escape(&ph_exr_file_name(&desc.name))
    );
    let _ = writeln!(o, "        </bsdf>");
    let _ = writeln!(o, "    </shape>");
    let _ = writeln!(o, "</scene>");
    o
}

/// Writes the Mitsuba 3 scene: XML, PLY mesh, environment EXR, p(h) EXR and lobe JSON.
#[derive(Debug, Clone, Copy, Default)]
pub struct MitsubaExporter;

impl Exporter for MitsubaExporter {
    fn name(&self) -> &'static str {
        "mitsuba"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["xml", "ply", "exr", "json"]
    }
    fn needs_view(&self) -> bool {
        true
    }
    fn build(
        &self,
        desc: &MaterialDesc,
        scene: Option<&SceneMesh>,
        dir: &Path,
    ) -> Result<Vec<OutputFile>, ExportError> {
        desc.validate()?;
        let scene = scene.ok_or(ExportError::NeedsScene {
            format: "mitsuba",
            what: "a scene mesh (--scene or --bake)",
        })?;
        let camera = scene.camera.as_ref().ok_or(ExportError::NeedsScene {
            format: "mitsuba",
            what: "a camera",
        })?;
        let env = scene.environment.as_ref().ok_or(ExportError::NeedsScene {
            format: "mitsuba",
            what: "an environment map (--env or --bake)",
        })?;
        let mesh = scene.validated()?;
        if !desc.isotropic && mesh.tangents.is_none() {
            return Err(ExportError::InvalidMesh {
                reason: format!(
                    "the layout {} is anisotropic but the mesh has no tangent field",
                    desc.layout
                ),
            });
        }
        let [xml, ply, env_file, lobes] = file_names(&desc.name);
        let (w, h, texels) = mitsuba_environment(env);
        let mut header = Header { attrs: Vec::new() };
        header.text(
            "glint.environment",
            &format!(
                "{} resampled for Mitsuba's envmap ({CONVENTIONS_DOC} section 5)",
                env.source
            ),
        );
        let lobe_json = serde_json::to_string_pretty(&desc.lobe_table_json()).map_err(|e| {
            ExportError::InvalidMaterial {
                material: desc.name.clone(),
                field: "lobes",
                reason: e.to_string(),
            }
        })?;
        Ok(vec![
            OutputFile {
                path: dir.join(xml),
                bytes: encode_scene_xml(desc, camera, env, RAY_OFFSET_FRACTION * diagonal(&mesh))
                    .into_bytes(),
            },
            OutputFile {
                path: dir.join(ply),
                bytes: encode_ply(&mesh),
            },
            OutputFile {
                path: dir.join(env_file),
                bytes: encode_rgb_exr(w, h, &texels, header),
            },
            OutputFile {
                path: dir.join(ph_exr_file_name(&desc.name)),
                bytes: encode_ph_exr(desc)?,
            },
            OutputFile {
                path: dir.join(lobes),
                bytes: lobe_json.into_bytes(),
            },
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mitsuba's envmap lookup (bilinear, texel centres at u = (i + 0.5)/W, rows at v = j/(H' − 1),
    /// u = atan2(x, −z)/2π) of the resampled map equals glint's bilinear lookup at the same
    /// direction.
    #[test]
    fn resampled_environment_reads_as_glint_reads() {
        let (w0, h0) = (16, 8);
        let texels = (0..w0 * h0)
            .map(|k| {
                [
                    (k % 7) as f32,
                    (k / 5 % 3) as f32 + 0.5,
                    (k * k % 11) as f32,
                ]
            })
            .collect();
        let env = SceneEnvironment {
            source: "t".into(),
            width: w0,
            height: h0,
            texels,
            rotation_rad: 0.0,
        };
        let (w, h, m) = mitsuba_environment(&env);
        let mitsuba = |d: [f64; 3]| {
            let u = (d[0].atan2(-d[2]) / (2.0 * std::f64::consts::PI)).rem_euclid(1.0);
            let v = d[1].clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            let x = u * w as f64 - 0.5;
            let y = v * (h - 1) as f64;
            let (x0, y0) = (x.floor(), y.floor().min((h - 2) as f64));
            let (fx, fy) = (x - x0, y - y0);
            let xi = |i: f64| (i as i64).rem_euclid(w as i64) as usize;
            let t = |x: usize, y: usize| m[y * w + x];
            std::array::from_fn::<f64, 3, _>(|k| {
                let (a, b) = (
                    t(xi(x0), y0 as usize)[k] as f64,
                    t(xi(x0 + 1.0), y0 as usize)[k] as f64,
                );
                let (c, e) = (
                    t(xi(x0), y0 as usize + 1)[k] as f64,
                    t(xi(x0 + 1.0), y0 as usize + 1)[k] as f64,
                );
                (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + e * fx) * fy
            })
        };
        let glint = |d: [f64; 3]| {
            let u = (0.5 + d[0].atan2(-d[2]) / (2.0 * std::f64::consts::PI)).rem_euclid(1.0);
            let v = d[1].clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            env.lookup_bilinear(u, v)
        };
        let mut worst = 0f64;
        for i in 0..97 {
            for j in 1..60 {
                let (phi, theta) = (i as f64 * 0.0651, j as f64 * std::f64::consts::PI / 60.0);
                let d = [
                    theta.sin() * phi.sin(),
                    theta.cos(),
                    -theta.sin() * phi.cos(),
                ];
                let (a, b) = (mitsuba(d), glint(d));
                for k in 0..3 {
                    worst = worst.max((a[k] - b[k]).abs());
                }
            }
        }
        assert!(worst < 1e-5, "worst {worst}");
    }

    #[test]
    fn ply_header_names_the_attributes_mitsuba_reads() {
        let mesh = CleanMesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            tangents: Some(vec![[1.0, 0.0, 0.0, -1.0]; 3]),
            uvs: None,
            indices: vec![0, 1, 2],
        };
        let bytes = encode_ply(&mesh);
        let text = String::from_utf8_lossy(&bytes);
        let header_end = text.find("end_header\n").unwrap() + "end_header\n".len();
        assert!(text[..header_end].contains("property float tangent_x\nproperty float tangent_y\nproperty float tangent_z\nproperty float handedness_0\n"));
        assert_eq!(bytes.len() - header_end, 3 * 10 * 4 + 13);
        let w = f32::from_le_bytes(bytes[header_end + 36..header_end + 40].try_into().unwrap());
        assert_eq!(w, -1.0);
    }
}
