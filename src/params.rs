//! Parameters: the bake's parameters gathered from the stages, and the four presets.
//!
//! Each stage owns its parameters — the struct, its `Default` and its `check()` live in the
//! stage's file (`orient.rs`, `clamp.rs`, `strands.rs`, `shells.rs`, `pack/`) — and
//! [`BakeParams`] gathers them, one section per stage. Scene files (TOML), presets and CLI flags
//! all end in these structs: a preset is a TOML file of overrides (`src/presets/*.toml`) read
//! through [`BakeParams::with_overrides`], the same serde path that reads a scene surface's
//! overrides, so a knob has exactly one definition. The stage defaults are the fur preset.
//!
//! Scale-free defaults: meshes arrive at any scale (a bunny of 0.2 m, a field of 500 m), so the
//! presets state shell height and strand density *relative to the bounding-box diagonal*
//! (`height_fraction`, `strands_per_diagonal`). An explicit `height` (world units) or `density`
//! (strands per world unit) overrides them; [`BakeParams::resolved_height`] and
//! [`BakeParams::resolved_density`] turn the relative values into world units once the mesh is
//! known, and the report shows the resolved figures.

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
pub use crate::grid::MAX_LAYERS;
pub use crate::output::pack::{Layout, PackParams};
pub use crate::stages::clamp::ClampParams;
pub use crate::stages::lod::LodParams;
pub use crate::stages::orient::OrientParams;
pub use crate::stages::shells::{ShadeParams, ShellParams};
pub use crate::stages::strands::{StrandModel, StrandParams};

/// Named parameter sets for common surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Animal fur: long tapered strands, dense, warm brown gradient.
    Fur,
    /// Carpet pile: short, very dense single-texel tufts (the seed's white-noise law).
    Carpet,
    /// Grass: tall, sparse, thick blades, green gradient.
    Grass,
    /// Moss: very short, very dense, white-noise law.
    Moss,
}

impl Preset {
    /// All presets, in the order tests and the study iterate them.
    pub const ALL: [Preset; 4] = [Preset::Fur, Preset::Carpet, Preset::Grass, Preset::Moss];

    /// The lowercase name used on the command line, in scene files and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fur => "fur",
            Preset::Carpet => "carpet",
            Preset::Grass => "grass",
            Preset::Moss => "moss",
        }
    }

    /// The tallest the preset's strands are in life, in metres, generously: an asset's default
    /// height past it (a fraction of the part's diagonal: 114 m blades on a 1 km terrain) is
    /// said in a warning, since glTF's lengths are metres.
    pub fn tallest(self) -> f32 {
        match self {
            Preset::Fur => 1.0,
            Preset::Carpet | Preset::Moss => 0.2,
            Preset::Grass => 3.0,
        }
    }

    /// The preset called `name`.
    pub fn from_name(name: &str) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The preset's overrides of the stage defaults, as TOML.
    pub fn overrides(self) -> &'static str {
        match self {
            Preset::Fur => include_str!("presets/fur.toml"),
            Preset::Carpet => include_str!("presets/carpet.toml"),
            Preset::Grass => include_str!("presets/grass.toml"),
            Preset::Moss => include_str!("presets/moss.toml"),
        }
    }
}

/// Everything a bake needs, one section per stage. `Default` is the `fur` preset.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BakeParams {
    pub orient: OrientParams,
    pub clamp: ClampParams,
    pub strands: StrandParams,
    pub shells: ShellParams,
    pub shade: ShadeParams,
    pub lod: LodParams,
    pub pack: PackParams,
    /// The `gravity` effect's bend (used only when a surface asks for the effect).
    pub gravity: crate::effects::gravity::GravityParams,
    /// The `tessellation` effect's factor and shape.
    pub tessellation: crate::stages::tessellate::TessellationParams,
    /// How finely the fur's colour follows an asset's (the colour stage).
    pub colour: crate::stages::colour::ColourParams,
    /// The `occlusion` effect's rays and strength.
    pub occlusion: crate::effects::occlusion::OcclusionParams,
    /// The `sheen` effect's colour and roughness (per preset).
    pub sheen: crate::effects::sheen::SheenParams,
    /// The `wind` effect's sway and period.
    pub wind: crate::effects::wind::WindParams,
    /// The `fins` effect's edge rule and strip.
    pub fins: crate::effects::fins::FinParams,
    /// The `outline` effect's width and colour.
    pub outline: crate::effects::outline::OutlineParams,
}

/// Keys whose value replaces the base value whole instead of merging into it: a strand model
/// names its law, and the fields of one law mean nothing to another.
const REPLACED_WHOLE: &[&str] = &["model"];

/// Merges `over` into `base`: tables merge key by key (except [`REPLACED_WHOLE`]), anything else
/// replaces.
fn merge(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o))
                if !REPLACED_WHOLE.contains(&key.as_str()) =>
            {
                merge(b, o)
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

impl BakeParams {
    /// The sections a scene file's surface and `--set` may name, in declaration order: the
    /// struct's own field list, as serde reads it, so a section added to the struct is a
    /// section of scene files with no list to keep beside it.
    pub fn sections() -> &'static [&'static str] {
        use serde::de::{value::Error, Error as _, Visitor};
        /// A deserializer that only records the field list of the struct asked of it.
        struct Fields<'a>(&'a std::cell::Cell<&'static [&'static str]>);
        impl<'de> serde::Deserializer<'de> for Fields<'_> {
            type Error = Error;
            fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Error> {
                Err(Error::custom("a struct's field list only"))
            }
            fn deserialize_struct<V: Visitor<'de>>(
                self,
                _: &'static str,
                fields: &'static [&'static str],
                _: V,
            ) -> Result<V::Value, Error> {
                self.0.set(fields);
                Err(Error::custom("field list recorded"))
            }
            serde::forward_to_deserialize_any! {
                bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
                byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map enum
                identifier ignored_any
            }
        }
        let fields = std::cell::Cell::new(&[][..]);
        let _ = BakeParams::deserialize(Fields(&fields));
        fields.get()
    }

    /// The named preset: the stage defaults with the preset's overrides.
    pub fn preset(preset: Preset) -> BakeParams {
        let over: toml::Table = toml::from_str(preset.overrides())
            .unwrap_or_else(|e| panic!("preset {} does not parse: {e}", preset.name()));
        BakeParams::default()
            .with_overrides(over)
            .unwrap_or_else(|e| panic!("preset {} does not apply: {e}", preset.name()))
    }

    /// These parameters with `over` (sections and keys as in a scene file) applied on top.
    /// Unknown keys and wrong types are errors naming the key; ranges are [`check`]ed separately.
    ///
    /// [`check`]: BakeParams::check
    pub fn with_overrides(&self, over: toml::Table) -> Result<BakeParams, toml::de::Error> {
        let mut base = toml::Table::try_from(self).expect("parameters serialize to TOML");
        merge(&mut base, over);
        base.try_into()
    }

    /// Checks ranges; the error names the parameter with its section (`shells.layers`). Called
    /// at the CLI/scene boundary.
    pub fn check(&self) -> Result<(), ParamError> {
        self.clamp.check().map_err(|e| e.within("clamp"))?;
        self.strands.check().map_err(|e| e.within("strands"))?;
        self.shells.check().map_err(|e| e.within("shells"))?;
        self.shade.check().map_err(|e| e.within("shade"))?;
        self.lod.check().map_err(|e| e.within("lod"))?;
        self.pack.check().map_err(|e| e.within("pack"))?;
        self.gravity.check().map_err(|e| e.within("gravity"))?;
        self.occlusion.check().map_err(|e| e.within("occlusion"))?;
        self.tessellation
            .check()
            .map_err(|e| e.within("tessellation"))?;
        self.colour.check().map_err(|e| e.within("colour"))?;
        self.sheen.check().map_err(|e| e.within("sheen"))?;
        self.wind.check().map_err(|e| e.within("wind"))?;
        self.fins.check().map_err(|e| e.within("fins"))?;
        self.outline.check().map_err(|e| e.within("outline"))?;
        Ok(())
    }

    /// What the `fins` and `outline` effects add to [`BakeParams::estimate_bytes`], when asked:
    /// an upper bound (three fin edges per triangle up to `fins.max`, each fin four float
    /// vertices and twelve 32-bit indices, and the strip; the hull three float vertices and
    /// three 32-bit indices per triangle).
    pub fn estimate_extra_bytes(
        &self,
        scene: &crate::model::mesh::Scene,
        fins: bool,
        outline: bool,
    ) -> u64 {
        let triangles = scene
            .meshes
            .iter()
            .map(|m| m.triangle_count() as u64)
            .sum::<u64>();
        let mut bytes = 0;
        if fins {
            let n = (3 * triangles).min(self.fins.max as u64);
            let strip = self.fins.rows as u64 * (4 * self.strands.mask_size as u64 + 1);
            bytes += n * (4 * (12 + 12 + 8) + 12 * 4) + strip * 4 / 3 + 8192;
        }
        if outline {
            bytes += 3 * triangles * (12 + 4) + 4096;
        }
        bytes
    }

    /// [`crate::output::pack::estimate_bytes`] for a loaded scene baked with these parameters: an upper
    /// bound of the written file (`tests/properties.rs` checks it against real bakes of random
    /// meshes).
    ///
    /// Vertices are counted as three per triangle, the most a bake can pack. A bake splits vertices
    /// after loading — a generated box projection (UVs missing or without area) copies a vertex once
    /// per projection plane; welding copies a vertex shared by the two sides of a sheet (or by several
    /// sheets) once per side — but it packs only vertices some triangle uses. Counting the loaded
    /// vertices undercounts exactly those inputs; on a closed, UV-mapped mesh (about one vertex per
    /// two triangles) the bound is 3–5× the file.
    pub fn estimate_bytes(&self, scene: &crate::model::mesh::Scene) -> u64 {
        let triangles = scene
            .meshes
            .iter()
            .map(|m| m.triangle_count() as u64)
            .sum::<u64>();
        // an asset part's shape keys: a target each over every vertex, as floats at worst
        let shape_keys: u64 = (scene.meshes.iter())
            .map(|m| m.morphs.len() as u64 * 3 * m.triangle_count() as u64 * 12)
            .sum();
        crate::output::pack::estimate_bytes(
            3 * triangles,
            triangles,
            self.shells.layers as u64,
            self.strands.mask_size as u64,
            self.pack.layout,
            (self.lod.levels.max(1) as u64, self.chunk_bound(scene)),
        ) + shape_keys
    }

    /// What animations add to [`BakeParams::estimate_bytes`]: the wind's clip (`wind`), and the
    /// fur's twins of an asset part's shape-key channels, `(channels, keys)`: how many channels
    /// move the part's weights, and their keys summed (three a key for `CUBICSPLINE`). A layer
    /// node's weights depend on its level and layer only and nodes with the same weights share
    /// an output, so a clip stores at most one output per layer mesh of any level, the fins and
    /// the outline, each a float per key and target (targets: the extrusion, the bend, the
    /// occlusion's shade, the wind's two and the shape keys); every node of every chunk costs a
    /// channel and a sampler in the JSON.
    pub fn estimate_animation_bytes(
        &self,
        scene: &crate::model::mesh::Scene,
        wind: bool,
        (channels, keys): (u64, u64),
    ) -> u64 {
        let levels = self.lod.levels.max(1) as u64;
        let meshes = crate::output::pack::level_layers(self.shells.layers as u64, levels) + 2;
        let nodes = self.chunk_bound(scene) * meshes;
        let targets = targets_bound(scene);
        // an output: its floats, its accessor and view (JSON) and padding; a node's channel
        // and sampler (JSON)
        let clip = |keys: u64, channels: u64| {
            meshes * (4 * keys * targets + 256 * channels) + channels * nodes * 128 + 4 * keys + 512
        };
        let wind = if wind {
            clip(self.wind.keyframes as u64 + 1, 1)
        } else {
            0
        };
        wind + if channels > 0 {
            clip(keys, channels)
        } else {
            0
        }
    }

    /// The JSON a copy of the surface's fur nodes adds (an instanced part's fur is copied to
    /// every instance, `output/graft.rs`): a node per layer mesh, the fins and the outline, and
    /// a channel per node for each of `channels` animation channels on them.
    pub fn estimate_copy_bytes(&self, scene: &crate::model::mesh::Scene, channels: u64) -> u64 {
        // an instanced part takes one level in one piece (`blocked`); a node names its mesh,
        // its weights (a float per target) and its marker
        let meshes = crate::output::pack::level_layers(self.shells.layers as u64, 1) + 2;
        meshes * (384 + 24 * targets_bound(scene) + 64 * channels) + 256
    }

    /// At most how many chunks the LOD stage cuts the scene into: cells of the chunk size over
    /// its bounding box (at most one per triangle); the stage may not run, but the bound holds
    /// either way.
    fn chunk_bound(&self, scene: &crate::model::mesh::Scene) -> u64 {
        let triangles = scene
            .meshes
            .iter()
            .map(|m| m.triangle_count() as u64)
            .sum::<u64>();
        match self.lod.chunk_size {
            Some(size) if size > 0.0 => {
                let (mut lo, mut hi) = (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY);
                for m in &scene.meshes {
                    for p in &m.positions {
                        let w = m.origin + p.as_dvec3();
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
                let cells = |e: f64| (e / size as f64).floor().max(0.0) as u64 + 1;
                let e = (hi - lo).max(glam::DVec3::ZERO);
                let mut axes = [e.x, e.y, e.z];
                axes.sort_by(|a, b| b.total_cmp(a));
                (cells(axes[0]).saturating_mul(cells(axes[1]))).min(triangles.max(1))
            }
            _ => 1,
        }
    }

    /// World-unit shell height for a mesh with the given bounding-box diagonal.
    pub fn resolved_height(&self, diagonal: f32) -> f32 {
        self.shells.resolved_height(diagonal)
    }

    /// Strands per world unit for a mesh with the given bounding-box diagonal.
    pub fn resolved_density(&self, diagonal: f32) -> f32 {
        self.strands
            .density
            .unwrap_or(self.strands.strands_per_diagonal / diagonal.max(f32::MIN_POSITIVE))
    }
}

/// At most how many morph targets a layer mesh of `scene` carries: the extrusion, the bend,
/// the occlusion's shade, the wind's two, and the shape keys of its mesh with the most.
fn targets_bound(scene: &crate::model::mesh::Scene) -> u64 {
    let morphs = scene.meshes.iter().map(|m| m.morphs.len()).max();
    5 + morphs.unwrap_or(0) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_pass_their_own_checks() {
        for p in Preset::ALL {
            BakeParams::preset(p).check().unwrap();
        }
    }

    #[test]
    fn toml_round_trip_and_partial_override() {
        let p = BakeParams::preset(Preset::Grass);
        let text = toml::to_string(&p).unwrap();
        assert_eq!(toml::from_str::<BakeParams>(&text).unwrap(), p);
        let partial: BakeParams = toml::from_str("[shells]\nlayers = 8\n").unwrap();
        assert_eq!(partial.shells.layers, 8);
        assert_eq!(partial.strands, BakeParams::default().strands);
    }

    #[test]
    fn check_names_the_bad_parameter() {
        let mut p = BakeParams::default();
        p.shells.layers = 0;
        let e = p.check().unwrap_err();
        assert!(e.message.contains("layers") && e.key == "shells.layers");
        let mut p = BakeParams::default();
        p.strands.mask_size = 100;
        assert_eq!(p.check().unwrap_err().key, "strands.mask_size");
    }

    #[test]
    fn a_model_override_replaces_the_whole_model() {
        let over: toml::Table =
            toml::from_str("[strands]\nmodel = { kind = \"noise\", threshold = 0.4 }\n").unwrap();
        let p = BakeParams::default().with_overrides(over).unwrap();
        assert_eq!(p.strands.model, StrandModel::Noise { threshold: 0.4 });
        assert_eq!(p.strands.mask_size, 256);
        let bad: toml::Table = toml::from_str("[shells]\nlayrs = 3\n").unwrap();
        let e = BakeParams::default().with_overrides(bad).unwrap_err();
        assert!(e.to_string().contains("layrs"), "{e}");
    }

    #[test]
    fn relative_values_resolve_against_the_diagonal() {
        let p = BakeParams::preset(Preset::Fur);
        assert_eq!(p.resolved_height(2.0), 0.07);
        let mut q = p.clone();
        q.shells.height = Some(0.5);
        assert_eq!(q.resolved_height(2.0), 0.5);
        assert_eq!(p.resolved_density(2.0), 120.0);
    }
}
