//! The size estimate of a baked file, before it is baked.

use super::model::Layout;

/// An upper bound of the GLB size for a mesh of at most `vertices` render vertices and
/// `triangles` triangles, made before any work so an oversize bake can be refused with the size
/// it would at most have had. Counts every stream at its widest encoding (float UVs, the float
/// extrusion delta, u32 indices past 65535 vertices, the density and bare-level colours), every
/// LOD level (`levels` with shells, each merging twice as many layers as the one before, and the
/// bare level) in each of `chunks` chunks, the mask PNG at its raw size plus an eighth (deflate's
/// fixed codes spend at most 9 bits a byte; encoders fall back to stored blocks when that is
/// larger) and its mips for the coarser levels (a third more), and 600 bytes of JSON per layer
/// mesh (a layer's mesh, material and node take about 450) plus 1000 per chunk and level.
pub fn estimate_bytes(
    vertices: u64,
    triangles: u64,
    layers: u64,
    mask_size: u64,
    layout: Layout,
    (levels, chunks): (u64, u64),
) -> u64 {
    // grey + alpha per texel, one filter byte per row; mips add at most a third
    let raw = mask_size * (2 * mask_size + 1);
    let png = (raw + raw / 8) * 4 / 3 + 4096 * (levels + 1);
    let level_layers = level_layers(layers, levels);
    let json = 8192 + chunks * (600 * level_layers + 1000 * (levels + 1));
    // each view is padded to 4 bytes
    let padding = 4 * (12 + 4 * (levels + 1) * chunks);
    let body = match layout {
        Layout::Compact => {
            let index = if vertices <= 65535 { 2 } else { 4 };
            vertices * (8 + 4 + 8 + 12 + 4 + 8) + (levels + 1) * triangles * 3 * index
        }
        Layout::SingleDraw => {
            let n = vertices * level_layers;
            let index = if n <= 65535 { 2 } else { 4 };
            n * (8 + 4 + 8 + 8) + triangles * level_layers * 3 * index
        }
        Layout::Layers => {
            // float positions and colours per layer; per level, the streams the layers share
            // (normals, texture coordinates, joints, the wind's two targets) and the index
            // stream they read prefixes of
            let index = if vertices <= 65535 { 2 } else { 4 };
            let shared = vertices * (12 + 8 + 8 + 24) + triangles * 3 * index;
            vertices * level_layers * (12 + 8) + (levels + 1) * shared
        }
    };
    28 + body + png + json + padding
}

/// At most how many layer meshes `levels` levels of a `layers`-layer stack write in one chunk:
/// LOD 0's, each coarser level's at most half the previous plus one, and the bare level.
pub fn level_layers(layers: u64, levels: u64) -> u64 {
    (0..levels.max(1))
        .map(|k| 1 + layers.saturating_sub(1).div_ceil(1 << k.min(62)))
        .sum::<u64>()
        + 1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimate_is_an_upper_bound() {
        let scene = crate::input::load(std::path::Path::new(concat!(
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
}
