#!/usr/bin/env bash
# An onboard.mcap read by independent readers (check_onboard.cjs: @mcap/core,
# @foxglove/omgidl-parser, @foxglove/omgidl-serialization from npm, installed into WORK_DIR by
# scripts/lib.sh's hq_npm_checkers). Exit 77 (skipped) with the reason when node,
# npm or the packages are unavailable.
# Usage: onboard_mcap.sh WORK_DIR FILE.mcap SUMMARY.txt | onboard_mcap.sh WORK_DIR --probe x
set -euo pipefail
work=$1
file=$2
summary=$3
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1' '@foxglove/omgidl-parser@1' \
  '@foxglove/omgidl-serialization@1'
work=$(cd "$work" && pwd)
# --probe: only install (or say why not), so a caller skips before flying.
[ "$file" = "--probe" ] && exit 0
node "$here/check_onboard.cjs" "$work/node_modules" "$file" "$summary"
