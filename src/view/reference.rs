//! The runtime reference: the classic shell technique, drawn on the GPU from the *input* mesh,
//! sharing nothing with the pack stage or the glTF file.
//!
//! The geometry-shader technique of the references (re-emit every triangle N times pushed out
//! along the normal, discard texels by a noise texture) expressed as WebGPU can: one instanced
//! draw, **layer = instance**. The vertex shader extrudes `position + delta · t_j`; the fragment
//! shader evaluates the strand law itself and discards:
//!
//! - **Noise law**: a raw 8-bit noise texture (`R8Unorm`, `NEAREST`, `REPEAT`), texel `(x, y)` =
//!   [`strands::noise8`]`(x, y, size, seed)`, sampled at `uv × tiles_per_uv`; discard when
//!   `n·(1 − t) < c`. The baked mask's survival codes are never consulted.
//! - **Cells law**: texel index `floor(fract(uv × tiles) × size)`, then `mix32` / `cell_hash` /
//!   `cell_rand` and the cell formula in WGSL, exactly as [`strands::survival`] computes them
//!   (wrapping `u32` arithmetic, same `f32` operation order).
//!
//! What the reference takes from the bake are the **decisions of the frames stage** — the float
//! render mesh ([`Baked::mesh`]) and its per-vertex extrusion ([`ShellStack::delta`]) — plus the
//! layer heights, shades and the mask tiling: the inputs of the technique, not its output. The
//! baked file must then match it to rasterization noise (quantized positions and UVs); any
//! disagreement in which strand texels survive which layer is a bake bug.
//!
//! Rejected: deriving the reference from the baked mask texture (it would verify nothing about
//! the mask), and CPU ray casting (slow, and a second rasterizer would add its own noise).
//! Possible disagreements that are not bugs: f32 rounding of the law exactly at a threshold
//! (`sqrt` and division are not correctly rounded in WGSL; `strands.rs` tests that such ties are
//! a handful of texels per mask) and texel-edge decisions moved by 16-bit UV quantization.
//!
//! The base layer (instance 0, t = 0) never discards: it is the opaque skin.

use glam::{DMat4, Vec2, Vec3};
use wgpu::util::DeviceExt as _;

use super::camera::{Camera, Sphere};
use super::gpu::{self, Frame, Gpu, Light};
use crate::mesh::Mesh;
use crate::params::{StrandModel, StrandParams};
use crate::shells::ShellStack;
use crate::strands;
use crate::Baked;

const WGSL: &str = include_str!("reference.wgsl");
const MAX_LAYERS: usize = 256;

/// What the reference draws: the input of the shell technique.
#[derive(Clone, Copy)]
pub struct ReferenceInput<'a> {
    /// Float render mesh (positions relative to `mesh.origin`, normals and UVs present).
    pub mesh: &'a Mesh,
    /// Layer heights, shades and the per-vertex extrusion at t = 1.
    pub shells: &'a ShellStack,
    /// The strand law.
    pub strands: &'a StrandParams,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
    /// glTF roughness of every layer (metallic is 0).
    pub roughness: f32,
}

impl<'a> ReferenceInput<'a> {
    /// The reference for a bake made with `params`.
    pub fn from_baked(
        baked: &'a Baked,
        params: &'a crate::params::BakeParams,
    ) -> ReferenceInput<'a> {
        ReferenceInput {
            mesh: &baked.mesh,
            shells: &baked.shells,
            strands: &params.strands,
            tiles_per_uv: baked.tiles_per_uv,
            roughness: params.shade.roughness,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ShellData {
    model: [f32; 16],
    tiles: [f32; 4],
    law: [f32; 4],
    ints: [u32; 4],
    material: [f32; 4],
    layers: [[f32; 4]; MAX_LAYERS],
}

/// Draws the runtime reference.
pub struct ReferenceRenderer {
    frame: Frame,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    pipeline: Option<(wgpu::TextureFormat, wgpu::RenderPipeline)>,
    data: Box<ShellData>,
    uniform: wgpu::Buffer,
    group: wgpu::BindGroup,
    vertices: [wgpu::Buffer; 4],
    indices: wgpu::Buffer,
    index_count: u32,
    layers: u32,
    layer_limit: Option<usize>,
    origin: glam::DVec3,
    /// Bounding sphere of the base and the outermost layer.
    pub bounds: Sphere,
}

impl ReferenceRenderer {
    pub fn new(gpu: &Gpu, input: ReferenceInput) -> ReferenceRenderer {
        let mesh = input.mesh;
        let shells = input.shells;
        assert!(shells.t.len() <= MAX_LAYERS && shells.t.len() == shells.color.len());
        assert_eq!(shells.delta.len(), mesh.vertex_count());
        let normals = mesh
            .normals
            .as_ref()
            .expect("the reference needs normals (bake fills them)");
        let uvs = mesh
            .uvs
            .as_ref()
            .expect("the reference needs UVs (bake fills them)");
        let device = &gpu.device;
        let frame = Frame::new(gpu);

        let f32s = |v: Vec<f32>, label| {
            let v = if v.is_empty() { vec![0.0; 4] } else { v };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&v),
                usage: wgpu::BufferUsages::VERTEX,
            })
        };
        let flat3 = |v: &[Vec3]| v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>();
        let vertices = [
            f32s(flat3(&mesh.positions), "positions"),
            f32s(flat3(normals), "normals"),
            f32s(uvs.iter().flat_map(|p| p.to_array()).collect(), "uvs"),
            f32s(flat3(&shells.delta), "deltas"),
        ];
        let ix = if mesh.indices.is_empty() {
            vec![0u32; 3]
        } else {
            mesh.indices.clone()
        };
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&ix),
            usage: wgpu::BufferUsages::INDEX,
        });

        // The raw noise texture of the noise law (one tile).
        let size = input.strands.mask_size;
        let seed = input.strands.seed;
        let noise: Vec<u8> = match input.strands.model {
            StrandModel::Noise { .. } => (0..size)
                .flat_map(|y| (0..size).map(move |x| strands::noise8(x, y, size, seed)))
                .collect(),
            StrandModel::Cells { .. } => vec![0; (size * size) as usize],
        };
        let noise_texture = device.create_texture_with_data(
            &gpu.queue,
            &wgpu::TextureDescriptor {
                label: Some("noise"),
                size: wgpu::Extent3d {
                    width: size,
                    height: size,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            &noise,
        );
        let noise_view = noise_texture.create_view(&Default::default());
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("noise"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Nearest,
            min_filter: wgpu::FilterMode::Nearest,
            ..Default::default()
        });

        let mut data: Box<ShellData> = bytemuck::zeroed_box();
        let (kind, law) = match input.strands.model {
            StrandModel::Noise { threshold } => (0.0, [threshold, 0.0, 0.0, 0.0]),
            StrandModel::Cells {
                thickness,
                min_length,
                texels_per_cell,
            } => (1.0, [thickness, min_length, texels_per_cell as f32, 0.0]),
        };
        data.tiles = [
            input.tiles_per_uv.x,
            input.tiles_per_uv.y,
            size as f32,
            kind,
        ];
        data.law = law;
        data.ints = [seed, shells.t.len() as u32, 0, 0];
        data.material = [0.0, input.roughness, 0.0, 0.0];
        for (j, (c, &t)) in shells.color.iter().zip(&shells.t).enumerate() {
            data.layers[j] = [c[0], c[1], c[2], t];
        }
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shell"),
            size: std::mem::size_of::<ShellData>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shell"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                super::gpu::fragment_texture_entry(1),
                super::gpu::fragment_sampler_entry(2),
            ],
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shell"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&noise_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("reference"),
            bind_group_layouts: &[Some(&frame.layout), Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("reference"),
            source: wgpu::ShaderSource::Wgsl(format!("{}\n{}", gpu::COMMON_WGSL, WGSL).into()),
        });

        // Bounds: base and outermost layer, in world space.
        let t_max = shells.t.iter().copied().fold(0.0f32, f32::max);
        let mut lo = glam::DVec3::splat(f64::INFINITY);
        let mut hi = glam::DVec3::splat(f64::NEG_INFINITY);
        for (p, d) in mesh.positions.iter().zip(&shells.delta) {
            for q in [*p, *p + *d * t_max] {
                let w = mesh.origin + q.as_dvec3();
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        let bounds = if lo.is_finite() {
            Sphere::around_box(lo, hi)
        } else {
            Sphere {
                center: mesh.origin,
                radius: 1.0,
            }
        };

        ReferenceRenderer {
            frame,
            pipeline_layout,
            module,
            pipeline: None,
            data,
            uniform,
            group,
            vertices,
            indices,
            index_count: mesh.indices.len() as u32,
            layers: shells.t.len() as u32,
            layer_limit: None,
            origin: mesh.origin,
            bounds,
        }
    }

    /// Number of layers (instances).
    pub fn layer_count(&self) -> usize {
        self.layers as usize
    }

    /// Shows layers `0..=k` only (`None`: all).
    pub fn set_layer_limit(&mut self, k: Option<usize>) {
        self.layer_limit = k;
    }

    fn instances(&self) -> u32 {
        self.layer_limit
            .map_or(self.layers, |k| (k as u32 + 1).min(self.layers))
    }

    /// Triangles drawn per frame.
    pub fn triangles(&self) -> usize {
        self.index_count as usize / 3 * self.instances() as usize
    }

    /// Writes the camera, light and shell uniforms and builds the pipeline for `format`.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        camera: &Camera,
        light: &Light,
        format: wgpu::TextureFormat,
    ) {
        self.frame.write(gpu, camera, light);
        self.data.model = DMat4::from_translation(self.origin - camera.anchor())
            .as_mat4()
            .to_cols_array();
        gpu.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&*self.data));
        if self.pipeline.as_ref().map(|p| p.0) != Some(format) {
            let attr = |loc, format| {
                [wgpu::VertexAttribute {
                    format,
                    offset: 0,
                    shader_location: loc,
                }]
            };
            let a = [
                attr(0, wgpu::VertexFormat::Float32x3),
                attr(1, wgpu::VertexFormat::Float32x3),
                attr(2, wgpu::VertexFormat::Float32x2),
                attr(3, wgpu::VertexFormat::Float32x3),
            ];
            let layouts: Vec<Option<wgpu::VertexBufferLayout>> = a
                .iter()
                .map(|a| {
                    Some(wgpu::VertexBufferLayout {
                        array_stride: a[0].format.size(),
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: a,
                    })
                })
                .collect();
            let pipeline = gpu
                .device
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("reference"),
                    layout: Some(&self.pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("vs_main"),
                        compilation_options: Default::default(),
                        buffers: &layouts,
                    },
                    primitive: gpu::primitive_state(true, false),
                    depth_stencil: Some(gpu::depth_state(true)),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some("fs_main"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                });
            self.pipeline = Some((format, pipeline));
        }
    }

    /// Records the instanced draw into `pass` (after [`ReferenceRenderer::prepare`]).
    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        let (_, pipeline) = self.pipeline.as_ref().expect("prepare() before record()");
        if self.index_count == 0 {
            return;
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.frame.bind_group, &[]);
        pass.set_bind_group(1, &self.group, &[]);
        for (i, b) in self.vertices.iter().enumerate() {
            pass.set_vertex_buffer(i as u32, b.slice(..));
        }
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, 0..self.instances());
    }
}
