#!/usr/bin/env bash
# Writes a program's man page (help2man, from its --help and --version) and its bash completion
# (the long options its --help lists), for the packages (cmake/HqInstall.cmake).
#   hq-program-docs.sh PROGRAM_PATH "ONE-LINE DESCRIPTION" MAN_DIR COMPLETION_DIR
set -euo pipefail
program=$1 description=$2 man_dir=$3 completion_dir=$4
name=$(basename "$program")
mkdir -p "$man_dir" "$completion_dir"
if command -v help2man >/dev/null; then
  help2man --no-info --no-discard-stderr --section 1 --name "$description" \
    --output "$man_dir/$name.1" "$program"
  gzip -9nf "$man_dir/$name.1"
fi
options=$("$program" --help | grep -oE -- '(^|[ ,])--[a-z0-9][a-z0-9-]*' | sed 's/^[ ,]*//' |
  sort -u | tr '\n' ' ')
function=_$(tr -c 'a-z0-9\n' '_' <<<"$name")
cat >"$completion_dir/$name" <<COMPLETION
# bash completion for $name (generated from its --help by cmake/hq-program-docs.sh)
$function() {
  local cur=\${COMP_WORDS[COMP_CWORD]}
  if [[ \$cur == -* ]]; then
    mapfile -t COMPREPLY < <(compgen -W "$options" -- "\$cur")
  else
    mapfile -t COMPREPLY < <(compgen -f -- "\$cur")
  fi
}
complete -o filenames -F $function $name
COMPLETION
