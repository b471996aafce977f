#!/usr/bin/env bash
# Throughput of `shellbake batch` with 1, 2 and 4 shard processes side by side on this machine
# (and one process with --jobs 2 and 4),
# over the generated library of 200 procedural meshes (`shellbake fixtures DIR --library 200`),
# each count from an empty output folder, three runs each (the median is printed). Then checks
# that every count wrote the same bytes. Run after a release build:
#   bash tests/bench/batch.sh [ASSETS]
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=$PWD/target/release/shellbake
n=${1:-200}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin" fixtures "$work/lib" --library "$n"
echo "| shard processes | wall time (median of 3) | assets/s | speed-up |"
echo "|---|---|---|---|"
base=""
for shards in 1 2 4; do
  times=()
  for run in 1 2 3; do
    out="$work/out-$shards-$run"
    start=$(date +%s.%N)
    for ((i = 0; i < shards; i++)); do
      "$bin" batch "$work/lib/manifest.toml" --shard "$i/$shards" --out "$out" -q &
    done
    wait
    end=$(date +%s.%N)
    times+=("$(echo "$end - $start" | bc -l)")
  done
  median=$(printf '%s\n' "${times[@]}" | sort -g | sed -n 2p)
  base=${base:-$median}
  printf '| %d | %.2f s | %.1f | %.2f× |\n' "$shards" "$median" \
    "$(echo "$n / $median" | bc -l)" "$(echo "$base / $median" | bc -l)"
done
# one process baking K assets at once instead
for jobs in 2 4; do
  times=()
  for run in 1 2 3; do
    out="$work/jobs-$jobs-$run"
    start=$(date +%s.%N)
    "$bin" batch "$work/lib/manifest.toml" --jobs "$jobs" --out "$out" -q
    end=$(date +%s.%N)
    times+=("$(echo "$end - $start" | bc -l)")
  done
  median=$(printf '%s\n' "${times[@]}" | sort -g | sed -n 2p)
  printf '| 1, --jobs %d | %.2f s | %.1f | %.2f× |\n' "$jobs" "$median" \
    "$(echo "$n / $median" | bc -l)" "$(echo "$base / $median" | bc -l)"
done
# every shard count wrote the same files
for shards in 2 4; do
  for f in "$work"/out-1-1/*.glb; do
    cmp -s "$f" "$work/out-$shards-1/$(basename "$f")" || { echo "differs: $shards shards, $(basename "$f")"; exit 1; }
  done
done
echo "outputs byte-identical for 1, 2 and 4 shards ($(ls "$work"/out-1-1/*.glb | wc -l) files)"
