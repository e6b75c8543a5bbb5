#!/usr/bin/env bash
# The walls of bench/ point one way (docs/architecture.md, "Rooms"): cli -> server -> campaign -> rt.
#   rt/        (bench/src/rt, bench/include/hil/bench/rt) includes nothing from campaign/, server/ or cli/
#   campaign/  (bench/src/campaign, bench/include/hil/bench/campaign) nothing from server/ or cli/
# Lists every offending #include with file:line. Checks the tree at $1 (default: this repository;
# the suite also runs it on tests/style/include_rules_fixture, which breaks each rule once, to see
# that it fails).
set -euo pipefail
if [[ ${1:-} == --self-test ]]; then  # the fixture breaks each rule once: both must be named
  fixture="$(dirname "$0")/include_rules_fixture"
  if out=$("$0" "$fixture"); then
    echo "the fixture's violations passed: $out"
    exit 1
  fi
  for want in 'bench/src/rt/uses_campaign.cpp:2:' 'bench/include/hil/bench/campaign/uses_server.hpp:4:'; do
    grep -qF "$want" <<<"$out" || { echo "not reported: $want"$'\n'"$out"; exit 1; }
  done
  echo "both violations of the fixture reported"
  exit 0
fi
root=${1:-"$(dirname "$0")/../.."}
cd "$root"
status=0
check() {  # check ROOM FORBIDDEN-ROOM... : every #include of the room's files against the rooms it may not use
  local room=$1
  shift
  local dirs=() forbidden
  for d in "bench/src/$room" "bench/include/hil/bench/$room"; do [[ -d $d ]] && dirs+=("$d"); done
  ((${#dirs[@]})) || return 0
  forbidden=$(IFS='|'; echo "$*")
  # An include names a room as a path segment: "hil/bench/server/x.hpp", "../server/x.hpp", "server/x.hpp".
  local hits
  hits=$(grep -rnE "^[[:space:]]*#[[:space:]]*include[[:space:]]*[<\"]([^\">]*/)?($forbidden)/" "${dirs[@]}" || true)
  if [[ -n $hits ]]; then
    printf '%s\n' "$hits"
    echo "$room/ may not include ${*/%//} (docs/architecture.md, Rooms)"
    status=1
  fi
}
check rt campaign server cli
check campaign server cli
((status == 0)) && echo "include rules hold: rt/ uses nothing of campaign/, server/, cli/; campaign/ nothing of server/, cli/"
exit $status
