#!/usr/bin/env bash
# Conformance of hq::mavlink with an independent implementation, node-mavlink (npm, v2.x):
# (a) frames our codec wrote are decoded by node-mavlink and every field checked, and node-mavlink
#     re-encoding them must give the same bytes; (b) frames node-mavlink wrote (v2, signed, v1)
#     are decoded by our codec and every field checked; (c) the router's table of target offsets
#     and CRC_EXTRA (message_targets.hpp) agrees with node-mavlink's definitions.
# Usage: conformance.sh HQ_MAVLINK_CONFORMANCE_BINARY WORK_DIR   (WORK_DIR holds node_modules)
# Exit 77 (ctest: skipped) when node, npm or the package are unavailable.
set -euo pipefail
tool=$1
work=$2

here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" 'node-mavlink@2'
version=$(hq_npm_version "$work" node-mavlink)
echo "node $(node --version), node-mavlink $version"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$tool" write "$tmp/ours.bin" "$tmp/ours.json"
node "$here/conformance.cjs" "$work/node_modules" decode "$tmp/ours.bin" "$tmp/ours.json"
node "$here/conformance.cjs" "$work/node_modules" encode "$tmp/theirs.bin" "$tmp/theirs.txt"
"$tool" check "$tmp/theirs.bin" "$tmp/theirs.txt"
"$tool" targets "$tmp/targets.json"
node "$here/conformance.cjs" "$work/node_modules" targets "$tmp/targets.json"
echo "conformance with node-mavlink $version: passed"
