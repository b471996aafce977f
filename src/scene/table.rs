//! The plan table: every stage of a bake, in the order it runs, and the effects a surface can
//! ask for, each with its name, its other names and the stage that computes it. Both enums and
//! their lists and names are written from these two lists by one macro, so adding a stage or an
//! effect is a row here: the scene reader, `--effect`, `--set`, the plan and the report take
//! the names from the rows.
//!
//! An effect's stage is the stage of the same name. The effects' order is their sort order (a
//! surface's effect list is kept sorted); the stages' is the order they run and are reported in.

use serde::{Deserialize, Serialize};

/// Writes [`Stage`] and [`Effect`] from the rows of the plan table.
macro_rules! plan_table {
    (
        stages { $( $stage:ident = $stage_name:literal, )* }
        effects { $( $(#[$doc:meta])* $effect:ident = $effect_name:literal $( or $alias:literal )*, )* }
    ) => {
        /// The stages of a bake, in the order they run.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Stage {
            $( $stage, )*
        }

        impl Stage {
            pub const ALL: [Stage; [$( $stage_name ),*].len()] = [$( Stage::$stage ),*];

            /// The name in reports and in `shellbake plan`.
            pub fn name(self) -> &'static str {
                match self {
                    $( Stage::$stage => $stage_name, )*
                }
            }
        }

        /// The effects' names, in their rows' order.
        const EFFECT_NAMES: &[&str] = &[$( $effect_name ),*];

        /// An effect a surface can ask for; each one is a stage that runs only when asked.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Effect {
            $( $(#[$doc])* $effect, )*
        }

        impl Effect {
            pub const ALL: [Effect; EFFECT_NAMES.len()] = [$( Effect::$effect ),*];

            /// Other names of effects: `comb` is the `gravity` effect
            /// (docs/how-it-works.md#the-plan).
            pub const ALIASES: &'static [(&'static str, Effect)] =
                &[$( $( ($alias, Effect::$effect), )* )*];

            /// The name in scene files, flags and reports.
            pub fn name(self) -> &'static str {
                match self {
                    $( Effect::$effect => $effect_name, )*
                }
            }

            /// The stage that computes the effect.
            pub fn stage(self) -> Stage {
                match self {
                    $( Effect::$effect => Stage::$effect, )*
                }
            }
        }
    };
}

plan_table! {
    stages {
        Load = "load",
        Merge = "merge",
        Orient = "orient",
        Tessellation = "tessellation",
        Colour = "colour",
        Weld = "weld",
        Frames = "frames",
        Smooth = "smooth",
        Collision = "collision",
        Clamp = "clamp",
        Occlusion = "occlusion",
        Strands = "strands",
        Tiling = "tiling",
        Shells = "shells",
        Gravity = "gravity",
        Wind = "wind",
        Sheen = "sheen",
        Fins = "fins",
        Outline = "outline",
        Cull = "cull",
        Lod = "lod",
        Pack = "pack",
        Write = "write",
    }
    effects {
        /// Shorten shells where they would pass through another part of the mesh (a BVH ray per
        /// vertex; `--clamp`).
        Collision = "collision",
        /// Drop the layer triangles on which no strand survives (on by default; `--no-cull`,
        /// `"no-cull"`).
        Cull = "cull",
        /// Distance LOD levels and chunks (on by default; `--no-lod`, `"no-lod"`).
        Lod = "lod",
        /// Bend the strands toward a direction (world gravity or a comb field), a second morph
        /// target weighted `t^k` (`--gravity`, `[surface.gravity]`, `comb_map`; also named `comb`).
        Gravity = "gravity" or "comb",
        /// Ambient occlusion of the base surface folded into each layer's shade, `COLOR_0` (rays
        /// against the BVH the collision bound shares; `--occlusion`, `[surface.occlusion]`).
        Occlusion = "occlusion",
        /// `KHR_materials_sheen` on the layer materials, stronger toward the tips (`--sheen`,
        /// `[surface.sheen]`).
        Sheen = "sheen",
        /// Strands sway: two morph targets and a looping animation of the layer weights (`--wind`,
        /// `[surface.wind]`).
        Wind = "wind",
        /// Subdivide the base before shelling, Phong-smoothed (`--tessellate`,
        /// `[surface.tessellation]`; also named `tessellate`).
        Tessellation = "tessellation" or "tessellate",
        /// Fin quads on mesh edges, textured from the strand model (`--fins`, `[surface.fins]`).
        Fins = "fins",
        /// An inverted hull in one unlit colour (`--outline`, `[surface.outline]`).
        Outline = "outline",
    }
}

impl Effect {
    /// The effect named `name`, or the effect it is another name of ([`Effect::ALIASES`]).
    pub fn from_name(name: &str) -> Option<Effect> {
        let name = Effect::ALIASES
            .iter()
            .find(|(alias, _)| *alias == name)
            .map_or(name, |(_, e)| e.name());
        Effect::ALL.into_iter().find(|e| e.name() == name)
    }
}

impl Stage {
    /// The effect that asks for this stage; `None` for a stage every bake runs.
    pub fn effect(self) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.stage() == self)
    }
}

/// An effect is written by its name (reports).
impl Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// An effect is read by its name or another name of it.
impl<'de> Deserialize<'de> for Effect {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Effect::from_name(&name)
            .ok_or_else(|| serde::de::Error::unknown_variant(&name, EFFECT_NAMES))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_effect_is_a_stage_and_names_are_unique() {
        for e in Effect::ALL {
            assert_eq!(e.stage().name(), e.name());
            assert_eq!(e.stage().effect(), Some(e));
            assert_eq!(Effect::from_name(e.name()), Some(e));
        }
        for (alias, e) in Effect::ALIASES {
            assert_eq!(Effect::from_name(alias), Some(*e));
            assert!(Stage::ALL.iter().all(|s| s.name() != *alias));
        }
        let mut names: Vec<&str> = Stage::ALL.iter().map(|s| s.name()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), Stage::ALL.len());
        assert_eq!(Stage::Load.effect(), None);
    }

    #[test]
    fn effects_sort_in_their_rows_order() {
        let mut sorted = Effect::ALL;
        sorted.sort();
        assert_eq!(sorted, Effect::ALL);
        assert_eq!(
            serde_json::to_string(&Effect::Gravity).unwrap(),
            "\"gravity\""
        );
        let e: Effect = serde_json::from_str("\"comb\"").unwrap();
        assert_eq!(e, Effect::Gravity);
        assert!(serde_json::from_str::<Effect>("\"fur\"").is_err());
    }
}
