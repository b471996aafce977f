//! `pack`'s parameters: how vertex attributes are stored ([`Quantize`]), where the compact
//! layers' weights go ([`LayerWeights`]), the rest of [`PackParams`], and glTF's component types.

use serde::{Deserialize, Serialize};

use super::model::Layout;
use crate::error::ParamError;

/// How vertex attributes are stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Quantize {
    /// `KHR_mesh_quantization`: POSITION u16 on the grid, NORMAL i8, TEXCOORD_0 u16 (with
    /// `KHR_texture_transform`). Smallest.
    #[default]
    Khr,
    /// Plain glTF 2.0 floats of the exact geometry and no required extension: positions as
    /// the bake computed them (relative to the surface's origin, which the root node
    /// translates by), the extrusion in world units, unit normals, texture coordinates with the
    /// tiling multiplied in. For clients that read neither extension (the `gltf` crate and
    /// Bevy, f3d, libGDX), and the accurate end of `shellbake study`: its compact layout draws
    /// what the runtime reference draws, pixel for pixel. The largest file.
    None,
}

impl Quantize {
    pub const ALL: [Quantize; 2] = [Quantize::Khr, Quantize::None];

    pub fn name(self) -> &'static str {
        match self {
            Quantize::Khr => "khr",
            Quantize::None => "none",
        }
    }
}

/// Where a compact layer's morph weight `t_j` is written.
///
/// Readers differ: three.js, Babylon.js, Filament and Unity glTFast (6.13 on) apply
/// `node.weights`; Bevy (`bevy_gltf`) and PlayCanvas (`glb-parser.js`) read `mesh.weights` only,
/// and a layer without them sits at weight 0, on the base surface, with no error. So the default
/// writes both (the node's win where both are read, and they are equal).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LayerWeights {
    /// On the layer's mesh and its node: every reader finds them.
    #[default]
    Both,
    /// On the layer's node only (`node.weights`): a mesh without default weights is one that
    /// gltfpack may share between layers, so running it over the file keeps the geometry once
    /// (with mesh weights it copies the geometry into every layer). Bevy and PlayCanvas then
    /// draw every layer on the base surface.
    Node,
    /// On the layer's mesh only (`mesh.weights`).
    Mesh,
}

impl LayerWeights {
    pub const ALL: [LayerWeights; 3] = [LayerWeights::Both, LayerWeights::Node, LayerWeights::Mesh];

    pub fn name(self) -> &'static str {
        match self {
            LayerWeights::Both => "both",
            LayerWeights::Node => "node",
            LayerWeights::Mesh => "mesh",
        }
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
    /// Attribute storage: quantized (`KHR_mesh_quantization`) or floats.
    pub quantize: Quantize,
    /// Texture coordinate bits, 8–16 (see [`crate::output::pack::UvGrid`]; quantized files only).
    pub texcoord_bits: u32,
    /// Where layer weights are written.
    pub layer_weights: LayerWeights,
}

impl Default for PackParams {
    fn default() -> Self {
        PackParams {
            layout: Layout::Compact,
            position_bits: 14,
            quantize: Quantize::Khr,
            texcoord_bits: 16,
            layer_weights: LayerWeights::Both,
        }
    }
}

impl PackParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("position_bits", self.position_bits as f32, 8.0, 16.0)?;
        ParamError::in_range("texcoord_bits", self.texcoord_bits as f32, 8.0, 16.0)?;
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
