#!/usr/bin/env bash
# Every program: --version and --help exit 0 on stdout, an unknown option exits 2 with a message
# naming the program on stderr (CLI11 alone exits 109), and hq-ground refuses the vehicle's
# options (--ros2, --stations) instead of ignoring them.
#   usage_test.sh BIN_DIR PROGRAM...
set -euo pipefail
bin=$1
shift
failures=0
check() {  # check DESCRIPTION EXPECTED_STATUS COMMAND...
  local what=$1 expected=$2 status=0
  shift 2
  "$@" >/tmp/usage_test.$$.out 2>/tmp/usage_test.$$.err || status=$?
  if [ "$status" -ne "$expected" ]; then
    echo "FAIL: $what exits $status, expected $expected: $(head -c 300 /tmp/usage_test.$$.err)"
    failures=$((failures + 1))
  fi
}
for program in "$@"; do
  exe=$bin/$program
  check "$program --version" 0 "$exe" --version
  grep -q "^$program " /tmp/usage_test.$$.out || {
    echo "FAIL: $program --version printed: $(cat /tmp/usage_test.$$.out)"; failures=$((failures + 1)); }
  check "$program --help" 0 "$exe" --help
  check "$program --no-such-option" 2 "$exe" --no-such-option
  grep -q "^$program: " /tmp/usage_test.$$.err || {
    echo "FAIL: $program's usage error does not name it: $(cat /tmp/usage_test.$$.err)"
    failures=$((failures + 1)); }
  check "$program --quiet --verbose" 2 "$exe" --quiet --verbose
done
for option in --ros2 "--stations 1"; do
  # shellcheck disable=SC2086
  check "hq-ground $option" 2 "$bin/hq-ground" $option --headless --duration-s 0.1
done
rm -f /tmp/usage_test.$$.out /tmp/usage_test.$$.err
total=$(($# * 4 + 2))
echo "$((total - failures)) passed, $failures failed"
[ "$failures" -eq 0 ]
