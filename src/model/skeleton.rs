//! Skinned fur: a skinned input keeps its skin, so the shells move with the body.
//!
//! A glTF input whose meshes carry `JOINTS_0`/`WEIGHTS_0` and whose nodes name a skin is read in
//! its **bind pose** (the mesh node's transform is ignored, as glTF 2.0 §3.7.3.3 says), with each
//! vertex's four joints and weights ([`crate::model::mesh::VertexSkin`]) and the [`Skeleton`]: the skin's
//! joints and every ancestor of them (the nodes their world matrices depend on), the inverse bind
//! matrices, and every animation channel that moves those nodes (translation, rotation, scale;
//! `LINEAR`, `STEP` or `CUBICSPLINE`). The fur is grown on the bind pose like any mesh; the output
//! then carries:
//!
//! - `JOINTS_0` (unsigned byte, or short past 256 joints) and `WEIGHTS_0` (normalized unsigned
//!   byte, each vertex's four summing to exactly 255) shared by every layer's primitive (the
//!   compact layout), or repeated per layer (single-draw); the morph targets (extrusion, bend,
//!   wind) apply before the skin, as glTF specifies, so each strand leaves the skin along the
//!   bone's frame;
//! - a copy of the skeleton under a node `<surface>_skeleton` that carries the surface's
//!   placement, a skin over the copied joints, and the input's animations retargeted to them;
//! - every layer node as a scene root without a transform, with the skin (a skinned mesh
//!   ignores its node's transform, and the glTF validator warns about skinned nodes that have a
//!   parent or a transform). The position dequantization the root node carries for unskinned
//!   surfaces moves into the inverse bind matrices: with `P` the placement, `R` the stored-value
//!   → world matrix, the written inverse bind matrix is `IBM · P⁻¹ · R`, and with the skeleton
//!   under `P` each joint gives `P · J · IBM · P⁻¹ · R · q = P · J · IBM · v` — the input's skinning,
//!   placed.
//!
//! Decisions (the design is silent): one skin per surface (meshes bound to different skins, or
//! skinned and rigid meshes mixed, are refused naming the nodes — bake them as separate
//! surfaces); a vertex's weights are normalised to sum to 1; a skinned surface's LOD chain
//! is carried by its layer nodes themselves (`MSFT_lod` switches a node's subtree, and a skinned
//! mesh node must be a root: `pack::place::skinned_switches`);
//! the inversion guard checks the bind pose only — a pose that folds the skin folds its fur too,
//! as it would with the runtime technique. Each clip loops over its own length, as three.js's
//! `AnimationMixer` plays it (within a channel, time is clamped to its keys, as glTF asks); `verify` compares the rest (bind) pose and a quarter and three quarters of the
//! longest clip.

use glam::{DMat4, DQuat, DVec3};

/// A node's local transform, translation · rotation · scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trs {
    pub translation: DVec3,
    pub rotation: DQuat,
    pub scale: DVec3,
}

impl Default for Trs {
    fn default() -> Self {
        Trs {
            translation: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            scale: DVec3::ONE,
        }
    }
}

impl Trs {
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// The TRS of a matrix without shear (a node's `matrix`).
    pub fn from_matrix(m: DMat4) -> Trs {
        let (scale, rotation, translation) = m.to_scale_rotation_translation();
        Trs {
            translation,
            rotation: rotation.normalize(),
            scale,
        }
    }
}

/// What an animation channel moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Path {
    Translation,
    Rotation,
    Scale,
}

impl Path {
    pub fn name(self) -> &'static str {
        match self {
            Path::Translation => "translation",
            Path::Rotation => "rotation",
            Path::Scale => "scale",
        }
    }

    pub fn from_name(name: &str) -> Option<Path> {
        [Path::Translation, Path::Rotation, Path::Scale]
            .into_iter()
            .find(|p| p.name() == name)
    }

    /// Components per key.
    pub fn components(self) -> usize {
        match self {
            Path::Rotation => 4,
            _ => 3,
        }
    }
}

/// How an animation sampler interpolates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Linear,
    Step,
    CubicSpline,
}

impl Interpolation {
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "LINEAR",
            Interpolation::Step => "STEP",
            Interpolation::CubicSpline => "CUBICSPLINE",
        }
    }

    /// Entries a key holds per animated value: 3 for `CUBICSPLINE` (in-tangent, value,
    /// out-tangent), else 1.
    pub fn per_key(self) -> usize {
        match self {
            Interpolation::CubicSpline => 3,
            _ => 1,
        }
    }

    pub fn from_name(name: &str) -> Option<Interpolation> {
        [
            Interpolation::Linear,
            Interpolation::Step,
            Interpolation::CubicSpline,
        ]
        .into_iter()
        .find(|i| i.name() == name)
    }
}

/// One channel: a node's translation, rotation or scale over time.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub node: usize,
    pub path: Path,
    pub interpolation: Interpolation,
    /// Key times, seconds, increasing.
    pub times: Vec<f32>,
    /// Per key, `path.components()` values (three times as many for `CUBICSPLINE`: in-tangent,
    /// value, out-tangent).
    pub values: Vec<f32>,
}

/// A track of `n` components per key (`times`, and `values` per key: three times as many for
/// `CUBICSPLINE`, in-tangent, value, out-tangent) at `time`, clamped to the keys: glTF's
/// `STEP`, `LINEAR` (slerped when `rotation`, not normalised) or `CUBICSPLINE` (Appendix C:
/// Hermite with tangents scaled by the key interval). Node channels and morph weights alike.
pub fn sample(
    interpolation: Interpolation,
    (times, values): (&[f32], &[f32]),
    n: usize,
    time: f32,
    rotation: bool,
) -> Vec<f32> {
    let cubic = interpolation == Interpolation::CubicSpline;
    let stride = interpolation.per_key() * n;
    let value = |k: usize| {
        let o = k * stride + if cubic { n } else { 0 };
        &values[o..o + n]
    };
    let keys = times.len();
    match times.iter().position(|&t| t > time) {
        _ if keys == 0 => vec![0.0; n],
        None => value(keys - 1).to_vec(),
        Some(0) => value(0).to_vec(),
        Some(k) => {
            let (t0, t1) = (times[k - 1], times[k]);
            let dt = t1 - t0;
            let f = if dt > 0.0 { (time - t0) / dt } else { 0.0 };
            match interpolation {
                Interpolation::Step => value(k - 1).to_vec(),
                Interpolation::Linear if rotation => {
                    let q = |v: &[f32]| {
                        DQuat::from_xyzw(v[0] as f64, v[1] as f64, v[2] as f64, v[3] as f64)
                    };
                    let r = q(value(k - 1)).slerp(q(value(k)), f as f64);
                    r.to_array().map(|x| x as f32).to_vec()
                }
                Interpolation::Linear => value(k - 1)
                    .iter()
                    .zip(value(k))
                    .map(|(&a, &b)| a + (b - a) * f)
                    .collect(),
                Interpolation::CubicSpline => {
                    let (f2, f3) = (f * f, f * f * f);
                    let out_tangent = &values[(k - 1) * stride + 2 * n..][..n];
                    let in_tangent = &values[k * stride..][..n];
                    (0..n)
                        .map(|c| {
                            (2.0 * f3 - 3.0 * f2 + 1.0) * value(k - 1)[c]
                                + (f3 - 2.0 * f2 + f) * dt * out_tangent[c]
                                + (-2.0 * f3 + 3.0 * f2) * value(k)[c]
                                + (f3 - f2) * dt * in_tangent[c]
                        })
                        .collect()
                }
            }
        }
    }
}

impl Channel {
    /// The value at `time`, clamped to the keys. Rotations are slerped (and normalised).
    pub fn at(&self, time: f32) -> Vec<f32> {
        let rotation = self.path == Path::Rotation;
        let keys = (&self.times[..], &self.values[..]);
        let out = sample(
            self.interpolation,
            keys,
            self.path.components(),
            time,
            rotation,
        );
        if rotation {
            let q = DQuat::from_xyzw(out[0] as f64, out[1] as f64, out[2] as f64, out[3] as f64);
            return q.normalize().to_array().map(|x| x as f32).to_vec();
        }
        out
    }

    /// The last key's time.
    pub fn end(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// `trs` with this channel's value at `time`.
    pub fn apply(&self, trs: &mut Trs, time: f32) {
        let v = self.at(time);
        let v3 = || DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        match self.path {
            Path::Translation => trs.translation = v3(),
            Path::Scale => trs.scale = v3(),
            Path::Rotation => {
                trs.rotation = DQuat::from_xyzw(v[0] as f64, v[1] as f64, v[2] as f64, v[3] as f64)
            }
        }
    }
}

/// An animation: its name and channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    pub name: String,
    pub channels: Vec<Channel>,
}

impl Clip {
    /// The last key of any channel, seconds.
    pub fn duration(&self) -> f32 {
        self.channels.iter().map(Channel::end).fold(0.0, f32::max)
    }
}

/// Plays every clip to `time` on the local transforms `locals` (indexed by the channels'
/// nodes), each clip looping over its own length as three.js's `AnimationMixer` plays it.
pub fn pose(locals: &mut [Trs], clips: &[Clip], time: f32) {
    for clip in clips {
        let length = clip.duration();
        let t = if length > 0.0 {
            time.rem_euclid(length)
        } else {
            0.0
        };
        for c in &clip.channels {
            if let Some(trs) = locals.get_mut(c.node) {
                c.apply(trs, t);
            }
        }
    }
}

/// Keeps the one clip to play: the one named `name`, or the first (the clips of a file are
/// separate motions — idle, run — that a viewer plays one at a time; playing all at once lets
/// the last write every joint it animates). The error lists the names the file has.
pub fn choose_clip(clips: &mut Vec<Clip>, name: Option<&str>) -> std::result::Result<(), String> {
    match name {
        None => clips.truncate(1),
        Some(n) => {
            let names: Vec<String> = clips.iter().map(|c| c.name.clone()).collect();
            clips.retain(|c| c.name == n);
            if clips.is_empty() {
                // (the caller escapes names from the file before they reach a terminal)
                let had = if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                };
                return Err(format!("no animation clip '{n}' (the file has: {had})"));
            }
            clips.truncate(1);
        }
    }
    Ok(())
}

/// A node of the skeleton copy.
#[derive(Clone, Debug, PartialEq)]
pub struct SkelNode {
    pub name: String,
    /// The rest (non-animated) local transform.
    pub trs: Trs,
    /// Children within the skeleton.
    pub children: Vec<usize>,
}

/// A skin and what its joints' world matrices depend on (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// The joints and their ancestors.
    pub nodes: Vec<SkelNode>,
    /// Nodes without a parent in the skeleton (their parent's world is the identity).
    pub roots: Vec<usize>,
    /// Joint `j` of the skin (what `JOINTS_0` indexes) is node `joints[j]`.
    pub joints: Vec<usize>,
    /// Per joint, the input's inverse bind matrix.
    pub inverse_bind: Vec<DMat4>,
    /// Animations, channels retargeted to `nodes`.
    pub clips: Vec<Clip>,
    /// The surface's placement (scale, then translation), applied to the bind-pose positions.
    pub placement: DMat4,
}

impl Skeleton {
    /// Scales by `scale` about the world origin, then translates (as [`crate::model::mesh::Mesh::place`]).
    pub fn place(&mut self, translation: DVec3, scale: f64) {
        self.placement = DMat4::from_translation(translation)
            * DMat4::from_scale(DVec3::splat(scale))
            * self.placement;
    }

    /// The longest clip's length, seconds (0 without animations).
    pub fn duration(&self) -> f32 {
        self.clips.iter().map(Clip::duration).fold(0.0, f32::max)
    }

    /// Every node's world matrix (in the input's frame, before placement) with every clip played
    /// to `time` ([`pose`]; `None`: the rest transforms).
    pub fn worlds_at(&self, time: Option<f32>) -> Vec<DMat4> {
        let mut locals: Vec<Trs> = self.nodes.iter().map(|n| n.trs).collect();
        if let Some(t) = time {
            pose(&mut locals, &self.clips, t);
        }
        let mut worlds = vec![DMat4::IDENTITY; self.nodes.len()];
        let mut stack: Vec<(usize, DMat4)> =
            self.roots.iter().map(|&r| (r, DMat4::IDENTITY)).collect();
        while let Some((n, parent)) = stack.pop() {
            worlds[n] = parent * locals[n].matrix();
            stack.extend(self.nodes[n].children.iter().map(|&c| (c, worlds[n])));
        }
        worlds
    }

    /// Per joint, the matrix that takes a placed bind-pose point to its placed posed position
    /// at `time`: `P · J · IBM · P⁻¹`.
    pub fn joint_matrices(&self, time: Option<f32>) -> Vec<DMat4> {
        let worlds = self.worlds_at(time);
        let p = self.placement;
        let p_inv = p.inverse();
        self.joints
            .iter()
            .zip(&self.inverse_bind)
            .map(|(&j, ibm)| p * worlds[j] * *ibm * p_inv)
            .collect()
    }
}

/// Normalises four weights to sum to 1 and merges repeated joints; zero-weight slots get joint
/// 0. All zero: the first joint with weight 1.
pub fn normalize_influences(joints: [u16; 4], weights: [f32; 4]) -> ([u16; 4], [f32; 4]) {
    let mut j = [0u16; 4];
    let mut w = [0.0f32; 4];
    let mut n = 0;
    for k in 0..4 {
        let wk = if weights[k].is_finite() {
            weights[k].max(0.0)
        } else {
            0.0
        };
        if wk == 0.0 {
            continue;
        }
        match j[..n].iter().position(|&x| x == joints[k]) {
            Some(i) => w[i] += wk,
            None => {
                j[n] = joints[k];
                w[n] = wk;
                n += 1;
            }
        }
    }
    let sum: f32 = w.iter().sum();
    if sum <= 0.0 {
        return ([joints[0], 0, 0, 0], [1.0, 0.0, 0.0, 0.0]);
    }
    (j, w.map(|x| x / sum))
}

/// Four weights (summing to 1) as normalized bytes summing to exactly 255: each rounded down,
/// the remainder given to the largest fractions first (ties: the first slot).
pub fn weight_bytes(w: [f32; 4]) -> [u8; 4] {
    let scaled = w.map(|x| (x.clamp(0.0, 1.0) * 255.0) as f64);
    let mut b = scaled.map(|x| x.floor() as u8);
    let sum: u32 = b.iter().map(|&x| x as u32).sum();
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&a, &c| {
        let fa = scaled[a] - scaled[a].floor();
        let fc = scaled[c] - scaled[c].floor();
        fc.total_cmp(&fa).then(a.cmp(&c))
    });
    for &k in order.iter().take(255u32.saturating_sub(sum) as usize) {
        b[k] += 1;
    }
    b
}

/// A vertex's influences as written: the weights as bytes ([`weight_bytes`]) and each joint
/// whose byte rounded to 0 replaced by joint 0 (the glTF validator warns about a joint named with
/// a zero weight).
pub fn influence_bytes(joints: [u16; 4], weights: [f32; 4]) -> ([u16; 4], [u8; 4]) {
    let b = weight_bytes(weights);
    (
        std::array::from_fn(|k| if b[k] == 0 { 0 } else { joints[k] }),
        b,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(path: Path, interpolation: Interpolation, values: Vec<f32>) -> Channel {
        Channel {
            node: 0,
            path,
            interpolation,
            times: vec![0.0, 1.0],
            values,
        }
    }

    #[test]
    fn channels_interpolate_and_clamp() {
        let c = channel(
            Path::Translation,
            Interpolation::Linear,
            vec![0.0, 0.0, 0.0, 2.0, 4.0, 6.0],
        );
        assert_eq!(c.at(0.5), vec![1.0, 2.0, 3.0]);
        assert_eq!(c.at(-1.0), vec![0.0; 3]);
        assert_eq!(c.at(5.0), vec![2.0, 4.0, 6.0]);
        let s = Channel {
            interpolation: Interpolation::Step,
            ..c.clone()
        };
        assert_eq!(s.at(0.9), vec![0.0; 3]);
        let half = std::f32::consts::FRAC_1_SQRT_2;
        let r = channel(
            Path::Rotation,
            Interpolation::Linear,
            vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0],
        );
        // halfway from identity to 180° about z: 90°
        let q = r.at(0.5);
        assert!(
            (q[2] - half).abs() < 1e-6 && (q[3] - half).abs() < 1e-6,
            "{q:?}"
        );
        // a cubic spline with zero tangents eases between the values
        let cs = channel(
            Path::Scale,
            Interpolation::CubicSpline,
            [[0.0; 3], [1.0; 3], [0.0; 3], [0.0; 3], [3.0; 3], [0.0; 3]].concat(),
        );
        assert_eq!(cs.at(0.0), vec![1.0; 3]);
        assert_eq!(cs.at(0.5), vec![2.0; 3]);
        assert_eq!(cs.at(1.0), vec![3.0; 3]);
    }

    #[test]
    fn joint_matrices_follow_the_pose_and_the_placement() {
        // two nodes: a root and a joint one unit up; the joint turns 180° about z over 1 s (90° at 0.5 s)
        let mut s = Skeleton {
            nodes: vec![
                SkelNode {
                    name: "root".into(),
                    trs: Trs::default(),
                    children: vec![1],
                },
                SkelNode {
                    name: "joint".into(),
                    trs: Trs {
                        translation: DVec3::Y,
                        ..Trs::default()
                    },
                    children: vec![],
                },
            ],
            roots: vec![0],
            joints: vec![1],
            inverse_bind: vec![DMat4::from_translation(-DVec3::Y)],
            clips: vec![Clip {
                name: "bend".into(),
                channels: vec![Channel {
                    node: 1,
                    ..channel(
                        Path::Rotation,
                        Interpolation::Linear,
                        vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0],
                    )
                }],
            }],
            placement: DMat4::IDENTITY,
        };
        assert_eq!(s.duration(), 1.0);
        // the bind pose moves nothing
        let rest = s.joint_matrices(None)[0];
        assert!(rest.abs_diff_eq(DMat4::IDENTITY, 1e-12));
        // a point two units up turns about the joint at y = 1: (0, 2) → (−1, 1)
        let p = s.joint_matrices(Some(0.5))[0].transform_point3(DVec3::new(0.0, 2.0, 0.0));
        assert!(p.abs_diff_eq(DVec3::new(-1.0, 1.0, 0.0), 1e-6), "{p}");
        // placed: scaled 2, moved +x 10; the placed point (10, 4) turns to (8, 2)
        s.place(DVec3::new(10.0, 0.0, 0.0), 2.0);
        let p = s.joint_matrices(Some(0.5))[0].transform_point3(DVec3::new(10.0, 4.0, 0.0));
        assert!(p.abs_diff_eq(DVec3::new(8.0, 2.0, 0.0), 1e-6), "{p}");
    }

    #[test]
    fn influences_normalise_and_bytes_sum_to_255() {
        let (j, w) = normalize_influences([3, 3, 5, 7], [0.25, 0.25, 0.5, 0.0]);
        assert_eq!(j, [3, 5, 0, 0]);
        assert_eq!(w, [0.5, 0.5, 0.0, 0.0]);
        assert_eq!(
            normalize_influences([2, 1, 0, 0], [0.0; 4]),
            ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
        );
        for w in [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0],
            [0.1, 0.2, 0.3, 0.4],
            [1.0, 0.0, 0.0, 0.0],
        ] {
            let b = weight_bytes(w);
            assert_eq!(
                b.iter().map(|&x| x as u32).sum::<u32>(),
                255,
                "{w:?} → {b:?}"
            );
        }
        assert_eq!(
            weight_bytes([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0]),
            [85, 85, 85, 0]
        );
    }
}
