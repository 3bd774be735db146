//! [`GpuPreview`]: the PRT frame on the GPU — per-vertex shading (compute), raster interpolation,
//! readback.
//!
//! Data, by how often it changes:
//! - per bake (uploaded once in [`GpuPreview::new`]): vertices (position, normal, tangent), each
//!   vertex's cut as (first leaf, end leaf, V, node), the render partition (ranges, their
//!   light-tree nodes, bounding cones), the leaves' corners and moments, the triangles;
//! - per rotation ([`GpuPreview::set_light`]): per light-tree node its radiance-weighted moment and
//!   power per channel, summed in f64 on the CPU (O(nodes)), and each leaf's radiance;
//! - per fit ([`GpuPreview::set_material`]): ρd, F0 and the p(h) table with its pre-filtered
//!   levels;
//! - per frame: the eye and the camera.
//!
//! Shading evaluates the mesh's own vertices (the CPU renderer's `max_edge_px = 0` setting); the
//! CPU frame at that setting is its reference (tests/it/gpu.rs). Invariants: every GPU call runs
//! inside an error scope and failures come back as [`GpuError`]; buffers are checked against the
//! device limits before they are made.

use super::uniforms::*;
use super::{GpuContext, GpuError};
use crate::bake::Cuts;
use crate::light::LightSums;
use crate::render::{Image, PhPyramid, PrtSettings};
use crate::scene::{Camera, Mesh};
use crate::sphere::LightTree;
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

const SHADE_WGSL: &str = include_str!("../../shaders/prt_shade.wgsl");
const RASTER_WGSL: &str = include_str!("../../shaders/prt_raster.wgsl");
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The offscreen target of one frame size.
struct Target {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row_bytes: u32,
}

/// The wgpu PRT preview of one bake.
pub struct GpuPreview {
    ctx: GpuContext,
    settings: PrtSettings,
    vertex_count: u32,
    node_count: u32,
    leaf_count: u32,
    index_count: u32,
    vertices: wgpu::Buffer,
    cut_offsets: wgpu::Buffer,
    cut_entries: wgpu::Buffer,
    partition: wgpu::Buffer,
    leaves: wgpu::Buffer,
    indices: wgpu::Buffer,
    radiance: wgpu::Buffer,
    light: Option<wgpu::Buffer>,
    table: Option<wgpu::Buffer>,
    uniforms: ShadeUniforms,
    shade_uniforms: wgpu::Buffer,
    raster_uniforms: wgpu::Buffer,
    shade_pipeline: wgpu::ComputePipeline,
    raster_pipeline: wgpu::RenderPipeline,
    raster_bind: wgpu::BindGroup,
    shade_bind: Option<wgpu::BindGroup>,
    target: Option<Target>,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// The loop iterations one shader invocation may take on llvmpipe, the software rasteriser behind
/// Mesa's lavapipe: it ends all of a shader's loops once 65,535 iterations have run in total
/// (`LP_MAX_TGSI_LOOP_ITERATIONS`, shared by every loop and counted per SIMD group of invocations),
/// silently. Nested loops made the preview drop runs at 8° partitions (white furnace 0.55 off) and
/// darken one bunny vertex with a 408-node cut by 5 %, so each lane of `prt_shade.wgsl` runs one
/// flat loop.
pub const SOFTWARE_LOOP_BUDGET: u64 = 65_535;

/// An upper bound on the loop iterations of one lane of `prt_shade.wgsl`'s `shade_block`, and of a
/// SIMD group of lanes of one vertex (its flat loop runs as long as its busiest lane): the bisection
/// for the first cut entry (at most 33 steps), then a step per run or gap (at most one per partition
/// node and two per cut entry) plus one per leaf summed astride the horizon (at most every leaf
/// once), plus the lanes' sum (6 steps). Direction sets up to 64 texels per side (24,576 leaves) stay
/// under [`SOFTWARE_LOOP_BUDGET`] whatever the partition.
fn loop_iterations_bound(partition_nodes: usize, max_cut: usize, leaves: usize) -> u64 {
    (33 + partition_nodes + 2 * max_cut + leaves + 6) as u64
}

impl GpuPreview {
    /// Uploads the bake: `settings.partition_deg` and `settings.prefilter` apply; shading is per
    /// vertex. On a software adapter, a bake whose shader loop could exceed
    /// [`SOFTWARE_LOOP_BUDGET`] (direction sets finer than 64 texels per side) is refused with
    /// [`GpuError::Limit`] rather than drawn wrong.
    pub fn new(
        ctx: &GpuContext,
        mesh: &Mesh,
        cuts: &Cuts,
        tree: &LightTree,
        tangents: Option<&[Vec4]>,
        settings: PrtSettings,
    ) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let vertex_count = mesh.positions.len();
        // One workgroup per vertex, on a 2D grid (see `encode_shade`).
        let max_groups = (ctx.limits.max_compute_workgroups_per_dimension as u64).pow(2);
        if vertex_count as u64 > max_groups {
            return Err(GpuError::Limit {
                what: "one workgroup per vertex",
                needed: vertex_count as u64,
                allowed: max_groups,
            });
        }
        let tangents = tangents.filter(|t| t.len() == vertex_count);
        let vertices: Vec<GpuVertex> = (0..vertex_count)
            .map(|v| GpuVertex {
                position: v4(mesh.positions[v], 1.0),
                normal: v4(mesh.normals.get(v).copied().unwrap_or(Vec3::ZERO), 0.0),
                tangent: tangents.map_or([0.0; 4], |t| t[v].to_array()),
            })
            .collect();
        let nodes = tree.nodes();
        let mut cut_offsets = Vec::with_capacity(vertex_count + 1);
        let mut cut_entries: Vec<[u32; 4]> = Vec::with_capacity(cuts.node_count());
        cut_offsets.push(0u32);
        for v in 0..vertex_count {
            for (k, vis) in cuts.cut(v) {
                let Some(node) = nodes.get(k as usize) else {
                    continue;
                };
                cut_entries.push([node.first, node.first + node.count, vis.to_bits(), k]);
            }
            cut_offsets.push(cut_entries.len() as u32);
        }
        let part = tree.partition(settings.partition_deg.to_radians().max(1e-6));
        if ctx.info.device_type == wgpu::DeviceType::Cpu {
            let max_cut = cut_offsets
                .windows(2)
                .map(|w| (w[1] - w[0]) as usize)
                .max()
                .unwrap_or(0);
            let needed = loop_iterations_bound(part.ranges.len(), max_cut, tree.leaf_count());
            if needed > SOFTWARE_LOOP_BUDGET {
                return Err(GpuError::Limit {
                    what: "the shading loop on a software adapter (llvmpipe)",
                    needed,
                    allowed: SOFTWARE_LOOP_BUDGET,
                });
            }
        }
        let partition: Vec<PartitionEntry> = part
            .ranges
            .iter()
            .zip(&part.nodes)
            .map(|(&(a, z), &k)| {
                let c = tree.corner_cone(k as usize);
                PartitionEntry {
                    range: [a, z, k, 0],
                    cone: [
                        c.axis.x as f32,
                        c.axis.y as f32,
                        c.axis.z as f32,
                        c.cos as f32,
                    ],
                }
            })
            .collect();
        let leaves: Vec<GpuLeaf> = tree
            .leaf_corners()
            .iter()
            .zip(tree.leaf_moments())
            .map(|(c, m)| GpuLeaf {
                corners: c.map(|d| v4(d.as_vec3(), 0.0)),
                moment: v4(m.as_vec3(), 0.0),
            })
            .collect();
        let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();

        let storage = |label: &str,
                       bytes: &[u8],
                       usage: wgpu::BufferUsages|
         -> Result<wgpu::Buffer, GpuError> {
            check_size(ctx, bytes.len() as u64)?;
            // Zero-sized bindings are invalid: pad empty arrays to one vec4.
            let contents: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
            Ok(
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                }),
            )
        };
        let ro = wgpu::BufferUsages::STORAGE;
        let vertices = storage("vertices", bytemuck::cast_slice(&vertices), ro)?;
        let cut_offsets = storage("cut offsets", bytemuck::cast_slice(&cut_offsets), ro)?;
        let cut_entries = storage("cut entries", bytemuck::cast_slice(&cut_entries), ro)?;
        let partition_buf = storage("partition", bytemuck::cast_slice(&partition), ro)?;
        let leaves = storage("leaves", bytemuck::cast_slice(&leaves), ro)?;
        let indices_buf = storage(
            "indices",
            bytemuck::cast_slice(&indices),
            wgpu::BufferUsages::INDEX,
        )?;
        let radiance_bytes = (vertex_count.max(1) * 16) as u64;
        check_size(ctx, radiance_bytes)?;
        let radiance = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vertex radiance"),
            size: radiance_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let uniforms = ShadeUniforms {
            eye: [0.0; 4],
            rho_d_f0: [0.0; 4],
            counts: [
                vertex_count as u32,
                tree.leaf_count() as u32,
                partition.len() as u32,
                nodes.len() as u32,
            ],
            table: [0, if tangents.is_some() { FLAG_TANGENTS } else { 0 }, 0, 0],
            levels: [[0; 4]; MAX_TABLE_LEVELS],
        };
        let shade_uniforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shade uniforms"),
            contents: bytemuck::bytes_of(&uniforms),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let raster_uniforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("raster uniforms"),
            contents: bytemuck::bytes_of(&RasterUniforms {
                clip_from_world: [[0.0; 4]; 4],
            }),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let shade_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("prt_shade.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADE_WGSL.into()),
        });
        let raster_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("prt_raster.wgsl"),
            source: wgpu::ShaderSource::Wgsl(RASTER_WGSL.into()),
        });
        let shade_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("prt shade"),
            layout: None,
            module: &shade_module,
            entry_point: Some("shade"),
            compilation_options: Default::default(),
            cache: None,
        });
        let raster_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("prt raster"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &raster_module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &raster_module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let raster_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster"),
            layout: &raster_pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: raster_uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: vertices.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: radiance.as_entire_binding(),
                },
            ],
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                reason: e.to_string(),
            });
        }
        Ok(Self {
            ctx: ctx.clone(),
            settings,
            vertex_count: vertex_count as u32,
            node_count: nodes.len() as u32,
            leaf_count: tree.leaf_count() as u32,
            index_count: indices.len() as u32,
            vertices,
            cut_offsets,
            cut_entries,
            partition: partition_buf,
            leaves,
            indices: indices_buf,
            radiance,
            light: None,
            table: None,
            uniforms,
            shade_uniforms,
            raster_uniforms,
            shade_pipeline,
            raster_pipeline,
            raster_bind,
            shade_bind: None,
            target: None,
        })
    }

    /// The device this preview renders on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Uploads the light of a rotation: per node the radiance-weighted moment and power (f64 sums
    /// rounded to f32 once), per leaf its radiance.
    pub fn set_light(&mut self, light: &LightSums, tree: &LightTree) -> Result<(), GpuError> {
        let nodes = tree.nodes();
        if nodes.len() as u32 != self.node_count
            || tree.leaf_count() as u32 != self.leaf_count
            || light.leaf_radiance().len() != tree.leaf_count()
        {
            return Err(GpuError::Wgpu {
                reason: "the light sums belong to another light tree than the bake's".into(),
            });
        }
        let mut data: Vec<[f32; 4]> = Vec::with_capacity(3 * nodes.len() + tree.leaf_count());
        for node in nodes {
            let (a, z) = (node.first as usize, (node.first + node.count) as usize);
            let (m, p) = (light.radiant_moment(a, z), light.power(a, z));
            for c in 0..3 {
                data.push([m[c].x as f32, m[c].y as f32, m[c].z as f32, p[c] as f32]);
            }
        }
        data.extend(
            light
                .leaf_radiance()
                .iter()
                .map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]),
        );
        let bytes: &[u8] = bytemuck::cast_slice(&data);
        if upload(&self.ctx, &mut self.light, "light", bytes)? {
            self.shade_bind = None;
        }
        Ok(())
    }

    /// Sets ρd, F0 and p(h) (`None`: diffuse only).
    pub fn set_material(
        &mut self,
        rho_d: [f64; 3],
        f0: f64,
        table: Option<&PhPyramid>,
    ) -> Result<(), GpuError> {
        self.uniforms.rho_d_f0 = [rho_d[0] as f32, rho_d[1] as f32, rho_d[2] as f32, f0 as f32];
        let mut flags = self.uniforms.table[1] & FLAG_TANGENTS;
        let mut texels: Vec<[f32; 4]> = Vec::new();
        self.uniforms.levels = [[0; 4]; MAX_TABLE_LEVELS];
        let mut level_count = 0u32;
        let mut lambda = 0.0f32;
        if let Some(table) = table {
            flags |= FLAG_SPECULAR;
            if self.settings.prefilter {
                flags |= FLAG_PREFILTER;
            }
            lambda = table.lambda() as f32;
            for (l, (resolution, level)) in table.levels().enumerate().take(MAX_TABLE_LEVELS) {
                self.uniforms.levels[l] = [texels.len() as u32, resolution as u32, 0, 0];
                texels.extend(level.iter().map(|t| [t[0], t[1], t[2], 0.0]));
                level_count += 1;
            }
        }
        if texels.is_empty() {
            texels.push([0.0; 4]);
        }
        self.uniforms.table = [level_count, flags, lambda.to_bits(), 0];
        let bytes: &[u8] = bytemuck::cast_slice(&texels);
        if upload(&self.ctx, &mut self.table, "p(h) table", bytes)? {
            self.shade_bind = None;
        }
        Ok(())
    }

    fn shade_bind(&mut self) -> Result<wgpu::BindGroup, GpuError> {
        if let Some(b) = &self.shade_bind {
            return Ok(b.clone());
        }
        let light = self.light.as_ref().ok_or(GpuError::NotReady {
            what: "light",
            call: "set_light",
        })?;
        let table = self.table.as_ref().ok_or(GpuError::NotReady {
            what: "material",
            call: "set_material",
        })?;
        let buffers = [
            &self.shade_uniforms,
            &self.vertices,
            &self.cut_offsets,
            &self.cut_entries,
            &self.partition,
            &self.leaves,
            light,
            table,
            &self.radiance,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let bind = self
            .ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("shade"),
                layout: &self.shade_pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
        self.shade_bind = Some(bind.clone());
        Ok(bind)
    }

    /// Records the shading pass for an eye position.
    fn encode_shade(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        eye: Vec3,
    ) -> Result<(), GpuError> {
        let bind = self.shade_bind()?;
        self.uniforms.eye = v4(eye, 1.0);
        self.ctx
            .queue
            .write_buffer(&self.shade_uniforms, 0, bytemuck::bytes_of(&self.uniforms));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prt shade"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.shade_pipeline);
        pass.set_bind_group(0, &bind, &[]);
        // One workgroup per vertex: x up to the device's limit, y as many rows as that takes (the
        // shader reads v = x + y · groups in x; `new` checked that the grid fits).
        let width = self.vertex_count.clamp(
            1,
            self.ctx.limits.max_compute_workgroups_per_dimension.max(1),
        );
        pass.dispatch_workgroups(width, self.vertex_count.div_ceil(width).max(1), 1);
        Ok(())
    }

    /// The radiance of every vertex seen from `eye` (shading pass plus readback), as the CPU's
    /// `Prt::shade_points` at the vertices.
    pub fn vertex_radiance(&mut self, eye: Vec3) -> Result<Vec<[f32; 3]>, GpuError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("vertex radiance"),
            });
        self.encode_shade(&mut encoder, eye)?;
        let size = self.radiance.size();
        let readback = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiance readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_buffer_to_buffer(&self.radiance, 0, &readback, 0, size);
        self.ctx.queue.submit([encoder.finish()]);
        let bytes = read_buffer(&self.ctx, &readback)?;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                reason: e.to_string(),
            });
        }
        let values: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        Ok(values
            .iter()
            .take(self.vertex_count as usize)
            .map(|v| [v[0], v[1], v[2]])
            .collect())
    }

    fn ensure_target(&mut self, width: u32, height: u32) -> Result<(), GpuError> {
        if self
            .target
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height)
        {
            return Ok(());
        }
        let max = self.ctx.limits.max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::Limit {
                what: "the frame's width and height",
                needed: width.max(height) as u64,
                allowed: max as u64,
            });
        }
        let device = &self.ctx.device;
        let extent = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            "preview colour",
            COLOR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let depth = texture(
            "preview depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let padded_row_bytes = (width * 16).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame readback"),
            size: padded_row_bytes as u64 * height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.target = Some(Target {
            width,
            height,
            depth_view: depth.create_view(&Default::default()),
            color,
            readback,
            padded_row_bytes,
        });
        Ok(())
    }

    /// Shades and rasterises a frame into the offscreen target (submitted, not waited for); returns
    /// the colour texture (Rgba32Float: linear radiance, alpha 1 on the object).
    pub fn draw(
        &mut self,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<&wgpu::Texture, GpuError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        self.submit_frame(camera, width, height, false)?;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                reason: e.to_string(),
            });
        }
        // submit_frame made the target; an error rather than a panic should that ever change.
        Ok(&self
            .target
            .as_ref()
            .ok_or(GpuError::NotReady {
                what: "render target",
                call: "submit_frame",
            })?
            .color)
    }

    fn submit_frame(
        &mut self,
        camera: &Camera,
        width: u32,
        height: u32,
        copy_out: bool,
    ) -> Result<(), GpuError> {
        self.ensure_target(width, height)?;
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("prt frame"),
            });
        self.encode_shade(&mut encoder, camera.eye())?;
        let raster = RasterUniforms {
            clip_from_world: camera.clip_from_world().to_cols_array_2d(),
        };
        self.ctx
            .queue
            .write_buffer(&self.raster_uniforms, 0, bytemuck::bytes_of(&raster));
        // ensure_target made it just above.
        let target = self.target.as_ref().ok_or(GpuError::NotReady {
            what: "render target",
            call: "submit_frame",
        })?;
        let color_view = target.color.create_view(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("prt raster"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.raster_pipeline);
            pass.set_bind_group(0, &self.raster_bind, &[]);
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.index_count, 0, 0..1);
        }
        if copy_out {
            encoder.copy_texture_to_buffer(
                target.color.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &target.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(target.padded_row_bytes),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
            );
        }
        self.ctx.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// A frame read back into an [`Image`] (pixels off the object stay uncovered and black).
    pub fn render(&mut self, camera: &Camera, width: u32, height: u32) -> Result<Image, GpuError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        self.submit_frame(camera, width, height, true)?;
        // submit_frame made the target.
        let target = self.target.as_ref().ok_or(GpuError::NotReady {
            what: "render target",
            call: "submit_frame",
        })?;
        // Straight from the mapped buffer, rows in parallel: at 1920×1080 the frame is 33 MB.
        let (w, row) = (width as usize, target.padded_row_bytes as usize / 16);
        let image = map_read(&self.ctx, &target.readback, |bytes| {
            let texels: &[[f32; 4]] = bytemuck::cast_slice(bytes);
            let mut image = Image::new(width, height);
            if w > 0 {
                image
                    .pixels
                    .par_chunks_mut(w)
                    .zip(image.covered.par_chunks_mut(w))
                    .enumerate()
                    .for_each(|(y, (pixels, covered))| {
                        let texels = &texels[y * row..y * row + w];
                        for ((t, p), c) in texels.iter().zip(pixels).zip(covered) {
                            if t[3] > 0.5 {
                                *p = [t[0], t[1], t[2]];
                                *c = true;
                            }
                        }
                    });
            }
            image
        })?;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                reason: e.to_string(),
            });
        }
        Ok(image)
    }
}

/// Writes `bytes` into `slot`, reusing its buffer when the size matches; true when a new buffer was
/// made (bind groups that hold the old one must be rebuilt).
fn upload(
    ctx: &GpuContext,
    slot: &mut Option<wgpu::Buffer>,
    label: &str,
    bytes: &[u8],
) -> Result<bool, GpuError> {
    if let Some(buffer) = slot.as_ref().filter(|b| b.size() == bytes.len() as u64) {
        ctx.queue.write_buffer(buffer, 0, bytes);
        return Ok(false);
    }
    check_size(ctx, bytes.len() as u64)?;
    *slot = Some(
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            }),
    );
    Ok(true)
}

fn check_size(ctx: &GpuContext, bytes: u64) -> Result<(), GpuError> {
    let allowed = ctx
        .limits
        .max_storage_buffer_binding_size
        .min(ctx.limits.max_buffer_size);
    if bytes > allowed {
        return Err(GpuError::Limit {
            what: "a buffer of the bake",
            needed: bytes,
            allowed,
        });
    }
    Ok(())
}

/// Maps a MAP_READ buffer after the queue's work and copies it out (also the app's screenshot
/// path).
pub fn read_buffer(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    map_read(ctx, buffer, <[u8]>::to_vec)
}

/// Maps a MAP_READ buffer after the queue's work, hands its bytes to `read`, and unmaps it.
fn map_read<T>(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T, GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback {
            reason: e.to_string(),
        })?;
    match rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(GpuError::Readback {
                reason: e.to_string(),
            });
        }
        Err(e) => {
            return Err(GpuError::Readback {
                reason: e.to_string(),
            });
        }
    }
    let out = {
        let view = buffer
            .slice(..)
            .get_mapped_range()
            .map_err(|e| GpuError::Readback {
                reason: e.to_string(),
            })?;
        read(&view)
    };
    buffer.unmap();
    Ok(out)
}
