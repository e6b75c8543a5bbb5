#!/usr/bin/env bash
# scripts/slurm-local start when a daemon cannot run (a slurmd that exits at once, put first on
# PATH): start must fail within its bound, name the daemon that exited, print its log, and leave
# no daemon of its folder running.
#   start_failure.sh SOURCE_DIR
set -euo pipefail
src=$(cd "$1" && pwd)
command -v munged >/dev/null || {
  echo "FAIL: munged is not installed; run scripts/setup.sh --test (installs slurm-wlm and munge)" >&2
  exit 1
}
work=$(mktemp -d /tmp/hil-slurm-fail.XXXXXX)
chmod 755 "$work"
trap '"$src/scripts/slurm-local" stop "$work/cluster" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
mkdir "$work/bin"
printf '#!/bin/sh\necho "stand-in slurmd: refusing to start" >&2\nexit 1\n' >"$work/bin/slurmd"
chmod +x "$work/bin/slurmd"

rc=0
PATH="$work/bin:$PATH" HIL_SLURM_START_TIMEOUT_S=60 "$src/scripts/slurm-local" start "$work/cluster" \
  >"$work/out" 2>&1 || rc=$?
cat "$work/out"
fail() {
  echo "FAIL: $*" >&2
  exit 1
}
((rc != 0)) || fail "start succeeded with a slurmd that exits"
grep -q "slurmd exited" "$work/out" || fail "start did not say that slurmd exited"
grep -q "stand-in slurmd: refusing to start" "$work/out" || fail "start did not print slurmd's output"
left=$(pgrep -a -f -- "$work/cluster/" || true)
[[ -z "$left" ]] || fail "daemons of the failed cluster still run: $left"
echo "PASS: a failed start names the daemon, shows its log and leaves nothing running"
