#!/usr/bin/env bash
# hq-ground --record as a process against a simulated vehicle (hq-sim-flight --link),
# its flight.mcap read by independent readers (check_flight.cjs: @mcap/core,
# @foxglove/omgidl-parser, @foxglove/omgidl-serialization from npm): a flight that ends normally
# (counts and stamps as hq-ground reports them), one killed with SIGKILL (still readable,
# at most about the last second lost), and one into a folder whose flight.mcap exists (told,
# not overwritten, the flight goes on).
# The project's own reader (hq-mcap-read) reads both files too, the killed one by recovery; the
# killed one is reported by hq-report (replay's reader) and rewritten by hq-report --recover into
# a complete file that @mcap/core reads through its summary and indexes.
# Usage: flight_mcap.sh HQ_ONBOARD HQ_GROUND HQ_MCAP_READ WORK_DIR HQ_REPORT   (run from the
# repository root; WORK_DIR holds node_modules). Exit 77 (ctest: skipped) when node, npm or the packages are unavailable.
set -euo pipefail
onboard=$1
ground=$2
mcap_read=$3
work=$4
report=$5

here=$(cd "$(dirname "$0")" && pwd)
source "$here/../../../scripts/lib.sh"
hq_npm_checkers "$work" '@mcap/core@2' '@mcap/support@1' '@foxglove/omgidl-parser@1' \
  '@foxglove/omgidl-serialization@1'
work=$(cd "$work" && pwd)
echo "node $(node --version), @mcap/core $(hq_npm_version "$work" @mcap/core)," \
     "@foxglove/omgidl-serialization $(hq_npm_version "$work" @foxglove/omgidl-serialization)"

# Loopback only, in a domain of this run's own.
hq_loopback_dds
domain=$((1 + $$ % 200))
tmp=$(mktemp -d)
vehicle_pid=""
cleanup() {
  if [ -n "$vehicle_pid" ]; then kill "$vehicle_pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT

"$onboard" --link --world onboard/sim/worlds/arena.yaml --duration-s 14 \
           --domain-id "$domain" --insecure >"$tmp/onboard.out" 2>&1 &
vehicle_pid=$!
ground_args=(--device sim --headless --haptics-config ground/config/demo_hand.yaml
             --domain-id "$domain" --insecure)

# A flight that ends normally.
"$ground" "${ground_args[@]}" --duration-s 4 --record "$tmp/flight" >"$tmp/ground.out" \
          2>"$tmp/ground.err" || { cat "$tmp/ground.err"; exit 1; }
grep -E '^  mcap ' "$tmp/ground.out"
node "$here/check_flight.cjs" "$work/node_modules" "$tmp/flight/flight.mcap" "$tmp/ground.out"
"$mcap_read" "$tmp/flight/flight.mcap" | tee "$tmp/read.out"
grep -q ' channels, summary,' "$tmp/read.out"

# A flight whose ground station is killed with SIGKILL.
"$ground" "${ground_args[@]}" --duration-s 60 --record "$tmp/killed" >"$tmp/killed.out" \
          2>"$tmp/killed.err" &
ground_pid=$!
sleep 3.5
kill -KILL "$ground_pid"
kill_ns=$(date +%s%N)
wait "$ground_pid" 2>/dev/null || true
ls -l "$tmp/killed/flight.mcap"
node "$here/check_flight.cjs" "$work/node_modules" "$tmp/killed/flight.mcap" --killed "$kill_ns"
"$mcap_read" "$tmp/killed/flight.mcap" | tee "$tmp/read.out"
grep -q 'no summary (recovered)' "$tmp/read.out"
# hq-report reads it as replay does, and --recover makes it whole: same messages, with a summary.
if command -v gnuplot >/dev/null; then
  "$report" "$tmp/killed/flight.mcap" --out "$tmp/killed-report" >"$tmp/report.out" 2>&1 ||
    { cat "$tmp/report.out"; exit 1; }
  grep -q 'no summary (the recorder was killed?)' "$tmp/killed-report/report.md"
fi
"$report" --recover "$tmp/killed/flight.mcap" "$tmp/recovered.mcap" | tee "$tmp/recover.out"
grep -q 'no summary (writer killed?), recovered by scanning' "$tmp/recover.out"
recovered=$(sed -n 's/^  messages *\([0-9]*\) recovered.*/\1/p' "$tmp/recover.out")
"$mcap_read" "$tmp/recovered.mcap" | tee "$tmp/read-recovered.out"
grep -q ": $recovered messages, [0-9]* channels, summary," "$tmp/read-recovered.out" ||
  { echo "recovered.mcap: expected $recovered messages with a summary"; exit 1; }
node "$here/check_flight.cjs" "$work/node_modules" "$tmp/recovered.mcap" --recovered "$kill_ns"
# A flight.mcap already there: never overwritten; told, and the flight goes on (exit 0).
mkdir -p "$tmp/taken"
echo "an earlier flight" >"$tmp/taken/flight.mcap"
"$ground" "${ground_args[@]}" --duration-s 1.5 --record "$tmp/taken" >"$tmp/taken.out" \
          2>"$tmp/taken.err" || { cat "$tmp/taken.err"; exit 1; }
grep 'mcap recording off: .*flight.mcap: exists' "$tmp/taken.err"
grep -q 'an earlier flight' "$tmp/taken/flight.mcap"
grep -qE '^  sent +[1-9][0-9]* commands' "$tmp/taken.out"
echo "flight.mcap read by @mcap/core and decoded with @foxglove/omgidl-serialization: passed"
