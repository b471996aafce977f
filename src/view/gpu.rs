//! The GPU context, render targets, read-back, timing, and the frame uniforms (camera and light)
//! that the baked renderer and the runtime reference share.
//!
//! Renderers never draw to a window directly: they record into a render pass on a
//! `&TextureView` (wgpu's example-harness habit), so the window, the headless `render` command,
//! `verify` and the tests run the same drawing code. [`Target`] is the headless colour + depth
//! pair; the window supplies its surface texture's view instead.
//!
//! Colour targets are `*8UnormSrgb`: shaders write linear radiance and the hardware encodes sRGB,
//! so the PNG bytes read back are sRGB-encoded as PNG expects. Depth is `Depth32Float`, compare
//! `Less`, cleared to 1. MSAA is off: alpha-tested strands under MSAA depend on the coverage
//! rules of each GPU, and verify wants the exact per-pixel decision.
//!
//! Timing: with `TIMESTAMP_QUERY` the render pass writes begin/end timestamps and
//! [`Gpu::time_passes`] reports GPU milliseconds per frame; otherwise (or additionally) wall time
//! around submit-and-wait. lavapipe reports timestamps, but they measure a CPU rasterizer.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Mat4, Vec3, Vec4};
use image::RgbaImage;
use wgpu::util::DeviceExt as _;

use super::camera::Camera;
use super::glb::GlbError;

/// Errors of the viewer: bad file, no GPU, I/O.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Glb(#[from] GlbError),
    #[error("GPU: {0}")]
    Gpu(String),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
    #[error("window: {0}")]
    Window(String),
    #[error(transparent)]
    Load(#[from] crate::Error),
    #[error("verify failed: {0}")]
    Verify(String),
}

pub type Result<T> = std::result::Result<T, ViewError>;

/// Colour format of headless targets.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format of every target.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Linear clear colour (a dark neutral grey, so silhouettes of dark fur still show).
pub const CLEAR: wgpu::Color = wgpu::Color {
    r: 0.03,
    g: 0.035,
    b: 0.04,
    a: 1.0,
};

/// [`CLEAR`] as the 8-bit sRGB a headless picture holds where nothing was drawn.
pub fn clear_srgb8() -> [u8; 3] {
    [CLEAR.r, CLEAR.g, CLEAR.b].map(crate::srgb::encode8)
}

/// Instance, adapter, device and queue.
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Whether render passes can write timestamps.
    pub timestamps: bool,
}

impl Gpu {
    /// A headless context on the best adapter (`WGPU_BACKEND` etc. are honoured).
    pub fn new() -> Result<Gpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        Gpu::with_instance(instance, None)
    }

    /// A context on `instance` able to present to `surface` when given.
    pub fn with_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Gpu> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            ..Default::default()
        }))
        .map_err(|e| ViewError::Gpu(format!("no adapter: {e}")))?;
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("shellbake"),
            required_features,
            required_limits: wgpu::Limits {
                // a skinned compact layer with every effect binds nine streams
                max_vertex_buffers: adapter.limits().max_vertex_buffers.clamp(8, 16),
                ..wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits())
            },
            ..Default::default()
        }))
        .map_err(|e| ViewError::Gpu(format!("no device: {e}")))?;
        Ok(Gpu {
            instance,
            adapter,
            device,
            queue,
            timestamps,
        })
    }

    /// Adapter name and backend, e.g. "llvmpipe (LLVM 19.1.7, 256 bits) (Vulkan)".
    pub fn adapter_name(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?})", info.name, info.backend)
    }

    /// Blocks until the queue is idle.
    pub fn wait(&self) {
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }

    /// Runs `record` for `frames` render passes on `target`, each in its own submission, and
    /// returns the timing. `record` receives the encoder and the timestamp writes to pass to its
    /// render pass.
    pub fn time_passes(
        &self,
        frames: u32,
        mut record: impl FnMut(&mut wgpu::CommandEncoder, Option<wgpu::RenderPassTimestampWrites<'_>>),
    ) -> Timing {
        let frames = frames.max(1);
        let queries = self.timestamps.then(|| {
            let set = self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * frames,
            });
            let size = 16 * frames as u64;
            let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps read"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        self.wait();
        let start = Instant::now();
        let mut cpu = std::time::Duration::ZERO;
        for f in 0..frames {
            let recording = Instant::now();
            let mut encoder = self.device.create_command_encoder(&Default::default());
            let ts = queries
                .as_ref()
                .map(|(set, _, _)| wgpu::RenderPassTimestampWrites {
                    query_set: set,
                    beginning_of_pass_write_index: Some(2 * f),
                    end_of_pass_write_index: Some(2 * f + 1),
                });
            record(&mut encoder, ts);
            self.queue.submit([encoder.finish()]);
            cpu += recording.elapsed();
        }
        self.wait();
        let wall_ms = start.elapsed().as_secs_f64() * 1e3 / frames as f64;
        let gpu_ms = queries.map(|(set, resolve, read)| {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.resolve_query_set(&set, 0..2 * frames, &resolve, 0);
            encoder.copy_buffer_to_buffer(&resolve, 0, &read, 0, 16 * frames as u64);
            self.queue.submit([encoder.finish()]);
            let stamps = self.read_buffer(&read);
            let ticks: Vec<u64> = stamps
                .chunks_exact(8)
                .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
                .collect();
            let period = self.queue.get_timestamp_period() as f64;
            let total: f64 = ticks
                .chunks_exact(2)
                .map(|p| p[1].saturating_sub(p[0]) as f64 * period)
                .sum();
            total / frames as f64 / 1e6
        });
        Timing {
            frames,
            gpu_ms,
            wall_ms,
            cpu_ms: cpu.as_secs_f64() * 1e3 / frames as f64,
        }
    }

    /// Maps a `MAP_READ` buffer and copies its bytes out.
    pub fn read_buffer(&self, buffer: &wgpu::Buffer) -> Vec<u8> {
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.wait();
        rx.recv()
            .expect("map callback ran")
            .expect("mapping a read-back buffer");
        let bytes = buffer.get_mapped_range(..).expect("mapped").to_vec();
        buffer.unmap();
        bytes
    }

    /// Copies a 4-byte-per-texel texture into an RGBA image (BGRA is swizzled).
    pub fn read_texture(&self, texture: &wgpu::Texture) -> RgbaImage {
        let (w, h) = (texture.width(), texture.height());
        let row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: row as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        );
        self.queue.submit([encoder.finish()]);
        let bytes = self.read_buffer(&buffer);
        let bgra = matches!(
            texture.format(),
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        );
        let mut out = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h as usize {
            let line = &bytes[y * row as usize..y * row as usize + w as usize * 4];
            for px in line.chunks_exact(4) {
                if bgra {
                    out.extend_from_slice(&[px[2], px[1], px[0], px[3]]);
                } else {
                    out.extend_from_slice(px);
                }
            }
        }
        RgbaImage::from_raw(w, h, out).expect("sized buffer")
    }
}

/// Frame timing of [`Gpu::time_passes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    pub frames: u32,
    /// Mean GPU time of one render pass, from timestamp queries, when the adapter has them.
    pub gpu_ms: Option<f64>,
    /// Mean wall time per frame, submit to completion.
    pub wall_ms: f64,
    /// Mean CPU time per frame to record its commands and submit them (encoder, render pass,
    /// every draw, `finish`, `submit`), the GPU's work not waited for: what draw calls cost the
    /// application's thread.
    pub cpu_ms: f64,
}

/// A headless colour + depth target.
pub struct Target {
    pub color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
}

impl Target {
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Target {
        let color = render_texture(
            gpu,
            "colour",
            (width, height),
            COLOR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let color_view = color.create_view(&Default::default());
        let depth_view = depth_texture(gpu, width, height).create_view(&Default::default());
        Target {
            color,
            color_view,
            depth_view,
        }
    }

    pub fn read(&self, gpu: &Gpu) -> RgbaImage {
        gpu.read_texture(&self.color)
    }
}

/// A depth texture of the given size.
pub fn depth_texture(gpu: &Gpu, width: u32, height: u32) -> wgpu::Texture {
    render_texture(
        gpu,
        "depth",
        (width, height),
        DEPTH_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    )
}

/// A single-sample, single-mip 2D texture to render into.
fn render_texture(
    gpu: &Gpu,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// Begins the render pass every renderer draws in: clear colour and depth.
pub fn begin_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("scene"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(CLEAR),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: timestamps,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// One directional light and a constant ambient term, in linear RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Unit vector towards the light, world space.
    pub direction: Vec3,
    /// Radiance scale of the directional light.
    pub color: Vec3,
    /// Ambient radiance multiplying the base colour.
    pub ambient: Vec3,
}

impl Default for Light {
    /// A key light from above-front-right; irradiance π·0.95 so that a white Lambertian surface
    /// facing it reads 0.95, ambient 0.2.
    fn default() -> Self {
        Light {
            direction: Vec3::new(0.35, 0.85, 0.4).normalize(),
            color: Vec3::splat(std::f32::consts::PI * 0.95),
            ambient: Vec3::splat(0.2),
        }
    }
}

/// Which mip chain [`upload_rgba_texture`] builds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mips {
    /// Level 0 only.
    None,
    /// Every channel box filtered ([`crate::stages::strands::box_mips`]).
    Box,
    /// Colour box filtered, alpha remapped to keep its coverage at every cutoff
    /// ([`crate::stages::strands::coverage_mips`]): textures that `MASK` materials alpha-test.
    CoverageAlpha,
}

/// Uploads RGBA8 pixels (row 0 first) as an `Rgba8UnormSrgb` texture with the mip chain `mips`
/// asks for. Both renderers upload their strand textures through here, so baked and reference
/// sample identical levels.
pub fn upload_rgba_texture(
    gpu: &Gpu,
    width: u32,
    height: u32,
    rgba: &[u8],
    mips: Mips,
) -> wgpu::TextureView {
    assert_eq!(rgba.len(), (width * height * 4) as usize);
    let mut data = rgba.to_vec();
    let mut levels = 1;
    if mips != Mips::None {
        let channel = |c: usize| rgba.iter().skip(c).step_by(4).copied().collect::<Vec<u8>>();
        let [r, g, b, a]: [Vec<Vec<u8>>; 4] = std::array::from_fn(|c| {
            if c == 3 && mips == Mips::CoverageAlpha {
                crate::stages::strands::coverage_mips(&channel(c), width, height)
            } else {
                crate::stages::strands::box_mips(&channel(c), width, height)
            }
        });
        levels += r.len() as u32;
        for (((r, g), b), a) in r.iter().zip(&g).zip(&b).zip(&a) {
            for (((&r, &g), &b), &a) in r.iter().zip(g).zip(b).zip(a) {
                data.extend_from_slice(&[r, g, b, a]);
            }
        }
    }
    let texture = gpu.device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some("base colour"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &data,
    );
    texture.create_view(&Default::default())
}

/// A read-only storage buffer the vertex stage reads (joint matrices) at `binding`.
pub fn vertex_storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// Bind group layout entry of a filterable 2D texture read by the fragment stage.
pub fn fragment_texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// Bind group layout entry of a filtering sampler used by the fragment stage.
pub fn fragment_sampler_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// The WGSL both renderers include: frame uniforms (group 0) and the metallic-roughness BRDF.
pub const COMMON_WGSL: &str = include_str!("common.wgsl");

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameData {
    view_proj: [f32; 16],
    eye: [f32; 4],
    light_dir: [f32; 4],
    light_color: [f32; 4],
    ambient: [f32; 4],
}

/// The frame uniform buffer and its bind group (group 0 of both renderers' pipelines).
pub struct Frame {
    pub layout: wgpu::BindGroupLayout,
    buffer: wgpu::Buffer,
    pub bind_group: wgpu::BindGroup,
}

impl Frame {
    pub fn new(gpu: &Gpu) -> Frame {
        let layout = gpu
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("frame"),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                }],
            });
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameData>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: buffer.as_entire_binding(),
            }],
        });
        Frame {
            layout,
            buffer,
            bind_group,
        }
    }

    /// Writes the camera (anchor-relative) and the light.
    pub fn write(&self, gpu: &Gpu, camera: &Camera, light: &Light) {
        let vp: Mat4 = camera.gpu_view_projection();
        let data = FrameData {
            view_proj: vp.to_cols_array(),
            eye: camera.gpu_eye().extend(1.0).to_array(),
            light_dir: light.direction.normalize().extend(0.0).to_array(),
            light_color: light.color.extend(0.0).to_array(),
            ambient: Vec4::from((light.ambient, 0.0)).to_array(),
        };
        gpu.queue
            .write_buffer(&self.buffer, 0, bytemuck::bytes_of(&data));
    }
}

/// Writes `image` as PNG to `path` (atomically).
pub fn save_png(image: &RgbaImage, path: &Path) -> Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|source| ViewError::Image {
            path: path.to_path_buf(),
            source,
        })?;
    crate::output::write::write_atomic(path, &bytes).map_err(|e| ViewError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })
}

/// A pipeline's primitive and depth state: triangles, CCW front faces, depth `Less`.
pub fn primitive_state(cull: bool, mirrored: bool) -> wgpu::PrimitiveState {
    wgpu::PrimitiveState {
        topology: wgpu::PrimitiveTopology::TriangleList,
        front_face: if mirrored {
            wgpu::FrontFace::Cw
        } else {
            wgpu::FrontFace::Ccw
        },
        cull_mode: cull.then_some(wgpu::Face::Back),
        ..Default::default()
    }
}

pub fn depth_state(write: bool) -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: Default::default(),
        bias: Default::default(),
    }
}
