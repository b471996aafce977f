//! Primitives that are not layers: the `fins` effect's fin quads and the `outline` effect's
//! inverted hull, each one mesh under the surface's root node (so the root's dequantization
//! places them), after the chunk and layer nodes.
//!
//! Positions go on the surface's position grid like the layers' (normalized `i16`, or the exact
//! floats of `--quantize none`); the grid is fitted over the hull too, so a hull wider than the
//! fur stays on it. Fin normals are `i8` like the layers'; fin texture coordinates are
//! normalized `u16` over `[0, u_max] × [0, 1]` in strip tiles, the strip bound with a
//! `KHR_texture_transform` scale of `(u_max, 1)`. The hull has positions and indices only: its
//! material is unlit. An asset part's shape keys are both meshes' targets, gathered from the
//! vertices they stand on (`carry_shape_keys`), so they follow the keys as the layers do.

use glam::{Vec2, Vec3};

use super::builder::{u16_colors, Builder};
use super::input::{Geometry, PackInput};
use super::model::{Alpha, Material, Node, Packed, Semantic, Texture, TextureRef};
use super::params::component;
use super::quantize::Bytes;

/// What the extras added: their nodes, and the bytes each wrote.
pub(super) struct Extras {
    pub nodes: Vec<usize>,
    pub fin_bytes: usize,
    pub outline_bytes: usize,
    /// The nodes whose mesh carries an asset part's shape keys (their only targets).
    pub shape_key_nodes: Vec<usize>,
}

/// Bytes of the streams from `first` on.
fn bytes_since(out: &Packed, first: usize) -> usize {
    out.streams[first..].iter().map(|s| s.bytes.len()).sum()
}

/// The surface's extras, as its effects ask: the fins' node, then the outline's.
pub(super) fn extras(b: &mut Builder, g: &Geometry, input: &PackInput) -> Extras {
    let mut nodes = Vec::new();
    let mut fin_bytes = 0;
    let mut outline_bytes = 0;
    if let Some(f) = input.fins {
        let first = b.out.streams.len();
        nodes.push(fins(b, g, input, f));
        fin_bytes = bytes_since(b.out, first);
    }
    if let Some(o) = input.outline {
        let first = b.out.streams.len();
        nodes.push(outline(b, g, input, o));
        outline_bytes = bytes_since(b.out, first);
    }
    let shape_key_nodes = match g.morphs.is_empty() {
        true => vec![],
        false => nodes.clone(),
    };
    Extras {
        nodes,
        fin_bytes,
        outline_bytes,
        shape_key_nodes,
    }
}

/// Gives `mesh` (one primitive over vertices `source` of the input mesh) the asset part's shape
/// keys as its targets, at their rest weights, so that it follows them as the layers do.
fn carry_shape_keys(
    b: &mut Builder,
    g: &Geometry,
    mesh: usize,
    source: &[u32],
    name: &'static str,
) {
    if g.morphs.is_empty() {
        return;
    }
    let targets: Vec<Vec<(Semantic, usize)>> = (g.morphs.iter().enumerate())
        .map(|(k, (values, stored))| {
            let picked: Vec<Vec3> = source.iter().map(|&v| values[v as usize]).collect();
            vec![(Semantic::Position, b.deltas(&picked, name, k, *stored))]
        })
        .collect();
    let mesh = &mut b.out.meshes[mesh];
    mesh.primitives[0].targets = targets;
    mesh.weights = g.shape_key_rest().collect();
    mesh.target_names = g.shape_key_names().unwrap_or_default().to_vec();
}

/// Positions `p` as the POSITION stream stores them.
fn stored(g: &Geometry, p: &[Vec3]) -> Vec<Vec3> {
    p.iter().map(|&p| g.stored(p)).collect()
}

/// The `fins` effect's node: one mesh of fin quads (positions, normals, strip texture
/// coordinates, indices) under a masked material that samples the fin strip. Returns the node.
fn fins(b: &mut Builder, g: &Geometry, input: &PackInput, f: &crate::effects::fins::Fins) -> usize {
    let m = f.mesh(input.mesh, input.delta);
    let position = b.positions("fin_position", &stored(g, &m.positions), &g.grid);
    let normal = b.normals(&m.normals);
    let (uv, scale) = fin_texcoords(b, &m.uvs);
    let indices = b.indices("fin_indices", &m.indices, m.positions.len());
    let png = crate::effects::fins::encode_strip_png(&f.strip);
    let image = b.stream("fin_strip", Semantic::Image, None, png, None, 0);
    let texture = Packed::push(&mut b.out.textures, Texture { image });
    let material = Packed::push(
        &mut b.out.materials,
        Material {
            name: format!("{}fins", input.prefix),
            base_color: [1.0; 4],
            alpha: Alpha::Mask(0.5),
            texture: Some(TextureRef {
                texture,
                offset: Vec2::ZERO,
                scale,
            }),
            roughness: input.roughness,
            sheen: None,
            unlit: false,
        },
    );
    let mut attributes = vec![
        (Semantic::Position, position),
        (Semantic::Normal, normal),
        (Semantic::TexCoord(0), uv),
    ];
    // each fin's corners: base a, base b, top b, top a
    let source: Vec<u32> = f.edges.iter().flat_map(|e| [e.a, e.b, e.b, e.a]).collect();
    // an asset's colour at the edge's ends, as the layers carry it at their roots (the strip
    // then holds the asset's neutral ramp): before, fins drew the preset's beige on any asset
    if let Some(albedo) = g.albedo {
        let colours = source
            .iter()
            .map(|&o| (albedo[o as usize].truncate(), u16::MAX));
        let color = u16_colors(b, "fin_color", colours, source.len());
        attributes.push((Semantic::Color(0), color));
    }
    let name = format!("{}fins", input.prefix);
    let mesh = b.single_primitive_mesh(name.clone(), attributes, indices, material);
    carry_shape_keys(b, g, mesh, &source, "fin_shape_key");
    node(b, name, mesh)
}

/// The fins' texture coordinates `uvs`: normalized u16 over [0, u_max] × [0, 1] (exact floats
/// under `--quantize none`). Returns the accessor and the scale for the texture transform.
fn fin_texcoords(b: &mut Builder, uvs: &[Vec2]) -> (usize, Vec2) {
    let u_max = uvs.iter().fold(f32::MIN_POSITIVE, |a, p| a.max(p.x));
    let mut uv = Bytes::default();
    let (stride, kind, scale) = if b.float {
        for p in uvs {
            uv.f32s(&p.to_array());
        }
        (8, component::FLOAT, Vec2::ONE)
    } else {
        let scale = Vec2::new(u_max, 1.0);
        for p in uvs {
            let q = (*p / scale * 65535.0).round();
            uv.u16s(&[q.x as u16, q.y as u16], 4);
        }
        (4, component::UNSIGNED_SHORT, scale)
    };
    let v = b.stream(
        "fin_texcoord",
        Semantic::TexCoord(0),
        None,
        uv.0,
        Some(stride),
        uvs.len(),
    );
    (b.out.accessor(v, kind, !b.float, "VEC2", None), scale)
}

/// The `outline` effect's node: the inverted hull (the surface pushed out by the outline's
/// offsets, its winding reversed) under an unlit opaque material. Returns the node.
fn outline(
    b: &mut Builder,
    g: &Geometry,
    input: &PackInput,
    o: &crate::effects::outline::Outline,
) -> usize {
    let hull: Vec<Vec3> = input
        .mesh
        .positions
        .iter()
        .zip(&o.offset)
        .map(|(&p, &d)| p + d)
        .collect();
    let position = b.positions("outline_position", &stored(g, &hull), &g.grid);
    let reversed = crate::effects::outline::reversed(&input.mesh.indices);
    let indices = b.indices("outline_indices", &reversed, hull.len());
    let c = o.color;
    let material = Packed::push(
        &mut b.out.materials,
        Material {
            name: format!("{}outline", input.prefix),
            base_color: [c[0], c[1], c[2], 1.0],
            alpha: Alpha::Opaque,
            texture: None,
            roughness: 1.0,
            sheen: None,
            unlit: true,
        },
    );
    let name = format!("{}outline", input.prefix);
    let attributes = vec![(Semantic::Position, position)];
    let mesh = b.single_primitive_mesh(name.clone(), attributes, indices, material);
    let source: Vec<u32> = (0..hull.len() as u32).collect();
    carry_shape_keys(b, g, mesh, &source, "outline_shape_key");
    node(b, name, mesh)
}

/// A node holding mesh `mesh`.
fn node(b: &mut Builder, name: String, mesh: usize) -> usize {
    let node = Node {
        name,
        tag: b.tag,
        mesh: Some(mesh),
        ..Node::default()
    };
    Packed::push(&mut b.out.nodes, node)
}
