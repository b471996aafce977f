//! A part's shape keys: its node's morph weights at rest and every animation channel on them,
//! read and checked.

use serde_json::Value;

use crate::error::{Error, Result};
use crate::input::document::{Document, Kind, Primitive};
use crate::model::skeleton::Interpolation;

/// The morph weights of a part's node: at rest, and as its animations move them. The fur's
/// layer nodes get the same, after their own weights (`output/graft.rs`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeKeys {
    /// The node's `weights`, else its mesh's, else zeros: one per target.
    pub rest: Vec<f32>,
    /// The mesh's `extras.targetNames`, one per target (empty when it has none).
    pub names: Vec<String>,
    /// Every animation channel on the node's `weights`.
    pub channels: Vec<WeightsChannel>,
}

impl ShapeKeys {
    /// The channels on the weights and their keys summed (three a key for `CUBICSPLINE`).
    pub fn clips(&self) -> (u64, u64) {
        let targets = self.rest.len().max(1);
        let keys = self
            .channels
            .iter()
            .map(|c| (c.values.len() / targets) as u64);
        (self.channels.len() as u64, keys.sum())
    }
}

/// One animation channel on a part's morph weights.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightsChannel {
    /// The animation it belongs to (the fur's channels join it).
    pub animation: usize,
    /// The key times' accessor (shared with the fur's channels).
    pub input: usize,
    pub interpolation: Interpolation,
    /// Per key, one value per target (`CUBICSPLINE`: in-tangents, values, out-tangents).
    pub values: Vec<f32>,
}

/// The shape keys of `prim`, drawn by `node` with mesh `mesh`: the rest weights and every
/// animation channel on the node's `weights`, checked (key count × targets values, finite).
pub(super) fn shape_keys(
    doc: &Document,
    buffers: &[Vec<u8>],
    (node, mesh): (usize, usize),
    prim: &Primitive,
) -> Result<ShapeKeys> {
    let targets = prim.targets.len();
    let weights = |v: &Value| {
        v.as_array()
            .filter(|w| w.len() == targets)
            .map(|w| w.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect())
    };
    let rest = weights(&doc.json["nodes"][node]["weights"])
        .or_else(|| weights(&doc.json["meshes"][mesh]["weights"]))
        .unwrap_or_else(|| vec![0.0; targets]);
    let mut channels = Vec::new();
    let empty = Vec::new();
    let animations = doc.json["animations"].as_array().unwrap_or(&empty);
    for (a, animation) in animations.iter().enumerate() {
        let samplers = animation["samplers"].as_array().unwrap_or(&empty);
        let on_node = (animation["channels"]
            .as_array()
            .unwrap_or(&empty)
            .iter()
            .enumerate())
        .filter(|(_, c)| {
            c["target"]["node"].as_u64() == Some(node as u64)
                && c["target"]["path"].as_str() == Some("weights")
        });
        for (k, c) in on_node {
            let element = format!("animation {a} channel {k}");
            let (keys, interpolation, output) =
                crate::input::skin::channel_keys(doc, buffers, (samplers, c), &element)?;
            let (input, keys) = (keys.accessor, keys.times.len());
            let per_key = interpolation.per_key();
            let values: Vec<f32> = (doc.read_accessor(buffers, output, &element)?.into_iter())
                .map(|v| v as f32)
                .collect();
            if doc.accessors[output].kind != Kind::Scalar
                || values.len() != keys * targets * per_key
                || values.iter().any(|v| !v.is_finite())
            {
                return Err(Error::invalid(
                    &doc.path,
                    element,
                    format!(
                        "morph weights must be {} finite scalars ({keys} keys × {targets} targets{})",
                        keys * targets * per_key,
                        if per_key == 3 { " × 3" } else { "" }
                    ),
                ));
            }
            channels.push(WeightsChannel {
                animation: a,
                input,
                interpolation,
                values,
            });
        }
    }
    let names: Vec<String> = (doc.json["meshes"][mesh]["extras"]["targetNames"].as_array())
        .filter(|n| n.len() == targets)
        .and_then(|n| n.iter().map(|v| v.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    Ok(ShapeKeys {
        rest,
        names,
        channels,
    })
}
