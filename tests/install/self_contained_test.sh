#!/usr/bin/env bash
# The installed programs do their main jobs without the source tree or the build tree: installs
# into a temporary prefix, runs each program from an empty folder under strace, and fails if any
# of them so much as looks up a path inside the source or the build tree (a config, a world, a
# calibration file, a library, a program). A file a program reads by default that is not
# installed shows up here, not on a vehicle that has no source tree.
#
# strace, rather than hiding the trees behind an empty bind mount: it needs no mount namespace
# (unavailable in most containers), and it names the file, where a hidden tree would only make a
# program fail somewhere later, or not at all when a fallback exists.
#   self_contained_test.sh BUILD_DIR CMAKE_COMMAND SOURCE_DIR
set -euo pipefail
build=$(realpath "$1")
cmake=$2
source_dir=$(realpath "$3")

if ! command -v strace >/dev/null; then
  echo "SKIPPED: strace is not installed (Debian package strace)"
  exit 0
fi
# Containers may forbid ptrace (seccomp, no CAP_SYS_PTRACE): then nothing can be traced.
if ! strace -f -qq -e trace=%file -o /dev/null true 2>/dev/null; then
  echo "SKIPPED: strace cannot trace here (ptrace not permitted): $(strace true 2>&1 | head -1)"
  exit 0
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
"$cmake" --install "$build" --prefix "$prefix" >/dev/null
mkdir "$tmp/run"
cd "$tmp/run"
# Nothing points the programs at the trees but what they carry themselves.
unset HQ_DATA_DIRS
# Cyclone DDS on loopback only: the link of hq-ground's run is nobody else's business.
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces></General></Domain></CycloneDDS>'

failures=0
fail() {
  echo "FAIL: $*"
  failures=$((failures + 1))
}

# traced NAME EXPECTED_STATUS PROGRAM ARGS...: runs an installed program under strace from the
# empty folder, checks its exit status, and that no path it touched is in either tree.
traced() {
  local name=$1 expected=$2 program=$3
  shift 3
  local trace=$tmp/$name.trace out=$tmp/$name.out status=0
  strace -f -qq --seccomp-bpf -e trace=%file -o "$trace" "$prefix/bin/$program" "$@" \
    >"$out" 2>&1 || status=$?
  if [ "$status" -ne "$expected" ]; then
    tail -20 "$out"
    fail "$name: $program $* exited $status, expected $expected"
  fi
  # A path is printed in full and quoted; the tree itself or anything below it counts.
  local touched
  touched=$(grep -F -e "\"$source_dir/" -e "\"$source_dir\"" -e "\"$build/" -e "\"$build\"" \
    "$trace" || true)
  if [ -n "$touched" ]; then
    echo "$touched" | head -20
    fail "$name: $program looked into the source tree $source_dir or the build tree $build" \
      "($(echo "$touched" | wc -l) system calls, the first above)"
  else
    echo "ok: $name ($program $*): nothing read from the source or build tree"
  fi
}

# Every program's help: nothing is read before the options are understood.
for program in "$prefix"/bin/*; do
  traced "help-$(basename "$program")" 0 "$(basename "$program")" --help
done

# The simulator, a short scripted flight with its default config (onboard/sim/config/sim.yaml)
# and the installed world.
traced hq-sim 0 hq-sim --world onboard/sim/worlds/arena.yaml --duration-s 2
# The on-board chain in closed loop with every default file: config, vehicle, simulator config.
cat >hop.yaml <<'EOF'
# Take off, hover, land: a short flight on the defaults.
frame: camera_heading
end_s: 8
steps:
  - {t_s: 0.0, mode: teleop, v_mps: [0, 0, 0]}
  - {t_s: 1.0, v_mps: [0, 0, -0.4]}
  - {t_s: 3.0, v_mps: [0, 0, 0]}
  - {t_s: 5.0, mode: land}
EOF
traced hq-sim-flight 0 hq-sim-flight --world onboard/sim/worlds/arena.yaml --script hop.yaml
grep -q "hq-sim-flight: config $prefix/share/haptiquad/config/onboard.yaml" "$tmp/hq-sim-flight.out" ||
  fail "hq-sim-flight: the config did not come from $prefix/share/haptiquad"

# The vehicle's program on a real recording, with the shipped camera file and every default.
data_root=${HQ_DATA_DIR:-$source_dir/../shared/data}
sequence=$data_root/tum/rgbd_dataset_freiburg1_xyz
if [ -f "$sequence/rgb.txt" ]; then
  # Without "..": the name must not start with the source tree's when the data is beside it.
  sequence=$(realpath "$sequence")
  traced hq-onboard 0 hq-onboard --source replay "$sequence" --camera calib/tum_fr1.yaml
  grep -q "hq-onboard: config $prefix/share/haptiquad/config/onboard.yaml" "$tmp/hq-onboard.out" ||
    fail "hq-onboard: the config did not come from $prefix/share/haptiquad"
else
  echo "hq-onboard replay not run: no $sequence (set HQ_DATA_DIR); the rest still counts"
fi

# Keys for a secured link, then the operator's station headless with its default haptics config
# and vehicle file for a moment (no vehicle: it only has to start, run and stop cleanly).
traced hq-keys-init 0 hq-keys init keys
traced hq-keys-vehicle 0 hq-keys identity keys --role vehicle --id 1
traced hq-keys-station 0 hq-keys identity keys --role station --id 1 --vehicles 1
traced hq-keys-check 0 hq-keys check keys --identity station_1 --peer vehicle_1
traced hq-ground 0 hq-ground --device sim --headless --duration-s 1 --insecure

# A file that exists nowhere is named with every folder looked in, none of them a tree.
traced missing-world 2 hq-sim --world worlds/none.yaml --duration-s 1
grep -q "worlds/none.yaml: file not found (looked in the current folder, $prefix/share/haptiquad)" \
  "$tmp/missing-world.out" || {
  cat "$tmp/missing-world.out"
  fail "the missing world was not named with exactly the folders looked in"
}

if [ "$failures" -gt 0 ]; then
  echo "FAIL: $failures check(s) failed"
  exit 1
fi
echo "every installed program ran from $tmp/run without the source tree or the build tree"
