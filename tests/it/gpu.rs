//! The wgpu preview against the CPU PRT renderer, and every shader through naga.
//!
//! The GPU tests need an adapter: in CI that is Mesa's lavapipe (`mesa-vulkan-drivers`, installed
//! by `.ci/test`). Without one they fail under `CI=true` and are skipped with a message elsewhere.

use crate::common;

use glint::bake::{BakeSettings, Baker};
use glint::fit::run::{Baked, FitSettings, fit};
use glint::gpu::{GpuContext, GpuPreview};
use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, ShadingPoint, Specular};
use glint::render::table::{PhPyramid, default_resolution};
use wgpu::naga;

#[test]
fn every_shader_validates_with_naga() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut checked = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("wgsl") {
            continue;
        }
        let source = std::fs::read_to_string(&path).unwrap();
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&source)));
        // Every shader states the BRDF convention.
        assert!(
            source.contains("WITHOUT the cosine") || source.contains("without the cosine"),
            "{}: no BRDF convention",
            path.display()
        );
        checked.push(path.file_name().unwrap().to_string_lossy().into_owned());
    }
    checked.sort();
    assert_eq!(
        checked,
        ["prt_raster.wgsl", "prt_shade.wgsl"],
        "every shader is validated"
    );
}

fn context() -> Option<GpuContext> {
    match GpuContext::headless() {
        Ok(ctx) => {
            println!("GPU adapter: {}", ctx.describe());
            Some(ctx)
        }
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("CI needs a GPU adapter (lavapipe): {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

const STROKES: &str = include_str!("../../samples/strokes/bunny-highlight.json");

/// Bakes `mesh` under studio, fits the sample strokes, and compares the GPU with the CPU per vertex
/// and per pixel, at two rotations.
fn compare(ctx: &GpuContext, mesh: &str) {
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
    let env = glint::env::load(&common::assets().join("hdr/small/studio_512.exr")).unwrap();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let bake = baker.bake_all(None, &|_| {});
    let tangents = baker.tangents.clone();
    let views = glint::fit::strokes::parse(STROKES).unwrap();
    let m = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: bake.decisions.resolution,
            tangents: tangents.as_deref(),
            anisotropic: bake.decisions.anisotropic,
        },
        &views,
        &FitSettings::default(),
    )
    .unwrap()
    .material;
    let lobes = m.lobes().unwrap();
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    // Vertex shading on both sides: the GPU preview shades the mesh's vertices; the default
    // partition (8°, what the app's wgpu preview uses). The CPU frame set to evaluate what the
    // shader evaluates: every leaf the horizon cuts clipped, p read from the 2D texels.
    let settings = PrtSettings {
        max_edge_px: 0.0,
        per_pixel: false,
        horizon_leaves: 0,
        texel_lookups: true,
        merge_runs: false,
        ..PrtSettings::default()
    };
    let prt = Prt::new(
        &scene.mesh,
        &bake.cuts,
        &baker.tree,
        tangents.as_deref(),
        settings,
    );
    let mut gpu = GpuPreview::new(
        ctx,
        &scene.mesh,
        &bake.cuts,
        &baker.tree,
        tangents.as_deref(),
        settings,
    )
    .unwrap();
    gpu.set_material(m.rho_d, m.f0, Some(&table)).unwrap();
    let shading = Shading {
        rho_d: m.rho_d,
        f0: m.f0,
        specular: Specular::Table(&table),
    };
    let camera = &scene.cameras[0];
    let (w, h) = (320, 240);
    for rotation in [0.0, 1.3] {
        let light = LightSums::new(&env, &baker.set, &baker.tree, rotation);
        gpu.set_light(&light, &baker.tree).unwrap();
        // Per vertex: the same sum in f32 against f64.
        let eye = camera.eye();
        let points: Vec<ShadingPoint> = (0..scene.mesh.positions.len() as u32)
            .map(|v| ShadingPoint {
                corners: [v; 3],
                bary: [1.0, 0.0, 0.0],
            })
            .collect();
        let cpu_v = prt.shade_points(&points, &light, eye.as_dvec3(), &shading);
        let gpu_v = gpu.vertex_radiance(eye).unwrap();
        let scale = cpu_v.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
        let (mut num, mut den, mut worst) = (0.0f64, 0.0f64, 0.0f64);
        for (c, g) in cpu_v.iter().zip(&gpu_v) {
            for k in 0..3 {
                let d = g[k] as f64 - c[k];
                num += d * d;
                den += c[k] * c[k];
                worst = worst.max(d.abs() / scale);
            }
        }
        let vertex_rmse = (num / den).sqrt();
        // Per pixel, over the pixels both cover; and how many pixels only one covers.
        let t0 = std::time::Instant::now();
        let gpu_image = gpu.render(camera, w, h).unwrap();
        let gpu_secs = t0.elapsed().as_secs_f64();
        let cpu_image = prt.render(&light, camera, w, h, &shading);
        let image_rmse = gpu_image.relative_rmse(&cpu_image).unwrap();
        let only_one = gpu_image
            .covered
            .iter()
            .zip(&cpu_image.covered)
            .filter(|(a, b)| a != b)
            .count();
        let covered = cpu_image.covered_count();
        println!(
            "{mesh} rotation {rotation}: {} vertices; per-vertex relative RMSE {vertex_rmse:.2e}, worst {worst:.2e} of the peak; {w}x{h} frame relative RMSE {image_rmse:.2e} over shared pixels, {only_one} of {covered} pixels covered by one renderer only; GPU frame {gpu_secs:.3} s",
            gpu_v.len()
        );
        // f32 against f64: ~1e-6 on lavapipe. llvmpipe's loop budget (65,535 iterations per
        // shader, gpu::SOFTWARE_LOOP_BUDGET) cuts nested loops short: with them, one bunny vertex
        // with a cut of 408 nodes came out 5 % dark (worst 5e-2), and at 8° most vertices went
        // wrong.
        assert!(
            vertex_rmse < 1e-4,
            "{mesh}: per-vertex GPU vs CPU {vertex_rmse}"
        );
        assert!(worst < 1e-4, "{mesh}: worst vertex {worst} of the peak");
        // The issue asks for 1 %; lavapipe measures ~1e-5 (f32 against f64), so a bound of 0.1 %
        // catches a broken term long before it reaches the goal.
        assert!(
            image_rmse <= 1e-3,
            "{mesh}: GPU vs CPU frame {image_rmse} > 0.1 %"
        );
        assert!(
            (only_one as f64) < 0.01 * covered as f64,
            "{mesh}: {only_one} of {covered} pixels differ in coverage"
        );
    }
    // Diffuse only: the table is not read.
    gpu.set_material(m.rho_d, m.f0, None).unwrap();
    let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
    gpu.set_light(&light, &baker.tree).unwrap();
    let diffuse = gpu.render(camera, w, h).unwrap();
    let cpu = prt.render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::None,
        },
    );
    let e = diffuse.relative_rmse(&cpu).unwrap();
    assert!(e <= 0.01, "{mesh}: diffuse-only GPU vs CPU {e}");
}

#[test]
fn gpu_preview_matches_the_cpu_frame_on_the_bunny() {
    if let Some(ctx) = context() {
        compare(&ctx, "bunny");
    }
}

#[test]
fn gpu_preview_matches_the_cpu_frame_on_the_teapot() {
    if let Some(ctx) = context() {
        compare(&ctx, "teapot");
    }
}

/// The shading pass runs one workgroup per vertex on a 2D grid once the vertices outnumber the
/// device's workgroups per dimension (65,535 on most): with that limit set to 100, a sphere's 500-odd
/// vertices take six rows, the last part empty, and every vertex comes out exactly as in one row.
#[test]
fn vertices_past_one_row_of_workgroups_shade_as_in_one() {
    let Some(ctx) = context() else { return };
    let scene = common::scene_from_mesh(common::uv_sphere(1.0, 32, 16, false));
    let env = glint::env::load(&common::assets().join("hdr/small/studio_512.exr")).unwrap();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let bake = baker.bake_all(None, &|_| {});
    let vertices = scene.mesh.positions.len();
    let mut narrow = ctx.clone();
    narrow.limits.max_compute_workgroups_per_dimension = 100;
    assert!(vertices > 500 && vertices < 600, "{vertices} vertices");
    let radiance = |ctx: &GpuContext| {
        lit_preview(
            ctx,
            &scene,
            &baker,
            &bake,
            &env,
            PrtSettings::default(),
            0.8,
        )
        .vertex_radiance(scene.cameras[0].eye())
        .unwrap()
    };
    let one_row = radiance(&ctx);
    let rows = radiance(&narrow);
    assert_eq!(one_row.len(), vertices);
    assert!(one_row.iter().flatten().any(|&c| c > 0.0));
    assert_eq!(rows, one_row);
}

/// The preview of `bake` under `env` (unrotated), with a diffuse albedo of `rho_d` in every channel
/// (F0 0.04, no p(h) table).
fn lit_preview(
    ctx: &GpuContext,
    scene: &glint::scene::Scene,
    baker: &Baker,
    bake: &glint::bake::Bake,
    env: &glint::env::EnvMap,
    settings: PrtSettings,
    rho_d: f64,
) -> GpuPreview {
    let mut gpu =
        GpuPreview::new(ctx, &scene.mesh, &bake.cuts, &baker.tree, None, settings).unwrap();
    gpu.set_light(
        &LightSums::new(env, &baker.set, &baker.tree, 0.0),
        &baker.tree,
    )
    .unwrap();
    gpu.set_material([rho_d; 3], 0.04, None).unwrap();
    gpu
}

/// A white furnace on the GPU: ρd = 1 under a uniform environment of radiance 1 with no occluder
/// renders 1 everywhere (closed form), and a frame before `set_light` is an error, not a panic.
#[test]
fn white_furnace_and_not_ready() {
    let Some(ctx) = context() else { return };
    let scene = common::scene_from_mesh(common::uv_sphere(1.0, 32, 16, false));
    let env = glint::env::EnvMap::uniform(64, 32, [1.0; 3]).unwrap();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let bake = baker.bake_all(None, &|_| {});
    let camera = &scene.cameras[0];
    // Every vertex at 1 for partitions from 2° to 32° (the default is 8°; at 8° and wider,
    // lavapipe's loop budget makes nested loops 0.55 off), on the 64-per-side set.
    assert_eq!(baker.tree.leaf_count(), 6 * 64 * 64);
    for partition_deg in [2.0, 8.0, 32.0] {
        let settings = PrtSettings {
            partition_deg,
            ..PrtSettings::default()
        };
        let radiance = lit_preview(&ctx, &scene, &baker, &bake, &env, settings, 1.0)
            .vertex_radiance(camera.eye())
            .unwrap();
        let worst = radiance
            .iter()
            .flatten()
            .fold(0.0f32, |a, &b| a.max((b - 1.0).abs()));
        assert!(
            worst < 1e-3,
            "furnace at {partition_deg}°: worst vertex off by {worst}"
        );
    }
    let mut gpu = GpuPreview::new(
        &ctx,
        &scene.mesh,
        &bake.cuts,
        &baker.tree,
        None,
        PrtSettings::default(),
    )
    .unwrap();
    let err = gpu.render(camera, 16, 16).unwrap_err();
    assert!(err.to_string().contains("set_light"), "{err}");
    gpu.set_light(
        &LightSums::new(&env, &baker.set, &baker.tree, 0.0),
        &baker.tree,
    )
    .unwrap();
    gpu.set_material([1.0; 3], 0.04, None).unwrap();
    let image = gpu.render(camera, 64, 64).unwrap();
    assert!(image.covered_count() > 500);
    let worst = image
        .pixels
        .iter()
        .zip(&image.covered)
        .filter(|(_, c)| **c)
        .flat_map(|(p, _)| p.iter())
        .fold(0.0f32, |a, &b| a.max((b - 1.0).abs()));
    assert!(worst < 1e-3, "furnace: worst pixel off by {worst}");
    assert!(
        gpu.render(camera, 0, 16).is_err(),
        "an empty frame is refused"
    );
}

/// The WGSL copy of the hemi-octahedral encoding (shaders/prt_shade.wgsl) against the one
/// definition (`glint_exporters::hemi_oct_encode`), run on the GPU: every texel direction of a 64²
/// table, each also mirrored below the horizon (where folding and clamping differ), and degenerate
/// vectors. The texel coordinates must agree to 1e-3 texel (f32 against f64).
#[test]
fn wgsl_hemi_oct_encode_matches_the_definition_on_every_texel() {
    use wgpu::util::DeviceExt as _;
    let Some(ctx) = context() else { return };
    let source = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/prt_shade.wgsl"),
    )
    .unwrap();
    let start = source
        .find("fn hemi_oct_encode(")
        .expect("the WGSL defines hemi_oct_encode");
    let body = &source[start..];
    let (mut depth, mut end) = (0, 0);
    for (i, c) in body.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    end = i + 1;
                    break;
                }
            }
            _ => {}
        }
    }
    let shader = format!(
        "@group(0) @binding(0) var<storage, read> dirs: array<vec4<f32>>;\n\
         @group(0) @binding(1) var<storage, read_write> uvs: array<vec2<f32>>;\n{}\n\
         @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
         if (id.x < arrayLength(&dirs)) {{ uvs[id.x] = hemi_oct_encode(dirs[id.x].xyz); }} }}",
        &body[..end]
    );
    const R: usize = 64;
    let mut dirs: Vec<[f64; 3]> = Vec::new();
    for y in 0..R {
        for x in 0..R {
            let h = glint_exporters::hemi_oct_decode(
                x as f64 / (R - 1) as f64,
                y as f64 / (R - 1) as f64,
            );
            dirs.push(h);
            dirs.push([h[0], h[1], -h[2]]);
        }
    }
    dirs.extend([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, -0.0]]);
    let packed: Vec<f32> = dirs
        .iter()
        .flat_map(|d| [d[0] as f32, d[1] as f32, d[2] as f32, 0.0])
        .collect();
    let device = &ctx.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("hemi_oct_encode test"),
        source: wgpu::ShaderSource::Wgsl(shader.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: None,
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&packed),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let size = (dirs.len() * 8) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(dirs.len().div_ceil(64) as u32, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, size);
    ctx.queue.submit([encoder.finish()]);
    let bytes = glint::gpu::preview::read_buffer(&ctx, &staging).unwrap();
    let uvs: &[f32] = bytemuck::cast_slice(&bytes);
    let mut worst = 0.0f64;
    for (k, d) in dirs.iter().enumerate() {
        let (u, v) = glint_exporters::hemi_oct_encode(*d);
        let du = (uvs[2 * k] as f64 - u).abs() * (R - 1) as f64;
        let dv = (uvs[2 * k + 1] as f64 - v).abs() * (R - 1) as f64;
        assert!(
            du <= 1e-3 && dv <= 1e-3,
            "direction {d:?}: WGSL ({}, {}) against ({u}, {v})",
            uvs[2 * k],
            uvs[2 * k + 1]
        );
        worst = worst.max(du).max(dv);
    }
    println!(
        "WGSL hemi_oct_encode: {} directions, worst difference {worst:.2e} texel",
        dirs.len()
    );
}
