#!/usr/bin/env bash
# An onboard.mcap read by independent readers (check_onboard.cjs: @mcap/core,
# @foxglove/omgidl-parser, @foxglove/omgidl-serialization from npm, installed into WORK_DIR as
# ground/mcap_recorder/test/flight_mcap.sh does). Exit 77 (skipped) with the reason when node,
# npm or the packages are unavailable.
# Usage: onboard_mcap.sh WORK_DIR FILE.mcap SUMMARY.txt | onboard_mcap.sh WORK_DIR --probe x
set -euo pipefail
work=$1
file=$2
summary=$3
command -v node >/dev/null || { echo "SKIPPED: node is not installed"; exit 77; }
command -v npm >/dev/null || { echo "SKIPPED: npm is not installed"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$work"
work=$(cd "$work" && pwd)
packages=('@mcap/core@2' '@mcap/support@1' '@foxglove/omgidl-parser@1'
          '@foxglove/omgidl-serialization@1')
if [ ! -f "$work/node_modules/@foxglove/omgidl-serialization/package.json" ] ||
   [ ! -f "$work/node_modules/@mcap/support/package.json" ]; then
  if ! npm install --no-audit --no-fund --prefix "$work" "${packages[@]}" \
       >"$work/npm-install.log" 2>&1; then
    echo "SKIPPED: npm install ${packages[*]} failed (see $work/npm-install.log)"
    exit 77
  fi
fi
# --probe: only install (or say why not), so a caller skips before flying.
[ "$file" = "--probe" ] && exit 0
node "$here/check_onboard.cjs" "$work/node_modules" "$file" "$summary"
