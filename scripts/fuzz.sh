#!/usr/bin/env bash
# Fuzzes one target (or all) for a bounded time, in the reliability build (build-san/, made here
# when missing). See tests/fuzz/README.md and docs/reliability.md.
#   scripts/fuzz.sh TARGET SECONDS [libFuzzer options...]   e.g. scripts/fuzz.sh config 3600
#   scripts/fuzz.sh all SECONDS                              every target in turn, SECONDS each
# The corpus grows in build-san/fuzz/corpus/TARGET/ (kept between runs; the seeds in
# tests/fuzz/corpus/TARGET/ are read, never written). A finding (crash, sanitizer report,
# unexpected exception, timeout, out of memory) fails the command and leaves the input in
# build-san/fuzz/findings/TARGET/; save it under tests/fuzz/regressions/TARGET/ once understood.
# A timeout counts only when its input is slow again when replayed alone (a busy machine's stall
# is not a finding).
set -euo pipefail
cd "$(dirname "$0")/.."
if (($# < 2)); then
  echo "usage: scripts/fuzz.sh TARGET|all SECONDS [libFuzzer options...]" >&2
  exit 2
fi
target=$1 seconds=$2
shift 2
build=${HIL_SAN_BUILD:-build-san}
list=$build/fuzz/targets.txt
scripts/sanitize.sh --build >/dev/null

names=()
while read -r name _; do [[ -n "$name" ]] && names+=("$name"); done <"$list"
if [[ "$target" != all ]]; then
  printf '%s\n' "${names[@]}" | grep -qx -- "$target" || { echo "fuzz: no target '$target' (have: ${names[*]})" >&2; exit 2; }
  names=("$target")
fi

symbolizer=$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)
[[ -n "$symbolizer" ]] && export ASAN_SYMBOLIZER_PATH="$symbolizer"
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# libFuzzer's -timeout is wall-clock time: on a machine busy with other work one run can pass
# 10 s while this process waits for a core (seen once: a 66-byte WebSocket op, "timeout after 11
# seconds" beside two builds, that replays in 0.5 s alone, process start included). A timeout is
# therefore confirmed by replaying its input alone, three times: an input that is slow in itself
# is slow every time and stays a finding; one that runs in time is said, not counted.
timeout_seen_only_under_load() {
  local name=$1 log=$2 findings=$3 input
  grep -q 'ERROR: libFuzzer: timeout' "$log" || return 1
  input=$(ls -t "$findings"/timeout-* 2>/dev/null | head -n 1)
  [[ -n "$input" ]] || return 1
  for _ in 1 2 3; do
    "$build/fuzz/fuzz_$name" -timeout=10 -rss_limit_mb=2048 "$input" >"$log.replay" 2>&1 || return 1
  done
  echo "fuzz: $name: a timeout seen only under load: $input replays in time alone, 3 of 3 (the log: $log); not a finding"
}

status=0
for name in "${names[@]}"; do
  read -r _ seeds dict < <(grep "^$name " "$list")
  work=$build/fuzz/corpus/$name findings=$build/fuzz/findings/$name log=$build/fuzz/logs/$name.log
  mkdir -p "$work" "$findings" "$(dirname "$log")"
  opts=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
    -artifact_prefix="$findings/")
  [[ "$dict" != - ]] && opts+=(-dict="$dict")
  echo "fuzz: $name for ${seconds}s (log $log)"
  if "$build/fuzz/fuzz_$name" "${opts[@]}" "$@" "$work" "$seeds" >"$log" 2>&1; then
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')
    rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')
    cov=$(grep -o 'cov: [0-9]* ft: [0-9]* corp: [0-9]*/[0-9a-zA-Z]*' "$log" | tail -1 || true)
    echo "fuzz: $name: no finding; $execs runs, $rate/s; $cov; corpus $(ls "$work" | wc -l) files"
  elif timeout_seen_only_under_load "$name" "$log" "$findings"; then
    : # said by the function; the input stays in $findings for a look
  else
    status=1
    echo "fuzz: $name: FINDING; the log's end:" >&2
    tail -n 40 "$log" >&2
    echo "fuzz: input(s) in $findings/; reproduce: $build/fuzz/fuzz_$name FILE" >&2
  fi
done
exit $status
