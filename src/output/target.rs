//! Engine targets (`--target NAME`, `[output] target = "…"`): for each engine, what its glTF
//! importer reads, as a choice of the file's constructs.
//!
//! One file cannot be right everywhere: the smallest file needs `KHR_mesh_quantization`, which
//! Godot 4 and Bevy refuse; the layer heights are morph weights, which Godot and Unreal's
//! glTFRuntime never apply statically; the coarser levels are a second scene, which PlayCanvas,
//! glTFRuntime and Unity glTFast's editor importer add on top of LOD 0. A target picks, per
//! engine (each cited from that importer's source in `tests/engines.rs`):
//!
//! | target | engines | attributes | layer height | LOD | sheen | meshopt |
//! |---|---|---|---|---|---|---|
//! | `web` (default) | three.js, Babylon.js | quantized | morph weights (mesh and node) | `MSFT_lod`, coarser levels in a second scene | kept | if asked |
//! | `blender` | Blender's importer | quantized | morph weights | LOD 0 only, one scene (Blender switches no level) | kept | no |
//! | `unity` | glTFast | quantized | morph weights | LOD 0 only, one scene | dropped | if asked |
//! | `playcanvas` | PlayCanvas | quantized | morph weights (it reads the mesh's) | LOD 0 only, one scene | kept | no |
//! | `bevy` | Bevy (`bevy_gltf`) | floats | morph weights (it reads the mesh's) | LOD 0 only, one scene | dropped | no |
//! | `godot` | Godot 4 | floats | every layer's own positions (`layers`) | LOD 0 only, one scene | dropped | no |
//! | `unreal` | glTFRuntime | quantized | every layer's own positions (`layers`) | LOD 0 only, one scene | kept | if asked |
//! | `portable` | any core glTF 2.0 reader | floats | every layer's own positions (`layers`) | LOD 0 only, one scene | dropped | no |
//!
//! "Floats" is `--quantize none`: float positions, normals and morph deltas, the tiling multiplied
//! into the texture coordinates, so neither `KHR_mesh_quantization` nor `KHR_texture_transform`
//! is required. "Every layer's own positions" is the `layers` layout: a mesh and material per
//! layer as in the compact layout, each layer's vertices written where that layer is, so no
//! static weight is needed; the layers share their normals, texture coordinates and index
//! stream (prefixes of one accessor). Not the single-draw layout, whose one primitive tells
//! the layers apart by `COLOR_0` alpha against one cutoff: stock PlayCanvas leaves `COLOR_0`
//! alpha out of its alpha test and drew every layer of such a file as a solid shell
//! (`tests/engines.rs`), and a per-layer material costs those engines nothing they refuse. A flag given beside `--target` wins
//! over it (`--target godot --layout compact` is a compact file), except `--compress meshopt`
//! for a target that cannot read it, which is refused. The summary names the target and the
//! engines it is for.
//!
//! Where sheen is not read it is left off, not folded into the base colour: the extension's
//! sheen is a rim light (the Charlie lobe, strongest at grazing angles, `effects::sheen`) whose
//! energy averaged over directions is `E · sheenColor`, under a tenth of the tips' colour
//! (`E` = 0.157, the fur preset's tip colour at most 0.55); a constant tint would spread that
//! tenth over the faces seen head-on, where the runtime technique draws none of it, and darken
//! nothing at the rim where it does.
//!
//! The default is `web`: it is the smallest file with its levels of detail (the bunny: 218 kB;
//! `bevy`, floats and LOD 0 only, 211 kB; `playcanvas` 166 kB without the levels; `layers`
//! 753 kB quantized for `unreal`, 1.09 MB in floats for `godot` and `portable`: every layer's
//! positions written out is what an engine without static weights costs; single-draw, which
//! wrote every layer's normals, texture coordinates and colours too, made 3.3 and 4.6 MB),
//! draws LOD by distance
//! in Babylon.js (and in three.js with a plugin), and every engine that reads its required
//! extensions draws its fur, since the weights are on the meshes too. What it costs elsewhere
//! is the coarser levels drawn over LOD 0 where every scene is loaded (PlayCanvas, glTFRuntime,
//! glTFast's editor importer), which their targets leave out. A skinned asset's fur is written
//! in floats whatever the target (its dequantization would have to live in the inverse bind
//! matrices), so its file is the same for `web` and `bevy`.

use serde::{Deserialize, Serialize};

use crate::output::pack::{LayerWeights, Layout, Quantize};

/// An engine target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    #[default]
    Web,
    Blender,
    Unity,
    Playcanvas,
    Bevy,
    Godot,
    Unreal,
    Portable,
}

/// What a target writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Profile {
    /// The engines the file is right for, as the summary names them.
    pub engines: &'static str,
    /// `Some(Layers)` where the engine applies no static morph weight.
    pub layout: Option<Layout>,
    pub quantize: Quantize,
    pub layer_weights: LayerWeights,
    /// Whether the coarser levels (`MSFT_lod` and a second scene) are written.
    pub lod: bool,
    /// Whether `KHR_materials_sheen` is read (else the sheen effect is left off).
    pub sheen: bool,
    /// Whether `EXT_meshopt_compression` can be read.
    pub meshopt: bool,
}

impl Target {
    pub const ALL: [Target; 8] = [
        Target::Web,
        Target::Blender,
        Target::Unity,
        Target::Playcanvas,
        Target::Bevy,
        Target::Godot,
        Target::Unreal,
        Target::Portable,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Target::Web => "web",
            Target::Blender => "blender",
            Target::Unity => "unity",
            Target::Playcanvas => "playcanvas",
            Target::Bevy => "bevy",
            Target::Godot => "godot",
            Target::Unreal => "unreal",
            Target::Portable => "portable",
        }
    }

    /// The target's choices (the table in the module comment).
    pub fn profile(self) -> Profile {
        let web = Profile {
            engines: "three.js and Babylon.js",
            layout: None,
            quantize: Quantize::Khr,
            layer_weights: LayerWeights::Both,
            lod: true,
            sheen: true,
            meshopt: true,
        };
        let one_scene = Profile { lod: false, ..web };
        let floats = Profile {
            quantize: Quantize::None,
            sheen: false,
            meshopt: false,
            ..one_scene
        };
        match self {
            Target::Web => web,
            Target::Blender => Profile {
                engines: "Blender",
                meshopt: false,
                ..one_scene
            },
            Target::Unity => Profile {
                engines: "Unity glTFast",
                sheen: false,
                ..one_scene
            },
            Target::Playcanvas => Profile {
                engines: "PlayCanvas",
                meshopt: false,
                ..one_scene
            },
            Target::Bevy => Profile {
                engines: "Bevy",
                ..floats
            },
            Target::Godot => Profile {
                engines: "Godot 4",
                layout: Some(Layout::Layers),
                ..floats
            },
            Target::Unreal => Profile {
                engines: "Unreal glTFRuntime",
                layout: Some(Layout::Layers),
                ..one_scene
            },
            Target::Portable => Profile {
                engines: "any glTF 2.0 reader: no extension",
                layout: Some(Layout::Layers),
                ..floats
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_through_serde() {
        for t in Target::ALL {
            let json = serde_json::to_string(&t).unwrap();
            assert_eq!(json, format!("\"{}\"", t.name()));
            assert_eq!(serde_json::from_str::<Target>(&json).unwrap(), t);
        }
    }

    #[test]
    fn targets_without_quantization_leave_every_extension_out() {
        for t in [Target::Bevy, Target::Godot, Target::Portable] {
            let p = t.profile();
            assert_eq!(p.quantize, Quantize::None, "{t:?}");
            assert!(!p.lod && !p.sheen && !p.meshopt, "{t:?}");
        }
    }
}
