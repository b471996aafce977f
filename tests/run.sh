#!/usr/bin/env bash
# The test command: brings what the tests need (tests/setup.sh), then runs every test.
#
#   bash tests/run.sh            every test (what CI runs)
#   bash tests/run.sh --quick    the inner loop: the unit tests and the integration tests that
#                                bake without a GPU or a browser (under two minutes on 2 cores
#                                once the tools are installed); extra arguments go to cargo test
set -euo pipefail
cd "$(dirname "$0")/.."
# Every integration test is a module of one binary, `all` (tests/all.rs); these suites are quick.
QUICK=(goldens:: architecture:: hostile_input:: determinism:: outputs:: effects:: gravity::
  comb:: batch:: fuzz_regressions::)
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
chmod 0700 "$XDG_RUNTIME_DIR"
if [ "${1:-}" = "--quick" ]; then
  shift
  cargo test --locked --lib "$@"
  exec cargo test --locked --test all "$@" -- "${QUICK[@]}"
fi
bash tests/setup.sh
cargo test --locked "$@"
