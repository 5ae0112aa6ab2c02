#!/usr/bin/env bash
# A recorded simulated flight passes scripts/check-mcap: hq-sim-flight --link --record (the
# vehicle's onboard.mcap) flown by hq-ground --device sim --headless --record (flight.mcap), a
# few seconds, on loopback in a domain of its own. Both files: one clock, log times never going
# back, every image/calibration/cloud frame with a transform path to odom, Foxglove messages as
# the official schemas define them. The vehicle's exit summary must show the frame channels.
# Usage: check_mcap_flight.sh HQ_SIM_FLIGHT HQ_GROUND WORK_DIR (run from the repository root).
# Exit 77 (skipped) when node, npm or the packages are unavailable.
set -euo pipefail
sim_flight=$1
ground=$2
work=$3
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1' '@foxglove/schemas@1' \
  '@foxglove/rosmsg@5' '@foxglove/rosmsg2-serialization@2'
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
  if ! grep -Eq "record $topic +[1-9][0-9]* messages" "$tmp/vehicle.out"; then
    echo "FAILED: onboard.mcap: no $topic messages"; cat "$tmp/vehicle.out"; exit 1
  fi
done
scripts/check-mcap --work "$work" "$tmp/vehicle/onboard.mcap" "$tmp/ground/flight.mcap"
