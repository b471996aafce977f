//! The runtime reference's fins and outline: what the technique's extra passes draw (fins
//! extruded from mesh edges, textured by a strip; the inverted hull drawn with front faces
//! culled, unlit), built here from the *input* mesh and the law texture, sharing nothing with
//! `pack` or the baked file, and drawn by the glTF renderer from a small in-memory glTF of
//! float accessors written here.
//!
//! - **Fins**: for each fin edge the fins stage chose (its decision, like the frames stage's
//!   extrusion), the quad `a, b, b + t·δ_b, a + t·δ_a` in both windings, `u` from the edge's
//!   offset along its world length, `v` = height. The strip comes from the reference's own
//!   law texture (`reference::law_texture`, handed in by the reference) by the law's own test per row: noise
//!   survives while `n·(1 − t) ≥ c`, a cell texel while its code reaches the row's step.
//! - **Outline**: the base shifted by the stage's offsets, each triangle's winding reversed,
//!   `KHR_materials_unlit` in the stage's colour.

use glam::{Vec2, Vec3};
use serde_json::json;

use super::glb::Asset;
use crate::effects::fins::{Fins, Strip};
use crate::effects::outline::Outline;
use crate::grid::{BASE_CODE, HEIGHT_STEPS};
use crate::model::mesh::Mesh;
use crate::params::{StrandModel, StrandParams};
use crate::stages::shells::ShadeParams;

/// The reference's strip: for each column, the band texel with the largest law value (its
/// shade), tested per row by the law itself. `law` is the reference's law texture for `strands`.
pub fn reference_strip(
    law: &[u8],
    strands: &StrandParams,
    shade: &ShadeParams,
    rows: u32,
) -> Strip {
    let size = strands.mask_size;
    let band = match strands.model {
        StrandModel::Noise { .. } => 1,
        StrandModel::Cells {
            texels_per_cell, ..
        } => texels_per_cell,
    };
    let mut rgba = Vec::new();
    for r in 0..rows {
        let t = (r as f32 + 0.5) / rows as f32;
        let k = ((t * HEIGHT_STEPS as f32).round() as u32).min(HEIGHT_STEPS);
        let t_k = crate::grid::step_height(k);
        let colour = crate::stages::shells::layer_color(shade, t);
        for x in 0..size {
            let mut best = (0u8, 0u8);
            for y in 0..band {
                let i = ((y * size + x) * 4) as usize;
                if law[i + 3] > best.0 || y == 0 {
                    best = (law[i + 3], law[i]);
                }
            }
            let survives = match strands.model {
                StrandModel::Noise { threshold } => {
                    best.0 as f32 / 255.0 * (1.0 - t_k) >= threshold
                }
                StrandModel::Cells { .. } => best.0 as u32 >= BASE_CODE + k,
            };
            let grey = crate::srgb::decode8(best.1);
            let c = colour.map(|c| crate::srgb::encode8(c as f64 * grey));
            rgba.extend_from_slice(&[c[0], c[1], c[2], if survives { 255 } else { 0 }]);
        }
    }
    Strip {
        width: size,
        height: rows,
        rgba,
    }
}

/// A binary chunk being filled with accessors.
#[derive(Default)]
struct Buffer {
    bin: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl Buffer {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views
            .push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats(&mut self, values: &[f32], kind: &str, count: usize) -> usize {
        let view = self.view(bytemuck::cast_slice(values));
        self.accessors.push(
            json!({ "bufferView": view, "componentType": 5126, "count": count, "type": kind }),
        );
        self.accessors.len() - 1
    }

    fn indices(&mut self, ix: &[u32]) -> usize {
        let view = self.view(bytemuck::cast_slice(ix));
        self.accessors.push(json!({ "bufferView": view, "componentType": 5125, "count": ix.len(), "type": "SCALAR" }));
        self.accessors.len() - 1
    }
}

/// What the reference draws besides its shells.
pub struct ExtrasInput<'a> {
    pub mesh: &'a Mesh,
    pub delta: &'a [Vec3],
    pub fins: Option<&'a Fins>,
    pub outline: Option<&'a Outline>,
    pub strands: &'a StrandParams,
    /// The reference's law texture for `strands`.
    pub law: &'a [u8],
    pub shade: &'a ShadeParams,
    pub roughness: f32,
}

/// The fins and outline as an in-memory glTF asset (`None` when there are neither).
pub fn extras_asset(input: &ExtrasInput) -> Option<Asset> {
    if input.fins.is_none() && input.outline.is_none() {
        return None;
    }
    let mesh = input.mesh;
    let flat3 = |v: &[Vec3]| v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>();
    let mut buf = Buffer::default();
    let mut meshes = Vec::new();
    let mut materials = Vec::new();
    let mut images = Vec::new();
    if let Some(f) = input.fins {
        let normals = mesh
            .normals
            .as_deref()
            .expect("the reference needs normals");
        let (mut p, mut n, mut uv, mut ix) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut colour = Vec::new();
        for e in &f.edges {
            let (a, b) = (e.a as usize, e.b as usize);
            let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
            let base = p.len() as u32;
            p.extend([
                pa,
                pb,
                pb + input.delta[b] * f.top,
                pa + input.delta[a] * f.top,
            ]);
            n.extend([normals[a], normals[b], normals[b], normals[a]]);
            if let Some(albedo) = &mesh.albedo {
                let [ca, cb] = [a, b].map(|v| albedo[v].truncate().clamp(Vec3::ZERO, Vec3::ONE));
                colour.extend([ca, cb, cb, ca]);
            }
            let u = e.offset + pa.distance(pb) * f.tiles_per_unit;
            uv.extend([
                Vec2::new(e.offset, 0.0),
                Vec2::new(u, 0.0),
                Vec2::new(u, f.top),
                Vec2::new(e.offset, f.top),
            ]);
            // front: a b b' a'; back: the reverse
            for [i, j, k] in [[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]] {
                ix.extend([base + i, base + j, base + k]);
            }
        }
        let strip = reference_strip(input.law, input.strands, input.shade, f.strip.height);
        let png = crate::effects::fins::encode_strip_png(&strip);
        let image = buf.view(&png);
        images.push(json!({ "bufferView": image, "mimeType": "image/png" }));
        materials.push(json!({
            "pbrMetallicRoughness": {
                "baseColorTexture": { "index": 0 },
                "metallicFactor": 0, "roughnessFactor": input.roughness,
            },
            "alphaMode": "MASK",
        }));
        let mut attributes = json!({
            "POSITION": buf.floats(&flat3(&p), "VEC3", p.len()),
            "NORMAL": buf.floats(&flat3(&n), "VEC3", n.len()),
            "TEXCOORD_0": buf.floats(&uv.iter().flat_map(|v| v.to_array()).collect::<Vec<_>>(), "VEC2", uv.len()),
        });
        // an asset's colour at the edge's ends (its fins take the asset's neutral ramp)
        if !colour.is_empty() {
            attributes["COLOR_0"] = json!(buf.floats(&flat3(&colour), "VEC3", colour.len()));
        }
        let indices = buf.indices(&ix);
        meshes.push(json!({ "primitives": [{ "attributes": attributes, "indices": indices, "material": materials.len() - 1 }] }));
    }
    if let Some(o) = input.outline {
        let hull: Vec<Vec3> = mesh
            .positions
            .iter()
            .zip(&o.offset)
            .map(|(&p, &d)| p + d)
            .collect();
        let reversed: Vec<u32> = mesh
            .indices
            .chunks_exact(3)
            .flat_map(|t| [t[2], t[1], t[0]])
            .collect();
        let c = o.color;
        materials.push(json!({
            "pbrMetallicRoughness": { "baseColorFactor": [c[0], c[1], c[2], 1.0] },
            "extensions": { "KHR_materials_unlit": {} },
        }));
        let attributes = json!({ "POSITION": buf.floats(&flat3(&hull), "VEC3", hull.len()) });
        let indices = buf.indices(&reversed);
        meshes.push(json!({ "primitives": [{ "attributes": attributes, "indices": indices, "material": materials.len() - 1 }] }));
    }
    let o = mesh.origin;
    let nodes: Vec<serde_json::Value> = (0..meshes.len())
        .map(|m| json!({ "mesh": m, "translation": [o.x, o.y, o.z] }))
        .collect();
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "buffers": [{ "byteLength": buf.bin.len() }],
        "bufferViews": buf.views,
        "accessors": buf.accessors,
    });
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!([{ "sampler": 0, "source": 0 }]);
        doc["samplers"] = json!([{ "magFilter": 9729, "minFilter": 9987 }]);
    }
    // the GLB container only (header and chunks): nothing of the pack stage
    let glb = crate::output::write::glb_bytes(&doc, &buf.bin);
    Some(Asset::from_glb(&glb).expect("the reference's own glTF reads back"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BakeParams, Preset};

    /// The reference's strip (from its own law texture and test) equals the bake's.
    #[test]
    fn the_reference_strip_matches_the_baked_one_for_every_preset() {
        for &preset in &Preset::ALL {
            let p = BakeParams::preset(preset);
            let mask = crate::stages::strands::bake_mask(&p.strands);
            let baked = crate::effects::fins::strip(&mask, &p.shade, 32);
            let reference = reference_strip(
                &super::super::reference::law_texture(&p.strands),
                &p.strands,
                &p.shade,
                32,
            );
            let differ = baked
                .rgba
                .iter()
                .zip(&reference.rgba)
                .filter(|(a, b)| a != b)
                .count();
            // the noise law's two forms of one test may round apart exactly at a threshold
            assert!(
                differ <= baked.rgba.len() / 1000,
                "{}: {differ} bytes differ",
                preset.name()
            );
        }
    }
}
