// prt_raster.wgsl — rasterises the mesh with the per-vertex radiance of prt_shade.wgsl, interpolated
// perspective-correctly (as render::prt::interpolate does on the CPU), into an Rgba32Float target:
// rgb = linear radiance, a = 1 where the object covers the pixel (the clear colour has a = 0).
//
// BRDF convention (src/brdf/mod.rs): f_r(wi, wo) = ρd/π + p(h)·s(wi, wo) without the cosine; this pass
// evaluates no BRDF, it only interpolates the radiance prt_shade.wgsl computed per vertex.
//
// Must match: RasterUniforms in src/gpu/uniforms.rs; GpuVertex in prt_shade.wgsl.

struct RasterUniforms {
    clip_from_world: mat4x4<f32>,
}

struct GpuVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
    tangent: vec4<f32>,
}

@group(0) @binding(0) var<uniform> r: RasterUniforms;
@group(0) @binding(1) var<storage, read> vertices: array<GpuVertex>;
@group(0) @binding(2) var<storage, read> radiance: array<vec4<f32>>;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) rgb: vec3<f32>,
}

// Drawn with an index buffer of the mesh's triangles: vertex_index is the mesh vertex.
@vertex
fn vs_main(@builtin(vertex_index) v: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = r.clip_from_world * vec4<f32>(vertices[v].position.xyz, 1.0);
    out.rgb = radiance[v].xyz;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.rgb, 1.0);
}
