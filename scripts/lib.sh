# Shared by scripts/run and scripts/test: install Debian packages, configure and build.
# Sourced, not run. Honours BUILD_DIR (default build) and CI (adds -Werror).
set -euo pipefail

HQ_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD_DIR=${BUILD_DIR:-$HQ_ROOT/build}

# Every Debian 12 package the build and tests need. Nothing is downloaded at build time.
HQ_PACKAGES=(
  cmake ninja-build g++ pkg-config
  libeigen3-dev libopencv-dev libopencv-contrib-dev libyaml-cpp-dev libcli11-dev
  libgtest-dev libgmock-dev libzstd-dev
  cyclonedds-dev cyclonedds-tools libpcl-dev libvisp-dev libceres-dev
  libfreenect-dev libfreenect-bin libopenni2-dev libsdl2-dev libimgui-dev
  xvfb xauth libgl1-mesa-dri gnuplot valgrind libbenchmark-dev dpkg-dev
  openssl libssl-dev
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
