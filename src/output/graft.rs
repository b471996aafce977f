//! Asset in, asset out (docs/how-it-works.md#the-document-kept-whole): the input document written
//! back whole, with the fur of its
//! furred parts added.
//!
//! [`graft`] takes the asset as read ([`Asset`]: its JSON and its buffers) and the fur-only file
//! the plan baked for its parts (one surface per part, each without a base layer: the part's own
//! primitive is the base), and writes one GLB:
//!
//! - **The input, kept.** Every object of the input JSON — scenes, nodes with their names,
//!   transforms and extras, meshes and primitives, materials, textures, samplers, images, skins,
//!   animations, cameras, `KHR_lights_punctual`, extensions and extras at every level — is
//!   written as it was, at the same index, so every reference inside it still holds. What
//!   changes is where bytes live, because the output is one self-contained GLB: every buffer
//!   becomes part of the one binary chunk (each buffer view moved by its buffer's offset there);
//!   an image given by a URI (a file beside a `.gltf`, or a `data:` URI, decoded) is embedded as
//!   a buffer view; and views compressed with `EXT_`/`KHR_meshopt_compression` are written decoded (the
//!   extension is dropped), since the reader decodes them and the compressed source would
//!   otherwise be carried twice.
//! - **The fur, added.** The fur file's objects are appended after the input's, every index
//!   shifted by the input's count of that kind. A rigid part's fur root hangs under the part's
//!   node, its transform `W⁻¹ · D` (`W` the node's world matrix, `D` the dequantization), so the
//!   node's animation moves the fur with it and the fur renders where it was baked. When
//!   `W⁻¹ · D` is not a translation-rotation-scale (a non-uniform scale under a rotation), it is
//!   split in two by its singular value decomposition: a node between the part's node and the
//!   root takes `T · U · Σ`, the root the rotation `Vᵀ`. Only a singular `W` (a scale of 0 at
//!   rest) leaves the root a scene root with `D`, and a warning says the fur will not follow. A
//!   skinned part's layer nodes are scene roots bound to the part's own skin (the same joints,
//!   the same inverse bind matrices: their positions are stored unquantized in the
//!   primitive's bind space), so the asset's clips animate the fur and every client computes
//!   true bounds from the positions. Each fur root's (and each skinned layer node's)
//!   `extras.shellbake_fur` names the node, mesh and primitive it grows on; a file read again
//!   skips those parts (no fur on fur).
//!   A part with shape keys (morph targets) has its layers carry the keys' deltas after their
//!   own targets (`pack`), and each animation channel on the part's morph weights gets a twin on
//!   every layer node of the part's fur, keyed at the same times: the node's own weights with
//!   the keys' replaced by the channel's (`follow_shape_keys`); the fins and the outline, whose
//!   only targets are the keys, likewise. Every level's twins join the channel's animation, so
//!   the file has the asset's clips and no more (a client without `MSFT_lod` finds no node for
//!   the coarser levels' channels and skips them: three.js warns once per channel). The single-draw
//!   layout's fur does not follow them (a warning says so), and a wind clip
//!   on the same nodes holds the keys at rest while the asset's clips hold the wind at rest (a
//!   warning too: one animation at a time sets a node's weights).
//!   The fur's coarser levels are the roots of a scene of their own, as in a plain bake
//!   (`write.rs`, "Where the coarser levels live"), and the file's `scene` names the default.
//! - **Extensions**: `extensionsUsed` and `extensionsRequired` are the union of both files'
//!   (less meshopt's, as above), in first-seen order.

use glam::{DMat3, DMat4, DQuat, DVec3};
use serde_json::{json, Map, Value};

use crate::error::{Error, Result};
use crate::input::asset::Asset;
use crate::input::document::local_matrix;
use crate::output::pack::Packed;

/// The asset with its fur: the GLB, its JSON, and what the graft had to warn about.
pub struct Grafted {
    pub glb: Vec<u8>,
    pub json: Value,
    pub warnings: Vec<String>,
}

/// How many objects of each kind the input holds: the fur's indices are shifted by these.
#[derive(Clone, Copy, Default)]
struct Base {
    nodes: usize,
    meshes: usize,
    materials: usize,
    textures: usize,
    images: usize,
    samplers: usize,
    accessors: usize,
    views: usize,
    skins: usize,
}

const MESHOPT: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

impl Base {
    /// The number of each kind of object `out` holds.
    fn of(out: &Value) -> Base {
        let count = |k: &str| out[k].as_array().map_or(0, Vec::len);
        Base {
            nodes: count("nodes"),
            meshes: count("meshes"),
            materials: count("materials"),
            textures: count("textures"),
            images: count("images"),
            samplers: count("samplers"),
            accessors: count("accessors"),
            views: count("bufferViews"),
            skins: count("skins"),
        }
    }
}

/// The output's buffers (buffer 0, the binary chunk, to be sized last; then the fur's fallback
/// buffers, which compressed views decode into) and, for each of the fur file's buffers, the
/// output buffer it becomes.
fn fur_buffers(fur_json: &Value) -> (Vec<Value>, Vec<usize>) {
    let mut buffers = vec![json!({})];
    let mut fur_buffers = Vec::new();
    for (b, declared) in fur_json["buffers"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
    {
        if b == 0 {
            fur_buffers.push(0);
        } else {
            buffers.push(declared.clone());
            fur_buffers.push(buffers.len() - 1);
        }
    }
    (buffers, fur_buffers)
}

/// Where the fur goes: the asset, the fur's packing, the shifts of the fur's indices in the
/// output, and the scene that takes fur roots.
struct Placing<'a> {
    asset: &'a Asset,
    packed: &'a Packed,
    base: Base,
    scene: usize,
}

impl Placing<'_> {
    /// Attaches the fur of surface `s` to the parts `group` of the asset in `out` (one skin or
    /// one node: the first part's), each fur root marked with the parts; returns the child a
    /// rigid part's fur hangs by under the part's node ([`Placing::attach_rigid`]; none for a
    /// skinned part, whose layer nodes are scene roots), or a warning when the fur cannot follow
    /// the node.
    fn attach(
        &self,
        out: &mut Value,
        s: usize,
        group: &[usize],
    ) -> std::result::Result<Option<usize>, String> {
        let (p, part) = (group[0], &self.asset.parts[group[0]]);
        let root = self.base.nodes + self.packed.surfaces[s].root;
        let place = |part: &crate::input::asset::Part| {
            json!({
                "node": part.node,
                "mesh": part.mesh,
                "primitive": part.primitive,
            })
        };
        let mut marker = place(part);
        if group.len() > 1 {
            let also: Vec<Value> = group[1..]
                .iter()
                .map(|&q| place(&self.asset.parts[q]))
                .collect();
            marker["also"] = Value::Array(also);
        }
        out["nodes"][root]["extras"]["shellbake_fur"] = marker.clone();
        // the part's node keeps its name to itself: engines that bind animation by node path
        // (Unity) or make names unique on import (Godot, Blender) see one node per name
        let name = format!(
            "{}_fur",
            out["nodes"][root]["name"].as_str().unwrap_or("shellbake")
        );
        out["nodes"][root]["name"] = json!(name);
        match part.skin {
            Some(skin) => {
                self.attach_skinned(out, s, skin, &marker);
                Ok(None)
            }
            None => self.attach_rigid(out, s, p).map(Some),
        }
    }

    /// Draws the fur of part `p` at every instance of its node, when it is instanced
    /// (`EXT_mesh_gpu_instancing`; `p` rigid, its fur root under the node). The extension draws
    /// the node's mesh once per instance and none of its children. Where the fur's layers have
    /// no morph targets (the bake writes an instanced part's fur in the `layers` layout) and
    /// each instance seen from a layer's node is a TRS, each layer node carries the instances
    /// itself ([`Placing::instance_in_place`]): one draw a layer for every instance. Otherwise
    /// — three.js draws no instanced mesh with morph targets at all (its loader's
    /// `InstancedMesh` carries no morph influences: it throws), and the wind's sway is one — the
    /// instances become nodes: per
    /// instance a node under the part's node with the instance's transform, holding the fur
    /// root (the first) or a copy of it and the nodes below (the meshes shared). Every
    /// animation channel on the fur's nodes (wind, shape keys) gets a twin on each copy.
    /// `attached` is the child [`Placing::attach_rigid`] hung under the node (the fur root,
    /// or the node between that places it). Returns a warning when the fur cannot be copied so.
    fn expand_instances(
        &self,
        out: &mut Value,
        bin: &mut Vec<u8>,
        p: usize,
        attached: Option<usize>,
    ) -> Option<String> {
        let part = &self.asset.parts[p];
        if part.instances.is_empty() {
            return None;
        }
        let name = crate::input::escape(&part.names.node);
        if part.skin.is_some() {
            return Some(format!(
                "node '{name}' is skinned and instanced (EXT_mesh_gpu_instancing): its fur is \
                 drawn once, bound to the skin"
            ));
        }
        let Some(root) = attached else {
            // a scene root: the node's transform cannot be undone
            return Some(format!(
                "node '{name}' is instanced (EXT_mesh_gpu_instancing), but its fur is a scene \
                 root (see above): it is drawn once, where the node's own transform puts it"
            ));
        };
        if self.instance_in_place(out, bin, root, &part.instances) {
            return None;
        }
        let children = out["nodes"][part.node]["children"].as_array_mut();
        let children = children.expect("the fur attached under the node");
        let at = (children.iter())
            .position(|c| c.as_u64() == Some(root as u64))
            .expect("the fur attached under the node");
        children.remove(at);
        let mut copies: Vec<(usize, usize)> = Vec::new();
        let mut holders = Vec::with_capacity(part.instances.len());
        for (i, &t) in part.instances.iter().enumerate() {
            let fur = match i {
                0 => root,
                _ => copy_subtree(out, root, &mut copies),
            };
            let mut holder = json!({ "name": format!("{}_fur_instance_{i}", part.names.node), "children": [fur] });
            match trs_of(t) {
                Some((t, r, sc)) => {
                    holder["translation"] = json!([t.x, t.y, t.z]);
                    holder["rotation"] = json!([r.x, r.y, r.z, r.w]);
                    holder["scale"] = json!([sc.x, sc.y, sc.z]);
                }
                None => holder["matrix"] = json!(t.to_cols_array()),
            }
            holders.push(push_one(out, "nodes", holder));
        }
        let children = out["nodes"][part.node]["children"]
            .as_array_mut()
            .expect("children");
        for (k, h) in holders.into_iter().enumerate() {
            children.insert(at + k, json!(h));
        }
        // the channels on the fur's nodes, twinned onto the copies
        let mut copies_of: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for (from, to) in copies {
            copies_of.entry(from).or_default().push(to);
        }
        let animations = out.get_mut("animations").and_then(Value::as_array_mut);
        for animation in animations.into_iter().flatten() {
            let Some(channels) = animation.get_mut("channels").and_then(Value::as_array_mut) else {
                continue;
            };
            let twins: Vec<Value> = (channels.iter())
                .flat_map(|c| {
                    let node = c["target"]["node"].as_u64().map(|n| n as usize);
                    let to = node.and_then(|n| copies_of.get(&n)).into_iter().flatten();
                    to.map(move |&to| {
                        let mut twin = c.clone();
                        twin["target"]["node"] = json!(to);
                        twin
                    })
                })
                .collect();
            channels.extend(twins);
        }
        None
    }

    /// Binds the layer nodes of surface `s` to `skin` (marked as the root is) and makes them
    /// and the surface's root roots of every scene that holds the part's node.
    fn attach_skinned(&self, out: &mut Value, s: usize, skin: usize, marker: &Value) {
        let (packed, base) = (self.packed, self.base);
        let surface = &packed.surfaces[s];
        let root = base.nodes + surface.root;
        // the layer nodes: roots of the fur file with a mesh, of this surface
        let layers: Vec<usize> = packed
            .roots
            .iter()
            .copied()
            .filter(|&n| packed.nodes[n].tag.surface == s && n != surface.root)
            .collect();
        // and the coarser levels' they name in MSFT_lod (in no scene)
        for n in crate::output::pack::skinned_nodes(packed, s, &layers) {
            let node = &mut out["nodes"][base.nodes + n];
            node["skin"] = json!(skin);
            node["extras"]["shellbake_fur"] = marker.clone();
        }
        // every scene that draws the part draws its fur (the file's default one when none
        // reaches it): a viewer opening another scene showed the creature bare
        let part = marker["node"].as_u64().expect("the part's node") as usize;
        let mut scenes = scenes_reaching(out, part);
        if scenes.is_empty() {
            scenes.push(self.scene);
        }
        for scene in scenes {
            let roots = std::iter::once(root).chain(layers.iter().map(|&n| base.nodes + n));
            add_to_scene(out, scene, roots);
        }
    }

    /// Makes the layer nodes of surface `s` follow the shape keys of part `p`, whose targets
    /// their meshes carry from [`PackedSurface::shape_keys_at`] on: every animation channel on
    /// the part's morph weights gets a twin for each layer node, keyed at the same times (the
    /// same input accessor), whose values are the node's own weights with the shape keys'
    /// replaced by the channel's (a `CUBICSPLINE` channel's tangents are zero for the node's
    /// own). Every level's twins (the coarser levels' are `MSFT_lod` alternatives) join the
    /// channel's animation: the asset's clips stay its clips. Layers with the
    /// same weights share an output, written into `bin`. Returns what the fur cannot follow.
    ///
    /// [`PackedSurface::shape_keys_at`]: crate::output::pack::PackedSurface::shape_keys_at
    fn follow_shape_keys(
        &self,
        out: &mut Value,
        bin: &mut Vec<u8>,
        s: usize,
        p: usize,
    ) -> Vec<String> {
        let (packed, base) = (self.packed, self.base);
        let part = &self.asset.parts[p];
        let Some(keys) = &part.shape_keys else {
            return vec![];
        };
        let node_name = crate::input::escape(&part.names.node);
        let surface = &packed.surfaces[s];
        let Some(at) = surface.shape_keys_at else {
            return vec![format!(
                "node '{node_name}' has shape keys, which the single-draw and layers layouts' fur \
                 does not follow (the compact layout's does)"
            )];
        };
        let k = keys.rest.len();
        // the surface's nodes that carry the keys, with where their targets start and their
        // weights, own and the keys': the layers (every level), the fins and the outline
        let extras = &surface.shape_key_extras;
        let layers: Vec<(usize, usize, &[f32])> = (0..packed.nodes.len())
            .filter(|i| packed.nodes[*i].tag.surface == s && !extras.contains(i))
            .map(|i| (i, at, packed.weights_of(i)))
            .filter(|&(_, at, w)| w.len() >= at + k)
            .chain(extras.iter().map(|&i| (i, 0, packed.weights_of(i))))
            .collect();
        for c in &keys.channels {
            let cubic = c.interpolation == crate::model::skeleton::Interpolation::CubicSpline;
            let entries = c.values.len() / k.max(1);
            let mut outputs: Vec<(Vec<u32>, usize)> = Vec::new();
            for &(n, at, rest) in &layers {
                let mut values = Vec::with_capacity(entries * rest.len());
                for e in 0..entries {
                    // a cubic key is in-tangents, values, out-tangents
                    let tangent = cubic && e % 3 != 1;
                    values.extend(rest.iter().enumerate().map(|(i, &w)| match i {
                        i if (at..at + k).contains(&i) => c.values[e * k + i - at],
                        _ if tangent => 0.0,
                        _ => w,
                    }));
                }
                let bits: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
                let output = match outputs.iter().find(|(b, _)| *b == bits) {
                    Some(&(_, a)) => a,
                    None => {
                        let a = float_accessor(out, bin, &values, ("SCALAR", "shape_key_weights"));
                        outputs.push((bits, a));
                        a
                    }
                };
                let animation = &mut out["animations"][c.animation];
                let sampler = push_one(
                    animation,
                    "samplers",
                    json!({
                        "input": c.input,
                        "output": output,
                        "interpolation": c.interpolation.name(),
                    }),
                );
                push_one(
                    animation,
                    "channels",
                    json!({
                        "sampler": sampler,
                        "target": { "node": base.nodes + n, "path": "weights" },
                    }),
                );
            }
        }
        let mut warnings = Vec::new();
        let windy = layers.iter().any(|&(_, at, rest)| rest.len() > at + k);
        if windy && !keys.channels.is_empty() {
            warnings.push(format!(
                "node '{node_name}': the wind's clip and the asset's clips on its shape keys both \
                 set the fur's layer weights, each holding the other's at rest: play one at a time"
            ));
        }
        warnings
    }

    /// Makes each layer node under `root` (the fur hung under an instanced part's node) carry
    /// the node's instances (`EXT_mesh_gpu_instancing`), seen from the layer: the layer draws
    /// at `W · J_i` where the part draws at `N · T_i` (`N` the node's world, `T_i` the
    /// instance), and the layer's world is `N · P` (`P` the transforms from the node down to
    /// it), so `J_i = P⁻¹ · T_i · P`. Returns false, changing nothing, where a layer has morph
    /// targets (three.js throws on them instanced) or some `J_i` is no TRS (a stretched node
    /// turned under its instances): the caller copies the fur instead.
    fn instance_in_place(
        &self,
        out: &mut Value,
        bin: &mut Vec<u8>,
        root: usize,
        instances: &[DMat4],
    ) -> bool {
        // every node drawing a mesh under `root`, with its `P`
        let mut layers: Vec<(usize, DMat4)> = Vec::new();
        // (nodes of the fur's own making: well formed)
        let local_of = |n: &Value| local_matrix(n).expect("a fur node's transform");
        let mut stack = vec![(root, local_of(&out["nodes"][root]))];
        while let Some((n, p)) = stack.pop() {
            let node = &out["nodes"][n];
            if let Some(m) = node["mesh"].as_u64() {
                let prims = out["meshes"][m as usize]["primitives"].as_array();
                if prims
                    .into_iter()
                    .flatten()
                    .any(|q| q.get("targets").is_some())
                {
                    return false;
                }
                layers.push((n, p));
            }
            for c in node["children"].as_array().into_iter().flatten() {
                let c = c.as_u64().expect("a node index") as usize;
                stack.push((c, p * local_of(&out["nodes"][c])));
            }
        }
        // one set of accessors a distinct `P` (the layers of one fur share one)
        let mut seen: Vec<(DMat4, Vec<Trs>)> = Vec::new();
        for &(_, p) in &layers {
            if seen.iter().any(|(q, _)| *q == p) {
                continue;
            }
            let inverse = p.inverse();
            let placed: Option<Vec<_>> = (instances.iter())
                .map(|&t| trs_of(inverse * t * p))
                .collect();
            match placed {
                Some(placed) => seen.push((p, placed)),
                None => return false,
            }
        }
        let mut written: Vec<(DMat4, Value)> = Vec::new();
        for (p, placed) in seen {
            let column = |f: &dyn Fn(&Trs) -> Vec<f64>| -> Vec<f32> {
                placed.iter().flat_map(f).map(|v| v as f32).collect()
            };
            let t = column(&|(t, _, _)| t.to_array().to_vec());
            let r = column(&|(_, r, _)| r.normalize().to_array().to_vec());
            let sc = column(&|(_, _, s)| s.to_array().to_vec());
            let attributes = json!({
                "TRANSLATION": float_accessor(out, bin, &t, ("VEC3", "fur_instances")),
                "ROTATION": float_accessor(out, bin, &r, ("VEC4", "fur_instances")),
                "SCALE": float_accessor(out, bin, &sc, ("VEC3", "fur_instances")),
            });
            written.push((p, attributes));
        }
        for (n, p) in layers {
            let attributes = &written.iter().find(|(q, _)| *q == p).expect("written").1;
            let node = out["nodes"][n].as_object_mut().expect("a node");
            let extensions = node.entry("extensions").or_insert_with(|| json!({}));
            extensions["EXT_mesh_gpu_instancing"] = json!({ "attributes": attributes });
        }
        true
    }

    /// Makes the root of surface `s` a child of part `p`'s node, its transform the
    /// dequantization relative to the node. Where that is no TRS (a rotation and an uneven
    /// scale meet: a rotated box stretched along one axis), it is split in two ([`two_trs_of`]):
    /// a node between the part's node and the root takes the translation, a rotation and the
    /// scale, and the root a rotation. Returns the child hung under the part's node (the root,
    /// or the node between). A node whose transform cannot be undone (a scale of 0) leaves the
    /// root in the scene where it was baked, with the warning returned instead.
    fn attach_rigid(
        &self,
        out: &mut Value,
        s: usize,
        p: usize,
    ) -> std::result::Result<usize, String> {
        let part = &self.asset.parts[p];
        let surface = &self.packed.surfaces[s];
        let root = self.base.nodes + surface.root;
        let dequantize = DMat4::from_scale_rotation_translation(
            DVec3::splat(surface.scale),
            DQuat::IDENTITY,
            surface.translation,
        );
        let local = part.world.inverse() * dequantize;
        let trs = |(t, r, sc): (DVec3, DQuat, DVec3), node: &mut Map<String, Value>| {
            node.insert("translation".into(), json!([t.x, t.y, t.z]));
            if r != DQuat::IDENTITY {
                node.insert("rotation".into(), json!([r.x, r.y, r.z, r.w]));
            }
            node.insert("scale".into(), json!([sc.x, sc.y, sc.z]));
        };
        let child = if let Some(placed) = trs_of(local) {
            trs(placed, out["nodes"][root].as_object_mut().expect("a node"));
            root
        } else if let Some((outer, inner)) = two_trs_of(local) {
            let node = out["nodes"][root].as_object_mut().expect("a node");
            node.remove("translation");
            node.remove("scale");
            node.insert(
                "rotation".into(),
                json!([inner.x, inner.y, inner.z, inner.w]),
            );
            let name = format!("{} placement", node["name"].as_str().unwrap_or("shellbake"));
            let mut between = Map::new();
            between.insert("name".into(), json!(name));
            trs(outer, &mut between);
            between.insert("children".into(), json!([root]));
            push_one(out, "nodes", Value::Object(between))
        } else {
            add_to_scene(out, self.scene, std::iter::once(root));
            return Err(format!(
                "node '{}' has a transform that cannot be undone (a scale of 0) at rest: its fur \
                 is a scene root placed where it was baked and does not follow the node's \
                 animation",
                crate::input::escape(&part.names.node)
            ));
        };
        let parent = out["nodes"][part.node].as_object_mut().expect("a node");
        let children = parent
            .entry("children")
            .or_insert_with(|| json!([]))
            .as_array_mut()
            .expect("children");
        children.push(json!(child));
        Ok(child)
    }
}

/// Appends a copy of node `n` and the nodes below it (meshes, skins and the rest shared);
/// returns the copy's index and records each `(node, copy)` in `copies`.
fn copy_subtree(out: &mut Value, n: usize, copies: &mut Vec<(usize, usize)>) -> usize {
    let mut node = out["nodes"][n].clone();
    let children: Vec<usize> = (node["children"].as_array().into_iter().flatten())
        .filter_map(|c| c.as_u64().map(|c| c as usize))
        .collect();
    if !children.is_empty() {
        let copied: Vec<usize> = children
            .iter()
            .map(|&c| copy_subtree(out, c, copies))
            .collect();
        node["children"] = json!(copied);
    }
    let copy = push_one(out, "nodes", node);
    copies.push((n, copy));
    copy
}

/// Writes `asset` with the fur grafted on: the fur's document (its JSON, and what appends its
/// binary, [`crate::output::write::append_binary`]) merged into the asset's, every index of the
/// fur shifted past the asset's, and its packing; surface `s` of the fur grows on part
/// `parts[s]` of the asset.
pub fn graft(
    asset: &Asset,
    groups: &[Vec<usize>],
    (fur_json, fur_bin): (&Value, impl FnOnce(&mut Vec<u8>)),
    packed: &Packed,
) -> Result<Grafted> {
    assert_eq!(
        groups.len(),
        packed.surfaces.len(),
        "one group of parts per fur surface"
    );
    let mut out = asset.doc.json.clone();
    let mut bin: Vec<u8> = Vec::new();
    carry_buffers(asset, &mut out, &mut bin);
    embed_images(asset, &mut out, &mut bin)?;
    let base = Base::of(&out);
    // the fur's binary chunk, after the input's
    align(&mut bin);
    let fur_offset = bin.len();
    fur_bin(&mut bin);
    // the fur's fallback buffers (compressed views decode into them) follow the input's
    let (mut buffers, fur_buffers) = fur_buffers(fur_json);
    append_fur(&mut out, fur_json, base, (fur_offset, &fur_buffers));

    // attach each surface's fur to its part
    let placing = Placing {
        asset,
        packed,
        base,
        scene: out["scene"].as_u64().unwrap_or(0) as usize,
    };
    let mut warnings = Vec::new();
    for (s, group) in groups.iter().enumerate() {
        let p = group[0];
        let attached = placing.attach(&mut out, s, group);
        warnings.extend(attached.as_ref().err().cloned());
        warnings.extend(placing.follow_shape_keys(&mut out, &mut bin, s, p));
        warnings.extend(placing.expand_instances(&mut out, &mut bin, p, attached.ok().flatten()));
    }
    add_lod_scene(&mut out, packed, base, placing.scene);
    merge_extensions(&mut out, fur_json);
    align(&mut bin);
    buffers[0] = json!({ "byteLength": bin.len() });
    out["buffers"] = Value::Array(buffers);
    let glb = crate::output::write::glb_bytes(&out, &bin);
    Ok(Grafted {
        glb,
        json: out,
        warnings,
    })
}

/// A float accessor of `kind` (`SCALAR`, `VEC3`, `VEC4`) over `values`, written into `bin`
/// (buffer 0) in a view named `name`.
fn float_accessor(
    out: &mut Value,
    bin: &mut Vec<u8>,
    values: &[f32],
    (kind, name): (&str, &str),
) -> usize {
    let width = match kind {
        "VEC3" => 3,
        "VEC4" => 4,
        _ => 1,
    };
    align(bin);
    let offset = bin.len();
    bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    let view = json!({
        "buffer": 0,
        "byteOffset": offset,
        "byteLength": 4 * values.len(),
        "name": name,
    });
    let view = push_one(out, "bufferViews", view);
    let accessor = json!({
        "bufferView": view,
        "componentType": 5126,
        "count": values.len() / width,
        "type": kind,
    });
    push_one(out, "accessors", accessor)
}

/// Appends `item` to the array `kind` of `v` (made when missing); returns its index.
fn push_one(v: &mut Value, kind: &str, item: Value) -> usize {
    let list = v
        .as_object_mut()
        .expect("an object")
        .entry(kind)
        .or_insert_with(|| json!([]))
        .as_array_mut()
        .expect("a list");
    list.push(item);
    list.len() - 1
}

fn align(bin: &mut Vec<u8>) {
    bin.resize(bin.len().next_multiple_of(8), 0);
}

/// Moves the input's buffers into `bin`, the views that read them shifted, compressed views
/// written decoded. Buffers no view reads are left out.
fn carry_buffers(asset: &Asset, out: &mut Value, bin: &mut Vec<u8>) {
    let Some(views) = out.get_mut("bufferViews").and_then(Value::as_array_mut) else {
        return;
    };
    for v in views.iter_mut() {
        if let Some(ext) = v.get_mut("extensions").and_then(Value::as_object_mut) {
            for name in MESHOPT {
                ext.remove(name);
            }
            if ext.is_empty() {
                v.as_object_mut().map(|o| o.remove("extensions"));
            }
        }
    }
    let mut offset: Vec<Option<usize>> = vec![None; asset.buffers.len()];
    for v in views.iter_mut() {
        let b = v["buffer"].as_u64().unwrap_or(0) as usize;
        let at = *offset[b].get_or_insert_with(|| {
            align(bin);
            let at = bin.len();
            bin.extend_from_slice(&asset.buffers[b]);
            at
        });
        let o = v.as_object_mut().expect("a buffer view");
        o.insert("buffer".into(), json!(0));
        let shifted = o.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize + at;
        o.insert("byteOffset".into(), json!(shifted));
    }
    for list in ["extensionsUsed", "extensionsRequired"] {
        if let Some(l) = out.get_mut(list).and_then(Value::as_array_mut) {
            l.retain(|e| !MESHOPT.contains(&e.as_str().unwrap_or("")));
        }
        if out
            .get(list)
            .and_then(Value::as_array)
            .is_some_and(Vec::is_empty)
        {
            out.as_object_mut().map(|o| o.remove(list));
        }
    }
}

/// The image types [`embed_images`] tells by their bytes.
const SNIFFED: [&str; 4] = ["image/png", "image/jpeg", "image/ktx2", "image/webp"];

/// Embeds every image given by a URI — a file, or a `data:` URI decoded (a GLB's images belong
/// in its binary chunk: the validator warns `DATA_URI_GLB` otherwise) — as a buffer view of
/// `bin`; one that cannot be read is an error naming it.
fn embed_images(asset: &Asset, out: &mut Value, bin: &mut Vec<u8>) -> Result<()> {
    let Some(images) = out["images"].as_array().cloned() else {
        return Ok(());
    };
    for (i, image) in images.iter().enumerate() {
        let Some(uri) = image["uri"].as_str() else {
            continue;
        };
        let bytes = asset.doc.read_uri(&format!("image {i}"), uri)?;
        // the media type a `data:` URI declares, for bytes not sniffed below
        let declared = uri
            .strip_prefix("data:")
            .and_then(|rest| rest.split_once(';'))
            .map(|(media, _)| media)
            .filter(|media| !media.is_empty());
        let mime = if bytes.starts_with(b"\x89PNG") {
            "image/png"
        } else if bytes.starts_with(&[0xff, 0xd8]) {
            "image/jpeg"
        } else if bytes.starts_with(b"\xabKTX 20") {
            "image/ktx2"
        } else if bytes.len() > 12 && &bytes[8..12] == b"WEBP" {
            "image/webp"
        } else {
            // a type the bytes do not bear out, or none, would write an invalid file (the
            // validator rejects it; a `map_Kd` naming a text file did): refused. A declared type
            // the sniffing above does not know (`image/vnd-ms.dds`) is kept.
            match image["mimeType"].as_str().or(declared) {
                Some(m) if !SNIFFED.contains(&m) => m,
                named => {
                    let element = format!("image {i} ('{}')", crate::input::escape(uri));
                    let message = match named {
                        Some(m) => format!("declared {m}, but its bytes are not one"),
                        None => "not a PNG, JPEG, KTX2 or WebP image".to_string(),
                    };
                    return Err(Error::invalid(&asset.doc.path, element, message));
                }
            }
        };
        align(bin);
        let view = out["bufferViews"].as_array().map_or(0, Vec::len);
        let entry = json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
        bin.extend_from_slice(&bytes);
        match out.get_mut("bufferViews").and_then(Value::as_array_mut) {
            Some(v) => v.push(entry),
            None => out["bufferViews"] = json!([entry]),
        }
        let o = out["images"][i].as_object_mut().expect("an image");
        o.remove("uri");
        o.insert("bufferView".into(), json!(view));
        o.insert("mimeType".into(), json!(mime));
    }
    Ok(())
}

/// Shifts the index at `pointer` inside `v` by `by`, when there is one.
fn shift(v: &mut Value, pointer: &str, by: usize) {
    if let Some(x) = v.pointer_mut(pointer) {
        if let Some(i) = x.as_u64() {
            *x = json!(i as usize + by);
        }
    }
}

/// Shifts each index of the list at `pointer` inside `v` by `by`.
fn shift_all(v: &mut Value, pointer: &str, by: usize) {
    for x in v
        .pointer_mut(pointer)
        .and_then(Value::as_array_mut)
        .into_iter()
        .flatten()
    {
        if let Some(i) = x.as_u64() {
            *x = json!(i as usize + by);
        }
    }
}

/// Appends `items` to the list `kind` of `out` (made when missing; nothing when empty).
fn push_items(out: &mut Value, kind: &str, items: Vec<Value>) {
    if items.is_empty() {
        return;
    }
    match out.get_mut(kind).and_then(Value::as_array_mut) {
        Some(list) => list.extend(items),
        None => out[kind] = Value::Array(items),
    }
}

/// A copy of the fur file's list `kind` (empty when missing).
fn fur_list(fur: &Value, kind: &str) -> Vec<Value> {
    fur[kind].as_array().cloned().unwrap_or_default()
}

/// The fur's buffer views, each view (and its compression extension) on the output buffer
/// `buffers` maps its buffer to; those on buffer 0 read the fur's chunk at `offset`.
fn fur_views(fur: &Value, (offset, buffers): (usize, &[usize])) -> Vec<Value> {
    let mut views = fur_list(fur, "bufferViews");
    let rebase = |v: &mut Value| {
        let b = v["buffer"].as_u64().unwrap_or(0) as usize;
        v["buffer"] = json!(buffers[b]);
        if b == 0 {
            let at = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            v["byteOffset"] = json!(at + offset);
        }
    };
    for v in &mut views {
        rebase(v);
        for name in MESHOPT {
            if let Some(ext) = v.pointer_mut(&format!("/extensions/{name}")) {
                rebase(ext);
            }
        }
    }
    views
}

/// The indices each kind holds, by JSON pointer, with what they are shifted by: one index
/// ([`shift`]) or a list ([`shift_all`]).
type Pointers<'a> = &'a [(&'a str, usize)];

/// Appends the fur's accessors, images, samplers, textures, skins and nodes to `out`, their
/// indices shifted by `base`.
fn append_shifted(out: &mut Value, fur: &Value, base: Base) {
    let rules: [(&str, Pointers, Pointers); 6] = [
        ("accessors", &[("/bufferView", base.views)], &[]),
        ("images", &[("/bufferView", base.views)], &[]),
        ("samplers", &[], &[]),
        (
            "textures",
            &[("/source", base.images), ("/sampler", base.samplers)],
            &[],
        ),
        (
            "skins",
            &[
                ("/inverseBindMatrices", base.accessors),
                ("/skeleton", base.nodes),
            ],
            &[("/joints", base.nodes)],
        ),
        (
            "nodes",
            &[("/mesh", base.meshes), ("/skin", base.skins)],
            &[
                ("/children", base.nodes),
                ("/extensions/MSFT_lod/ids", base.nodes),
            ],
        ),
    ];
    for (kind, one, all) in rules {
        let mut items = fur_list(fur, kind);
        for item in &mut items {
            for &(pointer, by) in one {
                shift(item, pointer, by);
            }
            for &(pointer, by) in all {
                shift_all(item, pointer, by);
            }
        }
        push_items(out, kind, items);
    }
}

/// The fur's meshes, their primitives' accessors (attributes, morph targets, indices) and
/// materials shifted by `base`.
fn fur_meshes(fur: &Value, base: Base) -> Vec<Value> {
    let mut meshes = fur_list(fur, "meshes");
    for m in &mut meshes {
        let primitives = m.get_mut("primitives").and_then(Value::as_array_mut);
        for p in primitives.into_iter().flatten() {
            let attributes = p.get_mut("attributes").and_then(Value::as_object_mut);
            for a in attributes.into_iter().flat_map(|o| o.values_mut()) {
                shift(a, "", base.accessors);
            }
            let targets = p.get_mut("targets").and_then(Value::as_array_mut);
            for t in targets.into_iter().flatten() {
                for a in t.as_object_mut().into_iter().flat_map(|o| o.values_mut()) {
                    shift(a, "", base.accessors);
                }
            }
            shift(p, "/indices", base.accessors);
            shift(p, "/material", base.materials);
        }
    }
    meshes
}

/// The fur's animations, their target nodes and sampler accessors shifted by `base`.
fn fur_animations(fur: &Value, base: Base) -> Vec<Value> {
    let mut animations = fur_list(fur, "animations");
    for a in &mut animations {
        let channels = a.get_mut("channels").and_then(Value::as_array_mut);
        for c in channels.into_iter().flatten() {
            shift(c, "/target/node", base.nodes);
        }
        let samplers = a.get_mut("samplers").and_then(Value::as_array_mut);
        for s in samplers.into_iter().flatten() {
            shift(s, "/input", base.accessors);
            shift(s, "/output", base.accessors);
        }
    }
    animations
}

/// Appends the fur file's objects to `out`, every index shifted by `base`; its buffer views
/// read the fur's chunk at `offset` (buffer 0) or the fallback buffers `buffers` maps to.
fn append_fur(out: &mut Value, fur: &Value, base: Base, chunk: (usize, &[usize])) {
    push_items(out, "bufferViews", fur_views(fur, chunk));
    append_shifted(out, fur, base);
    let mut materials = fur_list(fur, "materials");
    for m in &mut materials {
        shift_texture_indices(m, base.textures);
    }
    push_items(out, "materials", materials);
    push_items(out, "meshes", fur_meshes(fur, base));
    push_items(out, "animations", fur_animations(fur, base));
}

/// Shifts every texture index in a material (its `textureInfo`s, those of its extensions too).
fn shift_texture_indices(v: &mut Value, by: usize) {
    match v {
        Value::Object(o) => {
            for (k, child) in o.iter_mut() {
                if k == "index" {
                    if let Some(i) = child.as_u64() {
                        *child = json!(i as usize + by);
                    }
                } else {
                    shift_texture_indices(child, by);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|c| shift_texture_indices(c, by)),
        _ => {}
    }
}

/// Puts the fur's coarser levels (`MSFT_lod` alternatives) in the scene that holds them, as the
/// fur-only file does (`write.rs`, "Where the coarser levels live"): a scene of that name the
/// input already has (a re-bake), else a new last scene; and makes `shown`, the scene the fur
/// grows in, the default one, since Blender draws every scene's nodes when the file names none.
fn add_lod_scene(out: &mut Value, packed: &Packed, base: Base, shown: usize) {
    let levels = packed.lod_levels();
    let scenes = out
        .get("scenes")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    if levels.is_empty() || shown >= scenes {
        return;
    }
    out["scene"] = json!(shown);
    let scenes = out["scenes"].as_array_mut().expect("scenes");
    let named = |s: &Value| s["name"].as_str() == Some(crate::output::write::LOD_SCENE);
    let at = match scenes.iter().position(named) {
        Some(at) => at,
        None => {
            scenes.push(json!({ "name": crate::output::write::LOD_SCENE }));
            scenes.len() - 1
        }
    };
    add_to_scene(out, at, levels.into_iter().map(|n| base.nodes + n));
}

/// The scenes of `out` whose node trees hold `node`, in order.
fn scenes_reaching(out: &Value, node: usize) -> Vec<usize> {
    let scenes = out["scenes"].as_array().map_or(&[][..], Vec::as_slice);
    let ids = |v: &Value| -> Vec<usize> {
        (v.as_array().into_iter().flatten())
            .filter_map(|n| n.as_u64().map(|n| n as usize))
            .collect()
    };
    (0..scenes.len())
        .filter(|&k| {
            let mut seen = std::collections::HashSet::new();
            let mut stack = ids(&scenes[k]["nodes"]);
            while let Some(n) = stack.pop() {
                if n == node {
                    return true;
                }
                if seen.insert(n) {
                    stack.extend(ids(&out["nodes"][n]["children"]));
                }
            }
            false
        })
        .collect()
}

/// Adds `nodes` to scene `scene`'s roots (when the file has scenes; otherwise a parentless node
/// is a root already).
fn add_to_scene(out: &mut Value, scene: usize, nodes: impl Iterator<Item = usize>) {
    let Some(s) = out.pointer_mut(&format!("/scenes/{scene}")) else {
        return;
    };
    match s.get_mut("nodes").and_then(Value::as_array_mut) {
        Some(list) => list.extend(nodes.map(|n| json!(n))),
        None => s["nodes"] = Value::Array(nodes.map(|n| json!(n)).collect()),
    }
}

/// Largest difference, relative to the part's scale ([`places_as`]), between a part's
/// `W⁻¹ · D` and the transform its fur root (and the node between, if any) is given. A file's node transforms are `f32`: an
/// exporter that writes a uniform scale as three separately rounded values (Blender: one ulp
/// apart) or a quaternion a few ulps from unit length makes a rotated, uniformly scaled node
/// shear by about 1e-7, which is no reason for a second node. A real non-uniform scale under a
/// rotation shears by the scales' relative difference, so one of 1e-5 or more takes the two
/// nodes of [`two_trs_of`]. The root's transform moves the fur by at most this fraction of the
/// node's size: a sixtieth of a 14-bit position step.
const TRS_TOLERANCE: f64 = 1e-6;

/// `m` as translation, rotation and scale, when it is one ([`places_as`]).
fn trs_of(m: DMat4) -> Option<(DVec3, DQuat, DVec3)> {
    let (s, r, t) = m.to_scale_rotation_translation();
    let back = DMat4::from_scale_rotation_translation(s, r, t);
    (places_as(back, m) && s.is_finite() && r.is_finite() && t.is_finite()).then_some((t, r, s))
}

/// Whether `back` puts the fur where `m` does, to within [`TRS_TOLERANCE`]: its linear part
/// relative to `m`'s scale (its longest column: the stored positions span about that many
/// units), its translation relative to the larger of that and `m`'s translation. (Relative to
/// the largest entry of `m`, as before, a part far from its node's origin let a shear of 0.2 %
/// through: its translation set the size.)
fn places_as(back: DMat4, m: DMat4) -> bool {
    let linear = |x: DMat4| DMat3::from_mat4(x);
    let columns = linear(m).to_cols_array_2d();
    let scale = (columns.iter()).fold(0.0f64, |a, c| a.max(DVec3::from_array(*c).length()));
    let most = |v: &[f64]| v.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let linear_err = most(&(linear(back) - linear(m)).to_cols_array());
    let (t, t_back) = (m.w_axis.truncate(), back.w_axis.truncate());
    let span = scale.max(most(&t.to_array()));
    let err = most(&(t_back - t).to_array());
    scale > 0.0
        && linear_err <= TRS_TOLERANCE * scale
        && err <= TRS_TOLERANCE * span
        && back.is_finite()
}

/// `m` (an affine map) as a TRS times a rotation, `m = TRS(t, U, Σ) · R(Vᵀ)`, from the singular
/// value decomposition of its linear part `U Σ Vᵀ` (`U` and `V` rotations; a mirroring `m` takes
/// a negative scale): what any invertible affine map is, shear included, so a fur root under a
/// node of any transform has one. `V` holds the eigenvectors of `LᵀL`; `U`'s first two columns
/// are `L v / σ` for the two largest singular values, made orthonormal, and its third their
/// cross product, so `U` is a rotation however unevenly `L` scales (the smallest `σ`, which
/// squaring the condition number blurs, only scales). `None` when the map is singular, or the
/// decomposition does not give `m` back ([`places_as`]).
fn two_trs_of(m: DMat4) -> Option<((DVec3, DQuat, DVec3), DQuat)> {
    let linear = DMat3::from_mat4(m);
    let (eigenvalues, v) = symmetric_eigen(linear.transpose() * linear);
    // largest singular value first
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eigenvalues[b].total_cmp(&eigenvalues[a]));
    let mut v = DMat3::from_cols(v.col(order[0]), v.col(order[1]), v.col(order[2]));
    if v.determinant() < 0.0 {
        v.z_axis = -v.z_axis;
    }
    let sigma = order.map(|k| eigenvalues[k].max(0.0).sqrt());
    if !(sigma[0].is_finite() && sigma[2] > sigma[0] * 1e-9) {
        return None;
    }
    let u0 = (linear * v.x_axis).normalize();
    let u1 = linear * v.y_axis;
    let u1 = (u1 - u0 * u0.dot(u1)).normalize();
    let u2 = u0.cross(u1);
    let u = DMat3::from_cols(u0, u1, u2);
    // the third scale carries the mirroring, if any
    let scale = DVec3::new(sigma[0], sigma[1], u2.dot(linear * v.z_axis));
    let outer = DQuat::from_mat3(&u).normalize();
    let inner = DQuat::from_mat3(&v.transpose()).normalize();
    let t = m.w_axis.truncate();
    let back = DMat4::from_scale_rotation_translation(scale, outer, t) * DMat4::from_quat(inner);
    (places_as(back, m) && outer.is_finite() && inner.is_finite())
        .then_some(((t, outer, scale), inner))
}

/// The eigenvalues of the symmetric `a` and their unit eigenvectors (the columns), by cyclic
/// Jacobi rotations (each zeroes one off-diagonal pair; a 3 × 3 matrix converges in a few
/// sweeps to `f64` precision).
fn symmetric_eigen(a: DMat3) -> (DVec3, DMat3) {
    // row-major copies: a[r][c]
    let mut a = a.transpose().to_cols_array_2d();
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..64 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let diagonal = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= diagonal * 1e-17 || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // a ← Jᵀ a J and v ← v J, J the rotation in the (p, q) plane
            for row in &mut a {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            let (x, y) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * x[k] - s * y[k]);
            a[q] = std::array::from_fn(|k| s * x[k] + c * y[k]);
            for row in &mut v {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
        }
    }
    let values = DVec3::new(a[0][0], a[1][1], a[2][2]);
    // v is row-major: its columns are the eigenvectors
    (values, DMat3::from_cols_array_2d(&v).transpose())
}

/// The union of both files' extension lists, the input's first.
fn merge_extensions(out: &mut Value, fur: &Value) {
    for list in ["extensionsUsed", "extensionsRequired"] {
        let mut names: Vec<Value> = out[list].as_array().cloned().unwrap_or_default();
        for e in fur[list].as_array().into_iter().flatten() {
            if !names.contains(e) {
                names.push(e.clone());
            }
        }
        if !names.is_empty() {
            out[list] = Value::Array(names);
        }
    }
}

/// A translation, rotation and scale.
type Trs = (DVec3, DQuat, DVec3);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trs_of_refuses_shear_and_keeps_trs() {
        let m = DMat4::from_scale_rotation_translation(
            DVec3::new(2.0, 2.0, 2.0),
            DQuat::from_rotation_y(0.7),
            DVec3::new(1.0, -3.0, 5.0),
        );
        let (t, r, s) = trs_of(m).expect("a TRS");
        assert!((t - DVec3::new(1.0, -3.0, 5.0)).length() < 1e-12);
        assert!((s - DVec3::splat(2.0)).length() < 1e-12);
        assert!(r.angle_between(DQuat::from_rotation_y(0.7)) < 1e-9);
        // a non-uniform scale after a rotation shears
        let shear = DMat4::from_scale(DVec3::new(1.0, 3.0, 1.0)) * DMat4::from_rotation_z(0.5);
        assert!(trs_of(shear).is_none());
        // so does a scale 1e-5 apart, however small
        let slight = DMat4::from_rotation_z(0.5)
            * DMat4::from_scale(DVec3::new(1.0, 1.00001, 1.0))
            * DMat4::from_rotation_x(0.8);
        assert!(trs_of(slight).is_none());
    }

    #[test]
    fn any_invertible_affine_map_is_a_trs_times_a_rotation() {
        let maps = [
            // a rotated box stretched along one axis, placed by its dequantization
            DMat4::from_scale(DVec3::new(1.0, 1.0 / 3.0, 1.0))
                * DMat4::from_rotation_z(-0.52)
                * DMat4::from_scale_rotation_translation(
                    DVec3::splat(0.002),
                    DQuat::IDENTITY,
                    DVec3::new(1.5, -0.2, 0.3),
                ),
            // a shear, mirrored
            DMat4::from_cols_array(&[
                1.0, 0.4, 0.0, 0.0, 0.0, -2.0, 0.3, 0.0, 0.2, 0.0, 0.5, 0.0, 4.0, 5.0, 6.0, 1.0,
            ]),
            // a plain TRS, and equal scales (repeated singular values)
            DMat4::from_scale_rotation_translation(
                DVec3::splat(7.0),
                DQuat::from_rotation_y(1.1),
                DVec3::new(-1.0, 2.0, 0.0),
            ),
        ];
        for m in maps {
            let ((t, outer, scale), inner) = two_trs_of(m).expect("invertible");
            let back =
                DMat4::from_scale_rotation_translation(scale, outer, t) * DMat4::from_quat(inner);
            let err = (back - m).to_cols_array();
            assert!(err.iter().all(|e| e.abs() < 1e-12), "{m:?}: {err:?}");
            assert!(outer.is_normalized() && inner.is_normalized());
        }
        assert!(two_trs_of(DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0))).is_none());
        // nearly flat: U stays a rotation, the flat axis only scales
        let flat = DMat4::from_rotation_z(0.7)
            * DMat4::from_scale(DVec3::new(1.0, 1e-7, 1.0))
            * DMat4::from_rotation_x(0.3);
        let ((t, outer, scale), inner) = two_trs_of(flat).expect("invertible");
        let back =
            DMat4::from_scale_rotation_translation(scale, outer, t) * DMat4::from_quat(inner);
        let err = (back - flat).to_cols_array();
        assert!(err.iter().all(|e| e.abs() < 1e-12), "{err:?}");
        assert!((outer.length() - 1.0).abs() < 1e-12 && (inner.length() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_small_part_far_from_its_node_s_origin_is_judged_by_its_own_size() {
        // a 2 cm part 70 units from its node's origin, the node turned and stretched by 0.2 %:
        // no TRS places it (the old tolerance, relative to the translation, let it through)
        let m = DMat4::from_scale(DVec3::new(1.0, 1.0 / 1.002, 1.0))
            * DMat4::from_rotation_z(-0.7)
            * DMat4::from_scale_rotation_translation(
                DVec3::splat(0.01),
                DQuat::IDENTITY,
                DVec3::new(70.0, 0.0, 0.0),
            );
        assert!(trs_of(m).is_none());
        assert!(two_trs_of(m).is_some());
    }

    #[test]
    fn an_f32_uniform_scale_under_a_rotation_is_a_trs() {
        // as Blender exports a rotated rock scaled by 1.368: the scale's y one f32 ulp off, the
        // quaternion 7e-8 from unit length
        let s = 1.368_045_3_f32;
        let scale = glam::Vec3::new(s, f32::from_bits(s.to_bits() - 1), s).as_dvec3();
        let q = glam::Quat::from_xyzw(0.3, -0.5, 0.7, 0.4);
        let q = glam::Quat::from_xyzw(q.x * 1.000_000_1, q.y, q.z, q.w) / q.length();
        let world =
            DMat4::from_scale_rotation_translation(scale, q.as_dquat(), DVec3::new(3.0, 0.0, -2.0));
        // a normalized i16 grid: 32767 steps of a 1.5-unit rock's 14-bit grid
        let dequantize = DMat4::from_scale_rotation_translation(
            DVec3::splat(32767.0 * 1.5 / 16383.0),
            DQuat::IDENTITY,
            DVec3::new(3.1, 0.2, -2.05),
        );
        let local = world.inverse() * dequantize;
        let (t, r, sc) = trs_of(local).expect("within f32's reach of a TRS");
        let back = DMat4::from_scale_rotation_translation(sc, r, t);
        let err = (world * back - dequantize).to_cols_array();
        assert!(err.iter().all(|e| e.abs() < 1e-6), "{err:?}");
    }

    #[test]
    fn texture_indices_shift_everywhere_in_a_material() {
        let mut m = json!({
            "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } },
            "extensions": { "KHR_materials_sheen": { "sheenColorTexture": { "index": 2 } } }
        });
        shift_texture_indices(&mut m, 5);
        assert_eq!(m["pbrMetallicRoughness"]["baseColorTexture"]["index"], 5);
        assert_eq!(
            m["extensions"]["KHR_materials_sheen"]["sheenColorTexture"]["index"],
            7
        );
    }
}
