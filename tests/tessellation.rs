//! The `tessellation` effect on a coarse UV sphere (6 rings × 10 segments): the report gives the
//! factor and the triangles before and after; Phong smoothing brings the subdivided base toward
//! the sphere the facets approximate; the UV seam stays welded; `verify` passes in both layouts,
//! and fails when the reference is drawn from the untessellated base (the control: the
//! silhouette moved); the target edge length picks the factor; bakes are deterministic.

#![cfg(feature = "view")]

use crate::common;

use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;

fn coarse_sphere() -> shellbake::model::mesh::Scene {
    let mesh = shellbake::fixtures::procedural::sphere(1.0, 6, 10);
    shellbake::model::mesh::Scene {
        meshes: vec![mesh],
        ..Default::default()
    }
}

fn params(layout: Layout, factor: u32, alpha: f32) -> BakeParams {
    let mut p = BakeParams::preset(Preset::Fur);
    p.pack.layout = layout;
    p.shells.layers = 16;
    p.tessellation.factor = factor;
    p.tessellation.alpha = alpha;
    p
}

/// Largest distance inside the unit sphere of the baked base's vertices.
fn sag(b: &shellbake::Baked) -> f64 {
    b.mesh
        .positions
        .iter()
        .map(|p| 1.0 - (b.mesh.origin + p.as_dvec3()).length())
        .fold(0.0, f64::max)
}

#[test]
fn a_coarse_sphere_rounds_off_and_verifies() {
    let scene = coarse_sphere();
    let with = [Effect::Collision, Effect::Tessellation];
    let plain = shellbake::bake_with(&scene, &params(Layout::Compact, 1, 0.75), &[]);
    let flat = shellbake::bake_with(&scene, &params(Layout::Compact, 4, 0.0), &with);
    let round = shellbake::bake_with(&scene, &params(Layout::Compact, 4, 0.75), &with);

    let st = round.report.stage("tessellation").unwrap();
    assert!(st.ran);
    let before = st.counts["triangles_before"];
    assert_eq!(st.counts["factor"], 4.0);
    // the pole rows' flat triangles are left out before (the merge stage), every other is cut
    let plain_weld = plain.report.stage("weld").unwrap();
    let flat_triangles = plain.report.stage("merge").unwrap().counts["empty_triangles"];
    assert!(flat_triangles > 0.0);
    assert_eq!(st.counts["triangles_after"], 16.0 * before);
    let weld = round.report.stage("weld").unwrap();
    assert_eq!(
        weld.counts["sheet_vertices_split"], 0.0,
        "the seam stays welded"
    );
    assert_eq!(
        weld.counts["collapsed_triangles"],
        plain_weld.counts["collapsed_triangles"]
    );
    // a closed surface: V − E + F = 2 on the welded mesh, as before tessellating
    let euler = |b: &shellbake::Baked| {
        let w = b.report.stage("weld").unwrap();
        let merge = b.report.stage("merge").unwrap();
        let f = merge.counts["triangles"] - merge.counts["empty_triangles"];
        let f = b
            .report
            .stage("tessellation")
            .and_then(|s| s.counts.get("triangles_after").copied())
            .unwrap_or(f)
            - w.counts["collapsed_triangles"];
        w.counts["welded_vertices"] - 1.5 * f + f
    };
    assert_eq!(euler(&round), euler(&plain));

    // Phong brings the facets' interiors out toward the sphere
    let (s_flat, s_round) = (sag(&flat), sag(&round));
    println!("sag: flat {s_flat:.4}, Phong {s_round:.4}");
    assert!(s_round < 0.5 * s_flat, "{s_round} vs {s_flat}");

    for layout in [Layout::Compact, Layout::SingleDraw] {
        let p = params(layout, 4, 0.75);
        let b = shellbake::bake_with(&scene, &p, &with);
        let v = common::verify_glb(&b.glb, &b.surface, &p);
        for view in &v.views {
            println!("{layout:?} {}", view.line());
        }
        assert!(v.passed(), "{layout:?}: {:?}", v.failures());
    }
    // control: the tessellated file against the runtime technique on the coarse base
    let p = params(Layout::Compact, 4, 0.75);
    let v = common::verify_glb(&round.glb, &plain.surface, &p);
    assert!(
        !v.passed(),
        "a tessellated file must not pass against the coarse base's reference"
    );
}

#[test]
fn edge_length_picks_the_factor_and_bakes_repeat() {
    let scene = coarse_sphere();
    let mut p = params(Layout::Compact, 1, 0.75);
    // the coarse sphere's edges are 0.3–0.6 long
    p.tessellation.edge_length = Some(0.1);
    let a = shellbake::bake_with(&scene, &p, &[Effect::Tessellation]);
    let factor = a.report.stage("tessellation").unwrap().counts["factor"];
    assert!((4.0..=6.0).contains(&factor), "{factor}");
    let b = shellbake::bake_with(&scene, &p, &[Effect::Tessellation]);
    assert!(a.glb == b.glb, "same input, same bytes");
    common::assert_valid(&[{
        let dir = common::scratch("tessellation");
        let f = dir.join("sphere.glb");
        shellbake::output::write::write_glb(&f, &a.glb).unwrap();
        f
    }]);
}

/// Tessellating a mesh whose edges are far shorter than its strands buys nothing but triangles:
/// a warning says so (the coarse sphere's edges are 0.3–0.6; strands of 4 are 7 to 13 times
/// longer), and none with its default strands.
#[test]
fn tessellating_a_mesh_finer_than_its_strands_is_named() {
    let scene = coarse_sphere();
    let with = [Effect::Tessellation];
    let mut p = params(Layout::Compact, 2, 0.75);
    let warned = |b: &shellbake::Baked| {
        (b.report.warnings.iter()).any(|w| w.starts_with("tessellation: the mesh's edges"))
    };
    assert!(!warned(&shellbake::bake_with(&scene, &p, &with)));
    p.shells.height = Some(4.0);
    assert!(warned(&shellbake::bake_with(&scene, &p, &with)));
}
