#!/usr/bin/env bash
# The test command: brings what the tests need (tests/setup.sh), then runs every test.
#
#   bash tests/run.sh            every test (what CI runs)
#   bash tests/run.sh --quick    the inner loop: the unit tests and the integration tests that
#                                bake without a GPU or a browser (under two minutes on 2 cores
#                                once the tools are installed); extra arguments go to cargo test
set -euo pipefail
cd "$(dirname "$0")/.."
QUICK=(--lib --test goldens --test architecture --test hostile_input --test determinism
  --test outputs --test effects --test gravity --test comb --test batch --test fuzz_regressions)
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
chmod 0700 "$XDG_RUNTIME_DIR"
if [ "${1:-}" = "--quick" ]; then
  shift
  exec cargo test --locked "${QUICK[@]}" "$@"
fi
bash tests/setup.sh
cargo test --locked "$@"
