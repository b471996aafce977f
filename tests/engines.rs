//! Real engines, stock: PlayCanvas (`playcanvas_render.mjs`: `loadFromUrl(…, 'container')` and
//! `instantiateRenderEntity`, as a PlayCanvas user loads a file) draws a baked bunny in headless
//! Chromium, and what it draws is measured against three.js drawing the same file from the same
//! camera (`three_render.mjs`).
//!
//! What is measured is the silhouette: the pixels that differ from the clear colour. Fur widens
//! it, so the default bake drawn by PlayCanvas must cover clearly more of the frame than a bake of
//! one shell (`--layers 2`), and about as much as three.js's picture of the same file. The control
//! shows the test can fail: a bake whose layers keep their morph weights on the nodes only
//! (`--layer-weights node`) is drawn by PlayCanvas with every layer collapsed on the base surface
//! (PlayCanvas reads `mesh.weights` and ignores `node.weights`), so its silhouette falls back to
//! the bare one's.
//!
//! PlayCanvas also instantiates every scene of a file, not the default one alone; a default bake
//! keeps its coarser LOD levels (`MSFT_lod`'s targets) in a second scene, so PlayCanvas builds
//! mesh instances for those levels too. The second test counts them: the `--target playcanvas`
//! file (one scene, LOD 0 only) holds exactly the meshes that scene 0 reaches, drawn with the fur
//! three.js draws, and the default file holds more.
//!
//! The third test draws every target's file (`--target NAME`) of four inputs (the bunny, a grass
//! terrain, the skinned critter asset, the Stanford dragon) in both engines against a one-shell
//! control of the same target. Every target's file shows its fur in PlayCanvas as in three.js,
//! those of `godot`, `unreal` and `portable` (the `layers` layout) included. Those were
//! single-draw files once, whose layers are told apart by `COLOR_0`'s alpha, which stock
//! PlayCanvas leaves out of the alpha test, so it drew every layer as a solid shell: the first
//! test keeps a single-draw bake as a control that shows it ([`PLAYCANVAS_IGNORES_COLOR_0_ALPHA`]).

#![cfg(feature = "view")]

use crate::common;

use std::path::{Path, PathBuf};
use std::time::Instant;

use common::{bake, fixture, node, scratch, three_job};
use serde_json::Value;
use shellbake::output::pack::Layout;
use shellbake::view::{self, NamedView};

const SIZE: (u32, u32) = (384, 384);
/// 8-bit levels (any channel) by which a pixel must differ from the clear colour to belong to the
/// silhouette. Neither engine dithers: the background is the clear colour exactly, and every
/// counted figure below is the same from 0 to 6 levels (the darkest bare surface in shade begins
/// to drop out near 12).
const LEVELS: u8 = 6;
// The bounds below, against what SwiftShader gives (384 × 384, the front view): the default bake
// covers 30 307 pixels in PlayCanvas and 30 305 in three.js, the two disagreeing on 2 pixels; the
// one-shell bake 26 975, the node-weights control 26 884. The fur thus adds 12.4 % to the
// silhouette, which is what a missing or collapsed fur would lose.
/// The least growth of the silhouette the fur must give over the one-shell bake, in PlayCanvas:
/// half the 12.4 % measured.
const FUR_GAIN: f64 = 0.06;
/// How far PlayCanvas's silhouette of the default file may be from three.js's, relative: measured
/// 0.01 % (both engines rasterize on the same SwiftShader and alpha-test the same mask); 2 %
/// leaves room for another Chromium and stays a sixth of what the fur adds.
const ENGINES_APART: f64 = 0.02;
/// Share of three.js's silhouette over which the two silhouettes may disagree pixel by pixel
/// (catches a picture shifted, mirrored or upside down that keeps its area): measured 0.01 %.
const ENGINES_XOR: f64 = 0.02;
/// How far Filament's silhouette of a target's file may be from three.js's, relative, and the
/// share of three.js's silhouette over which they may disagree pixel by pixel, in the
/// every-target test: Filament's alpha test is not glTF's (`tests/filament.rs`: it keeps a
/// fragment a little past the cutoff), which moves strand edges. Measured (Filament 1.53.4):
/// the bunny +0.12–0.13 %, 47–48 pixels (0.16 %) for every target; the grass's float files
/// +0.67 %, 0.67 %; the dragon +0.18–0.21 %, 0.62–0.65 %. 2 % is three times the largest.
/// Its gain over the one-shell control (the fur drawn) is held to the input's `fur_gain`, as
/// PlayCanvas's: measured +12.6 % (bunny), +11.4 % (grass floats), +21 % (critter), +15.7 %
/// (dragon).
const FILAMENT_APART: f64 = 0.02;
// Two known failures of stock Filament 1.53.4 (gltfio), asserted as they are so that a change
// shows:
// - FILAMENT_BLANKS_THE_FLAT_QUANTIZED_PLANE: the grass plane's quantized files (`web`,
//   `blender`, `unity`, `playcanvas`, `unreal`: int16 positions under the node's dequantizing
//   scale) are drawn blank or nearly so: the one-shell control of each compact target and the
//   whole `unreal` file draw no pixel (but `web`'s, whose levels' scene Filament adds as a tiny
//   copy at the origin, no dequantization above it: its bare level, drawn lifted by its
//   extrusion target, covers 960 pixels), the compact fur files −1 % of three.js with 2.3 % of the
//   pixels apart; the float files of the same plane (`bevy`, `godot`, `portable`) draw as
//   three.js does. Filament draws the bunny's and the dragon's quantized files right, so it is
//   the flat plane (a quantization box with no depth) that it loses; not found further here.
//   Filament users bake a terrain with `--quantize none` (or `--target portable`).
// - FILAMENT_PLACES_A_SKINNED_ASSET_ELSEWHERE: the skinned critter, bare parts and fur alike,
//   stands lower and to the left in Filament's picture than in three.js's from the same camera
//   (the silhouettes overlap in part: −9.9 %, 169 % of three.js's pixels apart): the asset's
//   placement, not the fur, which Filament draws (+21 % over the one-shell control, both
//   placed alike). Only the gain is held for it.
/// How far the collapsed control's silhouette may be from the one-shell bake's, relative:
/// measured −0.34 % (the one shell's sparse strand tips are all it has over the bare surface).
const COLLAPSED_APART: f64 = 0.02;

fn playcanvas(jobs: &[Value], dir: &Path) -> Vec<Value> {
    assert!(
        common::repo()
            .join("tests/js/node_modules/playcanvas")
            .exists(),
        "tests/js/node_modules/playcanvas is missing: run `bash tests/setup.sh`"
    );
    let spec = dir.join("playcanvas_jobs.json");
    std::fs::write(&spec, serde_json::to_vec(jobs).unwrap()).unwrap();
    let done = node("playcanvas_render.mjs", &[spec]);
    assert_eq!(done.len(), jobs.len(), "{done:?}");
    assert!(done.iter().all(|d| d["ok"] == true), "{done:?}");
    done
}

/// The silhouette of `png`: for each pixel, whether it differs from the clear colour by more
/// than [`LEVELS`]. The corners must be the clear colour (a black, blank-white or mis-cleared
/// picture fails here).
fn silhouette(png: &Path) -> Vec<bool> {
    let img = image::open(png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), SIZE, "{}", png.display());
    let bg = view::gpu::clear_srgb8();
    let off = |p: &image::Rgb<u8>, levels: u8| (0..3).any(|c| p[c].abs_diff(bg[c]) > levels);
    for (x, y) in [
        (0, 0),
        (SIZE.0 - 1, 0),
        (0, SIZE.1 - 1),
        (SIZE.0 - 1, SIZE.1 - 1),
    ] {
        let p = img.get_pixel(x, y);
        assert!(
            !off(p, 1),
            "{}: corner ({x}, {y}) is {p:?}, not the clear colour {bg:?}",
            png.display()
        );
    }
    img.pixels().map(|p| off(p, LEVELS)).collect()
}

fn count(s: &[bool]) -> usize {
    s.iter().filter(|&&b| b).count()
}

/// Primitives of the meshes that `scenes[0]` reaches through its nodes' children: the mesh
/// instances a client drawing the default scene alone makes.
fn scene0_primitives(glb: &Path) -> usize {
    scenes_primitives(glb)[0]
}

/// A job for both pages: `glb` from `camera`, lit as the viewer lights. three.js draws the file's
/// default scene with its LOD 0 node as a plain node (no distance switching), which is the part
/// of the file PlayCanvas's scene 0 draws too.
fn job(glb: &Path, png: &Path, camera: &view::Camera) -> Value {
    let mut j = three_job(glb, png, camera, SIZE, None);
    j["msft_lod"] = Value::Bool(false);
    j
}

#[test]
fn playcanvas_draws_the_fur_three_js_draws() {
    let started = Instant::now();
    let dir = scratch("engines_silhouette");
    let bunny = fixture("bunny.obj");
    let (default, _) = bake(&bunny, &dir, "default.glb", &[]);
    let (control, _) = bake(
        &bunny,
        &dir,
        "node-weights.glb",
        &["--layer-weights", "node"],
    );
    let (one_shell, _) = bake(&bunny, &dir, "layers-2.glb", &["--layers", "2"]);
    let single = PLAYCANVAS_IGNORES_COLOR_0_ALPHA.name();
    let (single_draw, _) = bake(&bunny, &dir, "single-draw.glb", &["--layout", single]);
    // One camera for every picture: the default bake framed from the front, as three_compare.rs
    // frames it.
    let camera = view::camera_for_glb(
        &std::fs::read(&default).unwrap(),
        NamedView::Front.orbit(),
        SIZE,
    )
    .unwrap();
    let png = |name: &str| -> PathBuf { dir.join(format!("{name}.png")) };

    let pc = playcanvas(
        &[
            job(&default, &png("playcanvas-default"), &camera),
            job(&control, &png("playcanvas-node-weights"), &camera),
            job(&one_shell, &png("playcanvas-layers-2"), &camera),
            job(&single_draw, &png("playcanvas-single-draw"), &camera),
            {
                let png = png("playcanvas-single-draw-opacity-from-vertex-alpha");
                let mut j = job(&single_draw, &png, &camera);
                j["opacity_from_vertex_alpha"] = Value::Bool(true);
                j
            },
        ],
        &dir,
    );
    common::render(
        &[
            job(&default, &png("three-default"), &camera),
            job(&single_draw, &png("three-single-draw"), &camera),
        ],
        &dir,
    );
    single_draw_control(&png);

    let pc_default = silhouette(&png("playcanvas-default"));
    let pc_control = silhouette(&png("playcanvas-node-weights"));
    let pc_one_shell = silhouette(&png("playcanvas-layers-2"));
    let three = silhouette(&png("three-default"));
    let [d, c, s, t] = [&pc_default, &pc_control, &pc_one_shell, &three].map(|m| count(m));
    let xor = pc_default
        .iter()
        .zip(&three)
        .filter(|(a, b)| a != b)
        .count();
    let frame = (SIZE.0 * SIZE.1) as f64;
    let pct = |n: usize| 100.0 * n as f64 / frame;
    let rel = |a: usize, b: usize| a as f64 / b as f64 - 1.0;
    eprintln!(
        "silhouettes ({} x {}, pixels off the clear colour by more than {LEVELS} levels):",
        SIZE.0, SIZE.1
    );
    eprintln!(
        "  PlayCanvas default       {d:6} ({:.2} % of the frame)",
        pct(d)
    );
    eprintln!(
        "  PlayCanvas node weights  {c:6} ({:.2} %), {:+.2} % against --layers 2",
        pct(c),
        100.0 * rel(c, s)
    );
    eprintln!("  PlayCanvas --layers 2    {s:6} ({:.2} %)", pct(s));
    eprintln!("  three.js default         {t:6} ({:.2} %)", pct(t));
    eprintln!(
        "  fur: PlayCanvas default {:+.2} % against --layers 2; against three.js {:+.2} %, \
         disagreeing pixels {xor} ({:.2} % of three.js's)",
        100.0 * rel(d, s),
        100.0 * rel(d, t),
        100.0 * xor as f64 / t as f64
    );
    let mi: Vec<u64> = pc
        .iter()
        .map(|r| r["meshInstances"].as_u64().unwrap())
        .collect();
    eprintln!(
        "  PlayCanvas mesh instances: default {}, node weights {}, --layers 2 {} (scene 0 of the \
         default reaches {}: the rest are the coarser LOD levels of the second scene)",
        mi[0],
        mi[1],
        mi[2],
        scene0_primitives(&default)
    );
    eprintln!("  wall time {:.1} s", started.elapsed().as_secs_f64());

    assert!(
        rel(d, s) >= FUR_GAIN,
        "PlayCanvas's silhouette of the default bake ({d}) is not {:.0} % over the one-shell \
         bake's ({s}): the fur is missing",
        100.0 * FUR_GAIN
    );
    assert!(
        rel(d, t).abs() <= ENGINES_APART,
        "PlayCanvas's silhouette ({d}) is {:+.2} % from three.js's ({t}); at most ±{:.0} %",
        100.0 * rel(d, t),
        100.0 * ENGINES_APART
    );
    assert!(
        xor as f64 <= ENGINES_XOR * t as f64,
        "PlayCanvas and three.js disagree on {xor} silhouette pixels, over {:.0} % of {t}",
        100.0 * ENGINES_XOR
    );
    assert!(
        rel(c, s).abs() <= COLLAPSED_APART,
        "the node-weights control ({c}) should collapse to about the one-shell silhouette ({s}): \
         {:+.2} %",
        100.0 * rel(c, s)
    );
    assert!(
        rel(d, c) >= FUR_GAIN,
        "the default ({d}) and the collapsed control ({c}) should differ by the fur"
    );
}

/// The known failure ([`PLAYCANVAS_IGNORES_COLOR_0_ALPHA`]): PlayCanvas draws the single-draw
/// bunny as solid shells, wider than three.js's fur by [`SOLID_SHELLS_WIDER`], and as three.js
/// does once `opacityVertexColor` is set.
fn single_draw_control(png: &dyn Fn(&str) -> PathBuf) {
    let sil = |name: &str| silhouette(&png(name));
    let (pc, three) = (sil("playcanvas-single-draw"), sil("three-single-draw"));
    let fixed = sil("playcanvas-single-draw-opacity-from-vertex-alpha");
    let xor = |a: &[bool], b: &[bool]| a.iter().zip(b).filter(|(a, b)| a != b).count();
    let rel = |a: usize, b: usize| a as f64 / b as f64 - 1.0;
    let [p, t, f] = [&pc, &three, &fixed].map(|m| count(m));
    eprintln!(
        "  single-draw control: PlayCanvas {p} ({:+.2} % against three.js's {t}); with \
         opacityVertexColor {f} ({:+.2} %, xor {})",
        100.0 * rel(p, t),
        100.0 * rel(f, t),
        xor(&fixed, &three)
    );
    assert!(
        rel(p, t) >= SOLID_SHELLS_WIDER,
        "PlayCanvas's silhouette of the single-draw bunny ({p}) is {:+.2} % from three.js's \
         ({t}), no longer {:.0} % wider: does PlayCanvas now honour COLOR_0's alpha?",
        100.0 * rel(p, t),
        100.0 * SOLID_SHELLS_WIDER
    );
    assert!(
        rel(f, t).abs() <= ENGINES_APART && xor(&fixed, &three) as f64 <= ENGINES_XOR * t as f64,
        "with opacityVertexColor PlayCanvas's silhouette ({f}) should be three.js's ({t}): the \
         cause is not (only) COLOR_0's alpha"
    );
}

#[test]
fn the_playcanvas_target_draws_lod_0_once() {
    let dir = scratch("engines_lod");
    let bunny = fixture("bunny.obj");
    let (default, _) = bake(&bunny, &dir, "default.glb", &[]);
    let (no_lod, report) = bake(&bunny, &dir, "no-lod.glb", &["--target", "playcanvas"]);
    let camera = view::camera_for_glb(
        &std::fs::read(&no_lod).unwrap(),
        NamedView::Front.orbit(),
        SIZE,
    )
    .unwrap();
    let done = playcanvas(
        &[
            job(&no_lod, &dir.join("playcanvas-no-lod.png"), &camera),
            job(&default, &dir.join("playcanvas-default.png"), &camera),
        ],
        &dir,
    );
    let [no_lod_mi, default_mi] = [0, 1].map(|i| done[i]["meshInstances"].as_u64().unwrap());
    let layers = scene0_primitives(&no_lod);
    let default_scene0 = scene0_primitives(&default);
    eprintln!(
        "PlayCanvas mesh instances: --target playcanvas {no_lod_mi} (scene 0 reaches {layers} layer meshes, \
         the report draws {}), default {default_mi} (scene 0 reaches {default_scene0})",
        report["draw_calls"]
    );
    assert_eq!(
        no_lod_mi as usize, layers,
        "PlayCanvas should make one mesh instance per layer mesh of scene 0"
    );
    assert_eq!(report["draw_calls"].as_u64(), Some(layers as u64));
    // The default file's coarser levels live in a second scene, and PlayCanvas's
    // instantiateRenderEntity instantiates every scene: it holds the LOD 0 layers and those
    // levels' meshes besides, all drawn at once (it reads no MSFT_lod). The second scene's level
    // nodes are roots without the transform of scene 0's root node, so PlayCanvas draws those
    // levels as a small bunny (the quantized positions' scale) at the world origin, which here
    // lies inside the bunny's base and is hidden; `--target playcanvas` writes one scene and no
    // such copy.
    assert_eq!(default_scene0, layers);
    assert!(
        default_mi as usize > default_scene0,
        "PlayCanvas held {default_mi} mesh instances of the default file, not more than scene \
         0's {default_scene0}: does the file still keep its coarser levels in a second scene?"
    );
    // The target's file is drawn with its fur, as three.js draws it
    let s = silhouette(&dir.join("playcanvas-no-lod.png"));
    assert!(count(&s) > s.len() / 20, "PlayCanvas drew no bunny");
    common::render(
        &[job(&no_lod, &dir.join("three-no-lod.png"), &camera)],
        &dir,
    );
    let t = silhouette(&dir.join("three-no-lod.png"));
    let rel = count(&s) as f64 / count(&t) as f64 - 1.0;
    eprintln!(
        "--target playcanvas: PlayCanvas {} px, three.js {} px",
        count(&s),
        count(&t)
    );
    assert!(
        rel.abs() <= ENGINES_APART,
        "{} against {}",
        count(&s),
        count(&t)
    );
}

/// **Known failure, of a layout no target writes.** Stock PlayCanvas draws a single-draw file
/// (`--layout single-draw`) as solid shells instead of fur: its layers all lie in one primitive
/// and are told apart by
/// their vertices' `COLOR_0` alpha, `single_draw_cutoff / cutoff(k)` for layer `k`, against the
/// one `alphaCutoff` (15.5/255) of the material, below the least alpha any mask texel holds
/// (16/255). glTF multiplies the base colour's alpha by `COLOR_0`'s before the alpha test, and
/// three.js does. PlayCanvas 2.23.3 (paths under `tests/js/node_modules/playcanvas/build/
/// playcanvas/src/`) maps `COLOR_0` to `SEMANTIC_COLOR` (`framework/parsers/glb/gltf-accessor.js`),
/// but its glb-parser's `createMaterial` (`framework/parsers/glb-parser.js:421–428`) turns on
/// only `diffuseVertexColor` and `specularVertexColor` (channel `rgb`); `opacityVertexColor`
/// keeps its default, false (`scene/materials/standard-material.js`, `_defineTex2D("opacity",
/// "a")`), so the opacity chunk (`scene/shader-lib/glsl/chunks/standard/frag/opacity.js`, under
/// `STD_OPACITY_VERTEX`) never multiplies `vVertexColor.a` in, and every layer is alpha-tested
/// on the texture's alpha alone, which passes everywhere: each layer is drawn as an opaque copy
/// of the surface at its height, the outermost hiding the rest. The first test asserts that of
/// the bunny's single-draw file (PlayCanvas's silhouette at least [`SOLID_SHELLS_WIDER`] over
/// three.js's) and that the cause is that one flag: with `opacityVertexColor` set on the file's
/// materials (the page's `opacity_from_vertex_alpha`, what a PlayCanvas user would have to add
/// after loading), PlayCanvas draws it as three.js does. This is why the targets of engines that
/// apply no static weight write the `layers` layout (a material, and so an `alphaCutoff`, per
/// layer), and no target writes single-draw; the every-target test checks that.
const PLAYCANVAS_IGNORES_COLOR_0_ALPHA: Layout = Layout::SingleDraw;
/// The least amount by which PlayCanvas's silhouette of a single-draw file exceeds three.js's,
/// relative: measured +21.2 % (the bunny) to +48.9 % (the grass), the solid outer shells against
/// the fur's sparse, tapering strands; the bound is under half of the least and four times
/// [`ENGINES_APART`].
const SOLID_SHELLS_WIDER: f64 = 0.08;
/// Layers of every dragon bake, every target alike. The default (32) makes `layers` files of
/// 34 MB (`unreal`) and 50 MB (`godot`, `portable`), and at 16 layers the test took 97 s on 2
/// cores: each of the dragon's five distinct fur files is 3.2 M triangles a frame, and PlayCanvas
/// draws two frames before the read-back, 5–10 s a file on SwiftShader (three.js 2–3 s). 8 layers
/// (7 shells; `layers` files of 11 and 16 MB) keep it near 60 s, with the same verdicts as 16:
/// the fur +15.2 % over one shell (+17.7 % at 16), PlayCanvas within 0.01 % of three.js.
const DRAGON_LAYERS: &str = "8";

/// An input of the every-target test.
struct Input {
    name: &'static str,
    path: PathBuf,
    args: Vec<String>,
    /// The one camera of the input's pictures, framed on its `web` file.
    orbit: view::Orbit,
    /// The least growth of PlayCanvas's silhouette over the one-shell control's, relative: half
    /// of what is measured (see the test).
    fur_gain: f64,
}

/// Primitives of the meshes each scene of `glb` reaches (`scenes[i]`'s nodes and their
/// children): what PlayCanvas's `instantiateRenderEntity` makes mesh instances of, scene by scene.
fn scenes_primitives(glb: &Path) -> Vec<usize> {
    let g = common::Glb::parse(&std::fs::read(glb).unwrap());
    let nodes = g.json["nodes"].as_array().unwrap();
    let ids = |v: &Value| -> Vec<u64> {
        v.as_array()
            .into_iter()
            .flatten()
            .map(|n| n.as_u64().unwrap())
            .collect()
    };
    let mut out = Vec::new();
    for scene in g.json["scenes"].as_array().unwrap() {
        let mut stack = ids(&scene["nodes"]);
        let mut prims = 0;
        while let Some(n) = stack.pop() {
            let node = &nodes[n as usize];
            if let Some(m) = node["mesh"].as_u64() {
                prims += g.json["meshes"][m as usize]["primitives"]
                    .as_array()
                    .unwrap()
                    .len();
            }
            stack.extend(ids(&node["children"]));
        }
        out.push(prims);
    }
    out
}

/// Every target's file (`--target NAME`) for four inputs — the bunny, a grass terrain, the
/// skinned critter asset's fur materials, the Stanford dragon — drawn by stock PlayCanvas, by
/// stock Filament and by three.js from one camera per input, against a one-shell control of the
/// same target (`--layers 2`) drawn by each engine (Filament: [`FILAMENT_APART`] and the two
/// known failures beside it).
///
/// The measure is the silhouette, as in [`playcanvas_draws_the_fur_three_js_draws`]; the terrain
/// is seen from 10° above its plane, corner on, so that the blades along its two far edges stand
/// against the background. The fur must widen PlayCanvas's silhouette over the control's by the
/// input's `fur_gain`. A bare mesh cannot pass that: the control draws the same base surface
/// opaque, plus one shell's sparse strand tips, so its silhouette holds the bare one's and the
/// bare mesh's growth over it is at most zero; a file whose layers collapse on the base (as the
/// node-weights control of the first test) is no wider either. PlayCanvas's and three.js's
/// silhouettes of each file must then agree within [`ENGINES_APART`] and [`ENGINES_XOR`], which a
/// widening of some other kind (solid shells: [`PLAYCANVAS_IGNORES_COLOR_0_ALPHA`]) does not:
/// the single-draw files these targets wrote before failed there by 21–49 %.
///
/// Files that are the same to the byte (most targets differ only in what the input does not use:
/// `unity` and `playcanvas` without sheen, `godot` and `portable`, every compact target of the
/// skinned critter, whose fur is always floats in one scene) are drawn once, and their figures
/// are the same by construction; the table says which.
///
/// PlayCanvas's mesh instances are the primitives every scene of the file reaches: scene 0's for
/// every target but `web` and `blender`, whose coarser levels are a second scene that PlayCanvas
/// instantiates too (more instances than scene 0's), except where the file has no levels (the
/// skinned critter's: its layer nodes are scene roots, one level).
#[test]
fn every_target_s_file_shows_its_fur_in_playcanvas_filament_and_three_js() {
    use shellbake::output::target::Target;
    use std::collections::HashMap;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;

    let started = Instant::now();
    let dir = scratch("engines_targets");
    let front = NamedView::Front.orbit();
    let s = |v: &[&str]| -> Vec<String> { v.iter().map(|a| a.to_string()).collect() };
    // Measured growth over one shell (PlayCanvas, the compact targets): bunny +12.35 %, grass
    // +10.68 %, critter +12.80 %, dragon +15.23 %; each bound is about half of it. PlayCanvas and
    // three.js: at most 0.01 % apart and 4 disagreeing pixels (0.01 %) on any compact file, so
    // the first test's ENGINES_APART and ENGINES_XOR (2 %) hold with the same room, under half of
    // the least fur gain and a tenth of the single-draw control's gap.
    let inputs = [
        Input {
            name: "bunny",
            path: fixture("bunny.obj"),
            args: vec![],
            orbit: front,
            fur_gain: 0.06,
        },
        Input {
            name: "grass",
            path: fixture("plane.obj"),
            args: s(&["--preset", "grass"]),
            orbit: view::Orbit {
                yaw_deg: 45.0,
                pitch_deg: 10.0,
                ..front
            },
            fur_gain: 0.05,
        },
        Input {
            name: "critter",
            path: fixture("critter.glb"),
            args: s(&["--only", "material=fur_*"]),
            orbit: front,
            fur_gain: 0.06,
        },
        Input {
            name: "dragon",
            path: common::dragon(),
            args: s(&["--layers", DRAGON_LAYERS]),
            orbit: front,
            fur_gain: 0.075,
        },
    ];
    let single_draw: Vec<&str> = Target::ALL
        .iter()
        .filter(|t| t.profile().layout == Some(PLAYCANVAS_IGNORES_COLOR_0_ALPHA))
        .map(|t| t.name())
        .collect();
    assert!(
        single_draw.is_empty(),
        "{single_draw:?} write the single-draw layout, which PlayCanvas draws as solid shells"
    );

    // Bakes, two at a time (a bake is mostly one thread): (input, target, control).
    let bakes: Vec<(usize, Target, bool)> = (0..inputs.len())
        .flat_map(|i| {
            Target::ALL
                .into_iter()
                .flat_map(move |t| [(i, t, false), (i, t, true)])
        })
        .collect();
    let baked: Mutex<Vec<Option<PathBuf>>> = Mutex::new(vec![None; bakes.len()]);
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..2 {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(i, t, control)) = bakes.get(k) else {
                    break;
                };
                let input = &inputs[i];
                let mut args: Vec<&str> = input.args.iter().map(String::as_str).collect();
                args.extend(["--target", t.name()]);
                if control {
                    args.extend(["--layers", "2"]);
                }
                let kind = if control { "one-shell" } else { "fur" };
                let out = format!("{}-{}-{kind}.glb", input.name, t.name());
                let (glb, _) = bake(&input.path, &dir, &out, &args);
                baked.lock().unwrap()[k] = Some(glb);
            });
        }
    });
    let baked: Vec<PathBuf> = baked.into_inner().unwrap().into_iter().flatten().collect();
    assert_eq!(baked.len(), bakes.len());
    let baked_s = started.elapsed().as_secs_f64();

    // Distinct files, in bake order: bake k is drawn as `file_of[k]`.
    let mut by_digest: HashMap<Vec<u8>, usize> = HashMap::new();
    let mut files: Vec<usize> = Vec::new(); // the bake each distinct file was first made by
    let mut file_of = Vec::new();
    for (k, glb) in baked.iter().enumerate() {
        use sha2::Digest;
        let digest = sha2::Sha256::digest(std::fs::read(glb).unwrap()).to_vec();
        let f = *by_digest.entry(digest).or_insert_with(|| {
            files.push(k);
            files.len() - 1
        });
        file_of.push(f);
    }
    let cameras: Vec<view::Camera> = inputs
        .iter()
        .enumerate()
        .map(|(i, input)| {
            let web = bakes
                .iter()
                .position(|&(j, t, c)| j == i && t == Target::Web && !c)
                .unwrap();
            view::camera_for_glb(&std::fs::read(&baked[web]).unwrap(), input.orbit, SIZE).unwrap()
        })
        .collect();
    let png = |engine: &str, f: usize| -> PathBuf {
        let (i, t, control) = bakes[files[f]];
        let kind = if control { "one-shell" } else { "fur" };
        dir.join(format!(
            "{engine}-{}-{}-{kind}.png",
            inputs[i].name,
            t.name()
        ))
    };
    // PlayCanvas and Filament: every distinct file; three.js: every distinct fur file.
    let every_file = |engine: &str| -> Vec<Value> {
        (0..files.len())
            .map(|f| {
                job(
                    &baked[files[f]],
                    &png(engine, f),
                    &cameras[bakes[files[f]].0],
                )
            })
            .collect()
    };
    let pc_jobs = every_file("playcanvas");
    let fur_files: Vec<usize> = (0..files.len()).filter(|&f| !bakes[files[f]].2).collect();
    let three_jobs: Vec<Value> = fur_files
        .iter()
        .map(|&f| {
            job(
                &baked[files[f]],
                &png("three", f),
                &cameras[bakes[files[f]].0],
            )
        })
        .collect();
    let fil_jobs = every_file("filament");
    // the three pages at once: each spends part of its time on one core (loading, encoding)
    let (pc, fil) = std::thread::scope(|scope| {
        let pc = scope.spawn(|| playcanvas(&pc_jobs, &dir));
        let fil = scope.spawn(|| crate::filament::filament(&fil_jobs, &dir));
        common::render(&three_jobs, &dir);
        (pc.join().unwrap(), fil.join().unwrap())
    });
    let drawn_s = started.elapsed().as_secs_f64() - baked_s;

    let pc_sil: Vec<Vec<bool>> = (0..files.len())
        .map(|f| silhouette(&png("playcanvas", f)))
        .collect();
    let fil_sil: Vec<Vec<bool>> = (0..files.len())
        .map(|f| silhouette(&png("filament", f)))
        .collect();
    let three_sil: HashMap<usize, Vec<bool>> = fur_files
        .iter()
        .map(|&f| (f, silhouette(&png("three", f))))
        .collect();
    let xor = |a: &[bool], b: &[bool]| a.iter().zip(b).filter(|(a, b)| a != b).count();
    let rel = |a: usize, b: usize| a as f64 / b as f64 - 1.0;
    let prims: Vec<Vec<usize>> = (0..files.len())
        .map(|f| scenes_primitives(&baked[files[f]]))
        .collect();

    eprintln!(
        "every target's file in PlayCanvas, Filament and three.js ({} x {}, silhouettes: pixels off the \
         clear colour by more than {LEVELS} levels; dragon --layers {DRAGON_LAYERS}):",
        SIZE.0, SIZE.1
    );
    eprintln!(
        "  input    target           bytes same as      PC PC 1sh    gain  three  PC-3js   xor \
         {:>6}   mi  scn0 scenes  verdict",
        "xor%"
    );
    eprintln!(
        "  (PC: PlayCanvas's silhouette of the file, PC 1sh: of its --layers 2 control, gain: \
         PC over PC 1sh; three: three.js's silhouette, PC-3js: PC against it, xor: pixels where \
         the two differ; mi: PlayCanvas's mesh instances, scn0: primitives scene 0 reaches)"
    );
    let mut failures: Vec<String> = Vec::new();
    let mut fail = |ok: bool, what: String| {
        if !ok {
            failures.push(what);
        }
    };
    for (k, &(i, t, control)) in bakes.iter().enumerate() {
        if control {
            continue;
        }
        let input = &inputs[i];
        let (f, c) = (file_of[k], file_of[k + 1]);
        assert_eq!(bakes[k + 1], (i, t, true));
        let what = format!("{} --target {}", input.name, t.name());
        let first = bakes[files[f]];
        let same_as = if files[f] == k {
            String::new()
        } else {
            format!("= {}", first.1.name())
        };
        let (p, p1, th) = (count(&pc_sil[f]), count(&pc_sil[c]), count(&three_sil[&f]));
        let x = xor(&pc_sil[f], &three_sil[&f]);
        let mi = pc[f]["meshInstances"].as_u64().unwrap() as usize;
        let scenes = &prims[f];
        let (gain, apart, share) = (rel(p, p1), rel(p, th), x as f64 / th as f64);
        let verdict = "fur";
        eprintln!(
            "  {:<8} {:<10} {:>11} {:<8} {p:>6} {p1:>6} {:>+6.2}% {th:>6} {:>+6.2}% {x:>5} \
             {:>5.2}% {mi:>4} {:>5} {:>6}  {verdict}",
            input.name,
            t.name(),
            std::fs::metadata(&baked[k]).unwrap().len(),
            same_as,
            100.0 * gain,
            100.0 * apart,
            100.0 * share,
            scenes[0],
            scenes.len(),
        );
        fail(
            gain >= input.fur_gain,
            format!(
                "{what}: PlayCanvas's silhouette ({p}) is {:+.2} % over the one-shell \
                 control's ({p1}), not {:.1} %: the fur is missing",
                100.0 * gain,
                100.0 * input.fur_gain
            ),
        );
        fail(
            apart.abs() <= ENGINES_APART,
            format!(
                "{what}: PlayCanvas's silhouette ({p}) is {:+.2} % from three.js's ({th}); \
                 at most ±{:.0} %",
                100.0 * apart,
                100.0 * ENGINES_APART
            ),
        );
        fail(
            x as f64 <= ENGINES_XOR * th as f64,
            format!(
                "{what}: PlayCanvas and three.js disagree on {x} silhouette pixels, over \
                 {:.0} % of {th}",
                100.0 * ENGINES_XOR
            ),
        );
        // Filament, stock: the same measures against the same three.js picture
        let (fp, fp1) = (count(&fil_sil[f]), count(&fil_sil[c]));
        let fx = xor(&fil_sil[f], &three_sil[&f]);
        let (fgain, fapart) = (rel(fp, fp1), rel(fp, th));
        eprintln!(
            "  {:<8} {:<10} Filament {fp:>6} {fp1:>6} {:>+6.2}% against three.js {:>+6.2}% xor \
             {fx:>5} {:>5.2}% ({} renderables)",
            "",
            "",
            100.0 * fgain,
            100.0 * fapart,
            100.0 * fx as f64 / th as f64,
            fil[f]["renderables"]
        );
        let quantized = t.profile().quantize != shellbake::output::pack::Quantize::None;
        if input.name == "grass" && quantized {
            // known failure: see FILAMENT_BLANKS_THE_FLAT_QUANTIZED_PLANE
            // the web file's levels' scene, which Filament adds under no dequantization (a
            // tiny copy at the origin), draws its lifted bare level: the control's 960 pixels
            let copy = t == Target::Web && fp1 * 10 < fp;
            fail(
                fp == 0 || fp1 == 0 || copy,
                format!(
                    "{what}: Filament drew the fur ({fp}) and its one-shell control ({fp1}): \
                     does it now draw a flat quantized plane? Then leave it out of \
                     FILAMENT_BLANKS_THE_FLAT_QUANTIZED_PLANE"
                ),
            );
            continue;
        }
        fail(
            fgain >= input.fur_gain,
            format!(
                "{what}: Filament's silhouette ({fp}) is {:+.2} % over the one-shell control's \
                 ({fp1}), not {:.1} %: the fur is missing",
                100.0 * fgain,
                100.0 * input.fur_gain
            ),
        );
        // known difference: see FILAMENT_PLACES_A_SKINNED_ASSET_ELSEWHERE
        let skinned = input.name == "critter";
        fail(
            skinned || (fapart.abs() <= FILAMENT_APART && fx as f64 <= FILAMENT_APART * th as f64),
            format!(
                "{what}: Filament's silhouette ({fp}) is {:+.2} % from three.js's ({th}), \
                 disagreeing on {fx} pixels; at most {:.0} % either",
                100.0 * fapart,
                100.0 * FILAMENT_APART
            ),
        );
        let every_scene: usize = scenes.iter().sum();
        fail(
            mi == every_scene,
            format!(
                "{what}: PlayCanvas made {mi} mesh instances, not the {every_scene} primitives \
                 its scenes {scenes:?} reach"
            ),
        );
        if matches!(t, Target::Web | Target::Blender) && scenes.len() > 1 {
            fail(
                mi > scenes[0],
                format!(
                    "{what}: {mi} mesh instances, not more than scene 0's {}",
                    scenes[0]
                ),
            );
        } else {
            fail(
                mi == scenes[0]
                    && (scenes.len() == 1 || matches!(t, Target::Web | Target::Blender)),
                format!(
                    "{what}: {mi} mesh instances for scene 0's {} primitives ({} scenes)",
                    scenes[0],
                    scenes.len()
                ),
            );
        }
    }
    eprintln!(
        "  {} bakes ({} distinct files) {baked_s:.1} s; {} PlayCanvas and {} three.js pictures \
         {drawn_s:.1} s; wall time {:.1} s",
        bakes.len(),
        files.len(),
        pc_jobs.len(),
        three_jobs.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
