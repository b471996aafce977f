//! The runtime reference: the classic shell technique, drawn on the GPU from the *input* mesh,
//! sharing nothing with the pack stage or the glTF file.
//!
//! The geometry-shader technique of the references (re-emit every triangle N times pushed out
//! along the normal, discard texels by a noise texture) expressed as WebGPU can: one instanced
//! draw, **layer = instance**. The vertex shader extrudes `position + delta · t_j`; the fragment
//! shader samples the technique's **law texture** at `uv × tiles_per_uv` and discards:
//!
//! - **Noise law**: the raw noise texture, texel `(x, y)` = [`strands::noise8`]`(x, y, size,
//!   seed)`; discard when the seed's `n·(1 − t) < c`, in that form (the baked file tests the
//!   equivalent `n >= c/(1 − t)` in its `alphaCutoff`).
//! - **Cells law**: per texel the survival code `BASE_CODE + q` and the strand's shade, computed
//!   here on the CPU by [`law_texture`] — its own implementation of the strand law: it *scatters*
//!   each strand's jittered disc over the texels it covers (every periodic image, wrapped into
//!   the tile), and finds each code by a linear scan of the height steps, where `strands.rs`
//!   *gathers* the strands of a fixed neighbourhood per texel and binary-searches. A neighbourhood
//!   that misses a strand, a wrap error or a search bug shows as a different code. Discard when
//!   the sampled code is below the layer's cutoff `(BASE_CODE + k_j − ½)/255`.
//!
//! The texture is sampled as the baked file's is — `Rgba8UnormSrgb`, `LINEAR` magnification,
//! `LINEAR_MIPMAP_LINEAR` minification, `REPEAT`, and the same coverage-preserving mip chain
//! (uploaded through [`gpu::upload_rgba_texture`], as the glTF renderer does) — so both sides
//! compare the *same interpolated quantity* with the same per-layer threshold: the law is exact
//! under filtering, not only at texel centres. The grey channel (the strand's shade) multiplies
//! the layer colour, the base layer included.
//!
//! What the reference takes from the bake are the **decisions of the frames stage** — the float
//! render mesh ([`BakedSurface::mesh`]) and its per-vertex extrusion ([`ShellStack::delta`]) — plus the
//! layer heights, shades and the mask tiling: the inputs of the technique, not its output. The
//! baked mask is never consulted. The baked file must then match it to rasterization noise
//! (quantized positions and UVs); any disagreement in which strand texels survive which layer
//! is a bake bug.
//!
//! Rejected: deriving the reference from the baked mask texture (it would verify nothing about
//! the mask); evaluating the cells law per fragment in WGSL, as the first version did (a
//! fragment cannot interpolate the law between texels nor build mip levels, so it could not
//! follow a filtered mask; and WGSL's `sqrt` and division are not correctly rounded, which made
//! a handful of ties per mask); CPU ray casting (slow, and a second rasterizer would add its own
//! noise). Possible disagreements that are not bugs: `f32` rounding of the noise law exactly at
//! a threshold, and contour positions moved by 16-bit UV quantization.
//!
//! The base layer (instance 0, t = 0) never discards: it is the opaque skin.

use glam::{DMat4, Vec2, Vec3};
use wgpu::util::DeviceExt as _;

use super::camera::{Camera, Sphere};
use super::gpu::{self, Frame, Gpu, Light};
use crate::model::mesh::Mesh;
use crate::params::{StrandModel, StrandParams};
use crate::stages::shells::ShellStack;
use crate::stages::strands;
use crate::BakedSurface;

const WGSL: &str = include_str!("reference.wgsl");
const MAX_LAYERS: usize = 256;

/// What the reference draws: the input of the shell technique.
#[derive(Clone, Copy)]
pub struct ReferenceInput<'a> {
    /// Float render mesh (positions relative to `mesh.origin`, normals and UVs present).
    pub mesh: &'a Mesh,
    /// Layer heights, shades and the per-vertex extrusion at t = 1.
    pub shells: &'a ShellStack,
    /// What the effects left on the layers (bend, lean, wind, occlusion, sheen).
    pub laws: &'a crate::effects::laws::Laws,
    /// The strand law.
    pub strands: &'a StrandParams,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
    /// glTF roughness of every layer (metallic is 0).
    pub roughness: f32,
    /// Density per vertex (bytes; `None`: 1): the sampled law value is scaled by it on every
    /// layer above the base, as the density map asks.
    pub density: Option<&'a [u8]>,
    /// One sheen for every layer, that of their mean height: what the single-draw layout's one
    /// material can carry (`crate::effects::sheen`); the technique's per-layer sheen otherwise.
    pub mean_sheen: bool,
    /// The skin `mesh.skin` indexes (placed), when the input is skinned: the layers are skinned
    /// after the extrusion, bend and sway, as the technique would on a skinned character.
    pub skeleton: Option<&'a crate::model::skeleton::Skeleton>,
    /// The `fins` and `outline` effects' decisions (see `reference_extras.rs`).
    pub fins: Option<&'a crate::effects::fins::Fins>,
    pub outline: Option<&'a crate::effects::outline::Outline>,
    /// The layer colours' gradient (the fins' strip carries it).
    pub shade: &'a crate::stages::shells::ShadeParams,
    /// The world distance between strands on most of the surface
    /// ([`BakedSurface::strand_spacing`]): what `verify` holds against the pixels of its close
    /// view, where the reference, made from the same tiling, cannot tell.
    pub strand_spacing: f64,
    /// What the density asked for ([`BakedSurface::asked_spacing`]).
    pub asked_spacing: f64,
}

impl<'a> ReferenceInput<'a> {
    /// The reference for a bake made with `params`.
    pub fn from_baked(
        baked: &'a BakedSurface,
        params: &'a crate::params::BakeParams,
    ) -> ReferenceInput<'a> {
        ReferenceInput {
            mesh: &baked.mesh,
            shells: &baked.shells,
            laws: &baked.laws,
            strands: &params.strands,
            tiles_per_uv: baked.tiles_per_uv,
            roughness: params.shade.roughness,
            density: baked.density.as_deref(),
            mean_sheen: params.pack.layout == crate::params::Layout::SingleDraw,
            skeleton: baked.skeleton.as_ref(),
            fins: baked.fins.as_ref(),
            outline: baked.outline.as_ref(),
            shade: &params.shade,
            strand_spacing: baked.strand_spacing,
            asked_spacing: baked.asked_spacing,
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
    /// Cells law: per-layer code cutoff, four to a vector.
    cutoffs: [[f32; 4]; MAX_LAYERS / 4],
    /// The wind's angle `2π·time/period` (x) and growth exponent (y).
    wind: [f32; 4],
    /// Per layer: `KHR_materials_sheen` colour (rgb) and roughness (w); zero: none.
    sheen: [[f32; 4]; MAX_LAYERS],
}

/// One strand as the reference derives it from its cell hash.
struct RefStrand {
    x: f32,
    y: f32,
    len: f32,
    grey: u8,
}

fn ref_strand(cx: u32, cy: u32, cells: u32, seed: u32, min_length: f32) -> RefStrand {
    let h = strands::cell_hash(cx, cy, cells, seed);
    let unit = |v: u32| (v >> 8) as f32 / 16_777_216.0;
    let offset = |salt: u32| 0.5 + (unit(strands::mix32(h ^ salt)) - 0.5) * (2.0 * strands::JITTER);
    let shade_bits = strands::mix32(h ^ strands::SHADE_SALT) >> 24;
    RefStrand {
        x: offset(strands::JITTER_X_SALT),
        y: offset(strands::JITTER_Y_SALT),
        len: min_length + (1.0 - min_length) * unit(h),
        grey: (255 - ((shade_bits * shade_bits * strands::SHADE_SPAN) >> 16)) as u8,
    }
}

/// The strand law at squared distance `dd` (cell widths²) and height `t`:
/// `len − dist/thickness >= t`, as `r = (len − t)·thickness >= 0 && dd <= r²`.
fn inside(len: f32, thickness: f32, dd: f32, t: f32) -> bool {
    let r = (len - t) * thickness;
    r >= 0.0 && dd <= r * r
}

/// The reference's law texture, RGBA8 row-major (grey = shade, alpha = the law's quantity): the
/// raw noise, or the cells law's survival codes computed by scattering every strand.
pub fn law_texture(p: &StrandParams) -> Vec<u8> {
    let size = p.mask_size;
    let mut rgba = Vec::with_capacity((size * size * 4) as usize);
    let (thickness, min_length, tpc) = match p.model {
        StrandModel::Noise { .. } => {
            for y in 0..size {
                for x in 0..size {
                    let n = strands::noise8(x, y, size, p.seed);
                    rgba.extend_from_slice(&[
                        strands::NO_SHADE,
                        strands::NO_SHADE,
                        strands::NO_SHADE,
                        n,
                    ]);
                }
            }
            return rgba;
        }
        StrandModel::Cells {
            thickness,
            min_length,
            texels_per_cell,
        } => (thickness, min_length, texels_per_cell as i64),
    };
    let cells = size / tpc as u32;
    let inv = 1.0 / tpc as f32;
    let heights: Vec<f32> = (0..=strands::HEIGHT_STEPS)
        .map(strands::step_height)
        .collect();
    // per texel: (step, squared distance, cell index, grey) of the tallest covering strand
    let mut best: Vec<Option<(u32, f32, u32, u8)>> = vec![None; (size * size) as usize];
    for cy in 0..cells {
        for cx in 0..cells {
            let s = ref_strand(cx, cy, cells, p.seed, min_length);
            let reach = s.len * thickness;
            let span = |c: f32| {
                (
                    ((c - reach) * tpc as f32).floor() as i64 - 1,
                    ((c + reach) * tpc as f32).ceil() as i64 + 1,
                )
            };
            let (x0, x1) = span(cx as f32 + s.x);
            let (y0, y1) = span(cy as f32 + s.y);
            for ty in y0..=y1 {
                let ey = (ty.rem_euclid(tpc) as f32 + 0.5) * inv
                    - ((cy as i64 - ty.div_euclid(tpc)) as f32 + s.y);
                for tx in x0..=x1 {
                    let ex = (tx.rem_euclid(tpc) as f32 + 0.5) * inv
                        - ((cx as i64 - tx.div_euclid(tpc)) as f32 + s.x);
                    let dd = ex * ex + ey * ey;
                    if !inside(s.len, thickness, dd, heights[0]) {
                        continue;
                    }
                    let mut q = 0;
                    while q < strands::HEIGHT_STEPS
                        && inside(s.len, thickness, dd, heights[q as usize + 1])
                    {
                        q += 1;
                    }
                    let index = cy * cells + cx;
                    let texel = (ty.rem_euclid(size as i64) * size as i64
                        + tx.rem_euclid(size as i64)) as usize;
                    let wins = best[texel].is_none_or(|(bq, bdd, bi, _)| {
                        q > bq || (q == bq && (dd < bdd || (dd == bdd && index < bi)))
                    });
                    if wins {
                        best[texel] = Some((q, dd, index, s.grey));
                    }
                }
            }
        }
    }
    for b in best {
        let (code, grey) = match b {
            Some((q, _, _, grey)) => ((strands::BASE_CODE + q) as u8, grey),
            None => (strands::BASE_CODE as u8, strands::SKIN_SHADE),
        };
        rgba.extend_from_slice(&[grey, grey, grey, code]);
    }
    rgba
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
    vertices: [wgpu::Buffer; 8],
    /// The skin and its joint matrices at the current time (relative to `origin`).
    skeleton: Option<crate::model::skeleton::Skeleton>,
    joints: wgpu::Buffer,
    /// The `wind` effect's period (seconds), when the stack sways.
    wind_period: Option<f32>,
    indices: wgpu::Buffer,
    index_count: u32,
    layers: u32,
    layer_limit: Option<usize>,
    origin: glam::DVec3,
    /// The time the skin is posed at (`None`: rest).
    time: Option<f32>,
    /// The fins and the outline, drawn after the shells.
    extras: Option<super::gltf::GltfRenderer>,
    /// Bounding sphere of the base and the outermost layer.
    pub bounds: Sphere,
}

impl ReferenceRenderer {
    pub fn new(gpu: &Gpu, input: ReferenceInput) -> ReferenceRenderer {
        let mesh = input.mesh;
        let (shells, laws) = (input.shells, input.laws);
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
        let lean = || {
            laws.lean
                .as_deref()
                .expect("gravity and wind make lean axes")
        };
        // the `gravity` effect's bend at the tip per vertex (zero: straight strands)
        let bends = match &laws.bend {
            Some(b) => crate::effects::gravity::bend(&shells.delta, lean(), b),
            None => vec![Vec3::ZERO; mesh.vertex_count()],
        };
        let sways = match &laws.wind {
            Some(w) => crate::effects::gravity::bend(&shells.delta, lean(), &w.law),
            None => vec![Vec3::ZERO; mesh.vertex_count()],
        };
        let vertices = [
            f32s(flat3(&mesh.positions), "positions"),
            f32s(flat3(normals), "normals"),
            f32s(uvs.iter().flat_map(|p| p.to_array()).collect(), "uvs"),
            f32s(flat3(&shells.delta), "deltas"),
            // per vertex: density (1: none), the `occlusion` effect's darkening (0: none), the
            // `wind` effect's phase
            f32s(
                (0..mesh.vertex_count())
                    .flat_map(|v| {
                        [
                            input.density.map_or(1.0, |d| d[v] as f32 / 255.0),
                            laws.occlusion.as_ref().map_or(0.0, |a| a[v]),
                            laws.wind.as_ref().map_or(0.0, |w| w.phase[v]),
                        ]
                    })
                    .collect(),
                "scalars",
            ),
            f32s(flat3(&bends), "bends"),
            // the `wind` effect's sway at the tip per vertex
            f32s(flat3(&sways), "sways"),
            // a skinned input's joints and weights (unskinned: joint 0, weight 1), and the
            // asset's base colour at the root (white: none), interleaved
            f32s(
                (0..mesh.vertex_count())
                    .flat_map(|v| {
                        let [i, j, k] = mesh
                            .albedo
                            .as_ref()
                            .map_or([1.0; 3], |a| a[v].truncate().to_array());
                        match &mesh.skin {
                            Some(s) => {
                                let [a, b, c, d] = s.joints[v].map(f32::from);
                                let [e, f, g, h] = s.weights[v];
                                [a, b, c, d, e, f, g, h, i, j, k]
                            }
                            None => [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, i, j, k],
                        }
                    })
                    .collect(),
                "skin",
            ),
        ];
        let skeleton = input.skeleton.filter(|_| mesh.skin.is_some()).cloned();
        let joint_count = skeleton.as_ref().map_or(1, |k| k.joints.len());
        let joints = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("joints"),
            size: 64 * joint_count as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
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

        // The law texture, sampled exactly as the viewer samples the baked mask.
        let size = input.strands.mask_size;
        let seed = input.strands.seed;
        let law = law_texture(input.strands);
        let law_view = gpu::upload_rgba_texture(gpu, size, size, &law, gpu::Mips::CoverageAlpha);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("law"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });

        let mut data: Box<ShellData> = bytemuck::zeroed_box();
        let (kind, threshold) = match input.strands.model {
            StrandModel::Noise { threshold } => (0.0, threshold),
            StrandModel::Cells { .. } => (1.0, 0.0),
        };
        data.tiles = [
            input.tiles_per_uv.x,
            input.tiles_per_uv.y,
            size as f32,
            kind,
        ];
        data.law = [threshold, 0.0, 0.0, 0.0];
        // z: 1 when the layers are skinned
        data.ints = [seed, shells.t.len() as u32, skeleton.is_some() as u32, 0];
        // z: the bend's exponent k (layer weight t^k)
        let k = laws.bend.as_ref().map_or(1.0, |b| b.k);
        data.material = [0.0, input.roughness, k, 0.0];
        for (j, (c, &t)) in shells.color.iter().zip(&shells.t).enumerate() {
            data.layers[j] = [c[0], c[1], c[2], t];
            data.cutoffs[j / 4][j % 4] = strands::step_cutoff(shells.steps[j]);
            if let Some(s) = &laws.sheen {
                let mean = shells.t.iter().sum::<f32>() / shells.t.len().max(1) as f32;
                let c = s.layer_color(if input.mean_sheen { mean } else { t });
                data.sheen[j] = [c[0], c[1], c[2], s.roughness];
            }
        }
        data.wind = [0.0, laws.wind.as_ref().map_or(1.0, |w| w.law.k), 0.0, 0.0];
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
                super::gpu::vertex_storage_entry(3),
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
                    resource: wgpu::BindingResource::TextureView(&law_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: joints.as_entire_binding(),
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
        for ((p, d), b) in mesh.positions.iter().zip(&shells.delta).zip(&bends) {
            for q in [*p, *p + *d * t_max, *p + *d * t_max + *b] {
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

        // the fins of a part with the asset's colours take its neutral ramp, as the bake's do
        let fin_shade = crate::stages::shells::surface_shade(input.shade, mesh.albedo.is_some());
        let extras = super::reference_extras::extras_asset(&super::reference_extras::ExtrasInput {
            mesh,
            delta: &shells.delta,
            fins: input.fins,
            outline: input.outline,
            strands: input.strands,
            law: &law,
            shade: &fin_shade,
            roughness: input.roughness,
        })
        .map(|asset| {
            super::gltf::GltfRenderer::new(gpu, asset).expect("the reference's own glTF uploads")
        });

        ReferenceRenderer {
            extras,
            frame,
            pipeline_layout,
            module,
            pipeline: None,
            data,
            uniform,
            group,
            vertices,
            skeleton,
            joints,
            indices,
            index_count: mesh.indices.len() as u32,
            layers: shells.t.len() as u32,
            layer_limit: None,
            wind_period: laws.wind.as_ref().map(|w| w.period),
            origin: mesh.origin,
            time: None,
            bounds,
        }
    }

    /// Number of layers (instances).
    /// Sways the layers as the wind does `time` seconds into its period (`None`: at rest).
    pub fn set_time(&mut self, time: Option<f32>) {
        self.time = time;
        self.data.wind[0] = match (time, self.wind_period) {
            (Some(t), Some(period)) => std::f32::consts::TAU * t / period,
            _ => 0.0,
        };
        self.data.wind[2] = (time.is_some() && self.wind_period.is_some()) as u8 as f32;
    }

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
            + self.extras.as_ref().map_or(0, |e| e.triangles())
    }

    /// Draw calls per frame: the instanced stack, and the fins' and outline's.
    pub fn draw_calls(&self) -> usize {
        (self.index_count > 0) as usize + self.extras.as_ref().map_or(0, |e| e.draw_calls())
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
        // the joint matrices at the time, in the frame of the positions (relative to `origin`)
        if let Some(k) = &self.skeleton {
            let (to, from) = (
                DMat4::from_translation(-self.origin),
                DMat4::from_translation(self.origin),
            );
            let m: Vec<f32> = k
                .joint_matrices(self.time)
                .iter()
                .flat_map(|m| (to * *m * from).as_mat4().to_cols_array())
                .collect();
            gpu.queue
                .write_buffer(&self.joints, 0, bytemuck::cast_slice(&m));
        }
        if let Some(e) = &mut self.extras {
            e.prepare(gpu, camera, light, format);
        }
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
                attr(4, wgpu::VertexFormat::Float32x3),
                attr(5, wgpu::VertexFormat::Float32x3),
                attr(6, wgpu::VertexFormat::Float32x3),
            ];
            let mut layouts: Vec<Option<wgpu::VertexBufferLayout>> = a
                .iter()
                .map(|a| {
                    Some(wgpu::VertexBufferLayout {
                        array_stride: a[0].format.size(),
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: a,
                    })
                })
                .collect();
            let skin = [
                wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x4,
                    offset: 0,
                    shader_location: 7,
                },
                wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x4,
                    offset: 16,
                    shader_location: 8,
                },
                wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x3,
                    offset: 32,
                    shader_location: 9,
                },
            ];
            layouts.push(Some(wgpu::VertexBufferLayout {
                array_stride: 44,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &skin,
            }));
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
        if let Some(e) = &self.extras {
            e.record(pass);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BakeParams, Preset};

    /// The reference's scatter and the bake's gather must give the same texture byte for byte:
    /// the cells law is evaluated with correctly rounded operations only.
    #[test]
    fn law_texture_matches_the_baked_mask_for_every_preset_and_odd_parameters() {
        let mut cases: Vec<StrandParams> = Preset::ALL
            .iter()
            .map(|&p| BakeParams::preset(p).strands)
            .collect();
        for (thickness, min_length, tpc, size, seed) in [
            (2.0, 0.0, 4, 32, 3),
            (0.05, 1.0, 2, 16, 9),
            (1.3, 0.2, 16, 32, 0xffff_ffff),
        ] {
            cases.push(StrandParams {
                model: StrandModel::Cells {
                    thickness,
                    min_length,
                    texels_per_cell: tpc,
                },
                mask_size: size,
                seed,
                ..BakeParams::default().strands
            });
        }
        for p in cases {
            let mask = strands::bake_mask(&p);
            let law = law_texture(&p);
            let alpha: Vec<u8> = law.iter().skip(3).step_by(4).copied().collect();
            let grey: Vec<u8> = law.iter().step_by(4).copied().collect();
            assert!(alpha == mask.alpha, "{:?}: alpha differs", p.model);
            assert!(grey == mask.shade, "{:?}: shade differs", p.model);
        }
    }
}
