#!/usr/bin/env bash
# Make the cluster CA and one certificate per node of a cluster config.
# Usage: deploy/make-certs.sh deploy/cluster.toml OUT_DIR
# Copy OUT_DIR/ca.pem plus each peer's <name>.pem/<name>.key to its PC;
# keep ca.key offline.
set -euo pipefail
config=${1:?usage: make-certs.sh CONFIG OUT_DIR}
out=${2:?usage: make-certs.sh CONFIG OUT_DIR}
nodes=$(sed -n 's/^name *= *"\([^"]*\)".*/\1/p' "$config")
[ -n "$nodes" ] || { echo "make-certs: no [[node]] names in $config" >&2; exit 1; }
args=()
for n in $nodes; do args+=(--node "$n"); done
exec showcase-master certs --out "$out" "${args[@]}"
