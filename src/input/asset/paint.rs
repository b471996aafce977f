//! Reading a part's paint from its material ([`Paint`]'s colour factor, texture, alpha and
//! lighting) and decoding its base colour image; sampling it is `model::paint`'s.

use serde_json::Value;

use crate::input::document::Document;
use crate::model::paint::{
    base_colour, metal, roughness, texture_set, texture_transform, AlphaMode, ColorTexture, Paint,
    METAL_DIFFUSE,
};

impl Paint {
    /// The paint of primitive `prim`, its texture not decoded yet
    /// ([`Asset::paint`](super::Asset::paint)). A primitive without a material is drawn in glTF's
    /// default, white: its fur is white too (it grew the preset's brown, a colour the asset never
    /// showed).
    pub(super) fn of(
        doc: &Document,
        prim: &crate::input::document::Primitive,
        element: &str,
    ) -> Option<Paint> {
        let vertex_colors = prim.attribute("COLOR_0").is_some();
        let Some(m) = prim.material else {
            return Some(Paint {
                factor: [1.0; 4],
                texture: None,
                vertex_colors,
                alpha: AlphaMode::Opaque,
                unlit: false,
                roughness: Some(1.0),
                pending: None,
            });
        };
        let material = &doc.json["materials"][m];
        let (factor_of, info) = base_colour(material);
        let mut factor = [1.0f32; 4];
        if let Some(f) = factor_of.as_array() {
            for (k, v) in f.iter().take(4).enumerate() {
                factor[k] = v.as_f64().unwrap_or(1.0).clamp(0.0, 1.0) as f32;
            }
        }
        if let Some(m) = metal(material) {
            let dim = 1.0 - (1.0 - METAL_DIFFUSE) * m;
            factor.iter_mut().take(3).for_each(|c| *c *= dim);
        }
        Some(Paint {
            factor,
            texture: None,
            vertex_colors,
            alpha: AlphaMode::of(material),
            unlit: material["extensions"]["KHR_materials_unlit"].is_object(),
            roughness: roughness(material),
            pending: info
                .is_object()
                .then(|| (info.clone(), format!("{element}: material {m}'s"))),
        })
    }
}

impl ColorTexture {
    /// Decodes the texture `info` (a `textureInfo`) points at; the error says why it cannot.
    pub(super) fn read(
        doc: &Document,
        buffers: &[Vec<u8>],
        info: &Value,
    ) -> std::result::Result<ColorTexture, String> {
        let t = info["index"].as_u64().ok_or("has no index")? as usize;
        let texture = &doc.json["textures"][t];
        let decoded = texture_image(doc, buffers, texture)?;
        let (width, height) = decoded.dimensions();
        let texels = decoded.into_raw();
        let sampler = texture["sampler"]
            .as_u64()
            .map(|s| &doc.json["samplers"][s as usize]);
        let wrap = ["wrapS", "wrapT"].map(|k| sampler.and_then(|s| s[k].as_u64()).unwrap_or(10497));
        let nearest = sampler.and_then(|s| s["magFilter"].as_u64()) == Some(9728);
        Ok(ColorTexture {
            width,
            height,
            texels,
            wrap,
            nearest,
            transform: texture_transform(&info["extensions"]["KHR_texture_transform"]),
            set: texture_set(info),
        })
    }
}

/// The pixels of glTF texture `texture`'s `source` image (from a buffer view, or a URI the
/// document resolves), decoded by [`decode_image`]; the error says why there are none. The
/// bake's colour sampling and the viewer read textures through it. Only `source` is read: an
/// `EXT_texture_webp` or `KHR_texture_basisu` texture draws its PNG or JPEG fallback, if any.
pub fn texture_image(
    doc: &Document,
    buffers: &[Vec<u8>],
    texture: &Value,
) -> std::result::Result<image::RgbaImage, String> {
    let source = texture["source"]
        .as_u64()
        .ok_or("has no PNG or JPEG source")? as usize;
    let image = &doc.json["images"][source];
    let bytes = if let Some(v) = image["bufferView"].as_u64() {
        let v = v as usize;
        if v >= doc.views.len() {
            return Err(format!("(image {source}) names a missing view"));
        }
        (doc.view_bytes(buffers, v))
            .map_err(|m| format!("(image {source}): {m}"))?
            .to_vec()
    } else if let Some(uri) = image["uri"].as_str() {
        doc.read_uri(&format!("image {source}"), uri)
            .map_err(|e| format!("cannot be read ({e})"))?
    } else {
        return Err(format!(
            "(image {source}) has neither a buffer view nor a URI"
        ));
    };
    let element = || format!("image {source}");
    let left = doc.budget_left();
    let rgba = decode_image_within(&bytes, left).map_err(|e| match e {
        image::ImageError::Limits(_) => format!(
            "(image {source}) cannot be decoded within {left} bytes (a limit: --max-memory, at \
             most three 16384² images' worth)"
        ),
        e => format!("(image {source}) cannot be decoded ({e})"),
    })?;
    doc.charge(&element, rgba.as_raw().len() as u64)
        .map_err(|e| e.to_string())?;
    Ok(rgba)
}

/// The largest side of a base-colour image the bake decodes: 16384, what GPUs draw.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// `bytes` (PNG or JPEG) decoded to RGBA bytes, up to [`MAX_IMAGE_SIDE`] a side (the image
/// crate's default limit, 512 MB, refused a 12k texture): the bake's colour sampling and the
/// viewer read images through it.
pub fn decode_image(bytes: &[u8]) -> image::ImageResult<image::RgbaImage> {
    decode_image_within(bytes, crate::input::boundary::max_memory())
}

/// [`decode_image`] allocating at most `budget` bytes (and never more than three 16384² RGBA8
/// images' worth): a deflate bomb that would decode past either is an error of the image
/// crate's limits, before the allocation.
pub fn decode_image_within(bytes: &[u8], budget: u64) -> image::ImageResult<image::RgbaImage> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(budget.min(3 * 4 * (MAX_IMAGE_SIDE as u64).pow(2)));
    reader.limits(limits);
    Ok(reader.decode()?.into_rgba8())
}

/// What the fur of primitive `k` of mesh `m` does not carry of its material, for warnings: a
/// glow (fur over an emissive surface does not glow, and covers it) and material variants (the
/// fur keeps the default material's colours when a viewer switches the part to another).
pub(super) fn material_notes(doc: &Document, (m, k): (usize, usize), element: &str) -> Vec<String> {
    let prim = &doc.json["meshes"][m]["primitives"][k];
    let mut notes = Vec::new();
    if let Some(i) = prim["material"].as_u64() {
        let material = &doc.json["materials"][i as usize];
        let factor = material["emissiveFactor"].as_array().into_iter().flatten();
        let glows = factor.filter_map(Value::as_f64).any(|v| v > 0.0);
        if glows || material["emissiveTexture"].is_object() {
            notes.push(format!(
                "{element}: material {i} is emissive; the fur over it does not glow and covers it"
            ));
        }
    }
    if prim["extensions"]["KHR_materials_variants"].is_object() {
        notes.push(format!(
            "{element}: switches materials with KHR_materials_variants; its fur keeps the \
             colours of the default material"
        ));
    }
    notes
}
