#!/usr/bin/env bash
# The test command: brings what the tests need (tests/setup.sh), then runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tests/setup.sh
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
chmod 0700 "$XDG_RUNTIME_DIR"
cargo test --locked "$@"
