//! The merge stage: a surface's meshes become one render mesh — less the triangles of no area
//! and the vertices no triangle uses (a stray point or a vertex buffer shared with other
//! primitives would otherwise size the fur: `Mesh::drop_unused`) — whose positions within a
//! millionth of the diagonal of another are first snapped onto it (`crate::model::topology::snap_near_twins`: a
//! seam computed twice must not extrude apart), which takes the asset's colour at each strand
//! root (docs/how-it-works.md#colour-from-the-asset: sampled here, before any stage splits
//! vertices, so the colour rides with
//! them; tessellation alone samples its new vertices again, from the paint merge hands on while
//! the mesh keeps the UVs it was sampled at) and the UVs its strands follow: the mesh's own, or
//! a per-face box projection when it has none with area or `--fur-uv` says they cannot carry
//! strands (an asset keeps its own for its textures; the box is the fur's alone).

use glam::Vec3;

use crate::facts::{Facts, Reported};
use crate::model::box_uvs::generate_box_uvs;
use crate::model::mesh::{has_uv_area, Mesh, Scene};
use crate::model::paint::Palette;
use crate::stages::tiling::{fur_uv_box, FurUv};

/// Where a surface's fur takes its colour.
#[derive(Clone, Copy, Debug)]
pub enum FurColour<'a> {
    /// The preset's shade (a plain mesh or scene surface).
    Preset,
    /// The asset's paints (`None`: the asset's part has none; several: the parts of one fur
    /// have unlike materials, and each mesh's `paint_ids` say which), unless `color` overrides
    /// them.
    Asset {
        paint: Option<Palette<'a>>,
        color: Option<[f32; 3]>,
    },
}

/// The merged render mesh and what the stage decided.
pub struct Merged<'a> {
    pub mesh: Mesh,
    /// Which UVs the strands follow, and why (for the tiling stage's note).
    pub fur_uv: String,
    /// The strands follow a box projection chosen over the mesh's own UVs ([`fur_uv_box`]),
    /// through which any image map is read too.
    pub boxed: bool,
    /// The paint the fur's colour was sampled from, while the mesh keeps the `TEXCOORD_0` it
    /// was sampled at (no box projection replaced them, no shade colour overrides it): new
    /// vertices (tessellation) sample it again.
    pub paint: Option<Palette<'a>>,
    meshes: usize,
    vertices: usize,
    triangles: usize,
    /// Vertices no triangle uses, and triangles of no area, left out ([`Mesh::drop_unused`]).
    unused: usize,
    empty: usize,
    /// Vertices moved onto a near twin (`crate::model::topology::snap_near_twins`).
    snapped: usize,
    warnings: Vec<String>,
}

/// Merges `scene`'s meshes, colours the result and gives it the UVs its strands follow.
pub fn merge<'a>(scene: &Scene, colour: FurColour<'a>, fur_uv: FurUv) -> Merged<'a> {
    let mut mesh = scene.merged();
    let (vertices, triangles) = (mesh.vertex_count(), mesh.triangle_count());
    let (empty, unused) = mesh.drop_unused();
    if unused > 0 {
        mesh.recentre();
    }
    let diagonal = mesh.diagonal();
    let snapped = crate::model::topology::snap_near_twins(&mut mesh.positions, diagonal);
    if let FurColour::Asset { paint, color } = colour {
        let albedo = paint.map(|paint| paint.albedo(&mesh));
        mesh.albedo = match (color, albedo) {
            // one colour, where the material draws the surface (cut-outs stay bare)
            (Some(c), Some(a)) => Some(a.iter().map(|a| Vec3::from(c).extend(a.w)).collect()),
            (Some(c), None) => Some(vec![Vec3::from(c).extend(1.0); mesh.vertex_count()]),
            (None, albedo) => albedo,
        };
    }
    let mut paint = match colour {
        FurColour::Asset { paint, color: None } => paint,
        _ => None,
    };
    let mut warnings = Vec::new();
    if (mesh.albedo.as_ref()).is_some_and(|a| !a.is_empty() && a.iter().all(|c| c.w == 0.0)) {
        warnings.push(
            "the material draws none of this surface (its alpha is under the cutoff, or 0, \
             everywhere): it grows no fur"
                .into(),
        );
    }
    let mut follows = "the mesh's own".to_string();
    let mut boxed = false;
    // a box projection replaces the UVs a texture on TEXCOORD_0 reads (new vertices then blend
    // their corners' colour); one on another set reads `texture_uvs`, which stay
    let reads_uvs = mesh.texture_uvs.is_none();
    if !has_uv_area(&mesh) {
        paint = paint.filter(|_| !reads_uvs);
        warnings
            .push("texture coordinates have no area; generated a per-face box projection".into());
        generate_box_uvs(&mut mesh);
    } else if let Some(why) = fur_uv_box(&mesh, fur_uv) {
        follows = format!("a box projection: {why}");
        boxed = true;
        paint = paint.filter(|_| !reads_uvs);
        generate_box_uvs(&mut mesh);
    }
    Merged {
        mesh,
        fur_uv: follows,
        boxed,
        paint,
        meshes: scene.meshes.len(),
        vertices,
        triangles,
        unused,
        empty,
        snapped,
        warnings,
    }
}

impl Reported for Merged<'_> {
    fn facts(&self) -> Facts {
        Facts {
            warnings: self.warnings.clone(),
            ..Facts::counts([
                ("meshes", self.meshes as f64),
                ("vertices", self.vertices as f64),
                ("triangles", self.triangles as f64),
                ("unused_vertices", self.unused as f64),
                ("empty_triangles", self.empty as f64),
                ("snapped_positions", self.snapped as f64),
            ])
        }
    }
}
