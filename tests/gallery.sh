#!/usr/bin/env bash
# Regenerates the pictures the README shows (out/gallery/*.png): bakes fixtures with each preset
# and renders them with three.js in headless Chromium.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tests/setup.sh
cargo build --release --quiet
mkdir -p out/gallery
bin=target/release/shellbake
jobs="["
sep=""
for spec in bunny:fur teapot:carpet torus:grass sphere:moss; do
  mesh=${spec%%:*}; preset=${spec##*:}
  "$bin" bake "fixtures/$mesh.obj" --preset "$preset" -o "out/gallery/$mesh-$preset.glb" -q
  jobs+="$sep{\"glb\":\"out/gallery/$mesh-$preset.glb\",\"png\":\"out/gallery/$mesh-$preset-three.png\",\"width\":512,\"height\":512,"
  jobs+="\"camera\":{\"auto\":true,\"yaw\":25,\"pitch\":20,\"distance\":2.6,\"fovy_deg\":40},"
  jobs+="\"light\":{\"direction\":[1,2,3],\"intensity\":3.0},\"ambient\":0.5,\"background\":[0.05,0.05,0.06]}"
  sep=","
done
jobs+="]"
echo "$jobs" > out/gallery/jobs.json
node tests/js/three_render.mjs out/gallery/jobs.json
rm -f out/gallery/*.glb out/gallery/jobs.json

# Baked against the runtime reference (wgpu, llvmpipe): the close view of the fur bunny.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
"$bin" verify fixtures/bunny.obj --preset fur --out-dir out/gallery/verify -q
cp out/gallery/verify/bunny-close-reference.png out/gallery/bunny-close-reference.png
cp out/gallery/verify/bunny-close-baked.png out/gallery/bunny-close-baked.png
# (not "-difference.png": that suffix is kept for failing tests' pictures and is git-ignored)
cp out/gallery/verify/bunny-close-difference.png out/gallery/bunny-close-flip.png
rm -rf out/gallery/verify
