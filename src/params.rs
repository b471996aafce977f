//! Parameters: one struct per stage, their defaults, and the four presets.
//!
//! Every field states its unit, range and advice. Scene files (TOML) and CLI flags both
//! deserialize into these structs, so a knob has exactly one definition.
//!
//! Scale-free defaults: meshes arrive at any scale (a bunny of 0.2 m, a field of 500 m), so the
//! presets state shell height and strand density *relative to the bounding-box diagonal*
//! (`height_fraction`, `strands_per_diagonal`). An explicit `height` (world units) or `density`
//! (strands per world unit) overrides them; [`BakeParams::resolve`] turns the relative values into
//! world units once the mesh is known, and the report shows the resolved figures.

use serde::{Deserialize, Serialize};

/// Highest number of layers a bake can have (base included). Layer heights live on a grid of
/// [`crate::strands::HEIGHT_STEPS`] steps so that the 8-bit mask is exact for every layer; two
/// layers must not share a step.
pub const MAX_LAYERS: u32 = crate::strands::HEIGHT_STEPS;

/// Named parameter sets for common surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
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

    /// The lowercase name used on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fur => "fur",
            Preset::Carpet => "carpet",
            Preset::Grass => "grass",
            Preset::Moss => "moss",
        }
    }
}

/// How the survival height `s(uv)` of a texel is computed (DESIGN §3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum StrandModel {
    /// The seed technique's white-noise taper: texel survives while `n·(1−t) >= threshold`, so
    /// `s = 1 − threshold/n`. One strand per texel.
    Noise {
        /// Noise threshold `c`, in (0, 1). Higher = sparser strands. 0.2–0.5 is typical.
        threshold: f32,
    },
    /// Strand cells: one strand per cell at the cell centre, random length, radius shrinking
    /// with height: `s = lerp(min_length, 1, rand(cell)) − dist(uv, centre)/thickness`.
    Cells {
        /// Strand thickness at the root, in cell widths, (0, 2]. 0.5–1.0 gives round strands
        /// that touch at the root.
        thickness: f32,
        /// Shortest strand as a fraction of the full height, [0, 1].
        min_length: f32,
        /// Mask texels across one cell side, 2–64. 8 gives round strands at close range.
        texels_per_cell: u32,
    },
}

/// Which glTF layout `pack` writes (DESIGN §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// One quantized geometry shared by every layer; extrusion as a morph target; one small mesh
    /// and material per layer. Smallest file, one draw call per layer.
    Compact,
    /// All layers in one primitive and one material; per-layer threshold and shade in COLOR_0.
    /// Larger file, one draw call.
    SingleDraw,
}

impl Layout {
    /// The kebab-case name used on the command line, in scene files, reports and `extras`.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Compact => "compact",
            Layout::SingleDraw => "single-draw",
        }
    }
}

/// Strand stage parameters (`strands.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StrandParams {
    /// The strand law.
    pub model: StrandModel,
    /// Strands per world unit (along a line). `None`: `strands_per_diagonal` / diagonal.
    pub density: Option<f32>,
    /// Strands along the bounding-box diagonal when `density` is not given. 50–2000.
    pub strands_per_diagonal: f32,
    /// Side of the tileable mask texture in texels, power of two, 16–4096. 256 is plenty: the
    /// mask repeats, and one tile holds `mask_size / texels_per_cell` strands per side.
    pub mask_size: u32,
    /// Noise seed. The same seed gives the same strands on every machine.
    pub seed: u32,
    /// Strands per UV unit. When set, it replaces `density`: the mask tiles at this rate in UV
    /// space whatever the mesh's UV-to-world scale — for UV layouts authored at a set texel
    /// density, or strands that must follow a hand-painted UV stretch. Leave unset otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uv_density: Option<f32>,
}

/// Shell stage parameters (`shells.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShellParams {
    /// Number of layers including the base (t = 0), 1–[`MAX_LAYERS`]. More layers = denser,
    /// smoother strands and more overdraw. 16–64 is typical.
    pub layers: u32,
    /// Shell height in world units at t = 1. `None`: `height_fraction` × diagonal.
    pub height: Option<f32>,
    /// Shell height as a fraction of the bounding-box diagonal when `height` is not given.
    pub height_fraction: f32,
}

/// Shading parameters (per-layer colours, DESIGN §3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShadeParams {
    /// Linear RGB colour at the strand root (t = 0).
    pub root_color: [f32; 3],
    /// Linear RGB colour at the strand tip (t = 1).
    pub tip_color: [f32; 3],
    /// Ambient occlusion at the root, [0, 1]: `albedo *= lerp(1 − occlusion, 1, t)`.
    pub occlusion: f32,
    /// glTF roughness of every layer, [0, 1].
    pub roughness: f32,
}

/// Pack stage parameters (`pack/`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PackParams {
    /// Output layout.
    pub layout: Layout,
    /// Position quantization bits, 8–16. 14 keeps the error under 1/16384 of the largest extent.
    pub position_bits: u32,
}

/// Everything a bake needs. `Default` is the `fur` preset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BakeParams {
    pub orient: crate::orient::OrientParams,
    pub clamp: crate::clamp::ClampParams,
    pub strands: StrandParams,
    pub shells: ShellParams,
    pub shade: ShadeParams,
    pub pack: PackParams,
}

impl Default for StrandParams {
    fn default() -> Self {
        BakeParams::preset(Preset::Fur).strands
    }
}
impl Default for ShellParams {
    fn default() -> Self {
        BakeParams::preset(Preset::Fur).shells
    }
}
impl Default for ShadeParams {
    fn default() -> Self {
        BakeParams::preset(Preset::Fur).shade
    }
}
impl Default for PackParams {
    fn default() -> Self {
        PackParams {
            layout: Layout::Compact,
            position_bits: 14,
        }
    }
}
impl Default for BakeParams {
    fn default() -> Self {
        BakeParams::preset(Preset::Fur)
    }
}

impl BakeParams {
    /// The named preset.
    pub fn preset(preset: Preset) -> BakeParams {
        let pack = PackParams {
            layout: Layout::Compact,
            position_bits: 14,
        };
        let clamp = crate::clamp::ClampParams::default();
        let orient = crate::orient::OrientParams::default();
        match preset {
            Preset::Fur => BakeParams {
                orient: orient.clone(),
                clamp,
                strands: StrandParams {
                    model: StrandModel::Cells {
                        thickness: 0.9,
                        min_length: 0.55,
                        texels_per_cell: 8,
                    },
                    density: None,
                    strands_per_diagonal: 240.0,
                    mask_size: 256,
                    seed: 1,
                    uv_density: None,
                },
                shells: ShellParams {
                    layers: 32,
                    height: None,
                    height_fraction: 0.035,
                },
                shade: ShadeParams {
                    root_color: [0.16, 0.09, 0.045],
                    tip_color: [0.80, 0.62, 0.42],
                    occlusion: 0.7,
                    roughness: 0.75,
                },
                pack,
            },
            Preset::Carpet => BakeParams {
                orient: orient.clone(),
                clamp: clamp.clone(),
                strands: StrandParams {
                    model: StrandModel::Noise { threshold: 0.3 },
                    density: None,
                    strands_per_diagonal: 900.0,
                    mask_size: 256,
                    seed: 1,
                    uv_density: None,
                },
                shells: ShellParams {
                    layers: 16,
                    height: None,
                    height_fraction: 0.012,
                },
                shade: ShadeParams {
                    root_color: [0.22, 0.02, 0.03],
                    tip_color: [0.62, 0.10, 0.11],
                    occlusion: 0.6,
                    roughness: 0.9,
                },
                pack,
            },
            Preset::Grass => BakeParams {
                orient: orient.clone(),
                clamp: clamp.clone(),
                strands: StrandParams {
                    model: StrandModel::Cells {
                        thickness: 0.7,
                        min_length: 0.3,
                        texels_per_cell: 8,
                    },
                    density: None,
                    strands_per_diagonal: 120.0,
                    mask_size: 256,
                    seed: 1,
                    uv_density: None,
                },
                shells: ShellParams {
                    layers: 48,
                    height: None,
                    height_fraction: 0.08,
                },
                shade: ShadeParams {
                    root_color: [0.02, 0.09, 0.01],
                    tip_color: [0.35, 0.62, 0.12],
                    occlusion: 0.8,
                    roughness: 0.6,
                },
                pack,
            },
            Preset::Moss => BakeParams {
                orient: orient.clone(),
                clamp: clamp.clone(),
                strands: StrandParams {
                    model: StrandModel::Noise { threshold: 0.2 },
                    density: None,
                    strands_per_diagonal: 1200.0,
                    mask_size: 256,
                    seed: 1,
                    uv_density: None,
                },
                shells: ShellParams {
                    layers: 12,
                    height: None,
                    height_fraction: 0.008,
                },
                shade: ShadeParams {
                    root_color: [0.04, 0.08, 0.015],
                    tip_color: [0.25, 0.42, 0.07],
                    occlusion: 0.5,
                    roughness: 0.85,
                },
                pack,
            },
        }
    }

    /// Checks ranges; the message names the parameter. Called at the CLI/scene boundary.
    pub fn check(&self) -> Result<(), String> {
        let c = &self.clamp;
        let open_unit = |x: f32| x > 0.0 && x < 1.0;
        if !open_unit(c.ray_keep) || !open_unit(c.inversion_keep) {
            return Err("clamp ray_keep and inversion_keep must be in (0, 1)".into());
        }
        let s = &self.shells;
        if s.layers == 0 || s.layers > MAX_LAYERS {
            return Err(format!(
                "layers must be in 1..={MAX_LAYERS}, got {}",
                s.layers
            ));
        }
        if let Some(h) = s.height {
            if !(h.is_finite() && h >= 0.0) {
                return Err(format!(
                    "height must be a finite non-negative length, got {h}"
                ));
            }
        }
        if !(s.height_fraction.is_finite() && s.height_fraction >= 0.0) {
            return Err(format!(
                "height_fraction must be >= 0, got {}",
                s.height_fraction
            ));
        }
        let st = &self.strands;
        if let Some(d) = st.density {
            if !(d.is_finite() && d > 0.0) {
                return Err(format!(
                    "density must be a positive number of strands per unit, got {d}"
                ));
            }
        }
        if let Some(d) = st.uv_density {
            if !(d.is_finite() && d > 0.0) {
                return Err(format!(
                    "uv_density must be a positive number of strands per UV unit, got {d}"
                ));
            }
        }
        if !(st.strands_per_diagonal.is_finite() && st.strands_per_diagonal > 0.0) {
            return Err("strands_per_diagonal must be > 0".into());
        }
        if !st.mask_size.is_power_of_two() || !(16..=4096).contains(&st.mask_size) {
            return Err(format!(
                "mask_size must be a power of two in 16..=4096, got {}",
                st.mask_size
            ));
        }
        match st.model {
            StrandModel::Noise { threshold } => {
                if !(threshold > 0.0 && threshold < 1.0) {
                    return Err(format!(
                        "noise threshold must be in (0, 1), got {threshold}"
                    ));
                }
            }
            StrandModel::Cells {
                thickness,
                min_length,
                texels_per_cell,
            } => {
                if !(thickness > 0.0 && thickness <= 2.0) {
                    return Err(format!("cell thickness must be in (0, 2], got {thickness}"));
                }
                if !(0.0..=1.0).contains(&min_length) {
                    return Err(format!("min_length must be in [0, 1], got {min_length}"));
                }
                if !(2..=64).contains(&texels_per_cell)
                    || !st.mask_size.is_multiple_of(texels_per_cell)
                {
                    return Err(format!(
                        "texels_per_cell must be in 2..=64 and divide mask_size {}, got {texels_per_cell}",
                        st.mask_size
                    ));
                }
            }
        }
        let sh = &self.shade;
        let unit = |v: f32| (0.0..=1.0).contains(&v);
        if !sh.root_color.iter().chain(&sh.tip_color).all(|&c| unit(c)) {
            return Err("colours must be linear RGB in [0, 1]".into());
        }
        if !unit(sh.occlusion) || !unit(sh.roughness) {
            return Err("occlusion and roughness must be in [0, 1]".into());
        }
        if !(8..=16).contains(&self.pack.position_bits) {
            return Err(format!(
                "position_bits must be in 8..=16, got {}",
                self.pack.position_bits
            ));
        }
        Ok(())
    }

    /// World-unit shell height for a mesh with the given bounding-box diagonal.
    pub fn resolved_height(&self, diagonal: f32) -> f32 {
        self.shells
            .height
            .unwrap_or(self.shells.height_fraction * diagonal)
    }

    /// Strands per world unit for a mesh with the given bounding-box diagonal.
    pub fn resolved_density(&self, diagonal: f32) -> f32 {
        self.strands
            .density
            .unwrap_or(self.strands.strands_per_diagonal / diagonal.max(f32::MIN_POSITIVE))
    }
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
        assert!(p.check().unwrap_err().contains("layers"));
        let mut p = BakeParams::default();
        p.strands.mask_size = 100;
        assert!(p.check().unwrap_err().contains("mask_size"));
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
