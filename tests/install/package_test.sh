#!/usr/bin/env bash
# Builds the three .deb files with CPack and checks them as Debian policy and an operator would:
#   haptiquad-vehicle  hq-onboard, hq-keys, hq-onboard.service with its conffiles in /etc/haptiquad,
#                      and no GUI library among its Depends (SDL, GL, VTK, ImGui, X11, GTK, Qt)
#                      nor among what its programs load (ldd), but for what two Debian
#                      libraries it needs bring unavoidably (libopencv_core, libvisp_detection)
#   haptiquad-station  hq-ground, hq-report, the simulator and the tools
#   haptiquad-data     config/, calib/, README and docs
# each with /usr/share/doc/<package>/copyright (DEP-5) and changelog.Debian.gz, stripped
# programs, a man page and a bash completion per program. Every program of the extracted
# packages answers --version and --help, and `man -l` renders its page.
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
fail() { echo "FAIL: $*"; exit 1; }
deb_of() { ls "$tmp"/"$1"_*.deb 2>/dev/null || fail "no $1 package made"; }
vehicle=$(deb_of haptiquad-vehicle)
station=$(deb_of haptiquad-station)
data=$(deb_of haptiquad-data)

has() {  # has DEB PATH...
  local deb=$1 contents
  shift
  contents=$(dpkg-deb -c "$deb")
  for path in "$@"; do
    grep -q " $path\$" <<<"$contents" || fail "$path not in $(basename "$deb")"
  done
}
lacks() {  # lacks DEB PATH...
  local deb=$1 contents
  shift
  contents=$(dpkg-deb -c "$deb")
  for path in "$@"; do
    if grep -q " $path\$" <<<"$contents"; then fail "$path in $(basename "$deb")"; fi
  done
}
vehicle_programs=(hq-onboard hq-keys)
station_programs=(hq-ground hq-report hq-sim hq-sim-flight hq-odometry hq-record hq-evaluate
  hq-velocity-eval)
for program in "${vehicle_programs[@]}"; do
  has "$vehicle" ./usr/bin/$program ./usr/share/man/man1/$program.1.gz \
    ./usr/share/bash-completion/completions/$program
done
for program in "${station_programs[@]}"; do
  has "$station" ./usr/bin/$program ./usr/share/man/man1/$program.1.gz \
    ./usr/share/bash-completion/completions/$program
done
lacks "$vehicle" ./usr/bin/hq-ground ./usr/bin/hq-sim ./usr/bin/hq-sim-flight
has "$data" ./usr/share/haptiquad/config/onboard.yaml ./usr/share/haptiquad/calib/kinect_v1.yaml \
  ./usr/share/doc/haptiquad-data/README.md ./usr/share/doc/haptiquad-data/docs/vehicle-integration.md
has "$station" ./usr/share/haptiquad/onboard/sim/worlds/arena.yaml \
  ./usr/share/haptiquad/onboard/sim/config/sim.yaml ./usr/share/haptiquad/ground/config/core_paper_hand.yaml
for deb in "$vehicle" "$station" "$data"; do
  package=$(dpkg-deb -f "$deb" Package)
  has "$deb" ./usr/share/doc/$package/copyright ./usr/share/doc/$package/changelog.Debian.gz
done

# hq-onboard.service in Debian 12's places, the operator's files in /etc as conffiles, the user
# made by postinst; the service is neither enabled nor started by the package.
has "$vehicle" ./lib/systemd/system/hq-onboard.service ./usr/lib/sysusers.d/haptiquad.conf \
  ./etc/haptiquad/onboard.env ./etc/haptiquad/onboard.yaml ./etc/haptiquad/vehicle.yaml
mkdir "$tmp/control" "$tmp/root"
dpkg-deb -e "$vehicle" "$tmp/control"
for deb in "$vehicle" "$station" "$data"; do dpkg-deb -x "$deb" "$tmp/root"; done
root=$tmp/root
for conffile in /etc/haptiquad/onboard.env /etc/haptiquad/onboard.yaml /etc/haptiquad/vehicle.yaml; do
  grep -qx "$conffile" "$tmp/control/conffiles" || fail "$conffile is no conffile"
done
[ -x "$tmp/control/postinst" ] || fail "no executable postinst"
if grep -Eq "systemctl (enable|start)|deb-systemd-helper" "$tmp/control/postinst"; then
  fail "postinst enables or starts the service"
fi
unit=$root/lib/systemd/system/hq-onboard.service
grep -qx 'ExecStart=/usr/bin/hq-onboard --duration-s 0 $HQ_ONBOARD_ARGS' "$unit" || {
  grep -n ExecStart "$unit"; fail "the unit does not start /usr/bin/hq-onboard"; }
grep -qx "EnvironmentFile=/etc/haptiquad/onboard.env" "$unit" ||
  fail "the unit's EnvironmentFile is not /etc/haptiquad/onboard.env"
grep -q -- "--config /etc/haptiquad/onboard.yaml --vehicle /etc/haptiquad/vehicle.yaml" \
  "$root/etc/haptiquad/onboard.env" || fail "onboard.env misses /etc/haptiquad"
if command -v systemd-analyze >/dev/null; then
  # The packaged unit as it is but for its program's path, which is this extracted package's
  # (verify checks that the program exists and runs on the host's paths).
  sed "s|^ExecStart=/usr/bin/|ExecStart=$root/usr/bin/|" "$unit" >"$tmp/hq-onboard.service"
  verify=$(systemd-analyze verify "$tmp/hq-onboard.service" 2>&1) || {
    echo "$verify"; fail "systemd-analyze verify on the packaged unit"; }
  [ -z "$verify" ] || { echo "$verify"; fail "systemd-analyze verify warns"; }
fi
grep -q "^Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/" \
  "$root/usr/share/doc/haptiquad-vehicle/copyright" || fail "copyright is not DEP-5"
changelog=$(gzip -dc "$root/usr/share/doc/haptiquad-vehicle/changelog.Debian.gz")
grep -q "^haptiquad-vehicle (" <<<"$(head -1 <<<"$changelog")" ||
  fail "changelog.Debian names another package"

# The programs as installed: stripped, --version and --help answer (exit 0), the man page renders.
for program in "${vehicle_programs[@]}" "${station_programs[@]}"; do
  exe=$root/usr/bin/$program
  if file "$exe" | grep -q "not stripped"; then fail "$program is not stripped"; fi
  version=$("$exe" --version) || fail "$program --version exits $?"
  grep -Eq "^$program [0-9]+\.[0-9]+\.[0-9]+" <<<"$version" || fail "$program --version: $version"
  # Held whole before grep: `--help | grep -q` under pipefail fails when grep stops reading at
  # its match and the program, still writing its help, dies of SIGPIPE.
  help=$("$exe" --help) || fail "$program --help exits $?"
  grep -q -- "--verbose" <<<"$help" || fail "$program --help lists no --verbose"
  page=$(MANWIDTH=80 man -l "$root/usr/share/man/man1/$program.1.gz" 2>&1) ||
    fail "man -l $program: $page"
  grep -q -- "--quiet" <<<"$page" || fail "$program's man page lacks its options"
  bash -n "$root/usr/share/bash-completion/completions/$program" || fail "$program's completion"
done

# No GUI library for the companion computer: none among its Depends.
depends=$(dpkg-deb -f "$vehicle" Depends)
if grep -Eio "libsdl2[^,]*|libgl[0-9a-z-]*|libvtk[^,]*|libimgui[^,]*|libx11[^,]*|libgtk[^,]*|libqt[^,]*|libglfw[^,]*" \
    <<<"$depends"; then
  fail "haptiquad-vehicle depends on a GUI library: $depends"
fi
# Nor among what its installed programs load (ldd: every library, not only the direct ones), so
# the day a GUI library is linked back in, through a component or a library of ours, this fails.
# Two Debian libraries the vehicle needs bring some unavoidably, and only those are let through:
#   libopencv_core     built with OpenGL interop: GLX, GLdispatch, X11, xcb, Xau, Xdmcp
#   libvisp_detection  the AprilTag detector; it needs visp_vision -> visp_io -> opencv_videoio
#                      -> FFmpeg: VA-API and VDPAU with their X11 and xcb, cairo and pango
#                      (through librsvg), but no toolkit, GL or VTK
# Anything else that matches is ours to cut (pcl_io brought 29 VTK libraries, for instance).
gui_libraries='libvtk|libGL|libEGL|libOpenGL|libX|libxcb|libwayland|libQt|libgtk|libgdk|libSDL|libglfw|libimgui|opencv_highgui|opencv_viz|visp_gui|visp_ar|libcairo|libpango|libva|libvdpau|libdrm|libgbm'
unavoidable_via=(libopencv_core libvisp_detection)
loaded_gui() {  # loaded_gui LDD_OUTPUT: the GUI libraries' names, one a line
  awk '{print $1}' <<<"$1" | grep -E "$gui_libraries" | sort -u || true
}
for program in "${vehicle_programs[@]}"; do
  loaded=$(ldd "$root/usr/bin/$program") || fail "ldd $program: $loaded"
  grep -q "not found" <<<"$loaded" && { echo "$loaded"; fail "$program misses a library"; }
  allowed=""
  for via in "${unavoidable_via[@]}"; do
    path=$(awk -v via="$via" 'index($1, via ".so") == 1 {print $3}' <<<"$loaded")
    [ -n "$path" ] && allowed+=$(loaded_gui "$(ldd "$path")")$'\n'
  done
  extra=$(comm -23 <(loaded_gui "$loaded") <(grep -v '^$' <<<"$allowed" | sort -u))
  if [ -n "$extra" ]; then
    echo "$program loads GUI libraries that no unavoidable Debian library brings:"
    echo "$extra"
    # Which of the program's direct libraries brings each one, to say where to cut.
    for needed in $(objdump -p "$root/usr/bin/$program" | awk '/NEEDED/ {print $2}'); do
      path=$(awk -v lib="$needed" '$1 == lib {print $3}' <<<"$loaded")
      [ -z "$path" ] && continue
      brings=$(comm -12 <(loaded_gui "$(ldd "$path")
$needed") <(echo "$extra") | tr '\n' ' ')
      [ -n "$brings" ] && echo "  through $needed: $brings"
    done
    fail "$program loads a GUI library"
  fi
  echo "$program loads $(wc -l <<<"$loaded") libraries, $(loaded_gui "$loaded" | grep -c .) of" \
    "them from Debian's X11/GL/FFmpeg stack through ${unavoidable_via[*]}"
done
for library in libddsc0debian libopencv-core libfmt9 haptiquad-data; do
  grep -q "$library" <<<"$depends" || fail "haptiquad-vehicle's Depends lacks $library: $depends"
done
for deb in "$vehicle" "$station" "$data"; do
  echo "$(basename "$deb"): $(stat -c %s "$deb") bytes; Depends: $(dpkg-deb -f "$deb" Depends)"
done
echo "PASS: three packages, $(( ${#vehicle_programs[@]} + ${#station_programs[@]} )) programs"
