#!/usr/bin/env bash
# Regenerates the README's first pictures: the critter asset (fixtures/critter.glb) bare and
# furred with `--only material=fur_*`, drawn by stock three.js (GLTFLoader) in headless Chromium
# from the same cameras (overall and close), and the furred file imported into Blender (bpy)
# and rendered with Cycles at 64 transparent bounces; and the shape-key fixture
# (fixtures/shape_keys.glb) bare and furred at rest and stretched, drawn by the viewer.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tests/setup.sh
cargo build --release --quiet
mkdir -p out/gallery
tmp=$(mktemp -d)
target/release/shellbake bake fixtures/critter.glb --only 'material=fur_*' -o "$tmp/critter-fur.glb" -q
# thin parts: the legs with long fur, without and with clamp.thin
target/release/shellbake bake fixtures/critter.glb --only material=paws --height 0.08 -o "$tmp/legs.glb" -q
target/release/shellbake bake fixtures/critter.glb --only material=paws --height 0.08 --set clamp.thin=0.3 -o "$tmp/legs-thin.glb" -q
job() { # GLB PNG EYE TARGET
  echo "{\"glb\":\"$1\",\"png\":\"$2\",\"width\":480,\"height\":360,\"camera\":{\"eye\":$3,\"target\":$4,\"up\":[0,1,0],\"fovy_deg\":40,\"near\":0.05,\"far\":50},\"light\":{\"direction\":[0.4,1,0.6],\"intensity\":2.5},\"ambient\":0.4,\"background\":[0.55,0.6,0.7]}"
}
far='[1.2,1.3,2.4]'; centre='[0,0.6,0]'; near='[1.1,0.95,0.75]'; head='[0.5,0.7,0]'
{
  echo "["
  job fixtures/critter.glb out/gallery/asset-critter-bare.png "$far" "$centre"; echo ","
  job "$tmp/critter-fur.glb" out/gallery/asset-critter-fur.png "$far" "$centre"; echo ","
  job fixtures/critter.glb out/gallery/asset-critter-bare-close.png "$near" "$head"; echo ","
  job "$tmp/critter-fur.glb" out/gallery/asset-critter-fur-close.png "$near" "$head"; echo ","
  job "$tmp/legs.glb" out/gallery/asset-legs.png '[0.9,0.4,1.3]' '[0.1,0.25,0]'; echo ","
  job "$tmp/legs-thin.glb" out/gallery/asset-legs-thin.png '[0.9,0.4,1.3]' '[0.1,0.25,0]'
  echo "]"
} > "$tmp/jobs.json"
node tests/js/three_render.mjs "$tmp/jobs.json"
python3 tests/blender_render.py "$tmp/critter-fur.glb" out/gallery/asset-critter-blender.png 64 | tail -1
# shape keys: every clip played at 0.999 s (the last, `ease`, holds the key at 0.5)
target/release/shellbake bake fixtures/shape_keys.glb -o "$tmp/blob.glb" -q
shape() { # GLB NAME TIME
  target/release/shellbake render "$1" -o "out/gallery/asset-shape-key-$2.png" --view side \
    --size 320x320 --distance 3.2 --time "$3"
}
shape fixtures/shape_keys.glb bare 0.999
shape "$tmp/blob.glb" rest 0
shape "$tmp/blob.glb" stretched 0.999
rm -rf "$tmp"
