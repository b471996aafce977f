//! The glTF renderer: draws a parsed [`Asset`] (the subset shellbake writes, and the general
//! features listed in `glb.rs`) into a render pass.
//!
//! ## Resources
//! Every accessor is decoded to `f32` and uploaded once, keyed by accessor index, so the compact
//! layout's layers (one mesh per layer, all sharing one POSITION/NORMAL/TEXCOORD_0/delta/index
//! set) cost one upload. Per draw, a slot of one uniform buffer (bound with a dynamic offset,
//! 512 bytes: the data rounded up to the 256-byte offset alignment every device allows)
//! holds the model and normal matrices, the material factors, the `KHR_texture_transform` rows
//! and the morph weights; per material, a bind group holds its base colour texture (`*Srgb`, so
//! the sampler returns linear colour and untouched alpha) and sampler, or a 1×1 white texture.
//!
//! ## Texture filtering
//! The file's sampler is honoured: mag and min filters, and for a mipmapped min filter a mip
//! chain built on upload (the fragment shader samples with implicit derivatives). glTF leaves
//! mip generation to the client; the viewer box filters colour, and for a texture that a `MASK`
//! material alpha-tests it remaps each alpha level to keep level 0's coverage at every cutoff
//! (`strands::coverage_mips`), as engines with coverage-preserving alpha mips do — otherwise
//! alpha-tested fur thins out with distance. The runtime reference uploads its law texture
//! through the same function ([`gpu::upload_rgba_texture`]), so both sample the same levels.
//! [`MaskMips::Box`] builds plain box-filtered alpha mips instead, as three.js (WebGL's
//! `generateMipmap`) does, for comparing with such clients.
//!
//! ## Pipelines
//! One pipeline per (morph target count, COLOR_0 present, BLEND, culled, mirrored, target
//! format), built on first use. The WGSL is specialised by text substitution rather than by
//! binding zero streams for absent attributes: a primitive fetches only what it has, which keeps
//! the GPU timings of the two layouts honest. Back faces are culled unless `doubleSided`; a
//! world matrix with negative determinant flips the front face (glTF 3.7.4).
//!
//! ## Order
//! OPAQUE draws first, then MASK, then BLEND (unsorted, no depth write — shellbake writes no
//! BLEND materials, so no sorting was built), each class in file order. With depth test `Less`,
//! alpha-tested layers give the same picture in any order except on exact depth ties, where file
//! order (inner layer first) wins — the same order the runtime reference draws its instances in.
//!
//! ## Layers and LODs
//! [`GltfRenderer::set_layer_limit`] shows layers `0..=k`: in a compact file layer `j` is the
//! `j`-th child of the shellbake node; in a single-draw file (one primitive, indices ordered
//! inner to outer, `extras.shellbake.layers` = L) it is the first `(k+1)/L` of the index range.
//! [`GltfRenderer::set_lod`] selects `MSFT_lod` alternatives.

use std::collections::HashMap;

use glam::{DMat3, DMat4, DVec3};
use wgpu::util::DeviceExt as _;

use super::camera::{Camera, Sphere};
use super::glb::{AlphaMode, Asset, Material, MipFilter, SamplerDesc, Wrap, MAX_MORPH_TARGETS};
use super::gpu::{self, Frame, Gpu, Light, Result};

/// Bytes of one draw's uniform slot: its data, at an offset every device can bind.
const DRAW_SLOT: u64 = (std::mem::size_of::<DrawData>() as u64).next_multiple_of(256);
const WGSL: &str = include_str!("gltf.wgsl");

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DrawData {
    model: [f32; 16],
    normal_matrix: [f32; 16],
    base_color: [f32; 4],
    uv_row0: [f32; 4],
    uv_row1: [f32; 4],
    weights: [f32; MAX_MORPH_TARGETS],
    material: [f32; 4],
    emissive: [f32; 4],
    /// `KHR_materials_sheen` colour and roughness (zero: none).
    sheen: [f32; 4],
    /// x: the weight of the `COLOR_0` morph target.
    color_weight: [f32; 4],
}

/// The shader location of morph target `t`: 4–7 for the first four, 11–14 for the rest (8 holds
/// the `COLOR_0` target, 9 and 10 the skin).
fn target_location(t: usize) -> u32 {
    if t < 4 {
        4 + t as u32
    } else {
        7 + t as u32
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Key {
    targets: usize,
    color: bool,
    /// The target index of a `COLOR_0` morph target.
    color_target: Option<usize>,
    skinned: bool,
    blend: bool,
    cull: bool,
    mirrored: bool,
    format: wgpu::TextureFormat,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Class {
    Opaque,
    Mask,
    Blend,
}

struct DrawCall {
    world: DMat4,
    weights: [f32; MAX_MORPH_TARGETS],
    color_weight: f32,
    material: Material,
    material_group: usize,
    position: usize,
    normal: Stream,
    texcoord: Stream,
    color: Option<usize>,
    targets: Vec<usize>,
    color_target: Option<(usize, usize)>,
    /// `JOINTS_0` and `WEIGHTS_0`, and the instance's joint matrices.
    skin: Option<((usize, usize), Vec<DMat4>)>,
    indices: Option<usize>,
    /// Indices (or vertices when unindexed) of the whole primitive.
    elements: u32,
    /// Single-draw: the end of each layer's indices (`extras.shellbake_layers`).
    layer_ends: Vec<u32>,
    class: Class,
    layer: usize,
}

#[derive(Clone, Copy)]
enum Stream {
    Accessor(usize),
    /// Absent: zeros of this many components for the vertex count.
    Zeros(u64, usize),
}

/// Draws a glTF asset.
pub struct GltfRenderer {
    pub asset: Asset,
    frame: Frame,
    draw_layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    shaders: HashMap<(usize, bool, Option<usize>, bool), wgpu::ShaderModule>,
    pipelines: HashMap<Key, wgpu::RenderPipeline>,
    buffers: HashMap<usize, wgpu::Buffer>,
    /// `COLOR_0` interleaved with its morph target (stride 32), by the two accessors: one vertex
    /// buffer for both keeps the most a primitive binds within wgpu's eight.
    color_pairs: HashMap<(usize, usize), wgpu::Buffer>,
    /// `JOINTS_0` interleaved with `WEIGHTS_0` (stride 32), likewise.
    skin_pairs: HashMap<(usize, usize), wgpu::Buffer>,
    /// The joint matrices of every skinned draw (group 3), written by `prepare`.
    joints_layout: wgpu::BindGroupLayout,
    joints_buffer: wgpu::Buffer,
    joints_group: wgpu::BindGroup,
    zeros: HashMap<(u64, usize), wgpu::Buffer>,
    index_buffers: HashMap<usize, wgpu::Buffer>,
    /// Elements of the index buffers made for strips and fans (keyed as in `index_buffers`).
    strip_elements: HashMap<usize, u32>,
    material_groups: Vec<wgpu::BindGroup>,
    draw_buffer: wgpu::Buffer,
    draw_group: wgpu::BindGroup,
    draws: Vec<DrawCall>,
    /// A level forced everywhere, or `None`: by distance.
    lod: Option<usize>,
    switches: Vec<crate::view::glb::LodSwitch>,
    /// Current level of each switch.
    picks: Vec<usize>,
    /// One switch held at one level while the others pick by distance.
    pinned: Option<(usize, usize)>,
    layer_limit: Option<usize>,
    format: Option<wgpu::TextureFormat>,
    /// Bounding sphere of LOD 0, morph extents included.
    pub bounds: Sphere,
}

/// How the viewer builds the alpha mips of a texture that a `MASK` material tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaskMips {
    /// Each level keeps level 0's coverage at every cutoff (`strands::coverage_mips`), as
    /// engines with coverage-preserving alpha mips do: fur keeps its density with distance.
    #[default]
    CoveragePreserving,
    /// Plain box filtering, what WebGL's `generateMipmap` (three.js) and most clients do:
    /// alpha-tested fur thins out with distance. For comparing with such clients.
    Box,
}

impl GltfRenderer {
    /// Uploads `asset`, with coverage-preserving alpha mips for alpha-tested textures.
    pub fn new(gpu: &Gpu, asset: Asset) -> Result<GltfRenderer> {
        GltfRenderer::with_mask_mips(gpu, asset, MaskMips::default())
    }

    /// Uploads `asset`, building the alpha mips of alpha-tested textures as `mask_mips` says.
    pub fn with_mask_mips(gpu: &Gpu, asset: Asset, mask_mips: MaskMips) -> Result<GltfRenderer> {
        let device = &gpu.device;
        let frame = Frame::new(gpu);
        let draw_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("draw"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<DrawData>() as u64),
                },
                count: None,
            }],
        });
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("material"),
            entries: &[
                super::gpu::fragment_texture_entry(0),
                super::gpu::fragment_sampler_entry(1),
            ],
        });
        let joints_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("joints"),
            entries: &[super::gpu::vertex_storage_entry(0)],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gltf"),
            bind_group_layouts: &[
                Some(&frame.layout),
                Some(&draw_layout),
                Some(&material_layout),
                Some(&joints_layout),
            ],
            immediate_size: 0,
        });

        // Textures: one GPU texture per glTF texture, plus white for untextured materials. A
        // mipmapped sampler gets a mip chain; the alpha of a texture that a MASK material tests
        // keeps its coverage at every cutoff (see the module notes).
        let white = gpu::upload_rgba_texture(gpu, 1, 1, &[255; 4], gpu::Mips::None);
        // A texture the viewer could not decode (`None`) binds white: its material draws from
        // its factor.
        let textures: Vec<Option<(wgpu::TextureView, wgpu::Sampler)>> = asset
            .textures
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let t = t.as_ref()?;
                let alpha_tested = asset
                    .materials
                    .iter()
                    .any(|m| m.texture == Some(i) && matches!(m.alpha, AlphaMode::Mask(_)));
                let mips = match (t.sampler.mip, alpha_tested, mask_mips) {
                    (None, _, _) => gpu::Mips::None,
                    (Some(_), true, MaskMips::CoveragePreserving) => gpu::Mips::CoverageAlpha,
                    (Some(_), _, _) => gpu::Mips::Box,
                };
                Some((
                    gpu::upload_rgba_texture(gpu, t.width, t.height, &t.rgba, mips),
                    make_sampler(gpu, t.sampler),
                ))
            })
            .collect();
        let default_sampler = make_sampler(gpu, SamplerDesc::default());
        let group = |view: &wgpu::TextureView, sampler: &wgpu::Sampler| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("material"),
                layout: &material_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Sampler(sampler),
                    },
                ],
            })
        };
        let mut material_groups: Vec<wgpu::BindGroup> = asset
            .materials
            .iter()
            .map(
                |m| match m.texture.and_then(|t| textures.get(t)?.as_ref()) {
                    Some((view, sampler)) => group(view, sampler),
                    // none, an index the document's checks do not cover (an extension's), or a
                    // texture that could not be decoded
                    None => group(&white, &default_sampler),
                },
            )
            .collect();
        material_groups.push(group(&white, &default_sampler)); // the default material

        let bounds = match asset.bounds()? {
            Some((lo, hi)) => Sphere::around_box(lo, hi),
            None => Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
        };
        let draw_buffer = make_draw_buffer(gpu, 1);
        let draw_group = make_draw_group(gpu, &draw_layout, &draw_buffer);
        let (joints_buffer, joints_group) = make_joints(gpu, &joints_layout, 1);
        let mut r = GltfRenderer {
            asset,
            frame,
            draw_layout,
            pipeline_layout,
            shaders: HashMap::new(),
            pipelines: HashMap::new(),
            buffers: HashMap::new(),
            color_pairs: HashMap::new(),
            skin_pairs: HashMap::new(),
            joints_layout,
            joints_buffer,
            joints_group,
            zeros: HashMap::new(),
            index_buffers: HashMap::new(),
            strip_elements: HashMap::new(),
            material_groups,
            draw_buffer,
            draw_group,
            draws: Vec::new(),
            lod: None,
            switches: Vec::new(),
            picks: Vec::new(),
            pinned: None,
            layer_limit: None,
            format: None,
            bounds,
        };
        r.switches = r.asset.lod_switches()?;
        r.picks = vec![0; r.switches.len()];
        // every level once: a broken level fails here, not when the camera moves
        for k in 1..=r.lod_levels() {
            r.lod = Some(k);
            r.build_draws(gpu)?;
        }
        r.lod = None;
        r.build_draws(gpu)?;
        Ok(r)
    }

    /// Parses and uploads GLB bytes this process baked ([`Asset::from_own_glb`]: `verify`,
    /// `study` and `bench` draw the bake they just made).
    pub fn from_glb(gpu: &Gpu, glb: &[u8]) -> Result<GltfRenderer> {
        GltfRenderer::new(gpu, Asset::from_own_glb(glb)?)
    }

    /// Number of shell layers (or top-level meshes) the layer limit steps through.
    pub fn layer_count(&self) -> usize {
        self.asset
            .shell_layers
            .unwrap_or_else(|| self.draws.iter().map(|d| d.layer + 1).max().unwrap_or(0))
    }

    /// Shows layers `0..=k` only (`None`: all).
    pub fn set_layer_limit(&mut self, k: Option<usize>) {
        self.layer_limit = k;
    }

    pub fn lod_levels(&self) -> usize {
        self.asset.lod_levels()
    }

    /// Draws `MSFT_lod` level `lod` everywhere (0 = the full asset); `None`: each node's level
    /// by its distance from the camera, as the file's `extras.shellbake_lod` says (the
    /// default).
    /// Takes animated morph weights at `time` seconds (`None`: the file's static weights).
    pub fn set_time(&mut self, gpu: &Gpu, time: Option<f32>) -> Result<()> {
        self.asset.time = time;
        self.build_draws(gpu)
    }

    /// Whether the file animates anything the renderer draws.
    pub fn animated(&self) -> bool {
        self.asset.animations.iter().any(|a| !a.is_empty()) || !self.asset.clips.is_empty()
    }

    pub fn set_lod(&mut self, gpu: &Gpu, lod: Option<usize>) -> Result<()> {
        self.lod = lod.map(|l| l.min(self.lod_levels()));
        self.pinned = None;
        self.build_draws(gpu)
    }

    /// Picks levels by distance, except switch `pin.0` (an index into
    /// [`GltfRenderer::lod_switches`]) held at level `pin.1`: one chunk's level seen among its
    /// neighbours as a viewer would draw them.
    /// The draws follow at the next frame.
    pub fn pin_lod(&mut self, pin: Option<(usize, usize)>) {
        self.lod = None;
        self.pinned = pin;
        self.picks.clear();
    }

    /// The nodes whose level is picked by distance.
    pub fn lod_switches(&self) -> &[crate::view::glb::LodSwitch] {
        &self.switches
    }

    /// The level each distance-switched node draws now (empty when a level is forced or the
    /// file has none).
    pub fn lod_picks(&self) -> &[usize] {
        &self.picks
    }

    /// Picks each node's level for a camera at `eye`; rebuilds the draws when a pick changed.
    fn pick_lods(&mut self, gpu: &Gpu, eye: glam::DVec3) -> Result<()> {
        if self.lod.is_some() || self.switches.is_empty() {
            return Ok(());
        }
        let picks: Vec<usize> = self
            .switches
            .iter()
            .enumerate()
            .map(|(i, s)| match self.pinned {
                Some((p, level)) if p == i => level.min(s.distances.len() - 1),
                _ => s.level_at(eye),
            })
            .collect();
        if picks != self.picks {
            self.picks = picks;
            self.build_draws(gpu)?;
        }
        Ok(())
    }

    /// Elements drawn of each draw call under the current layer limit (0 = skipped).
    fn visible_elements(&self) -> Vec<u32> {
        self.draws
            .iter()
            .map(|d| match self.layer_limit {
                None => d.elements,
                Some(k) if !d.layer_ends.is_empty() => {
                    d.layer_ends[k.min(d.layer_ends.len() - 1)].min(d.elements)
                }
                Some(k) => {
                    if d.layer <= k {
                        d.elements
                    } else {
                        0
                    }
                }
            })
            .collect()
    }

    /// Triangles drawn per frame under the current layer limit and LOD.
    pub fn triangles(&self) -> usize {
        self.visible_elements()
            .iter()
            .map(|&e| e as usize / 3)
            .sum()
    }

    /// Draw calls per frame under the current layer limit and LOD.
    pub fn draw_calls(&self) -> usize {
        self.visible_elements().iter().filter(|&&e| e > 0).count()
    }

    fn build_draws(&mut self, gpu: &Gpu) -> Result<()> {
        let mut draws = Vec::new();
        let instances = match self.lod {
            Some(lod) => self.asset.instances(lod)?,
            None => self.asset.instances_with(|n| {
                match self.switches.iter().position(|s| s.nodes.contains(&n)) {
                    Some(i) => self
                        .asset
                        .lod_node(n, self.picks.get(i).copied().unwrap_or(0)),
                    None => n,
                }
            })?,
        };
        for inst in instances {
            let mesh = &self.asset.meshes[inst.mesh];
            for (p, prim) in mesh.primitives.iter().enumerate() {
                let material = prim
                    .material
                    .map(|m| self.asset.materials[m].clone())
                    .unwrap_or_default();
                let material_group = prim.material.unwrap_or(self.asset.materials.len());
                let vertices = self.asset.floats(prim.position)?.count();
                let mut accessors: Vec<usize> = vec![prim.position];
                accessors.extend(prim.normal);
                accessors.extend(prim.texcoord);
                accessors.extend(prim.color);
                accessors.extend(&prim.targets);
                // a colour target without a base colour would be invalid glTF: ignored
                let color_target = prim.color_target.filter(|_| prim.color.is_some());
                for a in accessors {
                    if !self.buffers.contains_key(&a) {
                        let f = self.asset.floats(a)?;
                        let data = if Some(a) == prim.color {
                            rgba(f, 1.0)
                        } else {
                            f.data
                        };
                        self.buffers.insert(a, vertex_buffer(gpu, &data));
                    }
                }
                let skin = prim.skin.zip(inst.joints.clone());
                if let Some(((j, w), _)) = &skin {
                    if !self.skin_pairs.contains_key(&(*j, *w)) {
                        let (joints, weights) = (self.asset.floats(*j)?, self.asset.floats(*w)?);
                        let data: Vec<f32> = joints
                            .data
                            .chunks_exact(4)
                            .zip(weights.data.chunks_exact(4))
                            .flat_map(|(j, w)| {
                                let w = super::glb::normalized_weights(w);
                                j.iter().copied().chain(w).collect::<Vec<_>>()
                            })
                            .collect();
                        self.skin_pairs.insert((*j, *w), vertex_buffer(gpu, &data));
                    }
                }
                if let (Some(c), Some((_, t))) = (prim.color, color_target) {
                    if !self.color_pairs.contains_key(&(c, t)) {
                        let base = rgba(self.asset.floats(c)?, 1.0);
                        let delta = rgba(self.asset.floats(t)?, 0.0);
                        let mut data = Vec::with_capacity(base.len() * 2);
                        for (b, d) in base.chunks_exact(4).zip(delta.chunks_exact(4)) {
                            data.extend_from_slice(b);
                            data.extend_from_slice(d);
                        }
                        self.color_pairs.insert((c, t), vertex_buffer(gpu, &data));
                    }
                }
                let normal = match prim.normal {
                    Some(a) => Stream::Accessor(a),
                    None => Stream::Zeros(3, vertices),
                };
                let texcoord = match prim.texcoord {
                    Some(a) => Stream::Accessor(a),
                    None => Stream::Zeros(2, vertices),
                };
                for s in [normal, texcoord] {
                    if let Stream::Zeros(c, n) = s {
                        self.zeros.entry((c, n)).or_insert_with(|| {
                            vertex_buffer(gpu, &vec![0.0; c as usize * n.max(1)])
                        });
                    }
                }
                // a strip or a fan: its triangle list, in an index buffer of its own (keyed past
                // every accessor)
                let strip_key = (prim.mode != 4)
                    .then(|| self.asset.doc.accessors.len() + (inst.mesh << 16) + p);
                if let Some(key) = strip_key {
                    if !self.index_buffers.contains_key(&key) {
                        let order: Vec<u32> = match prim.indices {
                            Some(a) => self.asset.indices(a)?,
                            None => (0..vertices as u32).collect(),
                        };
                        let ix = crate::input::triangle_list(prim.mode, &order);
                        if let Some(bad) = ix.iter().find(|&&i| i as usize >= vertices) {
                            return Err(crate::Error::invalid(
                                &self.asset.doc.path,
                                format!("mesh {} primitive {p}", inst.mesh),
                                format!("index {bad} is out of range ({vertices} vertices)"),
                            )
                            .into());
                        }
                        let buf =
                            gpu.device
                                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                                    label: Some("strip indices"),
                                    contents: bytemuck::cast_slice(if ix.is_empty() {
                                        &[0u32; 3][..]
                                    } else {
                                        &ix
                                    }),
                                    usage: wgpu::BufferUsages::INDEX,
                                });
                        self.strip_elements.insert(key, ix.len() as u32);
                        self.index_buffers.insert(key, buf);
                    }
                }
                let elements = match (strip_key, prim.indices) {
                    (Some(key), _) => self.strip_elements[&key],
                    (None, Some(a)) => {
                        if !self.index_buffers.contains_key(&a) {
                            let ix = self.asset.indices(a)?;
                            if let Some(bad) = ix.iter().find(|&&i| i as usize >= vertices) {
                                return Err(crate::Error::invalid(
                                    &self.asset.doc.path,
                                    format!("index accessor {a}"),
                                    format!("index {bad} is out of range ({vertices} vertices)"),
                                )
                                .into());
                            }
                            let buf =
                                gpu.device
                                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                                        label: Some("indices"),
                                        contents: bytemuck::cast_slice(&ix),
                                        usage: wgpu::BufferUsages::INDEX,
                                    });
                            self.index_buffers.insert(a, buf);
                        }
                        self.asset.indices(a)?.len() as u32
                    }
                    (None, None) => vertices as u32,
                };
                let mut weights = [0.0; MAX_MORPH_TARGETS];
                for (i, w) in weights.iter_mut().enumerate().take(prim.targets.len()) {
                    *w = inst.weights.get(i).copied().unwrap_or(0.0);
                }
                // the colour target's weight rides in the material vector's spare slot
                let color_weight =
                    color_target.map_or(0.0, |(i, _)| inst.weights.get(i).copied().unwrap_or(0.0));
                let class = match material.alpha {
                    AlphaMode::Opaque => Class::Opaque,
                    AlphaMode::Mask(_) => Class::Mask,
                    AlphaMode::Blend => Class::Blend,
                };
                draws.push(DrawCall {
                    world: inst.world,
                    weights,
                    color_weight,
                    material,
                    material_group,
                    position: prim.position,
                    normal,
                    texcoord,
                    color: prim.color,
                    targets: prim.targets.clone(),
                    color_target,
                    skin,
                    indices: strip_key.or(prim.indices),
                    elements: elements - elements % 3,
                    layer_ends: self.asset.meshes[inst.mesh].layer_ends.clone(),
                    class,
                    layer: inst.sibling,
                });
            }
        }
        draws.sort_by_key(|d| d.class);
        if draws.len() as u64 * DRAW_SLOT > self.draw_buffer.size() {
            self.draw_buffer = make_draw_buffer(gpu, draws.len());
            self.draw_group = make_draw_group(gpu, &self.draw_layout, &self.draw_buffer);
        }
        self.draws = draws;
        Ok(())
    }

    fn key(&self, d: &DrawCall, format: wgpu::TextureFormat) -> Key {
        Key {
            targets: d.targets.len(),
            color: d.color.is_some(),
            color_target: d.color_target.map(|c| c.0),
            skinned: d.skin.is_some(),
            blend: d.class == Class::Blend,
            cull: !d.material.double_sided,
            mirrored: DMat3::from_mat4(d.world).determinant() < 0.0,
            format,
        }
    }

    /// Writes the camera, light and per-draw uniforms and builds the pipelines for `format`.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        camera: &Camera,
        light: &Light,
        format: wgpu::TextureFormat,
    ) {
        self.pick_lods(gpu, camera.eye)
            .expect("every level was built when the asset was opened");
        self.frame.write(gpu, camera, light);
        let anchor = DMat4::from_translation(-camera.anchor());
        let mut bytes = vec![0u8; self.draws.len() * DRAW_SLOT as usize];
        let mut joints: Vec<f32> = Vec::new();
        for (i, d) in self.draws.iter().enumerate() {
            let joint_offset = (joints.len() / 16) as f32;
            if let Some((_, m)) = &d.skin {
                joints.extend(m.iter().flat_map(|m| m.as_mat4().to_cols_array()));
            }
            let model = anchor * d.world;
            let normal = DMat4::from_mat3(DMat3::from_mat4(d.world).inverse().transpose());
            let m = &d.material;
            let (cutoff, mode) = match m.alpha {
                AlphaMode::Opaque => (0.0, 0.0),
                AlphaMode::Mask(c) => (c, 1.0),
                AlphaMode::Blend => (0.0, 2.0),
            };
            let flat = matches!(d.normal, Stream::Zeros(..));
            let data = DrawData {
                model: model.as_mat4().to_cols_array(),
                normal_matrix: normal.as_mat4().to_cols_array(),
                base_color: m.base_color,
                uv_row0: [
                    m.uv_transform[0][0],
                    m.uv_transform[0][1],
                    m.uv_transform[0][2],
                    0.0,
                ],
                uv_row1: [
                    m.uv_transform[1][0],
                    m.uv_transform[1][1],
                    m.uv_transform[1][2],
                    0.0,
                ],
                weights: d.weights,
                color_weight: [d.color_weight, joint_offset, m.unlit as u8 as f32, 0.0],
                sheen: m.sheen.unwrap_or([0.0; 4]),
                material: [m.metallic, m.roughness, cutoff, mode],
                emissive: [
                    m.emissive[0],
                    m.emissive[1],
                    m.emissive[2],
                    if flat { 1.0 } else { 0.0 },
                ],
            };
            let o = i * DRAW_SLOT as usize;
            bytes[o..o + std::mem::size_of::<DrawData>()]
                .copy_from_slice(bytemuck::bytes_of(&data));
        }
        if !bytes.is_empty() {
            gpu.queue.write_buffer(&self.draw_buffer, 0, &bytes);
        }
        if !joints.is_empty() {
            if (joints.len() * 4) as u64 > self.joints_buffer.size() {
                (self.joints_buffer, self.joints_group) =
                    make_joints(gpu, &self.joints_layout, joints.len() / 16);
            }
            gpu.queue
                .write_buffer(&self.joints_buffer, 0, bytemuck::cast_slice(&joints));
        }
        for i in 0..self.draws.len() {
            let key = self.key(&self.draws[i], format);
            if !self.pipelines.contains_key(&key) {
                let p = self.build_pipeline(gpu, key);
                self.pipelines.insert(key, p);
            }
        }
        self.format = Some(format);
    }

    fn build_pipeline(&mut self, gpu: &Gpu, key: Key) -> wgpu::RenderPipeline {
        let module = self
            .shaders
            .entry((key.targets, key.color, key.color_target, key.skinned))
            .or_insert_with(|| {
                let mut inputs = String::new();
                let mut morph = String::new();
                let mut skin = String::new();
                if key.skinned {
                    inputs.push_str("    @location(9) joints: vec4<f32>,\n");
                    inputs.push_str("    @location(10) weights: vec4<f32>,\n");
                    skin.push_str(concat!(
                        "    let first = u32(draw.color_weight.y);\n",
                        "    let j = vec4<u32>(in.joints) + vec4<u32>(first);\n",
                        "    let skin = joint_matrices[j.x] * in.weights.x + joint_matrices[j.y] * in.weights.y\n",
                        "        + joint_matrices[j.z] * in.weights.z + joint_matrices[j.w] * in.weights.w;\n",
                        "    p = (skin * vec4<f32>(p, 1.0)).xyz;\n",
                        "    nrm = (skin * vec4<f32>(nrm, 0.0)).xyz;\n",
                    ));
                }
                if key.color {
                    inputs.push_str("    @location(3) color: vec4<f32>,\n");
                }
                for t in 0..key.targets {
                    let at = target_location(t);
                    inputs.push_str(&format!("    @location({at}) target{t}: vec3<f32>,\n"));
                    let (row, k) = (t / 4, t % 4);
                    morph.push_str(&format!("    p += in.target{t} * draw.weights[{row}][{k}];\n"));
                }
                let color = match (key.color, key.color_target) {
                    (true, Some(_)) => {
                        inputs.push_str("    @location(8) color_target: vec4<f32>,\n");
                        "    out.color = in.color + in.color_target * draw.color_weight.x;\n"
                    }
                    (true, None) => "    out.color = in.color;\n",
                    _ => "    out.color = vec4<f32>(1.0);\n",
                };
                let src = format!(
                    "{}\n{}",
                    gpu::COMMON_WGSL,
                    WGSL.replace("//INPUTS\n", &inputs)
                        .replace("//MORPH\n", &morph)
                        .replace("//SKIN\n", &skin)
                        .replace("//COLOR\n", color)
                );
                gpu.device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some("gltf"),
                        source: wgpu::ShaderSource::Wgsl(src.into()),
                    })
            })
            .clone();
        let attrs: Vec<[wgpu::VertexAttribute; 1]> = {
            let mut v = vec![
                [wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x3,
                    offset: 0,
                    shader_location: 0,
                }],
                [wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x3,
                    offset: 0,
                    shader_location: 1,
                }],
                [wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x2,
                    offset: 0,
                    shader_location: 2,
                }],
            ];
            if key.color && key.color_target.is_none() {
                v.push([wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x4,
                    offset: 0,
                    shader_location: 3,
                }]);
            }
            for t in 0..key.targets {
                v.push([wgpu::VertexAttribute {
                    format: wgpu::VertexFormat::Float32x3,
                    offset: 0,
                    shader_location: target_location(t),
                }]);
            }
            v
        };
        // COLOR_0 and its morph target, interleaved in one buffer
        let pair = [
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x4,
                offset: 0,
                shader_location: 3,
            },
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x4,
                offset: 16,
                shader_location: 8,
            },
        ];
        let mut layouts: Vec<Option<wgpu::VertexBufferLayout>> = attrs
            .iter()
            .map(|a| {
                let stride = match a[0].format {
                    wgpu::VertexFormat::Float32x2 => 8,
                    wgpu::VertexFormat::Float32x3 => 12,
                    _ => 16,
                };
                Some(wgpu::VertexBufferLayout {
                    array_stride: stride,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: a,
                })
            })
            .collect();
        if key.color && key.color_target.is_some() {
            // bound right after TEXCOORD_0, where a lone COLOR_0 goes
            layouts.insert(
                3,
                Some(wgpu::VertexBufferLayout {
                    array_stride: 32,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &pair,
                }),
            );
        }
        // JOINTS_0 and WEIGHTS_0, interleaved in one buffer, bound last
        let skin_pair = [
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x4,
                offset: 0,
                shader_location: 9,
            },
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x4,
                offset: 16,
                shader_location: 10,
            },
        ];
        if key.skinned {
            layouts.push(Some(wgpu::VertexBufferLayout {
                array_stride: 32,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &skin_pair,
            }));
        }
        let blend = key.blend.then_some(wgpu::BlendState::ALPHA_BLENDING);
        gpu.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("gltf"),
                layout: Some(&self.pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &layouts,
                },
                primitive: gpu::primitive_state(key.cull, key.mirrored),
                depth_stencil: Some(gpu::depth_state(!key.blend)),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: key.format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
    }

    /// Records the draws into `pass` (after [`GltfRenderer::prepare`] for the pass's format).
    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        let format = self.format.expect("prepare() before record()");
        pass.set_bind_group(0, &self.frame.bind_group, &[]);
        pass.set_bind_group(3, &self.joints_group, &[]);
        for (i, (d, elements)) in self.draws.iter().zip(self.visible_elements()).enumerate() {
            if elements == 0 {
                continue;
            }
            pass.set_pipeline(&self.pipelines[&self.key(d, format)]);
            pass.set_bind_group(1, &self.draw_group, &[(i as u64 * DRAW_SLOT) as u32]);
            pass.set_bind_group(2, &self.material_groups[d.material_group], &[]);
            let stream = |s: Stream| match s {
                Stream::Accessor(a) => &self.buffers[&a],
                Stream::Zeros(c, n) => &self.zeros[&(c, n)],
            };
            pass.set_vertex_buffer(0, self.buffers[&d.position].slice(..));
            pass.set_vertex_buffer(1, stream(d.normal).slice(..));
            pass.set_vertex_buffer(2, stream(d.texcoord).slice(..));
            let mut slot = 3;
            match (d.color, d.color_target) {
                (Some(c), Some((_, t))) => {
                    pass.set_vertex_buffer(slot, self.color_pairs[&(c, t)].slice(..));
                    slot += 1;
                }
                (Some(c), None) => {
                    pass.set_vertex_buffer(slot, self.buffers[&c].slice(..));
                    slot += 1;
                }
                _ => {}
            }
            for t in &d.targets {
                pass.set_vertex_buffer(slot, self.buffers[t].slice(..));
                slot += 1;
            }
            if let Some((pair, _)) = &d.skin {
                pass.set_vertex_buffer(slot, self.skin_pairs[pair].slice(..));
            }
            match d.indices {
                Some(a) => {
                    pass.set_index_buffer(
                        self.index_buffers[&a].slice(..),
                        wgpu::IndexFormat::Uint32,
                    );
                    pass.draw_indexed(0..elements, 0, 0..1);
                }
                None => pass.draw(0..elements, 0..1),
            }
        }
    }
}

/// A colour accessor as RGBA: a VEC3 one gets `alpha` (1 for a colour, 0 for a colour delta).
fn rgba(f: super::glb::Floats, alpha: f32) -> Vec<f32> {
    match f.components {
        3 => f
            .data
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], alpha])
            .collect(),
        _ => f.data,
    }
}

fn vertex_buffer(gpu: &Gpu, data: &[f32]) -> wgpu::Buffer {
    let data: &[f32] = if data.is_empty() { &[0.0; 4] } else { data };
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::VERTEX,
        })
}

fn make_draw_buffer(gpu: &Gpu, draws: usize) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("draws"),
        size: draws.max(1) as u64 * DRAW_SLOT,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn make_draw_group(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    buffer: &wgpu::Buffer,
) -> wgpu::BindGroup {
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("draws"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<DrawData>() as u64),
            }),
        }],
    })
}

/// A storage buffer of `matrices` joint matrices (at least one) and its bind group.
fn make_joints(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    matrices: usize,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("joints"),
        size: matrices.max(1) as u64 * 64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("joints"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    });
    (buffer, group)
}

fn make_sampler(gpu: &Gpu, s: SamplerDesc) -> wgpu::Sampler {
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::Clamp => wgpu::AddressMode::ClampToEdge,
        Wrap::Mirror => wgpu::AddressMode::MirrorRepeat,
    };
    let filter = |nearest: bool| {
        if nearest {
            wgpu::FilterMode::Nearest
        } else {
            wgpu::FilterMode::Linear
        }
    };
    gpu.device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("sampler"),
        address_mode_u: wrap(s.wrap_u),
        address_mode_v: wrap(s.wrap_v),
        mag_filter: filter(s.mag_nearest),
        min_filter: filter(s.min_nearest),
        mipmap_filter: match s.mip {
            Some(MipFilter::Linear) => wgpu::MipmapFilterMode::Linear,
            _ => wgpu::MipmapFilterMode::Nearest,
        },
        ..Default::default()
    })
}
