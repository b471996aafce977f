//! The builder one surface's streams, accessors, meshes and materials are appended through,
//! each tagged with the surface (and chunk, level and layer) they belong to.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::model::{Material, Mesh as PackedMesh, Packed, Primitive, Semantic, Tag};
use super::params::component;
use super::quantize::{quantize_normal, Bytes, PositionGrid, Targets, UvGrid};
use crate::model::mesh::PAR_MIN_LEN;

/// Appends one surface's streams to the file, tagged with the surface.
pub(super) struct Builder<'a> {
    pub(super) out: &'a mut Packed,
    pub(super) tag: Tag,
    /// The exact geometry as plain floats (`Quantize::None`).
    pub(super) float: bool,
    /// Materials by (level, layer): every chunk's layer shares one.
    pub(super) materials: Vec<((usize, usize), usize)>,
}

impl Builder<'_> {
    /// A mesh of one untargeted primitive, tagged with the builder's tag.
    pub(super) fn single_primitive_mesh(
        &mut self,
        name: String,
        attributes: Vec<(Semantic, usize)>,
        indices: usize,
        material: usize,
    ) -> usize {
        let primitive = Primitive {
            attributes,
            targets: vec![],
            indices: Some(indices),
            material,
        };
        let mesh = PackedMesh {
            name,
            tag: self.tag,
            primitives: vec![primitive],
            weights: vec![],
            layer_ranges: vec![],
            target_names: vec![],
        };
        Packed::push(&mut self.out.meshes, mesh)
    }

    /// The material of layer `layer` of level `level`, made by `make` the first time; one an
    /// earlier surface made, alike but for its name, is shared (200 parts with one preset wrote
    /// 11 809 materials, 68 of them distinct, 4.2 MB of JSON), found by its key
    /// ([`Material::key`]) in one look-up. A surface's own alike materials stay apart, so one
    /// surface's file is as it was.
    pub(super) fn material(
        &mut self,
        level: usize,
        layer: usize,
        make: impl FnOnce() -> Material,
    ) -> usize {
        if let Some(&(_, m)) = self.materials.iter().find(|(k, _)| *k == (level, layer)) {
            return m;
        }
        let made = make();
        let surface = self.tag.surface;
        let key = made.key();
        let m = match self.out.material_keys.get(&key) {
            Some(&(m, by)) if by != surface => m,
            _ => {
                let m = Packed::push(&mut self.out.materials, made);
                self.out.material_keys.entry(key).or_insert((m, surface));
                m
            }
        };
        self.materials.push(((level, layer), m));
        m
    }

    pub(super) fn stream(
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

    /// POSITION stream of `q` ([`super::input::Geometry::stored`]: grid levels, or a plain float file's
    /// exact positions): normalized i16 centred on the grid (stride 8), or floats (stride 12),
    /// with exact bounds.
    pub(super) fn positions(
        &mut self,
        name: &'static str,
        q: &[Vec3],
        grid: &PositionGrid,
    ) -> usize {
        let mut bytes = Bytes::default();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &p in q {
            let v = if self.float {
                bytes.f32s(&p.to_array());
                p
            } else {
                let s = grid.stored(p.to_array().map(|x| x as u16));
                bytes.i16s(&s, 8);
                Vec3::from_array(s.map(f32::from))
            };
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if q.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ZERO);
        }
        let (stride, component, normalized) = if self.float {
            (12, component::FLOAT, false)
        } else {
            (8, component::SHORT, true)
        };
        let v = self.stream(
            name,
            Semantic::Position,
            None,
            bytes.0,
            Some(stride),
            q.len(),
        );
        let bounds = |v: Vec3| v.to_array().map(|x| x as f64).to_vec();
        self.out.accessor(
            v,
            component,
            normalized,
            "VEC3",
            Some((bounds(lo), bounds(hi))),
        )
    }

    /// `JOINTS_0` (unsigned byte, or short past 256 joints) and `WEIGHTS_0` (normalized bytes
    /// summing to 255) of the vertices `order` lists.
    pub(super) fn skin(
        &mut self,
        (skin, joints): (&crate::model::mesh::VertexSkin, usize),
        order: &[u32],
    ) -> [usize; 2] {
        let wide = joints > 256;
        let mut j = Bytes::default();
        let mut w = Bytes::default();
        for &o in order {
            let (js, ws) = crate::model::skeleton::influence_bytes(
                skin.joints[o as usize],
                skin.weights[o as usize],
            );
            if wide {
                j.u16s(&js, 8);
            } else {
                j.0.extend(js.map(|x| x as u8));
            }
            w.0.extend(ws);
        }
        let n = order.len();
        let (stride, component) = if wide {
            (8, component::UNSIGNED_SHORT)
        } else {
            (4, component::UNSIGNED_BYTE)
        };
        let jv = self.stream("joints", Semantic::Joints(0), None, j.0, Some(stride), n);
        let ja = self.out.accessor(jv, component, false, "VEC4", None);
        let wv = self.stream("weights", Semantic::Weights(0), None, w.0, Some(4), n);
        let wa = self
            .out
            .accessor(wv, component::UNSIGNED_BYTE, true, "VEC4", None);
        [ja, wa]
    }

    /// A morph target (the extrusion delta, the bend, the wind's), in the stored position unit,
    /// with its bounds, as `stored` says: normalized `i16` for [`Targets::Steps`] (the values
    /// lie on its grid), float for [`Targets::Exact`].
    pub(super) fn deltas(
        &mut self,
        deltas: &[Vec3],
        name: &'static str,
        target: usize,
        stored: Targets,
    ) -> usize {
        let mut bytes = Bytes::default();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for d in deltas {
            lo = lo.min(*d);
            hi = hi.max(*d);
        }
        if deltas.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ZERO);
        }
        let n = deltas.len();
        let bounds = |v: [f32; 3]| v.map(|x| x as f64).to_vec();
        if stored == Targets::Steps {
            for &d in deltas {
                bytes.i16s(&Targets::levels(d), 8);
            }
            let dv = self.stream(name, Semantic::Position, Some(target), bytes.0, Some(8), n);
            let level = |v: Vec3| Targets::levels(v).map(|x| x as f32);
            let range = Some((bounds(level(lo)), bounds(level(hi))));
            return self.out.accessor(dv, component::SHORT, true, "VEC3", range);
        }
        for d in deltas {
            bytes.f32s(&d.to_array());
        }
        let dv = self.stream(name, Semantic::Position, Some(target), bytes.0, Some(12), n);
        let range = Some((bounds(lo.to_array()), bounds(hi.to_array())));
        self.out
            .accessor(dv, component::FLOAT, false, "VEC3", range)
    }

    pub(super) fn normals(&mut self, n: &[Vec3]) -> usize {
        let mut bytes = Bytes::default();
        if self.float {
            for &v in n {
                bytes.f32s(&v.to_array());
            }
            let v = self.stream("normal", Semantic::Normal, None, bytes.0, Some(12), n.len());
            return self.out.accessor(v, component::FLOAT, false, "VEC3", None);
        }
        // the nearest of eight lattice points, each measured: in parallel
        let quantized: Vec<[i8; 3]> = n.par_iter().map(|&v| quantize_normal(v)).collect();
        for q in &quantized {
            bytes.i8s(q, 4);
        }
        let v = self.stream("normal", Semantic::Normal, None, bytes.0, Some(4), n.len());
        self.out.accessor(v, component::BYTE, true, "VEC3", None)
    }

    pub(super) fn texcoords(
        &mut self,
        uvs: &[Vec2],
        grid: UvGrid,
        float: bool,
        tiles: Vec2,
    ) -> usize {
        let mut bytes = Bytes::default();
        if self.float {
            // no KHR_texture_transform: the tiling multiplied in
            for &uv in uvs {
                bytes.f32s(&(uv * tiles).to_array());
            }
            let uv = Semantic::TexCoord(0);
            let v = self.stream("texcoord", uv, None, bytes.0, Some(8), uvs.len());
            return self.out.accessor(v, component::FLOAT, false, "VEC2", None);
        }
        if float {
            for uv in uvs {
                bytes.f32s(&[uv.x, uv.y]);
            }
            let uv = Semantic::TexCoord(0);
            let v = self.stream("texcoord", uv, None, bytes.0, Some(8), uvs.len());
            return self.out.accessor(v, component::FLOAT, false, "VEC2", None);
        }
        let quantized: Vec<[u16; 2]> = (uvs.par_iter())
            .with_min_len(PAR_MIN_LEN)
            .map(|&uv| grid.quantize(uv))
            .collect();
        for q in &quantized {
            bytes.u16s(q, 4);
        }
        let uv = Semantic::TexCoord(0);
        let v = self.stream("texcoord", uv, None, bytes.0, Some(4), uvs.len());
        self.out
            .accessor(v, component::UNSIGNED_SHORT, true, "VEC2", None)
    }

    pub(super) fn indices(&mut self, name: &'static str, ix: &[u32], vertex_count: usize) -> usize {
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

/// A `COLOR_0` of `n` linear colours (clamped to [0, 1]) and alphas as normalized `u16`, so that
/// dark albedos keep their hue: the layers' roots and the fins carry the asset's colour so.
pub(super) fn u16_colors(
    b: &mut Builder,
    name: &'static str,
    colours: impl Iterator<Item = (Vec3, u16)>,
    n: usize,
) -> usize {
    let mut bytes = Bytes::default();
    let q = |v: f32| (v * 65535.0).round() as u16;
    for (c, alpha) in colours {
        let c = c.clamp(Vec3::ZERO, Vec3::ONE);
        bytes.u16s(&[q(c.x), q(c.y), q(c.z), alpha], 8);
    }
    let v = b.stream(name, Semantic::Color(0), None, bytes.0, Some(8), n);
    b.out
        .accessor(v, component::UNSIGNED_SHORT, true, "VEC4", None)
}
