#!/usr/bin/env bash
# Builds the .deb with CPack and checks what it holds and what it depends on: the programs in
# /usr/bin, the shipped files in /usr/share/haptiquad, and Debian's Cyclone DDS, OpenCV and fmt
# libraries found by dpkg-shlibdeps.
#   package_test.sh BUILD_DIR CPACK_COMMAND
set -euo pipefail
build=$1
cpack=$2
if ! command -v dpkg-shlibdeps >/dev/null || ! command -v dpkg-deb >/dev/null; then
  echo "SKIPPED: dpkg-shlibdeps/dpkg-deb not installed (Debian package dpkg-dev)"
  exit 0
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && "$cpack" --config "$build/CPackConfig.cmake" -B "$tmp" >"$tmp/cpack.log" 2>&1) || {
  cat "$tmp/cpack.log"; echo "FAIL: cpack"; exit 1; }
deb=$(ls "$tmp"/haptiquad_*.deb)
contents=$(dpkg-deb -c "$deb")
for path in ./usr/bin/hq-onboard ./usr/bin/hq-ground ./usr/bin/hq-sim \
    ./usr/share/haptiquad/config/onboard.yaml ./usr/share/haptiquad/calib/kinect_v1.yaml \
    ./usr/share/haptiquad/onboard/sim/worlds/arena.yaml; do
  grep -q " $path\$" <<<"$contents" || { echo "FAIL: $path not in $(basename "$deb")"; exit 1; }
done
depends=$(dpkg-deb -f "$deb" Depends)
for library in libddsc0debian libopencv-core libfmt9; do
  grep -q "$library" <<<"$depends" || { echo "FAIL: Depends lacks $library: $depends"; exit 1; }
done
echo "$(basename "$deb"): $(stat -c %s "$deb") bytes; Depends: $depends"
