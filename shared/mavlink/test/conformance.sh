#!/usr/bin/env bash
# Conformance of hq::mavlink with an independent implementation, node-mavlink (npm, v2.x):
# (a) frames our codec wrote are decoded by node-mavlink and every field checked, and node-mavlink
#     re-encoding them must give the same bytes; (b) frames node-mavlink wrote (v2, signed, v1)
#     are decoded by our codec and every field checked.
# Usage: conformance.sh HQ_MAVLINK_CONFORMANCE_BINARY WORK_DIR   (WORK_DIR holds node_modules)
# Exit 77 (ctest: skipped) when node, npm or the package are unavailable.
set -euo pipefail
tool=$1
work=$2

command -v node >/dev/null || { echo "SKIPPED: node is not installed"; exit 77; }
command -v npm >/dev/null || { echo "SKIPPED: npm is not installed"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$work"
if [ ! -f "$work/node_modules/node-mavlink/package.json" ]; then
  if ! npm install --no-audit --no-fund --prefix "$work" 'node-mavlink@2' >"$work/npm-install.log" 2>&1; then
    echo "SKIPPED: npm install node-mavlink failed (see $work/npm-install.log)"
    tail -5 "$work/npm-install.log"
    exit 77
  fi
fi
version=$(node -p "require('$work/node_modules/node-mavlink/package.json').version")
echo "node $(node --version), node-mavlink $version"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$tool" write "$tmp/ours.bin" "$tmp/ours.json"
node "$here/conformance.cjs" "$work/node_modules" decode "$tmp/ours.bin" "$tmp/ours.json"
node "$here/conformance.cjs" "$work/node_modules" encode "$tmp/theirs.bin" "$tmp/theirs.txt"
"$tool" check "$tmp/theirs.bin" "$tmp/theirs.txt"
echo "conformance with node-mavlink $version: passed"
