#!/usr/bin/env bash
# scripts/check-mcap fails on each fault it names, and only on it: files written by @mcap/core's
# own writer (bad_records.cjs), one good and one per fault (a backwards log time, two clocks,
# an image frame with no transform to odom, a ros2-profile channel whose schema does not parse,
# a ros2 message cut short; a good ros2 file passes).
# Usage: check_mcap_negative.sh WORK_DIR (run from the repository root). Exit 77: no npm.
set -euo pipefail
work=$1
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1' '@foxglove/schemas@1' \
  '@foxglove/rosmsg@5' '@foxglove/rosmsg2-serialization@2'
work=$(cd "$work" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
node "$here/bad_records.cjs" "$work/node_modules" "$tmp"
failures=0
expect() {  # expect FILE STATUS PATTERN
  local status=0
  scripts/check-mcap --work "$work" "$tmp/$1.mcap" >"$tmp/$1.out" 2>&1 || status=$?
  if [ "$status" -ne "$2" ] || ! grep -q -- "$3" "$tmp/$1.out"; then
    echo "FAILED: $1: exit $status (expected $2), output lacks '$3':"; cat "$tmp/$1.out"
    failures=$((failures + 1))
  else
    echo "ok: $1: exit $status, '$3'"
  fi
  # Each bad file fails on its fault only.
  if [ "$2" -ne 0 ] && [ "$(grep -c 'FAIL' "$tmp/$1.out")" -ne 1 ]; then
    echo "FAILED: $1: more than its one fault reported:"; cat "$tmp/$1.out"
    failures=$((failures + 1))
  fi
}
expect good 0 'check-mcap: OK'
expect backwards 1 'FAIL order: 1 of 4 messages go back in log time (worst 10.000 ms)'
expect two_clocks 1 'FAIL clock: channels start'
expect no_transform 1 'FAIL frames: /camera/image/compressed names frame "camera" with no transform path to odom'
expect ros2_bad_schema 1 'FAIL ros2: /bad: schema std_msgs/msg/Bad does not parse'
expect ros2_good 0 'check-mcap: OK'
expect ros2_bad_message 1 'FAIL ros2: /bad: a message does not decode with rosgraph_msgs/msg/Clock'
[ "$failures" -eq 0 ]
