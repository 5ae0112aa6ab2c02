#!/usr/bin/env bash
# Builds the .deb with CPack and checks what it holds and what it depends on: the programs in
# /usr/bin, the shipped files in /usr/share/haptiquad, hq-onboard.service with its conffiles in
# /etc/haptiquad, and Debian's Cyclone DDS, OpenCV and fmt libraries found by dpkg-shlibdeps.
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
# hq-onboard.service in Debian 12's places, the operator's files in /etc as conffiles, the user
# made by postinst; the service is neither enabled nor started by the package.
for path in ./lib/systemd/system/hq-onboard.service ./usr/lib/sysusers.d/haptiquad.conf \
    ./etc/haptiquad/onboard.env ./etc/haptiquad/onboard.yaml ./etc/haptiquad/vehicle.yaml \
    ./usr/share/haptiquad/onboard/sim/config/sim.yaml; do
  grep -q " $path\$" <<<"$contents" || { echo "FAIL: $path not in $(basename "$deb")"; exit 1; }
done
mkdir "$tmp/control" "$tmp/root"
dpkg-deb -e "$deb" "$tmp/control"
dpkg-deb -x "$deb" "$tmp/root"
for conffile in /etc/haptiquad/onboard.env /etc/haptiquad/onboard.yaml /etc/haptiquad/vehicle.yaml; do
  grep -qx "$conffile" "$tmp/control/conffiles" || { echo "FAIL: $conffile is no conffile"; exit 1; }
done
[ -x "$tmp/control/postinst" ] || { echo "FAIL: no executable postinst"; exit 1; }
if grep -Eq "systemctl (enable|start)|deb-systemd-helper" "$tmp/control/postinst"; then
  echo "FAIL: postinst enables or starts the service"; exit 1
fi
unit=$tmp/root/lib/systemd/system/hq-onboard.service
grep -qx 'ExecStart=/usr/bin/hq-onboard --duration-s 0 $HQ_ONBOARD_ARGS' "$unit" || {
  grep -n ExecStart "$unit"; echo "FAIL: the unit does not start /usr/bin/hq-onboard"; exit 1; }
grep -qx "EnvironmentFile=/etc/haptiquad/onboard.env" "$unit" || {
  echo "FAIL: the unit's EnvironmentFile is not /etc/haptiquad/onboard.env"; exit 1; }
grep -q -- "--config /etc/haptiquad/onboard.yaml --vehicle /etc/haptiquad/vehicle.yaml" \
  "$tmp/root/etc/haptiquad/onboard.env" || { echo "FAIL: onboard.env misses /etc/haptiquad"; exit 1; }
if command -v systemd-analyze >/dev/null; then
  # The packaged unit as it is but for its program's path, which is this extracted package's
  # (verify checks that the program exists and runs on the host's paths).
  sed "s|^ExecStart=/usr/bin/|ExecStart=$tmp/root/usr/bin/|" "$unit" >"$tmp/hq-onboard.service"
  verify=$(systemd-analyze verify "$tmp/hq-onboard.service" 2>&1) || {
    echo "$verify"; echo "FAIL: systemd-analyze verify on the packaged unit"; exit 1; }
  [ -z "$verify" ] || { echo "$verify"; echo "FAIL: systemd-analyze verify warns"; exit 1; }
fi

depends=$(dpkg-deb -f "$deb" Depends)
for library in libddsc0debian libopencv-core libfmt9; do
  grep -q "$library" <<<"$depends" || { echo "FAIL: Depends lacks $library: $depends"; exit 1; }
done
echo "$(basename "$deb"): $(stat -c %s "$deb") bytes; Depends: $depends"
