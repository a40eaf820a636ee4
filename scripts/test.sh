#!/usr/bin/env bash
# The project's test command (README): installs what the tests need when it
# is missing, then runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo test --workspace --locked --no-fail-fast "$@"
