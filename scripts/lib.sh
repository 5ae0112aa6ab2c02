# Shared by scripts/run and scripts/test: install Debian packages, configure and build.
# Sourced, not run. Honours BUILD_DIR (default build) and CI (adds -Werror).
set -euo pipefail

HQ_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD_DIR=${BUILD_DIR:-$HQ_ROOT/build}

# Every Debian 12 package the build and tests need. Nothing is downloaded at build time.
# strace and systemd (systemd-analyze) serve tests/install: no program reads the source tree,
# and hq-onboard.service verifies; help2man writes the man pages from --help, man-db reads them.
HQ_PACKAGES=(
  cmake ninja-build g++ pkg-config
  libeigen3-dev libopencv-dev libopencv-contrib-dev libyaml-cpp-dev libcli11-dev
  libgtest-dev libgmock-dev libzstd-dev nlohmann-json3-dev libfmt-dev
  cyclonedds-dev cyclonedds-tools libpcl-dev libvisp-dev libceres-dev
  libfreenect-dev libfreenect-bin libopenni2-dev libsdl2-dev libimgui-dev
  xvfb xauth libgl1-mesa-dri gnuplot valgrind libbenchmark-dev dpkg-dev
  openssl libssl-dev
  strace systemd help2man man-db
  clang-format clang-tidy
)

hq_install() {
  local missing=()
  for p in "${HQ_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    echo "== installing: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
      "${missing[@]}" >/dev/null
  fi
}

# Node.js and npm run the independent checkers of the tests (node-mavlink, @mcap/core), which the
# test scripts install into the build tree. Best effort: without them those tests report SKIPPED.
hq_install_checkers() {
  if command -v node >/dev/null && command -v npm >/dev/null; then return 0; fi
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  echo "== installing: nodejs npm (independent checkers of the tests)"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends nodejs npm \
    >/dev/null 2>&1 || echo "== nodejs/npm unavailable: the npm-checked tests will report SKIPPED" >&2
}

hq_build() {
  local werror=OFF ci=()
  # CI: warnings are errors, and the strict set (cmake/HqWarnings.cmake) is on even in a build
  # folder whose cache predates its default.
  [ "${CI:-}" = "true" ] && werror=ON ci=(-DHQ_STRICT_WARNINGS=ON)
  cmake -S "$HQ_ROOT" -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHQ_WERROR=$werror \
    "${ci[@]}" "$@" >/dev/null
  cmake --build "$BUILD_DIR" -j "$(nproc)"
}

# Cyclone DDS on the loopback interface only, for the demos and test scripts that run both ends
# of the link on this machine: no other DDS process on the network sees (or commands) them.
hq_loopback_dds() {
  export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces></General></Domain></CycloneDDS>'
}

# hq_npm_checkers WORK_DIR PACKAGE@VERSION...: the npm packages a test script's independent
# checker needs, installed into WORK_DIR/node_modules (in the build tree) unless all are there.
# Without node or npm, or when the install fails, prints "SKIPPED: <reason>" and exits 77
# (ctest: skipped), so a test script calls it before doing anything else.
hq_npm_checkers() {
  local work=$1
  shift
  command -v node >/dev/null || { echo "SKIPPED: node is not installed"; exit 77; }
  command -v npm >/dev/null || { echo "SKIPPED: npm is not installed"; exit 77; }
  mkdir -p "$work"
  local spec name missing=0
  for spec in "$@"; do
    name=${spec%@*}  # @mcap/core@2 -> @mcap/core, node-mavlink@2 -> node-mavlink
    [ -f "$work/node_modules/$name/package.json" ] || missing=1
  done
  [ "$missing" -eq 0 ] && return 0
  if ! npm install --no-audit --no-fund --prefix "$work" "$@" >"$work/npm-install.log" 2>&1; then
    echo "SKIPPED: npm install $* failed (see $work/npm-install.log)"
    tail -5 "$work/npm-install.log"
    exit 77
  fi
}

# hq_npm_version WORK_DIR PACKAGE: the installed version of PACKAGE, for the scripts' first line.
hq_npm_version() {
  node -p "require('$1/node_modules/$2/package.json').version"
}
