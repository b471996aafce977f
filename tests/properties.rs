//! Property tests over random meshes — degenerate and non-manifold topology, duplicate
//! positions, extreme scales and offsets — for weld, frames, clamp, strands and pack: no panic,
//! everything finite, and each stage's invariant holds.

use crate::common;

use common::Glb;
use glam::{DVec3, Vec3};
use proptest::prelude::*;
use shellbake::model::mesh::{Mesh, Scene};
use shellbake::params::{BakeParams, Layout, StrandModel, StrandParams};
use shellbake::scene::Effect;

/// A random mesh: vertices on a coarse 4×4×4 lattice (so positions repeat, triangles degenerate
/// and edges are shared by many faces), random triangles, then scaled and offset.
fn arb_mesh() -> impl Strategy<Value = Mesh> {
    (
        prop::collection::vec((0u8..4, 0u8..4, 0u8..4), 3..40),
        prop::collection::vec((0usize..64, 0usize..64, 0usize..64), 1..60),
        -5i32..=4,
        prop::sample::select(vec![0.0, 1.0, 1e3, 1e6]),
    )
        .prop_map(|(lattice, tris, exp, offset)| {
            let scale = 10f32.powi(exp);
            let positions: Vec<Vec3> = lattice
                .iter()
                .map(|&(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) * scale)
                .collect();
            let n = positions.len();
            let indices = tris
                .iter()
                .flat_map(|&(a, b, c)| [(a % n) as u32, (b % n) as u32, (c % n) as u32])
                .collect();
            Mesh {
                origin: DVec3::splat(offset),
                positions,
                indices,
                ..Default::default()
            }
        })
}

fn scene_of(m: &Mesh) -> Scene {
    let mut m = m.clone();
    shellbake::model::box_uvs::generate_box_uvs(&mut m);
    Scene {
        meshes: vec![m],
        warnings: vec![],
        skeleton: None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn weld_keeps_positions_and_drops_only_collapsed_triangles(m in arb_mesh()) {
        let w = shellbake::stages::weld::weld(&m.positions, &m.indices);
        prop_assert_eq!(w.remap.len(), w.vertex_source.len());
        prop_assert!(w.vertex_source.len() >= m.positions.len());
        for (v, &id) in w.remap.iter().enumerate() {
            prop_assert_eq!(w.positions[id as usize], m.positions[w.vertex_source[v] as usize]);
        }
        for t in w.indices.chunks_exact(3) {
            prop_assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        }
        // exactly the triangles with three distinct positions are kept, each on render vertices
        // at the welded vertex's position
        let distinct = |t: &[u32]| {
            let p = [0, 1, 2].map(|k| m.positions[t[k] as usize].to_array().map(|x| (x + 0.0).to_bits()));
            p[0] != p[1] && p[1] != p[2] && p[0] != p[2]
        };
        let kept = m.indices.chunks_exact(3).filter(|t| distinct(t)).count();
        prop_assert_eq!(kept * 3, w.indices.len());
        for (&r, &wv) in w.render_indices.iter().zip(&w.indices) {
            prop_assert_eq!(w.remap[r as usize], wv);
        }
    }

    #[test]
    fn frames_are_finite_unit_vectors(m in arb_mesh()) {
        let w = shellbake::stages::weld::weld(&m.positions, &m.indices);
        let f = shellbake::stages::frames::extrusion_frames(&w, None);
        for d in &f.direction {
            prop_assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-3, "{}", d);
        }
        prop_assert_eq!(f.fallbacks.iter().sum::<usize>(), w.positions.len());
    }

    #[test]
    fn clamp_scales_are_in_range_and_layers_never_invert(m in arb_mesh(), frac in 0.01f32..2.0) {
        let w = shellbake::stages::weld::weld(&m.positions, &m.indices);
        let f = shellbake::stages::frames::extrusion_frames(&w, None);
        let h = m.diagonal() * frac;
        let params = shellbake::stages::clamp::ClampParams::default();
        let s = shellbake::stages::clamp::smooth(&w, &f, h, &params);
        let bound = shellbake::stages::clamp::collision_bound(&w, &shellbake::stages::clamp::MeshBvh::build(&w), &s, h, &params);
        let c = shellbake::stages::clamp::clamp_heights(&w, s, h, &params, Some(&bound));
        prop_assert!(c.welded_scale.iter().all(|s| s.is_finite() && (0.0..=1.0).contains(s)));
        let dirs = &c.welded_direction;
        for tri in w.indices.chunks_exact(3) {
            let p = [0, 1, 2].map(|k| w.positions[tri[k] as usize].as_dvec3());
            let n0 = (p[1] - p[0]).cross(p[2] - p[0]);
            if n0.length() <= 1e-9 * (m.diagonal() as f64).powi(2) {
                continue;
            }
            for t in [0.25, 0.5, 1.0] {
                let q = [0, 1, 2].map(|k| {
                    let v = tri[k] as usize;
                    p[k] + (dirs[v] * h * c.welded_scale[v]).as_dvec3() * t
                });
                let n = (q[1] - q[0]).cross(q[2] - q[0]);
                prop_assert!(n.dot(n0) > 0.0, "triangle {:?} inverts at t={}", tri, t);
            }
        }
    }

    #[test]
    fn masks_hold_valid_codes_and_coverage_never_grows(
        seed in any::<u32>(),
        threshold in 0.01f32..0.99,
        thickness in 0.05f32..2.0,
        min_length in 0.0f32..1.0,
        cells in prop::bool::ANY,
    ) {
        let model = if cells {
            StrandModel::Cells { thickness, min_length, texels_per_cell: 4 }
        } else {
            StrandModel::Noise { threshold }
        };
        let p = StrandParams { model, mask_size: 32, seed, ..BakeParams::default().strands };
        let mask = shellbake::stages::strands::bake_mask(&p);
        prop_assert!(mask.alpha.iter().all(|&c| c as u32 >= shellbake::stages::strands::BASE_CODE));
        let mut last = 1.0;
        for k in (1..=shellbake::stages::strands::HEIGHT_STEPS).step_by(17) {
            let c = mask.coverage(k);
            prop_assert!(c <= last);
            last = c;
        }
    }

    #[test]
    fn bakes_are_finite_and_exact_to_one_grid_step(m in arb_mesh(), single in prop::bool::ANY, clamp in prop::bool::ANY) {
        let scene = scene_of(&m);
        let mut p = BakeParams::default();
        p.shells.layers = 5;
        p.strands.mask_size = 16;
        p.pack.layout = if single { Layout::SingleDraw } else { Layout::Compact };
        let effects: &[Effect] = if clamp { &[Effect::Collision] } else { &[] };
        let baked = shellbake::bake_with(&scene, &p, effects);
        let g = Glb::parse(&baked.glb);
        for i in 0..g.json["accessors"].as_array().unwrap().len() {
            prop_assert!(g.accessor(i).iter().flatten().all(|v| v.is_finite()));
        }
        // positions of the top layer against the exact extrusion
        let grid = baked.packed.grid;
        let t = *baked.shells.t.last().unwrap();
        for &old in &baked.packed.vertex_order {
            let o = old as usize;
            let want = baked.mesh.positions[o] + baked.shells.delta[o] * t;
            let q = grid.quantize(baked.mesh.positions[o]);
            let d = baked.shells.delta[o] / grid.step;
            let got = grid.dequantize(q) + d * grid.step * t;
            prop_assert!((got - want).abs().max_element() <= grid.step * 1.001 + want.abs().max_element() * 1e-6);
        }
    }
}

/// `m` as a bake may receive it: UVs missing (`uv == 0`), present but without area (`1`, all at
/// one point: the bake regenerates them and splits vertices) or random (`2`); with `sheet`, every
/// face listed a second time reversed on the same vertices (welding splits those vertices).
fn scene_with(m: &Mesh, uv: u8, sheet: bool, seed: u32) -> Scene {
    let mut m = m.clone();
    if sheet {
        let back: Vec<u32> = m
            .indices
            .chunks_exact(3)
            .flat_map(|t| [t[0], t[2], t[1]])
            .collect();
        m.indices.extend(back);
    }
    m.uvs = match uv {
        0 => None,
        1 => Some(vec![glam::Vec2::splat(0.5); m.positions.len()]),
        _ => Some(
            (0..m.positions.len() as u32)
                .map(|i| {
                    let h = (i ^ seed).wrapping_mul(0x9e37_79b9);
                    glam::Vec2::new((h >> 16) as f32 / 65536.0, (h & 0xffff) as f32 / 4096.0)
                })
                .collect(),
        ),
    };
    Scene {
        meshes: vec![m],
        warnings: vec![],
        skeleton: None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// `--max-output` holds: the estimate made before any work bounds the written file, whatever
    /// the bake splits (generated UVs, sheet sides) and for every layout, layer count and mask.
    #[test]
    fn the_size_estimate_bounds_the_written_file(
        m in arb_mesh(),
        uv in 0u8..3,
        sheet in prop::bool::ANY,
        single in prop::bool::ANY,
        layers in 1u32..=48,
        mask_size in prop::sample::select(vec![16u32, 64, 128]),
        seed in any::<u32>(),
    ) {
        let scene = scene_with(&m, uv, sheet, seed);
        let mut p = BakeParams::default();
        p.shells.layers = layers;
        p.strands.mask_size = mask_size;
        p.strands.seed = seed;
        p.pack.layout = if single { Layout::SingleDraw } else { Layout::Compact };
        let estimate = p.estimate_bytes(&scene);
        let baked = shellbake::bake(&scene, &p);
        prop_assert!(
            estimate >= baked.glb.len() as u64,
            "estimate {} < written {} ({} vertices packed from {} loaded)",
            estimate, baked.glb.len(), baked.packed.base_vertices, m.positions.len()
        );
    }
}
