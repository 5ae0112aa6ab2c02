#!/usr/bin/env bash
# A simulated vehicle with the ROS 2 topics on (hq-sim-flight --link --ros2
# --insecure) against hq_ros2_probe: a native station takes it off, a ROS 2 teleop node flies
# it over rt/<ns>/cmd_vel (Twist, as teleop_twist_keyboard), the native station overrides it; the probe dumps every rt/ topic
# as raw CDR into DUMP_DIR.
# Usage: ros2_topics.sh HQ_ONBOARD HQ_ROS2_PROBE DUMP_DIR   (run from the repository root)
#        ros2_topics.sh --decode DUMP_DIR WORK_DIR   decodes the dump with @foxglove/rosmsg2-
#        serialization (npm, installed into WORK_DIR); exit 77 (ctest: skipped) without npm.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"

if [ "$1" = "--decode" ]; then
  dump=$2
  work=$3
  command -v node >/dev/null || { echo "SKIPPED: node is not installed"; exit 77; }
  command -v npm >/dev/null || { echo "SKIPPED: npm is not installed"; exit 77; }
  [ -f "$dump/odom.cdr" ] || { echo "no dump in $dump: the flight test did not run"; exit 1; }
  hq_npm_checkers "$work" '@foxglove/rosmsg@5' '@foxglove/rosmsg2-serialization@3'
  work=$(cd "$work" && pwd)
  echo "node $(node --version), @foxglove/rosmsg $(hq_npm_version "$work" @foxglove/rosmsg)," \
       "@foxglove/rosmsg2-serialization $(hq_npm_version "$work" @foxglove/rosmsg2-serialization)"
  exec node "$here/decode_ros2.cjs" "$work/node_modules" "$dump" hq1
fi

onboard=$1
probe=$2
dump=$3
rm -rf "$dump"
mkdir -p "$dump"
# Loopback only, in a domain of this run's own.
hq_loopback_dds
domain=$((1 + $$ % 200))
vehicle_pid=""
cleanup() { if [ -n "$vehicle_pid" ]; then kill "$vehicle_pid" 2>/dev/null || true; fi; }
trap cleanup EXIT

"$onboard" --link --ros2 --insecure --world onboard/sim/worlds/arena.yaml \
           --duration-s 60 --domain-id "$domain" >"$dump/onboard.out" 2>&1 &
vehicle_pid=$!
status=0
"$probe" --domain-id "$domain" --out "$dump" --ns hq1 --seconds 50 || status=$?
kill -INT "$vehicle_pid" 2>/dev/null || true
wait "$vehicle_pid" 2>/dev/null || true
vehicle_pid=""
grep -E 'ros2|ROS 2' "$dump/onboard.out" || true
if [ "$status" -ne 0 ]; then
  echo "probe failed ($status); hq-sim-flight said:"
  tail -30 "$dump/onboard.out"
  exit 1
fi
