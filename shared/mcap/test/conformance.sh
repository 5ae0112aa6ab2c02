#!/usr/bin/env bash
# Conformance of hq::mcap with an independent implementation, @mcap/core (npm, the Foxglove MCAP
# library, with @mcap/support for zstd): files our writer produced are read by McapIndexedReader
# (footer, summary, chunk indexes, seeking by topic and time, CRCs) and McapStreamReader (every
# record in order, CRCs), and everything is checked against what the writer reports (JSON); and
# files @mcap/core's McapWriter produced (zstd chunks, no chunks) are read by hq::mcap, whole
# and cut in half. A file without summary rewritten by hq::mcap::recover (hq-report --recover)
# is read by both of @mcap/core's readers like any complete file.
# Usage: conformance.sh HQ_MCAP_CONFORMANCE_BINARY WORK_DIR   (WORK_DIR holds node_modules)
# Exit 77 (ctest: skipped) when node, npm or the packages are unavailable.
set -euo pipefail
tool=$1
work=$2

here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1'
work=$(cd "$work" && pwd)
core=$(hq_npm_version "$work" @mcap/core)
echo "node $(node --version), @mcap/core $core, @mcap/support $(hq_npm_version "$work" @mcap/support)"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$tool" write "$tmp"
for name in zstd none nosummary recovered; do
  node "$here/conformance.cjs" "$work/node_modules" read "$tmp/$name.mcap" "$tmp/$name.json"
done
for chunks in zstd none; do
  node "$here/conformance.cjs" "$work/node_modules" write "$tmp/theirs-$chunks.mcap" \
       "$tmp/theirs-$chunks.txt" "$chunks"
  "$tool" check "$tmp/theirs-$chunks.mcap" "$tmp/theirs-$chunks.txt"
done
echo "conformance with @mcap/core $core: passed"
