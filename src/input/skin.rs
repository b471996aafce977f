//! Skins and node animations of a glTF document, for the loader (a skinned input's
//! [`Skeleton`]) and the viewer (a baked file's joints and clips). What they mean is in
//! [`crate::model::skeleton`]; here they are read and checked: a skin's inverse bind matrices are `MAT4`
//! floats, one per joint (absent: identities); a channel's keys are `SCALAR` floats, increasing,
//! its values `VEC3`/`VEC4` floats (rotations also as normalized integers), as many as the keys
//! ask. Channels on `weights` are not node transforms and are left to the caller.

use std::collections::HashMap;

use glam::DMat4;
use serde_json::Value;

use super::document::{Document, Kind};
use crate::error::{Error, Result};
use crate::facts::{Facts, Reported};
use crate::model::skeleton::{Channel, Clip, Interpolation, Path, SkelNode, Skeleton};

/// Skin `s`: its joints (node indices) and inverse bind matrices.
pub fn read_skin(
    doc: &Document,
    buffers: &[Vec<u8>],
    s: usize,
) -> Result<(Vec<usize>, Vec<DMat4>)> {
    let skin = &doc.json["skins"][s];
    let element = format!("skin {s}");
    let joints: Vec<usize> = skin["joints"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(Value::as_u64)
                .map(|j| j as usize)
                .collect()
        })
        .unwrap_or_default();
    if joints.is_empty() {
        return Err(Error::invalid(&doc.path, element, "has no joints"));
    }
    let ibm = match skin["inverseBindMatrices"].as_u64() {
        None => vec![DMat4::IDENTITY; joints.len()],
        Some(a) => {
            let a = a as usize;
            let acc = &doc.accessors[a];
            if acc.kind != Kind::Mat4 || acc.component_type != 5126 || acc.count != joints.len() {
                return Err(Error::invalid(
                    &doc.path,
                    format!("{element}: accessor {a}"),
                    format!(
                        "inverseBindMatrices must be {} MAT4 floats (one per joint)",
                        joints.len()
                    ),
                ));
            }
            doc.read_accessor(buffers, a, &element)?
                .chunks_exact(16)
                .map(DMat4::from_cols_slice)
                .collect()
        }
    };
    if ibm.iter().any(|m| !m.is_finite() || m.determinant() == 0.0) {
        return Err(Error::invalid(
            &doc.path,
            element,
            "an inverse bind matrix is not finite or not invertible",
        ));
    }
    Ok((joints, ibm))
}

/// Every animation's translation, rotation and scale channels, on document nodes.
pub fn read_clips(doc: &Document, buffers: &[Vec<u8>]) -> Result<Vec<Clip>> {
    let mut clips = Vec::new();
    let empty = Vec::new();
    for (i, a) in doc.json["animations"]
        .as_array()
        .unwrap_or(&empty)
        .iter()
        .enumerate()
    {
        let mut channels = Vec::new();
        let samplers = a["samplers"].as_array().unwrap_or(&empty);
        for (k, c) in a["channels"]
            .as_array()
            .unwrap_or(&empty)
            .iter()
            .enumerate()
        {
            let element = format!("animation {i} channel {k}");
            let (Some(node), Some(path)) =
                (c["target"]["node"].as_u64(), c["target"]["path"].as_str())
            else {
                continue;
            };
            let Some(path) = Path::from_name(path) else {
                continue; // weights (or an extension's path)
            };
            let (input, interpolation, output) =
                channel_keys(doc, buffers, (samplers, c), &element)?;
            let times = input.times;
            let kind = if path == Path::Rotation {
                Kind::Vec4
            } else {
                Kind::Vec3
            };
            let per_key = interpolation.per_key();
            let values: Vec<f32> = doc
                .read_accessor(buffers, output, &element)?
                .into_iter()
                .map(|v| v as f32)
                .collect();
            if doc.accessors[output].kind != kind
                || doc.accessors[output].count != times.len() * per_key
                || values.iter().any(|v| !v.is_finite())
            {
                return Err(Error::invalid(
                    &doc.path,
                    element,
                    format!(
                        "{} values must be {} finite {} (one{} per key)",
                        path.name(),
                        times.len() * per_key,
                        kind.name(),
                        if per_key == 3 { " triple" } else { "" }
                    ),
                ));
            }
            channels.push(Channel {
                node: node as usize,
                path,
                interpolation,
                times,
                values,
            });
        }
        if !channels.is_empty() {
            let name = a["name"]
                .as_str()
                .map_or_else(|| format!("animation_{i}"), str::to_string);
            clips.push(Clip { name, channels });
        }
    }
    Ok(clips)
}

/// The keys of an animation channel `c` (its animation's `samplers`): the input accessor and
/// its times (checked increasing, finite scalars), the interpolation, and the output accessor.
pub(super) fn channel_keys(
    doc: &Document,
    buffers: &[Vec<u8>],
    (samplers, c): (&[Value], &Value),
    element: &str,
) -> Result<(Keys, Interpolation, usize)> {
    let sampler = c["sampler"].as_u64().and_then(|s| samplers.get(s as usize));
    let name = sampler
        .and_then(|s| s["interpolation"].as_str())
        .unwrap_or("LINEAR");
    let interpolation = Interpolation::from_name(name).ok_or_else(|| {
        Error::invalid(
            &doc.path,
            element,
            format!(
                "interpolation '{}' is not glTF's",
                super::boundary::escape(name)
            ),
        )
    })?;
    let (Some(input), Some(output)) = (
        sampler.and_then(|s| s["input"].as_u64()),
        sampler.and_then(|s| s["output"].as_u64()),
    ) else {
        return Err(Error::invalid(
            &doc.path,
            element,
            "its sampler lacks input or output",
        ));
    };
    let (input, output) = (input as usize, output as usize);
    let times: Vec<f32> = doc
        .read_accessor(buffers, input, element)?
        .into_iter()
        .map(|t| t as f32)
        .collect();
    if doc.accessors[input].kind != Kind::Scalar
        || times.iter().any(|t| !t.is_finite())
        || times.windows(2).any(|w| w[1] <= w[0])
    {
        return Err(Error::invalid(
            &doc.path,
            element,
            "key times must be increasing finite scalars",
        ));
    }
    Ok((
        Keys {
            accessor: input,
            times,
        },
        interpolation,
        output,
    ))
}

/// A channel's key times and the accessor they are read from.
pub(super) struct Keys {
    pub accessor: usize,
    pub times: Vec<f32>,
}

/// The skeleton of skin `s`: its joints and their ancestors copied (document order), the inverse
/// bind matrices, and the channels that move any of them.
pub fn read_skeleton(doc: &Document, buffers: &[Vec<u8>], s: usize) -> Result<Skeleton> {
    let (joints, inverse_bind) = read_skin(doc, buffers, s)?;
    let mut parent = vec![None; doc.nodes.len()];
    for (n, node) in doc.nodes.iter().enumerate() {
        for &c in &node.children {
            parent[c] = Some(n);
        }
    }
    let mut keep = vec![false; doc.nodes.len()];
    for &j in &joints {
        let mut n = Some(j);
        while let Some(k) = n {
            if keep[k] {
                break;
            }
            keep[k] = true;
            n = parent[k];
        }
    }
    let kept: Vec<usize> = (0..doc.nodes.len()).filter(|&n| keep[n]).collect();
    let index: HashMap<usize, usize> = kept.iter().enumerate().map(|(i, &n)| (n, i)).collect();
    let nodes = kept
        .iter()
        .map(|&n| SkelNode {
            name: doc.nodes[n]
                .name
                .clone()
                .unwrap_or_else(|| format!("node_{n}")),
            trs: doc.nodes[n].trs,
            children: doc.nodes[n]
                .children
                .iter()
                .filter_map(|c| index.get(c).copied())
                .collect(),
        })
        .collect();
    let roots = kept
        .iter()
        .enumerate()
        .filter(|&(_, &n)| parent[n].is_none_or(|p| !keep[p]))
        .map(|(i, _)| i)
        .collect();
    let clips = read_clips(doc, buffers)?
        .into_iter()
        .filter_map(|mut clip| {
            clip.channels.retain_mut(|c| match index.get(&c.node) {
                Some(&i) => {
                    c.node = i;
                    true
                }
                None => false,
            });
            (!clip.channels.is_empty()).then_some(clip)
        })
        .collect();
    Ok(Skeleton {
        nodes,
        roots,
        joints: joints.iter().map(|j| index[j]).collect(),
        inverse_bind,
        clips,
        placement: DMat4::IDENTITY,
    })
}

/// The load stage's facts about a skinned input: what the file keeps.
impl Reported for Skeleton {
    fn facts(&self) -> Facts {
        let clips: Vec<String> = self
            .clips
            .iter()
            .map(|c| super::boundary::escape(&c.name))
            .collect();
        let clips = if clips.is_empty() {
            "none".into()
        } else {
            clips.join(", ")
        };
        Facts::counts([
            ("skin_joints", self.joints.len() as f64),
            ("skin_nodes", self.nodes.len() as f64),
            ("skin_clips", self.clips.len() as f64),
        ])
        .with_note(format!(
            "skinned: the skin, its skeleton and clips ({clips}) are kept; the fur grows on the bind pose"
        ))
    }
}
