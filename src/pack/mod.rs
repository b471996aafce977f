//! Pack: quantization, vertex ordering and the byte streams of the two layouts (DESIGN §4).
//!
//! `pack` turns the editable mesh and the shell stack into [`Packed`]: byte streams, accessors
//! over them, primitives and materials — a neutral description that `write.rs` turns into glTF
//! JSON. All byte encoding lives here; no JSON is written here.
//!
//! Order of work follows meshoptimizer's recommendation: index order for the vertex cache
//! (`meshopt_optimizeVertexCache`), then vertex order for fetch (first use in the index buffer,
//! as `optimizeVertexFetchRemap` does), then quantization. Both are deterministic. Vertices no
//! triangle uses are dropped.
//!
//! - **compact**: one quantized geometry (POSITION u16, NORMAL i8, TEXCOORD_0 u16, morph target 0
//!   = extrusion delta as float, see below) shared by every layer; layer `j` is a primitive reusing the same
//!   accessors with its own material (`MASK`, `alphaCutoff` = the mask's cutoff for the layer's
//!   step, per-layer colour) and weight `t_j`. The base layer is opaque (still textured: the
//!   mask's grey carries the strands' shade onto the skin) and has no morph target. Adding a
//!   layer costs JSON only.
//! - **single-draw**: every layer's vertices explicitly (positions quantized per layer), all in
//!   one primitive with one material; `COLOR_0` (u16 normalized RGBA) carries the layer's shade
//!   and an alpha `a_j = C/cutoff_j` against one fixed cutoff `C`, so `a_j·alpha >= C ⇔
//!   alpha >= cutoff_j` for any (interpolated) mask alpha: the compact layer's test. `C` is the
//!   lower of `(BASE_CODE − ½)/255` and the base layer's law cutoff, so `C <= cutoff_j` for every
//!   layer (`a_j <= 1`) and every texel, whose alpha is at least `BASE_CODE/255`, passes the base
//!   layer (`a_0 = 1`): the base stays opaque. Indices run from the inner to the outer layer.
//!
//! The extrusion delta has a precision of its own: 32-bit float in grid units, not integers on
//! the position grid. On the grid, a delta the clamp shortened to a few steps loses its
//! direction (the Stanford dragon kept 158 inverted outer-shell triangles that way). A float
//! delta costs 4 more bytes per vertex than an `i16` one; scaling an `i16` delta up and the layer
//! weights down would keep it at 8 bytes but breaks every client's bounding box (three.js adds
//! the whole target to the bounds). Then `guard.rs` checks the stored geometry, so no layer
//! triangle of the written file inverts.

mod guard;
mod model;
mod quantize;

pub use model::{
    Accessor, Alpha, Material, Mesh as PackedMesh, Node, Packed, PackedSurface, Primitive,
    Semantic, ShellExtras, Stream, StreamKind, Tag, Texture, TextureRef,
};

pub use quantize::{dequantize_normal, quantize_normal, PositionGrid, UvGrid};

use glam::{Vec2, Vec3};
use image::ImageEncoder;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::mesh::Mesh;
use crate::shells::ShellStack;
use crate::strands::{Mask, BASE_CODE};
use quantize::Bytes;

/// Which glTF layout `pack` writes (DESIGN §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// One quantized geometry shared by every layer; extrusion as a morph target; one small mesh
    /// and material per layer. Smallest file, one draw call per layer.
    Compact,
    /// All layers in one primitive and one material; per-layer threshold and shade in COLOR_0.
    /// Larger file, one draw call.
    SingleDraw,
}

impl Layout {
    /// Every layout, in the order the CLI lists them.
    pub const ALL: [Layout; 2] = [Layout::Compact, Layout::SingleDraw];

    /// The kebab-case name used on the command line, in scene files, reports and `extras`.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Compact => "compact",
            Layout::SingleDraw => "single-draw",
        }
    }

    /// The layout called `name`.
    pub fn from_name(name: &str) -> Option<Layout> {
        Layout::ALL.into_iter().find(|l| l.name() == name)
    }
}

/// Pack stage parameters (`pack/`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PackParams {
    /// Output layout.
    pub layout: Layout,
    /// Position quantization bits, 8–16. 14 keeps the error under 1/16384 of the largest extent.
    pub position_bits: u32,
}

impl Default for PackParams {
    fn default() -> Self {
        PackParams {
            layout: Layout::Compact,
            position_bits: 14,
        }
    }
}

impl PackParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if !(8..=16).contains(&self.position_bits) {
            return Err(ParamError::new(
                "position_bits",
                format!(
                    "position_bits must be in 8..=16, got {}",
                    self.position_bits
                ),
            ));
        }
        Ok(())
    }
}

/// glTF component types.
pub mod component {
    pub const BYTE: u32 = 5120;
    pub const UNSIGNED_BYTE: u32 = 5121;
    pub const SHORT: u32 = 5122;
    pub const UNSIGNED_SHORT: u32 = 5123;
    pub const UNSIGNED_INT: u32 = 5125;
    pub const FLOAT: u32 = 5126;
}

/// What `pack` needs besides the mesh and the stack.
pub struct PackInput<'a> {
    pub mesh: &'a Mesh,
    pub shells: &'a ShellStack,
    pub mask: &'a Mask,
    /// Mask tiles per UV unit (u and v).
    pub tiles_per_uv: Vec2,
    /// The layers each triangle of `mesh` shows in (the cull stage's result).
    pub culled: &'a crate::cull::Culled,
    /// Density per vertex of `mesh` (`COLOR_0` alpha), when the surface has a density map.
    pub density: Option<&'a [u8]>,
    pub roughness: f32,
    /// The surface's index in the file and the name of its root node.
    pub surface: usize,
    pub name: &'a str,
    /// Prefix of the surface's mesh and material names (empty for a file of one surface).
    pub prefix: &'a str,
}

/// Packs one surface into byte streams for `params.layout`, appended to `out`: its streams,
/// accessors, texture, materials, meshes and a root node with one child per layer. Returns what
/// the packing decided (also pushed to `out.surfaces`).
pub fn pack(input: &PackInput, params: &PackParams, out: &mut Packed) -> PackedSurface {
    let mesh = input.mesh;
    if cfg!(debug_assertions) {
        mesh.validate();
    }
    assert!(
        mesh.normals.is_some() && mesh.uvs.is_some(),
        "pack needs normals and uvs"
    );
    assert_eq!(input.shells.delta.len(), mesh.vertex_count());

    // Triangles by the number of layers they show in, most first, so that every layer draws a
    // prefix of one index buffer (culling); meshopt's vertex cache order within each group,
    // then fetch order.
    let nv = mesh.vertex_count();
    let layers = input.shells.t.len();
    let top = &input.culled.top;
    assert_eq!(
        top.len(),
        mesh.triangle_count(),
        "one cull result per triangle"
    );
    let mut triangles: Vec<u32> = (0..top.len() as u32).collect();
    triangles.sort_by_key(|&t| std::cmp::Reverse(top[t as usize]));
    let mut indices = Vec::with_capacity(mesh.indices.len());
    let mut kept = vec![0usize; layers];
    for group in triangles.chunk_by(|&a, &b| top[a as usize] == top[b as usize]) {
        let ix: Vec<u32> = group
            .iter()
            .flat_map(|&t| {
                mesh.indices[3 * t as usize..3 * t as usize + 3]
                    .iter()
                    .copied()
            })
            .collect();
        indices.extend(meshopt::optimize_vertex_cache(&ix, nv));
        for k in &mut kept[..top[group[0] as usize] as usize] {
            *k += group.len();
        }
    }
    // Fetch order = first use in the ordered index buffer (what meshopt's
    // optimizeVertexFetchRemap computes; done here because the binding truncates its remap
    // table when some vertices are unused). Unused vertices are dropped. The vertices a prefix
    // of the triangles uses are then a prefix of the vertices.
    let mut fetch = vec![u32::MAX; nv];
    let mut order = Vec::with_capacity(nv);
    for &i in &indices {
        if fetch[i as usize] == u32::MAX {
            fetch[i as usize] = order.len() as u32;
            order.push(i);
        }
    }
    let indices: Vec<u32> = indices.iter().map(|&i| fetch[i as usize]).collect();
    // vertices used by each layer's triangles
    let layer_vertices: Vec<usize> = kept
        .iter()
        .map(|&n| indices[..3 * n].iter().max().map_or(0, |&m| m as usize + 1))
        .collect();
    let pick = |v: &[Vec3]| order.iter().map(|&o| v[o as usize]).collect::<Vec<_>>();
    let positions = pick(&mesh.positions);
    let normals = pick(mesh.normals.as_ref().unwrap());
    let deltas = pick(&input.shells.delta);
    let uvs: Vec<Vec2> = order
        .iter()
        .map(|&o| mesh.uvs.as_ref().unwrap()[o as usize])
        .collect();
    let density: Option<Vec<u8>> = input
        .density
        .map(|d| order.iter().map(|&o| d[o as usize]).collect());

    let grid = PositionGrid::fit(
        // the base and the fully extruded surface
        positions
            .iter()
            .copied()
            .chain(positions.iter().zip(&deltas).map(|(&p, &d)| p + d)),
        params.position_bits.min(15),
    );
    // Deltas in grid units, shortened where the stored geometry would invert.
    let mut deltas: Vec<Vec3> = deltas.iter().map(|&d| d / grid.step).collect();
    let shells = input.shells;
    let top = shells.t.iter().copied().fold(0.0f32, f32::max);
    let guarded = match params.layout {
        Layout::Compact => {
            let base: Vec<Vec3> = positions
                .iter()
                .map(|&p| grid.quantize(p).map(f32::from).into())
                .collect();
            guard::guard(
                &base,
                &mut deltas,
                &indices,
                &guard::MorphPath { base: &base, top },
            )
        }
        Layout::SingleDraw => {
            let base: Vec<Vec3> = positions
                .iter()
                .map(|&p| (p - grid.min) / grid.step)
                .collect();
            let check = guard::RoundedLayers {
                base: &base,
                t: &shells.t,
                top_level: grid.max_level() as f32,
            };
            guard::guard(&base, &mut deltas, &indices, &check)
        }
    };
    let uv_grid = UvGrid::fit(&uvs);
    let tiles = input.tiles_per_uv;
    let texel_error = (uv_grid.extent * tiles * input.mask.size as f32 / 65535.0).max_element();
    let float_uvs = texel_error > 0.125;

    let tag = Tag {
        surface: input.surface,
        ..Tag::default()
    };
    let mut b = Builder { out, tag };
    let png = encode_mask_png(input.mask);
    let image = b
        .out
        .stream("mask", Semantic::Image, None, tag, (png, None, 0));
    let texture = Packed::push(&mut b.out.textures, Texture { image });
    let (uv_offset, uv_scale) = if float_uvs {
        (Vec2::ZERO, tiles)
    } else {
        (uv_grid.lo * tiles, uv_grid.extent * tiles)
    };

    let ordered = Ordered {
        grid,
        uv_grid,
        float_uvs,
        positions,
        normals,
        uvs,
        deltas,
        indices,
        density,
        kept,
        layer_vertices,
    };
    let texture = TextureRef {
        texture,
        offset: uv_offset,
        scale: uv_scale,
    };
    let ordered_kept = ordered.kept.clone();
    let layer_meshes = match params.layout {
        Layout::Compact => compact(&mut b, input, &ordered, texture),
        Layout::SingleDraw => single_draw(&mut b, input, &ordered, texture),
    };
    let translation = grid.min.as_dvec3() + mesh.origin;
    let out = b.out;
    let root = out.nodes.len();
    let layer_nodes: Vec<usize> = (root + 1..root + 1 + layer_meshes.len()).collect();
    out.nodes.push(Node {
        name: input.name.to_string(),
        tag,
        children: layer_nodes.clone(),
        translation: Some(translation),
        scale: Some(grid.step as f64),
        extras: Some(ShellExtras {
            layout: params.layout,
            height: shells.height,
            // the layers the file holds (culling drops layers no triangle shows in)
            t: (0..shells.t.len())
                .filter(|&j| j == 0 || ordered_kept[j] > 0)
                .map(|j| shells.t[j])
                .collect(),
        }),
        ..Node::default()
    });
    for &m in &layer_meshes {
        out.nodes.push(Node {
            name: out.meshes[m].name.clone(),
            tag: out.meshes[m].tag,
            mesh: Some(m),
            ..Node::default()
        });
    }
    out.roots.push(root);
    let surface = PackedSurface {
        layout: params.layout,
        root,
        layer_meshes,
        layer_nodes,
        uv_offset,
        uv_scale,
        translation,
        scale: grid.step as f64,
        grid,
        float_uvs,
        base_vertices: nv,
        vertex_order: order,
        guarded,
    };
    out.surfaces.push(surface.clone());
    surface
}

/// The mesh in optimized vertex order with its quantization grids: what both layouts encode.
struct Ordered {
    grid: PositionGrid,
    uv_grid: UvGrid,
    float_uvs: bool,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    /// Extrusion deltas in grid units (already guarded).
    deltas: Vec<Vec3>,
    indices: Vec<u32>,
    /// Density per vertex (`COLOR_0` alpha), when the surface has a density map.
    density: Option<Vec<u8>>,
    /// Triangles each layer draws: a prefix of `indices`.
    kept: Vec<usize>,
    /// Vertices each layer's triangles use: a prefix of the vertices.
    layer_vertices: Vec<usize>,
}

/// Appends one surface's streams to the file, tagged with the surface.
struct Builder<'a> {
    out: &'a mut Packed,
    tag: Tag,
}

impl Builder<'_> {
    fn stream(
        &mut self,
        name: &'static str,
        semantic: Semantic,
        target: Option<usize>,
        bytes: Vec<u8>,
        stride: Option<usize>,
        count: usize,
    ) -> usize {
        self.out
            .stream(name, semantic, target, self.tag, (bytes, stride, count))
    }

    /// POSITION stream (u16 × 3, stride 8) with exact integer bounds.
    fn positions(&mut self, q: &[[u16; 3]]) -> usize {
        let mut bytes = Bytes::default();
        let (mut lo, mut hi) = ([u16::MAX; 3], [0u16; 3]);
        for p in q {
            bytes.u16s(p, 8);
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        let v = self.stream(
            "position",
            Semantic::Position,
            None,
            bytes.0,
            Some(8),
            q.len(),
        );
        let bounds = (lo.map(|x| x as f64).to_vec(), hi.map(|x| x as f64).to_vec());
        self.out
            .accessor(v, component::UNSIGNED_SHORT, false, "VEC3", Some(bounds))
    }

    fn normals(&mut self, n: &[Vec3]) -> usize {
        let mut bytes = Bytes::default();
        for &v in n {
            bytes.i8s(&quantize_normal(v), 4);
        }
        let v = self.stream("normal", Semantic::Normal, None, bytes.0, Some(4), n.len());
        self.out.accessor(v, component::BYTE, true, "VEC3", None)
    }

    fn texcoords(&mut self, uvs: &[Vec2], grid: UvGrid, float: bool) -> usize {
        let mut bytes = Bytes::default();
        if float {
            for uv in uvs {
                bytes.f32s(&[uv.x, uv.y]);
            }
            let uv = Semantic::TexCoord(0);
            let v = self.stream("texcoord", uv, None, bytes.0, Some(8), uvs.len());
            return self.out.accessor(v, component::FLOAT, false, "VEC2", None);
        }
        for &uv in uvs {
            bytes.u16s(&grid.quantize(uv), 4);
        }
        let uv = Semantic::TexCoord(0);
        let v = self.stream("texcoord", uv, None, bytes.0, Some(4), uvs.len());
        self.out
            .accessor(v, component::UNSIGNED_SHORT, true, "VEC2", None)
    }

    fn indices(&mut self, name: &'static str, ix: &[u32], vertex_count: usize) -> usize {
        let mut bytes = Bytes::default();
        // 65535 is the primitive-restart value of u16 and may not appear.
        let component = if vertex_count <= 65535 {
            let small: Vec<u16> = ix.iter().map(|&i| i as u16).collect();
            bytes.u16s(&small, 0);
            component::UNSIGNED_SHORT
        } else {
            bytes.u32s(ix);
            component::UNSIGNED_INT
        };
        while bytes.0.len() % 4 != 0 {
            bytes.0.push(0);
        }
        let v = self.stream(name, Semantic::Indices, None, bytes.0, None, ix.len());
        self.out.accessor(v, component, false, "SCALAR", None)
    }
}

/// The compact layout: one geometry and one extrusion target shared by every layer mesh.
/// Returns the layer meshes in layer order.
fn compact(b: &mut Builder, input: &PackInput, s: &Ordered, texture: TextureRef) -> Vec<usize> {
    let (grid, positions, deltas) = (&s.grid, &s.positions, &s.deltas);
    let q: Vec<[u16; 3]> = positions.iter().map(|&p| grid.quantize(p)).collect();
    let position = b.positions(&q);
    let normal = b.normals(&s.normals);
    let texcoord = b.texcoords(&s.uvs, s.uv_grid, s.float_uvs);
    let mut bytes = Bytes::default();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for d in deltas {
        bytes.f32s(&d.to_array());
        lo = lo.min(*d);
        hi = hi.max(*d);
    }
    if deltas.is_empty() {
        (lo, hi) = (Vec3::ZERO, Vec3::ZERO);
    }
    let dv = b.stream(
        "extrusion",
        Semantic::Position,
        Some(0),
        bytes.0,
        Some(12),
        deltas.len(),
    );
    let bounds = |v: Vec3| v.to_array().map(|x| x as f64).to_vec();
    let delta = b.out.accessor(
        dv,
        component::FLOAT,
        false,
        "VEC3",
        Some((bounds(lo), bounds(hi))),
    );
    let ix = b.indices("indices", &s.indices, positions.len());
    let density = s.density.as_ref().map(|d| {
        let mut bytes = Bytes::default();
        for &d in d {
            bytes.0.extend_from_slice(&[255, 255, 255, d]);
        }
        let v = b.stream(
            "density",
            Semantic::Color(0),
            None,
            bytes.0,
            Some(4),
            d.len(),
        );
        b.out
            .accessor(v, component::UNSIGNED_BYTE, true, "VEC4", None)
    });
    // one index accessor per distinct triangle count, all over the one index stream
    let mut prefixes: Vec<(usize, usize)> = vec![(s.indices.len() / 3, ix)];
    let shells = input.shells;
    (0..shells.t.len())
        .filter(|&j| j == 0 || s.kept[j] > 0)
        .map(|j| {
            let ix = match prefixes.iter().find(|&&(n, _)| n == s.kept[j]) {
                Some(&(_, a)) => a,
                None => {
                    let mut a = b.out.accessors[ix].clone();
                    a.count = 3 * s.kept[j];
                    let a = Packed::push(&mut b.out.accessors, a);
                    prefixes.push((s.kept[j], a));
                    a
                }
            };
            let c = shells.color[j];
            let base = j == 0;
            let name = format!("{}layer_{j:03}", input.prefix);
            let material = Packed::push(
                &mut b.out.materials,
                Material {
                    name: name.clone(),
                    base_color: [c[0], c[1], c[2], 1.0],
                    alpha: if base {
                        Alpha::Opaque
                    } else {
                        Alpha::Mask(input.mask.cutoff(shells.steps[j]))
                    },
                    texture: Some(texture),
                    roughness: input.roughness,
                },
            );
            let mut attributes = vec![
                (Semantic::Position, position),
                (Semantic::Normal, normal),
                (Semantic::TexCoord(0), texcoord),
            ];
            attributes.extend(density.map(|d| (Semantic::Color(0), d)));
            let primitive = Primitive {
                attributes,
                targets: if base {
                    vec![]
                } else {
                    vec![vec![(Semantic::Position, delta)]]
                },
                indices: Some(ix),
                material,
            };
            let tag = Tag {
                layer: Some(j),
                ..b.tag
            };
            Packed::push(
                &mut b.out.meshes,
                PackedMesh {
                    name,
                    tag,
                    primitives: vec![primitive],
                    weights: if base { vec![] } else { vec![shells.t[j]] },
                },
            )
        })
        .collect()
}

/// An upper bound of the GLB size for a mesh of at most `vertices` render vertices and
/// `triangles` triangles, made before any work so an oversize bake can be refused with the size
/// it would at most have had. Counts every stream at its widest encoding (float UVs, the float
/// extrusion delta, u32 indices past 65535 vertices), the mask PNG at its raw size plus an eighth
/// (deflate's fixed codes spend at most 9 bits a byte; encoders fall back to stored blocks when
/// that is larger) and 600 bytes of JSON per layer (a layer's mesh, material and node take about
/// 450).
pub fn estimate_bytes(
    vertices: u64,
    triangles: u64,
    layers: u64,
    mask_size: u64,
    layout: Layout,
) -> u64 {
    // grey + alpha per texel, one filter byte per row
    let raw = mask_size * (2 * mask_size + 1);
    let png = raw + raw / 8 + 4096;
    let json = 8192 + 600 * layers;
    // each view is padded to 4 bytes; 8 views at most
    let padding = 8 * 3;
    let body = match layout {
        Layout::Compact => {
            let index = if vertices <= 65535 { 2 } else { 4 };
            vertices * (8 + 4 + 8 + 12) + triangles * 3 * index
        }
        Layout::SingleDraw => {
            let n = vertices * layers;
            let index = if n <= 65535 { 2 } else { 4 };
            n * (8 + 4 + 8 + 8) + triangles * layers * 3 * index
        }
    };
    28 + body + png + json + padding
}

/// `COLOR_0` alpha of a single-draw layer at height step `k`, as normalized u16: 1 for the base
/// layer, [`single_draw_cutoff`]` / cutoff(k)` above it (see the module notes).
pub fn single_draw_alpha(mask: &Mask, k: u32) -> u16 {
    if k == 0 {
        return u16::MAX;
    }
    let a = single_draw_cutoff(mask) as f64 / mask.cutoff(k) as f64;
    (a * 65535.0).round() as u16
}

/// The fixed alpha cutoff of the single-draw material: half a code below the lowest alpha any
/// texel holds, or the base layer's law cutoff when that is lower.
pub fn single_draw_cutoff(mask: &Mask) -> f32 {
    ((BASE_CODE as f32 - 0.5) / 255.0).min(mask.cutoff(0))
}

/// The single-draw layout: every layer's vertices in one primitive of one mesh. Returns that
/// mesh (once: it holds every layer).
fn single_draw(b: &mut Builder, input: &PackInput, s: &Ordered, texture: TextureRef) -> Vec<usize> {
    let (grid, positions, deltas) = (&s.grid, &s.positions, &s.deltas);
    let shells = input.shells;
    let layers = shells.t.len();
    let total: usize = s.layer_vertices.iter().sum();
    let mut q = Vec::with_capacity(total);
    let mut colors = Bytes::default();
    let mut all_ix: Vec<u32> = Vec::new();
    for j in 0..layers {
        // layer j: the vertices and triangles it keeps (prefixes)
        let (nv, first) = (s.layer_vertices[j], q.len() as u32);
        let t = shells.t[j];
        let top_level = grid.max_level() as f32;
        q.extend(positions[..nv].iter().zip(deltas).map(|(&p, &d)| {
            let r = guard::layer_point((p - grid.min) / grid.step, d, t, top_level);
            [r.x as u16, r.y as u16, r.z as u16]
        }));
        let c = shells.color[j];
        let alpha = single_draw_alpha(input.mask, shells.steps[j]);
        for v in 0..nv {
            // density scales every layer above the base
            let a = match &s.density {
                Some(d) if j > 0 => (alpha as u32 * d[v] as u32 + 127) / 255,
                _ => alpha as u32,
            };
            let rgba = [
                (c[0].clamp(0.0, 1.0) * 65535.0).round() as u16,
                (c[1].clamp(0.0, 1.0) * 65535.0).round() as u16,
                (c[2].clamp(0.0, 1.0) * 65535.0).round() as u16,
                a as u16,
            ];
            colors.u16s(&rgba, 8);
        }
        all_ix.extend(s.indices[..3 * s.kept[j]].iter().map(|&i| i + first));
    }
    let position = b.positions(&q);
    let pick = |j: usize| 0..s.layer_vertices[j];
    let all_normals: Vec<Vec3> = (0..layers)
        .flat_map(|j| pick(j).map(|v| s.normals[v]))
        .collect();
    let normal = b.normals(&all_normals);
    let all_uvs: Vec<Vec2> = (0..layers)
        .flat_map(|j| pick(j).map(|v| s.uvs[v]))
        .collect();
    let texcoord = b.texcoords(&all_uvs, s.uv_grid, s.float_uvs);
    let cv = b.stream("color", Semantic::Color(0), None, colors.0, Some(8), total);
    let color = b
        .out
        .accessor(cv, component::UNSIGNED_SHORT, true, "VEC4", None);
    let ix = b.indices("indices", &all_ix, total);
    let name = format!("{}shells", input.prefix);
    let material = Packed::push(
        &mut b.out.materials,
        Material {
            name: name.clone(),
            base_color: [1.0; 4],
            alpha: Alpha::Mask(single_draw_cutoff(input.mask)),
            texture: Some(texture),
            roughness: input.roughness,
        },
    );
    let primitive = Primitive {
        attributes: vec![
            (Semantic::Position, position),
            (Semantic::Normal, normal),
            (Semantic::TexCoord(0), texcoord),
            (Semantic::Color(0), color),
        ],
        targets: vec![],
        indices: Some(ix),
        material,
    };
    let mesh = PackedMesh {
        name,
        tag: b.tag,
        primitives: vec![primitive],
        weights: vec![],
    };
    vec![Packed::push(&mut b.out.meshes, mesh)]
}

/// The mask as a grey+alpha PNG (grey = the strands' shade, alpha = the noise byte or the
/// survival code), deflated at the highest level with adaptive filtering. Deterministic.
pub fn encode_mask_png(mask: &Mask) -> Vec<u8> {
    let mut pixels = Vec::with_capacity(mask.alpha.len() * 2);
    for (&a, &g) in mask.alpha.iter().zip(&mask.shade) {
        pixels.push(g);
        pixels.push(a);
    }
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    enc.write_image(&pixels, mask.size, mask.size, image::ExtendedColorType::La8)
        .expect("encoding a PNG into memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_draw_alpha_reproduces_every_layer_cutoff() {
        // For every law of the presets (and a threshold below the code floor), every layer step
        // k and every mask value m: m/255 · a_k >= C  ⇔  m/255 >= cutoff(k) (the compact layer's
        // test), with a margin that f32 rounding on a GPU cannot cross; and the base layer shows
        // every texel.
        let params = crate::params::Preset::ALL
            .map(|p| crate::params::BakeParams::preset(p).strands)
            .into_iter()
            .chain([crate::params::StrandParams {
                model: crate::params::StrandModel::Noise { threshold: 0.02 },
                ..crate::params::BakeParams::default().strands
            }]);
        for p in params {
            let mask =
                crate::strands::bake_mask(&crate::params::StrandParams { mask_size: 16, ..p });
            let c = single_draw_cutoff(&mask) as f64;
            assert!(single_draw_alpha(&mask, 0) == u16::MAX && c < BASE_CODE as f64 / 255.0);
            for k in 1..=crate::strands::HEIGHT_STEPS {
                let a = single_draw_alpha(&mask, k) as f64 / 65535.0;
                let cutoff = mask.cutoff(k) as f64;
                for m in BASE_CODE..=255 {
                    let v = m as f64 / 255.0;
                    if (v - cutoff).abs() < 1e-6 * cutoff {
                        continue; // a tie of the law itself
                    }
                    assert_eq!(v * a >= c, v >= cutoff, "{:?} k={k} m={m}", p.model);
                    let margin = (v * a - c).abs() / c;
                    assert!(margin > 1e-6, "{:?} k={k} m={m} margin={margin}", p.model);
                }
            }
        }
    }

    #[test]
    fn estimate_is_an_upper_bound() {
        let scene = crate::load::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/fixtures/bunny.obj"
        )))
        .unwrap();
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let mut p = crate::params::BakeParams::default();
            p.pack.layout = layout;
            let baked = crate::bake(&scene, &p);
            let est = p.estimate_bytes(&scene);
            let len = baked.glb.len() as u64;
            assert!(est >= len, "{est} < {len}");
            // three vertices per triangle against about a half on a closed mesh
            assert!(est < len * 5, "estimate {est} too loose for {len}");
        }
    }

    #[test]
    fn png_is_deterministic_and_decodes_to_the_codes() {
        let p = crate::params::BakeParams::default().strands;
        let m = crate::strands::bake_mask(&crate::params::StrandParams { mask_size: 32, ..p });
        let a = encode_mask_png(&m);
        assert_eq!(a, encode_mask_png(&m));
        let img = image::load_from_memory(&a).unwrap().to_luma_alpha8();
        let alpha: Vec<u8> = img.pixels().map(|p| p.0[1]).collect();
        let grey: Vec<u8> = img.pixels().map(|p| p.0[0]).collect();
        assert_eq!((alpha, grey), (m.alpha.clone(), m.shade.clone()));
    }
}
