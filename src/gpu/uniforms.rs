//! Rust `#[repr(C)]` Pod mirrors of the WGSL structs in `shaders/prt_shade.wgsl` and
//! `shaders/prt_raster.wgsl`, and the flag bits they share.
//!
//! Must match: field order, types and sizes of the WGSL declarations. Every struct is built from
//! 16-byte vectors, so WGSL's layout rules add no hidden padding; `tests` checks each size against
//! naga's layouter on the parsed shaders, so a change on one side only fails the build's tests.
//!
//! Invariants: plain data, no GPU calls.

use bytemuck::{Pod, Zeroable};

/// Most pre-filtered table levels the shader addresses (must match `levels` in `ShadeUniforms`).
pub const MAX_TABLE_LEVELS: usize = 40;
/// Evaluate the specular term (must match `FLAG_SPECULAR`).
pub const FLAG_SPECULAR: u32 = 1;
/// Pre-filter p by each run's spread (must match `FLAG_PREFILTER`).
pub const FLAG_PREFILTER: u32 = 2;
/// Vertices carry tangents; build the frame from them (must match `FLAG_TANGENTS`).
pub const FLAG_TANGENTS: u32 = 4;
/// Invocations per workgroup of `shade`, which is one vertex's lanes (must match `@workgroup_size`
/// and `LANES`).
pub const SHADE_WORKGROUP: u32 = 64;

/// Must match `ShadeUniforms` in prt_shade.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ShadeUniforms {
    /// xyz: the eye in world space.
    pub eye: [f32; 4],
    /// rgb: ρd; w: F0.
    pub rho_d_f0: [f32; 4],
    /// vertex_count, leaf_count, partition_count, node_count.
    pub counts: [u32; 4],
    /// level_count, flags, λ as bits, 0.
    pub table: [u32; 4],
    /// Per level: texel offset, resolution, 0, 0.
    pub levels: [[u32; 4]; MAX_TABLE_LEVELS],
}

/// Must match `GpuVertex` in both shaders.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 4],
    pub normal: [f32; 4],
    /// xyz tangent, w handedness ±1.
    pub tangent: [f32; 4],
}

/// Must match `PartitionEntry` in prt_shade.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PartitionEntry {
    /// first leaf, end leaf, light-tree node, 0.
    pub range: [u32; 4],
    /// axis xyz, cos of the half-angle.
    pub cone: [f32; 4],
}

/// Must match `GpuLeaf` in prt_shade.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuLeaf {
    pub corners: [[f32; 4]; 4],
    pub moment: [f32; 4],
}

/// Must match `RasterUniforms` in prt_raster.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct RasterUniforms {
    /// Column-major, as glam's `Mat4::to_cols_array_2d`.
    pub clip_from_world: [[f32; 4]; 4],
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::naga;

    /// Size of a named struct as naga lays it out.
    fn wgsl_size(source: &str, name: &str) -> u32 {
        let module = naga::front::wgsl::parse_str(source).expect("parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("lays out");
        let (handle, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{name} not in the shader"));
        layouter[handle].size
    }

    #[test]
    fn mirrors_match_the_wgsl_layouts() {
        let shade = include_str!("../../shaders/prt_shade.wgsl");
        let raster = include_str!("../../shaders/prt_raster.wgsl");
        assert_eq!(
            wgsl_size(shade, "ShadeUniforms") as usize,
            size_of::<ShadeUniforms>()
        );
        assert_eq!(
            wgsl_size(shade, "GpuVertex") as usize,
            size_of::<GpuVertex>()
        );
        assert_eq!(
            wgsl_size(raster, "GpuVertex") as usize,
            size_of::<GpuVertex>()
        );
        assert_eq!(
            wgsl_size(shade, "PartitionEntry") as usize,
            size_of::<PartitionEntry>()
        );
        assert_eq!(wgsl_size(shade, "GpuLeaf") as usize, size_of::<GpuLeaf>());
        assert_eq!(
            wgsl_size(raster, "RasterUniforms") as usize,
            size_of::<RasterUniforms>()
        );
        // The constants the shader declares.
        for (name, value) in [
            ("FLAG_SPECULAR", FLAG_SPECULAR),
            ("FLAG_PREFILTER", FLAG_PREFILTER),
            ("FLAG_TANGENTS", FLAG_TANGENTS),
        ] {
            assert!(
                shade.contains(&format!("const {name}: u32 = {value}u;")),
                "{name} differs"
            );
        }
        assert!(shade.contains(&format!("@workgroup_size({SHADE_WORKGROUP})")));
        assert!(shade.contains(&format!("const LANES: u32 = {SHADE_WORKGROUP}u;")));
        assert!(shade.contains(&format!("levels: array<vec4<u32>, {MAX_TABLE_LEVELS}>")));
    }
}
