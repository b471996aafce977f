//! Paint: where a part's fur takes its colour, and how it is sampled. A material's base colour
//! (factor, texture, vertex colours, alpha mode, roughness, metal) read per vertex of the fur
//! ([`Paint::albedo`], [`Palette`] for a fur of several materials), the texture sampled as the
//! client would (wrap modes, `NEAREST`, `KHR_texture_transform`), and the colour difference the
//! colour stage and the warnings measure ([`delta_e76`]). Reading a paint from a file (its
//! material, decoding its image) is the loader's (`input::asset`); sampling it is shared by the
//! stages and the viewer.

use glam::{Vec2, Vec3, Vec4};
use serde_json::Value;

use crate::model::mesh::Mesh;

/// Colour difference (CIE76) past which [`Palette::detail_lost`] counts a point as lost: about
/// twice what an eye tells apart side by side, so texture noise and filtering do not count.
pub const DETAIL_DELTA_E: f64 = 10.0;

/// CIE76 difference of two linear-RGB colours (sRGB primaries, D65 white).
pub fn delta_e76(a: Vec3, b: Vec3) -> f64 {
    let lab = |c: Vec3| glam::DVec3::from(crate::srgb::lab(c.as_dvec3().to_array()));
    lab(a).distance(lab(b))
}

/// Where a part's fur takes its colour: the material's base colour at each strand root, and
/// where it grows at all: a material that cuts its surface out by alpha (`MASK`) or fades it
/// (`BLEND`) grows fur only where the surface is drawn.
#[derive(Clone, Debug)]
pub struct Paint {
    /// `baseColorFactor` (linear RGBA).
    pub factor: [f32; 4],
    pub texture: Option<ColorTexture>,
    /// Multiply by the primitive's `COLOR_0`.
    pub vertex_colors: bool,
    /// The material's `alphaMode`.
    pub alpha: AlphaMode,
    /// The material is `KHR_materials_unlit`: the fur grafted onto the part is unlit too, so it
    /// keeps the flat colours the part is drawn in.
    pub unlit: bool,
    /// The material's roughness ([`roughness`]): the fur is drawn no shinier than the part it
    /// grows from. `None` where a texture sets it.
    pub roughness: Option<f32>,
    /// The base-colour `textureInfo` and the element it belongs to, not decoded yet: reading
    /// an asset decodes no image, [`crate::input::asset::Asset::paint`] decodes those of the parts the bake furs.
    pub(crate) pending: Option<(Value, String)>,
}

/// A material's `alphaMode`, and `alphaCutoff` for `MASK`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    #[default]
    Opaque,
    Mask(f32),
    Blend,
}

impl AlphaMode {
    /// A material's `alphaMode` (`OPAQUE` when absent or unknown), `alphaCutoff` 0.5 when
    /// absent: what the bake's paint and the viewer read.
    pub fn of(material: &Value) -> AlphaMode {
        match material["alphaMode"].as_str() {
            Some("MASK") => AlphaMode::Mask(material["alphaCutoff"].as_f64().unwrap_or(0.5) as f32),
            Some("BLEND") => AlphaMode::Blend,
            _ => AlphaMode::Opaque,
        }
    }

    /// How much of the surface a base-colour alpha draws: all of it (opaque), all or none
    /// (`MASK`, by the cutoff), or the alpha itself (`BLEND`).
    pub fn coverage(self, alpha: f32) -> f32 {
        match self {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Mask(cutoff) => (alpha >= cutoff) as u8 as f32,
            AlphaMode::Blend => alpha.clamp(0.0, 1.0),
        }
    }
}

/// A decoded base-colour texture and how it is sampled.
#[derive(Clone, Debug)]
pub struct ColorTexture {
    pub width: u32,
    pub height: u32,
    /// The image's RGBA bytes (sRGB colour, linear alpha), row by row: a quarter of the
    /// memory of decoded floats, which an 8k texture made 1 GB; decoded per sample.
    pub texels: Vec<u8>,
    /// glTF wrap modes (10497 repeat, 33071 clamp, 33648 mirrored repeat) in u and v.
    pub wrap: [u64; 2],
    /// The sampler's `magFilter` is `NEAREST` (palette and pixel-art textures): texels are read
    /// whole, not blended.
    pub nearest: bool,
    /// `KHR_texture_transform`: `uv' = M · (u, v, 1)`.
    pub transform: glam::Affine2,
    /// The texture coordinate set it reads ([`texture_set`]).
    pub set: u32,
}

/// The texture coordinate set a `textureInfo` reads: its `KHR_texture_transform`'s `texCoord`
/// where it has one (the extension overrides it), else its own `texCoord`, else 0.
pub fn texture_set(info: &Value) -> u32 {
    let over = &info["extensions"]["KHR_texture_transform"]["texCoord"];
    let set = over.as_u64().or(info["texCoord"].as_u64()).unwrap_or(0);
    set.min(u32::MAX as u64) as u32
}

/// A material's base colour: its factor and its `textureInfo` (JSON, either absent). A
/// specular-glossiness material (`KHR_materials_pbrSpecularGlossiness`, which Babylon.js and
/// Blender draw) without a metallic-roughness fallback has them as its diffuse; the fallback,
/// where there is one, is what three.js draws. What the fur's paint and the viewer read.
pub fn base_colour(material: &Value) -> (&Value, &Value) {
    let pbr = &material["pbrMetallicRoughness"];
    let sg = &material["extensions"]["KHR_materials_pbrSpecularGlossiness"];
    match (pbr.is_object(), sg.is_object()) {
        (false, true) => (&sg["diffuseFactor"], &sg["diffuseTexture"]),
        _ => (&pbr["baseColorFactor"], &pbr["baseColorTexture"]),
    }
}

/// A material's roughness as the client draws it: `roughnessFactor` (1 when not given, as glTF
/// defaults it), or for a specular-glossiness material without a metallic-roughness fallback
/// `1 − glossinessFactor` (glossiness 1 when not given). `None` where a texture scales it
/// (`metallicRoughnessTexture`, `specularGlossinessTexture`): the factor alone says nothing
/// then (exporters write 1 under a texture).
pub fn roughness(material: &Value) -> Option<f32> {
    let pbr = &material["pbrMetallicRoughness"];
    let sg = &material["extensions"]["KHR_materials_pbrSpecularGlossiness"];
    let r = match (pbr.is_object(), sg.is_object()) {
        (false, true) if sg["specularGlossinessTexture"].is_object() => return None,
        (false, true) => 1.0 - sg["glossinessFactor"].as_f64().unwrap_or(1.0),
        _ if pbr["metallicRoughnessTexture"].is_object() => return None,
        _ => pbr["roughnessFactor"].as_f64().unwrap_or(1.0),
    };
    Some(r.clamp(0.0, 1.0) as f32)
}

/// The share of a metal's base colour its fur takes: a metal's base colour is the tint of its
/// reflections, drawn dark wherever little is reflected, and the fur is no metal (glTF's
/// metallic 0): at its base colour, a near-black chrome visor whose base colour was pale blue
/// grew pale-blue felt. A quarter keeps the tint at about the lightness the metal shows under a
/// plain sky.
pub const METAL_DIFFUSE: f32 = 0.25;

/// The material's `metallicFactor` where it says the surface is mostly metal (0.5 or more,
/// written out, with no `metallicRoughnessTexture` to vary it): an omitted factor is glTF's 1,
/// which converters and hand-written files leave out without meaning metal, and is not taken.
pub fn metal(material: &Value) -> Option<f32> {
    let pbr = &material["pbrMetallicRoughness"];
    let m = pbr["metallicFactor"].as_f64()?;
    (m >= 0.5 && !pbr["metallicRoughnessTexture"].is_object()).then_some(m.min(1.0) as f32)
}

impl Paint {
    /// Whether a texture colours it (vertex colours and a factor alone interpolate exactly).
    pub fn has_detail(&self) -> bool {
        self.texture.is_some()
    }

    /// The texture coordinate set its texture reads, when it has one ([`texture_set`]).
    pub fn texture_set(&self) -> Option<u32> {
        let pending = self.pending.as_ref().map(|(info, _)| texture_set(info));
        pending.or(self.texture.as_ref().map(|t| t.set))
    }

    /// The fur's colour at each vertex of `mesh` (the texture read through its `texture_uvs`,
    /// else its `uvs`: the coordinates the texture names; its `colors` are the primitive's
    /// `COLOR_0`): linear RGB, and in `w` how much of the surface around the vertex the
    /// material draws ([`AlphaMode::coverage`]).
    ///
    /// The texture is read inside the vertex's faces, not at the vertex itself: each face
    /// around it is sampled half a texel in from the corner, toward the face's UV centroid, and
    /// the samples averaged (the colours weighted by their coverage, so a vertex on the rim of a
    /// cut-out takes the colour of the side that is drawn). A vertex sits on the edge of its UV
    /// island (a cylinder's side at v = 0, a plane's border at u = 1), where a sample at the
    /// vertex blends in the texel across the edge: the texture's other side under `REPEAT`, or
    /// the next island. That colour then spread over every triangle of the vertex, so a blue and
    /// yellow cylinder grew purple fur along its rims.
    pub fn albedo(&self, mesh: &Mesh) -> Vec<Vec4> {
        albedo_by(mesh, |_| self)
    }

    /// Over the triangles `indices` of `mesh`, the area where the fur's colour misses this
    /// paint's texture and the area drawn, by four points a triangle ([`Palette::detail_lost`]);
    /// `None` without a texture or colours.
    pub(crate) fn detail_sums(
        &self,
        mesh: &Mesh,
        indices: &[u32],
        coarser_than: f32,
    ) -> Option<(f64, f64)> {
        use rayon::prelude::*;
        let (Some(t), Some(uvs), Some(albedo)) =
            (&self.texture, mesh.paint_uvs(), mesh.albedo.as_deref())
        else {
            return None;
        };
        let colors = mesh.colors.as_deref();
        // the centroid, and a point toward each corner (which lends its vertex colour)
        const AT: [([f32; 3], usize); 4] = [
            ([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 0),
            ([2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0], 0),
            ([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0], 1),
            ([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0], 2),
        ];
        let sums: Vec<(f64, f64)> = (indices.par_chunks(3 * 4096))
            .map(|block| {
                let (mut lost, mut total) = (0.0f64, 0.0f64);
                for f in block.chunks_exact(3) {
                    let v = [0, 1, 2].map(|k| f[k] as usize);
                    let p = v.map(|v| mesh.positions[v]);
                    let area = (p[1] - p[0]).cross(p[2] - p[0]).length() as f64 / 2.0;
                    if area.is_nan() || area <= 0.0 {
                        continue;
                    }
                    let longest = (0..3).map(|k| p[k].distance(p[(k + 1) % 3]));
                    let cut = longest.fold(0.0f32, f32::max) > coarser_than;
                    for (w, near) in AT {
                        let drawn: Vec4 = (0..3).map(|k| albedo[v[k]] * w[k]).sum();
                        let uv: Vec2 = (0..3).map(|k| uvs[v[k]] * w[k]).sum();
                        let truth = self.shade(t.sample(uv), colors.map(|c| c[v[near]]));
                        if truth.w < 0.5 || drawn.w <= 0.0 {
                            continue;
                        }
                        total += area;
                        if cut && delta_e76(drawn.truncate(), truth.truncate()) > DETAIL_DELTA_E {
                            lost += area;
                        }
                    }
                }
                (lost, total)
            })
            .collect();
        Some((sums.iter()).fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1)))
    }

    /// The fur's colour at one point, given its `TEXCOORD_0` and `COLOR_0` (see
    /// [`Paint::albedo`]).
    pub fn colour_at(&self, uv: Option<Vec2>, color: Option<crate::model::mesh::Rgba16>) -> Vec4 {
        let texel = match (&self.texture, uv) {
            (Some(t), Some(uv)) => t.sample(uv),
            _ => Vec4::ONE,
        };
        self.shade(texel, color)
    }

    /// [`Paint::colour_at`] read up to half a texel from `uv` toward `inside` (a point inside
    /// the face the point lies on, such as its UV centroid), as [`Paint::albedo`] reads corners:
    /// a point on a UV island's edge takes the island's colour, not the texel across the edge.
    pub fn colour_toward(
        &self,
        uv: Vec2,
        inside: Vec2,
        color: Option<crate::model::mesh::Rgba16>,
    ) -> Vec4 {
        let texel = match &self.texture {
            Some(t) => t.sample_toward(uv, inside),
            None => Vec4::ONE,
        };
        self.shade(texel, color)
    }

    /// Factor × texel × vertex colour, the alpha turned into coverage.
    fn shade(&self, texel: Vec4, color: Option<crate::model::mesh::Rgba16>) -> Vec4 {
        let mut c = Vec4::from(self.factor) * texel;
        if let (true, Some(k)) = (self.vertex_colors, color) {
            c *= Vec4::from(k.map(crate::model::mesh::level_unit));
        }
        let c = c.clamp(Vec4::ZERO, Vec4::ONE);
        c.truncate().extend(self.alpha.coverage(c.w))
    }
}

/// [`Paint::albedo`] with each vertex's colour from its own paint, `paint(v)` (a triangle's
/// corners have one): one pass, whatever the number of paints.
fn albedo_by<'p>(mesh: &Mesh, paint: impl Fn(usize) -> &'p Paint) -> Vec<Vec4> {
    let n = mesh.vertex_count();
    let colors = mesh.colors.as_deref();
    let uvs = mesh.paint_uvs();
    // the vertices whose paint reads a texture (the others take their colour as it is)
    let textured = |v: usize| uvs.is_some() && paint(v).texture.is_some();
    // per vertex: colours weighted by coverage, their plain sum, coverage, samples
    let mut sum = vec![(Vec3::ZERO, Vec3::ZERO, 0.0f32, 0u32); n];
    for f in mesh.indices.chunks_exact(3) {
        let p = paint(f[0] as usize);
        let (Some(t), Some(uvs)) = (&p.texture, uvs) else {
            continue;
        };
        let centroid = f.iter().map(|&v| uvs[v as usize]).sum::<Vec2>() / 3.0;
        for &v in f {
            let v = v as usize;
            let texel = t.sample_toward(uvs[v], centroid);
            let c = p.shade(texel, colors.map(|k| k[v]));
            let s = &mut sum[v];
            *s = (
                s.0 + c.truncate() * c.w,
                s.1 + c.truncate(),
                s.2 + c.w,
                s.3 + 1,
            );
        }
    }
    let mut albedo: Vec<Vec4> = (sum.iter().enumerate())
        .map(|(v, &(weighted, plain, coverage, count))| {
            let (p, color) = (paint(v), colors.map(|k| k[v]));
            match (textured(v), count) {
                (false, _) => p.colour_at(None, color),
                (true, 0) => p.colour_at(uvs.map(|u| u[v]), color),
                _ if coverage > 0.0 => (weighted / coverage).extend(coverage / count as f32),
                _ => (plain / count as f32).extend(0.0),
            }
        })
        .collect();
    // a vertex whose surface is cut out everywhere takes the colour of its drawn
    // neighbours, which the fur thinning out toward it shows
    let mut near = vec![Vec4::ZERO; n];
    for f in mesh.indices.chunks_exact(3) {
        if !textured(f[0] as usize) {
            continue;
        }
        for (a, b) in [
            (f[0], f[1]),
            (f[1], f[2]),
            (f[2], f[0]),
            (f[1], f[0]),
            (f[2], f[1]),
            (f[0], f[2]),
        ] {
            let (a, b) = (a as usize, b as usize);
            if albedo[a].w == 0.0 && albedo[b].w > 0.0 {
                near[a] += (albedo[b].truncate() * albedo[b].w).extend(albedo[b].w);
            }
        }
    }
    for (c, n) in albedo.iter_mut().zip(&near) {
        if n.w > 0.0 {
            *c = (n.truncate() / n.w).extend(0.0);
        }
    }
    albedo
}

/// The paints of one fur, whose parts may have unlike materials (one character's parts baked
/// as one fur: `fur_groups` in the crate root): each vertex takes the paint its
/// [`Mesh::paint_ids`] names, the first where the mesh has none. A triangle's three vertices
/// have one paint (each triangle comes from one part), so a paint reads its own triangles only.
#[derive(Clone, Copy, Debug)]
pub struct Palette<'a>(pub &'a [Paint]);

impl<'a> Palette<'a> {
    /// The paint of vertex `v` of `mesh`.
    pub fn at(self, mesh: &Mesh, v: usize) -> &'a Paint {
        &self.0[Self::id(mesh, v)]
    }

    /// The index of vertex `v`'s paint ([`Mesh::paint_ids`], 0 without them).
    fn id(mesh: &Mesh, v: usize) -> usize {
        mesh.paint_ids.as_ref().map_or(0, |ids| ids[v] as usize)
    }

    /// Whether any paint has detail ([`Paint::has_detail`]).
    pub fn has_detail(self) -> bool {
        self.0.iter().any(Paint::has_detail)
    }

    /// The triangles of `mesh` (its indices) each paint colours, by paint.
    fn triangles(self, mesh: &Mesh) -> Vec<Vec<u32>> {
        let mut by_paint = vec![Vec::new(); self.0.len()];
        for f in mesh.indices.chunks_exact(3) {
            by_paint[Self::id(mesh, f[0] as usize)].extend_from_slice(f);
        }
        by_paint
    }

    /// [`Paint::albedo`], each vertex from its own paint.
    pub fn albedo(self, mesh: &Mesh) -> Vec<Vec4> {
        albedo_by(mesh, |v| self.at(mesh, v))
    }

    /// The share of `mesh`'s area (by four points a triangle) where its per-vertex fur colour
    /// (`mesh.albedo`, interpolated as a client draws it) differs from the texture by more than
    /// [`DETAIL_DELTA_E`] (CIE76): the detail finer than the triangles that the fur cannot show
    /// (a striped rug of two triangles grew a plain yellow carpet, a path painted across a
    /// ground grew a zig-zag of its triangles). Only triangles whose longest edge is over
    /// `coarser_than` count (those the colour stage could have cut further: what it left under
    /// it is the strands' own resolution). `None` without a texture or vertex colours; each
    /// paint reads its own triangles.
    pub fn detail_lost(self, mesh: &Mesh, coarser_than: f32) -> Option<f64> {
        let sums = (self.0.iter().zip(self.triangles(mesh)))
            .filter_map(|(paint, indices)| paint.detail_sums(mesh, &indices, coarser_than));
        let (lost, total) = sums.fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
        (total > 0.0).then(|| lost / total)
    }
}

impl ColorTexture {
    /// The texture at `uv` (glTF convention, v down the image): bilinear, or the texel it falls
    /// in under a `NEAREST` sampler.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        self.sample_transformed(self.transform.transform_point2(uv))
    }

    /// The texture up to half a texel from `uv` toward `toward` along each axis (no further
    /// than `toward`): a sample inside the face whose corner `uv` is and whose UV centroid
    /// `toward` is, off the texel edge a corner on an island's border sits on.
    pub fn sample_toward(&self, uv: Vec2, toward: Vec2) -> Vec4 {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let p = self.transform.transform_point2(uv);
        let c = self.transform.transform_point2(toward);
        let step = ((c - p) * size).clamp(Vec2::splat(-0.5), Vec2::splat(0.5));
        self.sample_transformed(p + step / size)
    }

    fn sample_transformed(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        let at = |i: i64, j: i64| {
            let i = wrap(i, w, self.wrap[0]);
            let j = wrap(j, h, self.wrap[1]);
            let at = 4 * (j * w + i) as usize;
            let p = &self.texels[at..at + 4];
            Vec4::new(
                crate::srgb::decode8(p[0]) as f32,
                crate::srgb::decode8(p[1]) as f32,
                crate::srgb::decode8(p[2]) as f32,
                p[3] as f32 / 255.0,
            )
        };
        let (x, y) = (uv.x as f64 * w as f64, uv.y as f64 * h as f64);
        if self.nearest {
            return at(x.floor() as i64, y.floor() as i64);
        }
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let top = at(i, j).lerp(at(i + 1, j), fx);
        let bottom = at(i, j + 1).lerp(at(i + 1, j + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// Texel `i` of `n` under a glTF wrap mode.
fn wrap(i: i64, n: i64, mode: u64) -> i64 {
    match mode {
        33071 => i.clamp(0, n - 1),
        33648 => {
            let p = i.rem_euclid(2 * n);
            if p < n {
                p
            } else {
                2 * n - 1 - p
            }
        }
        _ => i.rem_euclid(n),
    }
}

/// A `KHR_texture_transform` object as the matrix it stands for (translation · rotation ·
/// scale, the extension's order); identity when absent. The rotation turns UVs by `[c s; −s c]`
/// (rows), as three.js, Blender's exporter and Babylon.js read it; the extension's sample GLSL,
/// read column-major, would be the transpose, which no client draws. Shared by the bake's
/// colour sampling and the viewer, so the bare asset and its fur agree.
pub fn texture_transform(t: &Value) -> glam::Affine2 {
    if !t.is_object() {
        return glam::Affine2::IDENTITY;
    }
    let pair = |k: &str, d: f32| -> Vec2 {
        let a = &t[k];
        Vec2::new(
            a[0].as_f64().map_or(d, |v| v as f32),
            a[1].as_f64().map_or(d, |v| v as f32),
        )
    };
    let (offset, scale) = (pair("offset", 0.0), pair("scale", 1.0));
    let r = t["rotation"].as_f64().unwrap_or(0.0) as f32;
    let (s, c) = r.sin_cos();
    // glTF's rotation matrix: [c s; -s c] (counter-clockwise in UV space, v down)
    let rotation = glam::Mat2::from_cols(Vec2::new(c, -s), Vec2::new(s, c));
    glam::Affine2::from_mat2_translation(rotation * glam::Mat2::from_diagonal(scale), offset)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::mesh::Scene;

    #[test]
    fn roughness_is_the_factor_unless_a_texture_scales_it() {
        use serde_json::json;
        let of = |m: Value| roughness(&m);
        assert_eq!(of(json!({})), Some(1.0));
        assert_eq!(
            of(json!({"pbrMetallicRoughness": {"roughnessFactor": 0.4}})),
            Some(0.4)
        );
        let textured = json!({"pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0}}});
        assert_eq!(of(textured), None);
        let sg = |e: Value| json!({"extensions": {"KHR_materials_pbrSpecularGlossiness": e}});
        assert_eq!(of(sg(json!({"glossinessFactor": 0.25}))), Some(0.75));
        assert_eq!(
            of(sg(json!({"specularGlossinessTexture": {"index": 0}}))),
            None
        );
    }

    /// A 4 × 4 texture: the top two rows blue, the bottom two yellow; alpha 0 in the right
    /// half when `cut`.
    fn two_tone(nearest: bool, cut: bool) -> ColorTexture {
        let texels = (0..16)
            .flat_map(|k| {
                let (i, j) = (k % 4, k / 4);
                let c = if j < 2 {
                    Vec3::Z
                } else {
                    Vec3::new(1.0, 1.0, 0.0)
                };
                let alpha = if cut && i >= 2 { 0 } else { 255 };
                let [r, g, b] = (c * 255.0).to_array().map(|v| v as u8);
                [r, g, b, alpha]
            })
            .collect();
        ColorTexture {
            width: 4,
            height: 4,
            texels,
            wrap: [10497, 10497],
            nearest,
            transform: glam::Affine2::IDENTITY,
            set: 0,
        }
    }

    /// A strip of quads over u in [0, 1], v in [0, 0.5] (the blue half, its edges on the
    /// texture's top edge and on the colour boundary), `columns` quads wide.
    fn strip(columns: usize) -> Mesh {
        let mut m = Mesh::default();
        let mut uvs = Vec::new();
        for i in 0..=columns {
            for v in [0.0, 0.5] {
                let u = i as f32 / columns as f32;
                m.positions.push(Vec3::new(u, v, 0.0));
                uvs.push(Vec2::new(u, v));
            }
        }
        for i in 0..columns as u32 {
            let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            m.indices.extend_from_slice(&[a, b, c, c, b, d]);
        }
        m.uvs = Some(uvs);
        m
    }

    #[test]
    fn fur_colour_is_read_inside_the_faces_not_across_the_uv_island_s_edge() {
        // every vertex of the strip is on its island's edge: at v = 0 a sample blends in the
        // texture's bottom row (REPEAT), at v = 0.5 the yellow half; both halves yellow-blue
        for nearest in [false, true] {
            let paint = Paint {
                factor: [1.0; 4],
                texture: Some(two_tone(nearest, false)),
                vertex_colors: false,
                alpha: AlphaMode::Opaque,
                unlit: false,
                roughness: Some(1.0),
                pending: None,
            };
            let mesh = strip(4);
            let at_vertex = paint.colour_at(Some(Vec2::new(0.5, 0.0)), None);
            if !nearest {
                assert!(
                    at_vertex.x > 0.4,
                    "the sample at the vertex blends: {at_vertex}"
                );
            }
            for (v, c) in paint.albedo(&mesh).iter().enumerate() {
                assert!(
                    c.abs_diff_eq(Vec4::new(0.0, 0.0, 1.0, 1.0), 1e-6),
                    "vertex {v} (nearest {nearest}): {c}"
                );
            }
        }
    }

    #[test]
    fn a_cut_out_surface_draws_no_fur_and_its_rim_takes_the_drawn_side_s_colour() {
        let mesh = strip(4);
        for (alpha, drawn) in [(AlphaMode::Mask(0.5), 1.0), (AlphaMode::Blend, 1.0)] {
            let paint = Paint {
                factor: [1.0; 4],
                texture: Some(two_tone(true, true)),
                vertex_colors: false,
                alpha,
                unlit: false,
                roughness: Some(1.0),
                pending: None,
            };
            let albedo = paint.albedo(&mesh);
            for (v, c) in albedo.iter().enumerate() {
                let u = mesh.uvs.as_ref().unwrap()[v].x;
                // left of the cut drawn, right of it not, on it partly
                let ok = match u {
                    u if u < 0.5 => c.w == drawn,
                    u if u > 0.5 => c.w == 0.0,
                    _ => c.w > 0.0 && c.w < 1.0,
                };
                assert!(ok, "{alpha:?} vertex {v} at u {u}: {c}");
                assert!(
                    c.truncate().abs_diff_eq(Vec3::Z, 1e-6),
                    "{alpha:?} vertex {v}: the drawn side's colour, not the hidden one: {c}"
                );
            }
        }
        // a half-transparent BLEND material (the factor's alpha) grows half the fur
        let half = Paint {
            factor: [1.0, 1.0, 1.0, 0.5],
            texture: Some(two_tone(false, false)),
            vertex_colors: false,
            alpha: AlphaMode::Blend,
            unlit: false,
            roughness: Some(1.0),
            pending: None,
        };
        for c in half.albedo(&mesh) {
            assert!(
                (c.w - 0.5).abs() < 1e-6 && c.truncate().abs_diff_eq(Vec3::Z, 1e-6),
                "{c}"
            );
        }
        let opaque = AlphaMode::Opaque;
        assert_eq!(opaque.coverage(0.0), 1.0, "opaque materials ignore alpha");
        assert_eq!(AlphaMode::Mask(0.5).coverage(0.49), 0.0);
        assert_eq!(AlphaMode::Blend.coverage(0.3), 0.3);
    }

    #[test]
    fn parts_of_unlike_paints_merged_take_each_its_own_colour() {
        // a textured, cut-out strip and a plain red one, merged as one fur's mesh: each
        // vertex's colour is what its own paint gives its own strip alone, and the colour
        // stage's detail test reads the textured one only
        let textured = Paint {
            factor: [1.0; 4],
            texture: Some(two_tone(true, true)),
            vertex_colors: false,
            alpha: AlphaMode::Mask(0.5),
            unlit: false,
            roughness: Some(1.0),
            pending: None,
        };
        let red = Paint {
            factor: [1.0, 0.0, 0.0, 1.0],
            texture: None,
            ..textured.clone()
        };
        let (a, mut b) = (strip(4), strip(3));
        b.origin.y = 2.0;
        let alone = [textured.albedo(&a), red.albedo(&b)].concat();
        let paints = [textured, red];
        let mut scene = Scene::default();
        for (k, mut m) in [a, b].into_iter().enumerate() {
            m.paint_ids = Some(vec![k as u32; m.vertex_count()]);
            scene.meshes.push(m);
        }
        let merged = scene.merged();
        let palette = Palette(&paints);
        assert_eq!(palette.albedo(&merged), alone);
        assert!(palette.has_detail());
        assert!(std::ptr::eq(
            palette.at(&merged, merged.vertex_count() - 1),
            &paints[1]
        ));
    }

    #[test]
    fn a_specular_glossiness_material_has_its_colour_as_diffuse() {
        use serde_json::json;
        let sg = json!({ "KHR_materials_pbrSpecularGlossiness": {
            "diffuseFactor": [0.5, 0.25, 1.0, 1.0], "diffuseTexture": { "index": 3 } } });
        let alone = json!({ "extensions": sg });
        let (factor, texture) = base_colour(&alone);
        assert_eq!(
            (factor[1].as_f64(), texture["index"].as_u64()),
            (Some(0.25), Some(3))
        );
        // with a metallic-roughness fallback, the fallback (what three.js draws)
        let both = json!({ "extensions": sg, "pbrMetallicRoughness": {
            "baseColorTexture": { "index": 1 } } });
        assert_eq!(base_colour(&both).1["index"].as_u64(), Some(1));
        assert!(base_colour(&json!({})).1.is_null());
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap(-1, 4, 10497), 3);
        assert_eq!(wrap(-1, 4, 33071), 0);
        assert_eq!(wrap(4, 4, 33648), 3);
        assert_eq!(wrap(-1, 4, 33648), 0);
    }
}
