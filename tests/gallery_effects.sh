#!/usr/bin/env bash
# Regenerates the effect pictures docs/guide.md shows (out/gallery/effect-*.png), rendered by stock
# three.js (GLTFLoader, AnimationMixer for the wind) in headless Chromium: each effect beside the
# same bake without it, the every-effect scene (fixtures/effects.toml) at two times, and the
# silhouettes scene (fixtures/silhouettes.toml: fins, outline, tessellation).
# Run by tests/gallery.sh; runs alone too (after tests/setup.sh and a release build).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/shellbake
out=out/gallery
work=$(mktemp -d)
mkdir -p "$out"

jobs="["
sep=""
# job GLB PNG YAW PITCH DISTANCE FOVY TIME  (TIME "null": the file's static weights)
job() {
  jobs+="$sep{\"glb\":\"$1\",\"png\":\"$2\",\"width\":384,\"height\":384,"
  jobs+="\"camera\":{\"auto\":true,\"yaw\":$3,\"pitch\":$4,\"distance\":$5,\"fovy_deg\":$6},"
  jobs+="\"light\":{\"direction\":[1,2,3],\"intensity\":3.0},\"ambient\":0.5,"
  jobs+="\"background\":[0.05,0.05,0.06],\"time\":$7}"
  sep=","
}
# job_at GLB PNG EYE TARGET FOVY: a fixed camera (world units)
job_at() {
  jobs+="$sep{\"glb\":\"$1\",\"png\":\"$2\",\"width\":384,\"height\":384,"
  jobs+="\"camera\":{\"eye\":$3,\"target\":$4,\"up\":[0,1,0],\"fovy_deg\":$5,\"near\":0.5,\"far\":100},"
  jobs+="\"light\":{\"direction\":[1,2,3],\"intensity\":3.0},\"ambient\":0.5,"
  jobs+="\"background\":[0.05,0.05,0.06]}"
  sep=","
}
"$bin" bake fixtures/bunny.obj -o "$work/bunny.glb" -q
"$bin" bake fixtures/bunny.obj --gravity -o "$work/bunny-gravity.glb" -q
"$bin" bake fixtures/bunny.obj --sheen -o "$work/bunny-sheen.glb" -q
"$bin" bake fixtures/bunny.obj --wind -o "$work/bunny-wind.glb" -q
# occlusion reaching a quarter of the diagonal, at full strength, on the teapot's folds
cp fixtures/teapot.obj "$work/"
printf '[[surface]]\nmesh = "teapot.obj"\neffects = [%s]\n[surface.occlusion]\nradius = 0.25\nstrength = 1.0\n' \
  '' > "$work/teapot.toml"
printf '[[surface]]\nmesh = "teapot.obj"\neffects = [%s]\n[surface.occlusion]\nradius = 0.25\nstrength = 1.0\n' \
  '"occlusion"' > "$work/teapot-occlusion.toml"
"$bin" bake "$work/teapot.toml" -o "$work/teapot.glb" -q
"$bin" bake "$work/teapot-occlusion.toml" -o "$work/teapot-occlusion.glb" -q
"$bin" bake fixtures/effects.toml -o "$work/effects.glb" -q
# skinned fur: the procedural tube as it is, and combed down its length
"$bin" bake fixtures/tube_skinned.glb -o "$work/tube.glb" -q
cp fixtures/tube_skinned.glb "$work/"
printf '[[surface]]\nmesh = "tube_skinned.glb"\neffects = ["comb"]\n[surface.gravity]\ncomb = [0.0, 1.0]\nstrength = 0.6\n' \
  > "$work/tube-comb.toml"
"$bin" bake "$work/tube-comb.toml" -o "$work/tube-comb.glb" -q
# tessellation: a coarse UV sphere (6 rings, 10 segments), as it is and cut by 4 with Phong
node -e '
const R = 6, S = 10, v = [], f = [];
for (let i = 0; i <= R; i++) for (let j = 0; j <= S; j++) {
  const t = Math.PI * i / R, p = 2 * Math.PI * j / S;
  v.push(`v ${(Math.sin(t) * Math.cos(p)).toFixed(6)} ${Math.cos(t).toFixed(6)} ${(Math.sin(t) * Math.sin(p)).toFixed(6)}`);
  v.push(`vt ${(j / S).toFixed(6)} ${(i / R).toFixed(6)}`);
}
for (let i = 0; i < R; i++) for (let j = 0; j < S; j++) {
  const a = i * (S + 1) + j + 1, b = a + S + 1;
  f.push(`f ${a}/${a} ${a + 1}/${a + 1} ${b + 1}/${b + 1}`, `f ${a}/${a} ${b + 1}/${b + 1} ${b}/${b}`);
}
console.log(v.filter((_, k) => k % 2 == 0).join("\n") + "\n" + v.filter((_, k) => k % 2 == 1).join("\n") + "\n" + f.join("\n"));
' > "$work/coarse.obj"
"$bin" bake "$work/coarse.obj" --preset moss -o "$work/coarse.glb" -q
"$bin" bake "$work/coarse.obj" --preset moss --tessellate --set tessellation.factor=4 -o "$work/coarse-tess.glb" -q
job "$work/bunny.glb" "$out/effect-none.png" 90 10 1.5 30 null
job "$work/bunny-gravity.glb" "$out/effect-gravity.png" 90 10 1.5 30 null
job "$work/bunny-sheen.glb" "$out/effect-sheen.png" 90 10 1.5 30 null
job "$work/bunny-wind.glb" "$out/effect-wind-0.png" 90 10 1.5 30 0.5
job "$work/bunny-wind.glb" "$out/effect-wind-1.png" 90 10 1.5 30 1.5
job "$work/teapot.glb" "$out/effect-teapot-none.png" 120 25 1.5 35 null
job "$work/teapot-occlusion.glb" "$out/effect-occlusion.png" 120 25 1.5 35 null
job "$work/effects.glb" "$out/effect-scene-0.png" 25 18 1.3 40 0.75
job "$work/effects.glb" "$out/effect-scene-1.png" 25 18 1.3 40 2.25
job "$work/tube.glb" "$out/effect-skin-0.png" 0 5 2.6 35 0.5
job "$work/tube.glb" "$out/effect-skin-1.png" 0 5 2.6 35 1.5
job "$work/tube-comb.glb" "$out/effect-comb.png" 0 5 2.6 35 0.5
job "$work/coarse.glb" "$out/effect-tess-none.png" 20 15 2.4 35 null
job "$work/coarse-tess.glb" "$out/effect-tess.png" 20 15 2.4 35 null
# fins: the bunny's back and ears against the sky, close, with and without (the shells alone
# look hollow where they are seen edge-on)
"$bin" bake fixtures/bunny.obj --fins -o "$work/bunny-fins.glb" -q
job_at "$work/bunny.glb" "$out/effect-fins-none.png" "[18,5,2]" "[0,5.5,-2]" 22
job_at "$work/bunny-fins.glb" "$out/effect-fins.png" "[18,5,2]" "[0,5.5,-2]" 22
# outline: the bunny with a pale hull (the dark default hides on the dark background) of a
# twenty-fifth of its diagonal (past the fur, which hides a thinner hull); the silhouettes scene
"$bin" bake fixtures/bunny.obj --outline --set outline.width_fraction=0.04 --set "outline.color=[0.85,0.8,0.6]" --clamp -o "$work/bunny-outline.glb" -q
job "$work/bunny-outline.glb" "$out/effect-outline.png" 90 10 1.5 30 null
"$bin" bake fixtures/silhouettes.toml -o "$work/silhouettes.glb" -q
job "$work/silhouettes.glb" "$out/effect-silhouettes.png" 0 15 2.9 40 null
jobs+="]"
echo "$jobs" > "$work/jobs.json"
node tests/js/three_render.mjs "$work/jobs.json"
rm -rf "$work"
