//! Skin and animation: the skeleton's nodes, skin and retargeted clips, and the wind's
//! channels.

use crate::stages::lod::Level;

use super::builder::Builder;
use super::model::{self, Animation, Channel, Node, Packed, Semantic, Skin};
use super::params::component;
use super::quantize::Bytes;

/// Writes skeleton `k` for the layer nodes `layers`: its nodes (names kept, for retargeting)
/// under a node carrying the placement, the skin (inverse bind matrices `IBM · P⁻¹ · R`, with `R`
/// = `dequantize`), each layer node bound to it, and the clips retargeted. Returns the wrapper.
pub(super) fn skeleton(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    dequantize: glam::DMat4,
    layers: &[usize],
    name: &str,
) -> usize {
    let (first, wrapper) = skeleton_nodes(b, k, name);
    let skin = skeleton_skin(b, k, (first, dequantize), name);
    for &l in layers {
        b.out.nodes[l].skin = Some(skin);
    }
    for clip in &k.clips {
        let channels = clip
            .channels
            .iter()
            .map(|c| clip_channel(b, c, first))
            .collect();
        b.out.animations.push(Animation {
            name: clip.name.clone(),
            channels,
        });
    }
    wrapper
}

/// The skeleton's joint nodes (names and rest poses kept) and the wrapper node above its roots
/// that carries the placement. Returns the first joint node and the wrapper.
pub(super) fn skeleton_nodes(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    name: &str,
) -> (usize, usize) {
    let first = b.out.nodes.len();
    for n in &k.nodes {
        let node = Node {
            name: n.name.clone(),
            tag: b.tag,
            children: n.children.iter().map(|&c| first + c).collect(),
            translation: Some(n.trs.translation),
            rotation: Some(n.trs.rotation),
            scale: Some(n.trs.scale),
            ..Node::default()
        };
        b.out.nodes.push(node);
    }
    let (scale, rotation, translation) = k.placement.to_scale_rotation_translation();
    let wrapper = Packed::push(
        &mut b.out.nodes,
        Node {
            name: format!("{name}_skeleton"),
            tag: b.tag,
            children: k.roots.iter().map(|&r| first + r).collect(),
            translation: Some(translation),
            rotation: Some(rotation),
            scale: Some(scale),
            ..Node::default()
        },
    );
    (first, wrapper)
}

/// The skin over the joint nodes from `first` on: its joints and inverse bind matrices
/// (`IBM · P⁻¹ · R`, with `R` = `dequantize`). Returns the skin.
pub(super) fn skeleton_skin(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    (first, dequantize): (usize, glam::DMat4),
    name: &str,
) -> usize {
    let unplace = k.placement.inverse() * dequantize;
    let ibm: Vec<glam::DMat4> = k.inverse_bind.iter().map(|m| *m * unplace).collect();
    let n = ibm.len();
    let v = b.stream(
        "inverse_bind",
        Semantic::InverseBind,
        None,
        model::matrix_bytes(&ibm),
        None,
        n,
    );
    let inverse_bind = b.out.accessor(v, component::FLOAT, false, "MAT4", None);
    Packed::push(
        &mut b.out.skins,
        Skin {
            name: name.to_string(),
            joints: k.joints.iter().map(|&j| first + j).collect(),
            inverse_bind,
        },
    )
}

/// One channel of a skeleton clip, retargeted to the joint nodes from `first` on: its keyframe
/// times (with their range) and values.
pub(super) fn clip_channel(
    b: &mut Builder,
    c: &crate::model::skeleton::Channel,
    first: usize,
) -> Channel {
    let mut times = Bytes::default();
    times.f32s(&c.times);
    let t = b.stream(
        "skin_times",
        Semantic::Animation,
        None,
        times.0,
        None,
        c.times.len(),
    );
    let lo = c.times.first().copied().unwrap_or(0.0) as f64;
    let hi = c.times.last().copied().unwrap_or(0.0) as f64;
    let input = b.out.accessor(
        t,
        component::FLOAT,
        false,
        "SCALAR",
        Some((vec![lo], vec![hi])),
    );
    let mut values = Bytes::default();
    values.f32s(&c.values);
    let per = c.path.components();
    let count = c.values.len() / per;
    let v = b.stream(
        "skin_values",
        Semantic::Animation,
        None,
        values.0,
        None,
        count,
    );
    let kind = if per == 4 { "VEC4" } else { "VEC3" };
    let output = b.out.accessor(v, component::FLOAT, false, kind, None);
    Channel {
        node: first + c.node,
        input,
        output,
        path: Some(c.path),
        interpolation: c.interpolation,
    }
}

/// A surface's wind animation as it is built: its channels (LOD 0's, then the coarser levels'),
/// the keyframe times, and the value accessors made so far (nodes with the same weights share
/// one).
#[derive(Default)]
pub(super) struct WindAnimation {
    pub(super) channels: Vec<Channel>,
    pub(super) times: Option<usize>,
    pub(super) outputs: Vec<(Vec<u32>, usize)>,
}

/// The wind channel of `node` (showing mesh `m` of `level`), when the mesh has the wind's
/// targets (its last two): every key holds the node's own weights with the wind's replaced by
/// their value at that time (compact: the layer's `t^k sin ωτ`, `t^k cos ωτ`; single-draw, whose
/// targets hold `t^k`: `sin ωτ`, `cos ωτ`).
pub(super) fn wind_channel(
    b: &mut Builder,
    wind: &crate::effects::wind::Wind,
    (node, m): (usize, usize),
    level: &Level,
    animation: &mut WindAnimation,
) -> Option<Channel> {
    let mesh = &b.out.meshes[m];
    let targets = mesh.primitives.first().map_or(0, |p| p.targets.len());
    let rest = b.out.weights_of(node).to_vec();
    if targets < 2 || rest.len() != targets {
        return None;
    }
    let t = mesh.tag.layer.map_or(1.0, |j| level.layers[j].t);
    let times = wind.times();
    let mut values = Vec::with_capacity(times.len() * targets);
    for &time in &times {
        values.extend_from_slice(&rest[..targets - 2]);
        values.extend(wind.weights(time, t));
    }
    let key: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
    let output = match animation.outputs.iter().find(|(k, _)| *k == key) {
        Some(&(_, a)) => a,
        None => {
            let mut bytes = Bytes::default();
            bytes.f32s(&values);
            let n = values.len();
            let v = b.stream("wind_weights", Semantic::Animation, None, bytes.0, None, n);
            let a = b.out.accessor(v, component::FLOAT, false, "SCALAR", None);
            animation.outputs.push((key, a));
            a
        }
    };
    let input = *animation.times.get_or_insert_with(|| {
        let mut bytes = Bytes::default();
        bytes.f32s(&times);
        let n = times.len();
        let v = b.stream("wind_times", Semantic::Animation, None, bytes.0, None, n);
        let bounds = (vec![0.0], vec![wind.period as f64]);
        b.out
            .accessor(v, component::FLOAT, false, "SCALAR", Some(bounds))
    });
    Some(Channel {
        node,
        input,
        output,
        path: None,
        interpolation: crate::model::skeleton::Interpolation::Linear,
    })
}
