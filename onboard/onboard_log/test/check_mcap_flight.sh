#!/usr/bin/env bash
# A recorded simulated flight passes scripts/check-mcap: hq-sim-flight --link --record (the
# vehicle's onboard.mcap) flown by hq-ground --device sim --headless --record (flight.mcap), a
# few seconds, on loopback in a domain of its own. Both files: one clock, log times never going
# back, every image/calibration/cloud frame with a transform path to odom, Foxglove messages as
# the official schemas define them. The vehicle's exit summary must show the frame channels.
# The vehicle's ROS 2 bag (ros2.mcap) too: the "ros2" profile's rules, every message decoded
# from its ros2msg schema, and its values those the vehicle published (check_ros2_record.cjs);
# the same bag with one message cut short, or a schema whose type does not resolve, must fail.
# Usage: check_mcap_flight.sh HQ_SIM_FLIGHT HQ_GROUND WORK_DIR (run from the repository root).
# Exit 77 (skipped) when node, npm or the packages are unavailable.
set -euo pipefail
sim_flight=$1
ground=$2
work=$3
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1' '@foxglove/schemas@1' \
  '@foxglove/rosmsg@5' '@foxglove/rosmsg2-serialization@2' '@foxglove/omgidl-parser@1' \
  '@foxglove/omgidl-serialization@1'
work=$(cd "$work" && pwd)

hq_loopback_dds
domain=$((1 + ($$ + 97) % 200))
tmp=$(mktemp -d)
vehicle_pid=""
cleanup() {
  if [ -n "$vehicle_pid" ]; then kill "$vehicle_pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT

"$sim_flight" --link --world onboard/sim/worlds/arena.yaml --duration-s 12 --domain-id "$domain" \
              --insecure --record "$tmp/vehicle" >"$tmp/vehicle.out" 2>&1 &
vehicle_pid=$!
"$ground" --device sim --headless --duration-s 6 --domain-id "$domain" --insecure \
          --record "$tmp/ground" >"$tmp/ground.out" 2>&1 || { cat "$tmp/ground.out"; exit 1; }
wait "$vehicle_pid" || { cat "$tmp/vehicle.out"; exit 1; }
vehicle_pid=""

for topic in /tf /tf_static /camera/calibration /obstacles; do
  if ! grep -Eq "^  record $topic +[1-9][0-9]* messages" "$tmp/vehicle.out"; then
    echo "FAILED: onboard.mcap: no $topic messages"; cat "$tmp/vehicle.out"; exit 1
  fi
done
scripts/check-mcap --work "$work" "$tmp/vehicle/onboard.mcap" "$tmp/ground/flight.mcap"
# The bag's frames carry the ROS namespace (hq1/odom ...), its topics too (/hq1/odom).
odom=$(grep -Eo '^  ros2 record /[A-Za-z0-9_/]+/odom ' "$tmp/vehicle.out" | awk '{print $3}')
[ -n "$odom" ] || { echo "FAILED: ros2.mcap: no odom topic in the summary"; cat "$tmp/vehicle.out"; exit 1; }
scripts/check-mcap --work "$work" --root-frame "${odom#/}" "$tmp/vehicle/ros2.mcap" |
  tee "$tmp/check.out"
channels=$(grep -c '^  ros2 record /' "$tmp/vehicle.out")
grep -q "ros2.mcap: .*profile \"ros2\", [1-9] frame(s) used, $channels ros2 channel(s) decoded" \
  "$tmp/check.out" || { echo "FAILED: ros2.mcap: not all $channels channels decoded"; exit 1; }
node "$here/check_ros2_record.cjs" "$work/node_modules" "$tmp/vehicle/onboard.mcap" \
     "$tmp/vehicle/ros2.mcap" "$tmp/vehicle.out" || { cat "$tmp/vehicle.out"; exit 1; }
ls -l "$tmp/vehicle"

# The same bag damaged: each fails the check on its fault.
for mode in message schema; do
  node "$here/corrupt_ros2_record.cjs" "$work/node_modules" "$tmp/vehicle/ros2.mcap" \
       "$tmp/bad_$mode.mcap" "$mode" "$odom"
  status=0
  scripts/check-mcap --work "$work" --root-frame "${odom#/}" "$tmp/bad_$mode.mcap" \
    >"$tmp/bad_$mode.out" 2>&1 || status=$?
  case $mode in
    message) want="FAIL ros2: $odom: a message does not decode with nav_msgs/msg/Odometry" ;;
    schema) want="FAIL ros2: $odom: schema nav_msgs/msg/Odometry does not parse" ;;
  esac
  if [ "$status" -ne 1 ] || ! grep -qF -- "$want" "$tmp/bad_$mode.out"; then
    echo "FAILED: ros2.mcap with a damaged $mode: exit $status, expected 1 with '$want':"
    cat "$tmp/bad_$mode.out"; exit 1
  fi
  echo "ok: ros2.mcap with a damaged $mode fails: $want"
done
