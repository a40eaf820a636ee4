#!/usr/bin/env bash
# The project's test command (README): installs what the tests need when it
# is missing, then runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# lavapipe complains on every device creation when this is unset.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo test --workspace --locked --no-fail-fast "$@"
# The V4L2 camera backend (feature `v4l2`): its structure layouts and
# errors, which need no camera.
cargo test -p showcase-render --features v4l2 --locked --lib camera::v4l2
