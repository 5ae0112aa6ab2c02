#!/usr/bin/env bash
# A GCS beside the companion, in real processes on loopback: hq-sim --sitl (the FC),
# hq-onboard --source sitl --gcs udp:127.0.0.1:PORT (the companion, routing the FC's MAVLink) and
# a ground control station made of node-mavlink (gcs_node.cjs, listening as QGroundControl does).
# GIVEN the three WHEN the GCS sends heartbeats, lists every parameter, sets one and reads it
# back THEN each step passes through the companion; the FC counts the GCS's heartbeats and
# parameters, and the companion's summary counts frames forwarded both ways; the companion's
# ODOMETRY reaches both the FC (fused) and the GCS, its TIMESYNC with the FC only the FC.
# Usage: gcs_process_test.sh HQ_SIM HQ_ONBOARD WORK_DIR   (WORK_DIR holds node_modules)
# Exit 77 (ctest: skipped) when node, npm or the package are unavailable.
set -euo pipefail
sim=$1
onboard=$2
work=$3
for program in "$sim" "$onboard"; do
  [ -x "$program" ] || { echo "FAILED: $program is not built" >&2; exit 1; }
done
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../scripts/lib.sh"
hq_npm_checkers "$work" 'node-mavlink@2'
echo "node $(node --version), node-mavlink $(hq_npm_version "$work" node-mavlink)"
cd "$HQ_ROOT"

out=$(mktemp -d)
fc_port=$((20000 + ($$ * 7) % 20000))
gcs_port=$((fc_port + 1))
channel="hq-gcs-test-$$"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  rm -f "/dev/shm/hq-$channel"
  [ "${keep:-0}" = 1 ] || rm -rf "$out"
}
trap cleanup EXIT

node "$here/gcs_node.cjs" "$work/node_modules" "$gcs_port" 30 >"$out/gcs.out" 2>&1 &
gcs_pid=$!
pids+=("$gcs_pid")
"$sim" --sitl --world onboard/sim/worlds/arena.yaml --duration-s 60 \
  --mavlink "udp-listen:$fc_port" --channel "$channel" >"$out/sim.out" 2>"$out/sim.err" &
sim_pid=$!
pids+=("$sim_pid")
"$onboard" --source sitl --fc "mavlink:udp:127.0.0.1:$fc_port" --channel "$channel" \
  --gcs "udp:127.0.0.1:$gcs_port" --duration-s 50 >"$out/onboard.out" 2>"$out/onboard.err" &
onboard_pid=$!
pids+=("$onboard_pid")

gcs_rc=0
wait "$gcs_pid" || gcs_rc=$?
# Both print their summaries on SIGINT; the companion first, while its FC is still there.
kill -INT "$onboard_pid" 2>/dev/null || true
onboard_rc=0
wait "$onboard_pid" || onboard_rc=$?
kill -INT "$sim_pid" 2>/dev/null || true
wait "$sim_pid" || true

echo "== node-mavlink GCS"
cat "$out/gcs.out"
echo "== hq-onboard (GCS lines)"
grep -E "GCS|MAVLink messages|flight controller|velocity to the FC|FC clock" "$out/onboard.out" || true
echo "== hq-sim --sitl (MAVLink lines)"
grep -E "mavlink:|GCS heartbeats|vision: ODOMETRY" "$out/sim.out" || true

failures=0
check() {  # check DESCRIPTION COMMAND...
  if ! "${@:2}"; then
    echo "FAILED: $1" >&2
    failures=$((failures + 1))
  fi
}
number() { sed -n "s/.*$1 \([0-9][0-9]*\).*/\1/p" "$2" | tail -1; }
check "the node GCS passed (exit $gcs_rc)" test "$gcs_rc" -eq 0
check "hq-onboard ended cleanly on SIGINT (exit $onboard_rc)" test "$onboard_rc" -eq 0
check "hq-onboard heard the GCS's heartbeat" grep -q "GCS heard: system 255, component 190" \
  "$out/onboard.err"
check "the FC's frames reached the GCS" test "$(number 'FC -> GCS' "$out/onboard.out")" -gt 0
check "the GCS's frames reached the FC" test "$(number 'GCS -> FC' "$out/onboard.out")" -gt 0
check "the FC heard the GCS's heartbeats" test "$(number 'GCS heartbeats' "$out/sim.out")" -ge 3
check "the FC set one parameter" grep -q "parameters sent [0-9]*, set 1," "$out/sim.out"
check "the FC fused the companion's ODOMETRY beside the GCS" \
  test "$(number 'ODOMETRY received [0-9]*, fused' "$out/sim.out")" -gt 0
check "the FC answered the companion's TIMESYNC" \
  test "$(number 'TIMESYNC answered' "$out/sim.out")" -gt 0
check "hq-onboard's routing dropped nothing" \
  grep -q "no route 0, target on its own link 0, loop 0, malformed 0" "$out/onboard.out"
if [ "$failures" -ne 0 ]; then
  keep=1
  echo "gcs_process_test: $failures failures; logs in $out" >&2
  exit 1
fi
echo "gcs_process_test: passed"
