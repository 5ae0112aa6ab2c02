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
