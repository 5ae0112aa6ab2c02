#!/usr/bin/env bash
# Installs the build into a temporary prefix and runs the main job's flight from an empty folder
# elsewhere: the programs must find their shipped files (config/, calib/, worlds, flights) in
# <prefix>/share/haptiquad, not in the source tree or the current folder.
#   install_test.sh BUILD_DIR CMAKE_COMMAND
set -euo pipefail
build=$1
cmake=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix

"$cmake" --install "$build" --prefix "$prefix" >/dev/null
for program in hq-onboard hq-sim-flight hq-ground hq-sim hq-report hq-odometry hq-record hq-evaluate hq-keys; do
  [ -x "$prefix/bin/$program" ] || { echo "FAIL: $program not installed in $prefix/bin"; exit 1; }
done
for file in config/onboard.yaml config/haptics.yaml calib/tum_fr1.yaml \
    onboard/sim/worlds/arena.yaml onboard/closed_loop/flights/core_paper_box.yaml \
    ground/config/core_paper_hand.yaml; do
  [ -f "$prefix/share/haptiquad/$file" ] || { echo "FAIL: $file not installed"; exit 1; }
done

# hq-onboard.service and what it reads, configured for this prefix (the .deb's are checked by
# package_test.sh): a unit systemd accepts, and arguments hq-onboard accepts.
unit=$prefix/lib/systemd/system/hq-onboard.service
for file in "$unit" "$prefix/lib/sysusers.d/haptiquad.conf" "$prefix/etc/haptiquad/onboard.env" \
    "$prefix/etc/haptiquad/onboard.yaml" "$prefix/etc/haptiquad/vehicle.yaml"; do
  [ -f "$file" ] || { echo "FAIL: $file not installed"; exit 1; }
done
grep -qx "ExecStart=$prefix/bin/hq-onboard --duration-s 0 \$HQ_ONBOARD_ARGS" "$unit" || {
  grep -n "ExecStart" "$unit"; echo "FAIL: the unit does not start $prefix/bin/hq-onboard"; exit 1; }
grep -qx "EnvironmentFile=$prefix/etc/haptiquad/onboard.env" "$unit" || {
  echo "FAIL: the unit's EnvironmentFile is not $prefix/etc/haptiquad/onboard.env"; exit 1; }
if command -v systemd-analyze >/dev/null; then
  # verify prints a warning for anything it ignores (unknown keys, bad values) yet may exit 0.
  verify=$(systemd-analyze verify "$unit" 2>&1) || {
    echo "$verify"; echo "FAIL: systemd-analyze verify $unit"; exit 1; }
  [ -z "$verify" ] || { echo "$verify"; echo "FAIL: systemd-analyze verify warns"; exit 1; }
  echo "systemd-analyze verify: hq-onboard.service is clean"
else
  echo "systemd-analyze not installed (Debian package systemd): the unit was not verified"
fi
# The service's arguments as systemd gives them (one word per space). With no camera here the
# run must get past the options, the config and the vehicle file and stop at the camera, with
# the status the unit retries (6), not the one it gives up on (2, bad input).
HQ_ONBOARD_ARGS=$(sed -n 's/^HQ_ONBOARD_ARGS=//p' "$prefix/etc/haptiquad/onboard.env")
[ -n "$HQ_ONBOARD_ARGS" ] || { echo "FAIL: no HQ_ONBOARD_ARGS in onboard.env"; exit 1; }
service_log=$tmp/service.log
status=0
# shellcheck disable=SC2086  # split into words, as systemd splits an unbraced $VAR
(cd "$tmp" && "$prefix/bin/hq-onboard" --duration-s 0 $HQ_ONBOARD_ARGS) >"$service_log" 2>&1 ||
  status=$?
if grep -q "this build has no openni2 support" "$service_log"; then
  echo "the service's arguments were not run: this build has no OpenNI2"
elif [ "$status" -ne 6 ] || ! grep -q "hq-onboard: openni2:<any device>: cannot open" "$service_log"; then
  cat "$service_log"
  echo "FAIL: hq-onboard on onboard.env's arguments exited $status, expected 6 at the camera"
  exit 1
else
  echo "hq-onboard on onboard.env's arguments: config and vehicle file read, stopped at the" \
    "absent camera with status 6"
fi

# Moving the prefix proves the lookup is relative to the executable, not a compiled-in path.
mv "$prefix" "$tmp/moved"
prefix=$tmp/moved
mkdir "$tmp/elsewhere"
cd "$tmp/elsewhere"
log=$tmp/onboard.log
"$prefix/bin/hq-sim-flight" --world onboard/sim/worlds/arena.yaml \
  --script onboard/closed_loop/flights/core_paper_box.yaml --csv fig6-8.csv >"$log" 2>&1 || {
  cat "$log"; echo "FAIL: the installed hq-sim-flight did not fly"; exit 1; }
grep -q "hq-sim-flight: config $prefix/share/haptiquad/config/onboard.yaml" "$log" || {
  cat "$log"; echo "FAIL: the config did not come from the installed share/haptiquad"; exit 1; }
grep -Eq "collision ticks +0$" "$log" || { cat "$log"; echo "FAIL: the flight collided"; exit 1; }
[ -s fig6-8.csv ] || { echo "FAIL: no Fig. 6-8 CSV written in the current folder"; exit 1; }

# A file that exists nowhere is named, with every folder looked in.
if "$prefix/bin/hq-sim-flight" --world worlds/none.yaml \
    --script onboard/closed_loop/flights/core_paper_box.yaml >"$log" 2>&1; then
  echo "FAIL: a missing world was accepted"; exit 1
fi
grep -q "worlds/none.yaml: file not found (looked in the current folder" "$log" || {
  cat "$log"; echo "FAIL: the missing world was not named with the folders looked in"; exit 1; }
echo "installed to a moved prefix; flew the main job from $tmp/elsewhere with its shipped files"
