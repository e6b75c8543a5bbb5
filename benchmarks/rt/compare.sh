#!/usr/bin/env bash
# The loop's wake-up latency next to cyclictest, run the same way: SCHED_FIFO at the same
# priority, pinned to the same CPU, memory locked, absolute CLOCK_MONOTONIC sleeps, one thread,
# same period and duration; one after the other, never at the same time.
#   [ROUNDS=N] benchmarks/rt/compare.sh BUILD_DIR [SECONDS] [PRIORITY] [CPU] [RATES...]
# e.g. ROUNDS=3 benchmarks/rt/compare.sh build-server 60 80 1 1000 5000   (needs root or CAP_SYS_NICE)
# Rounds alternate the two programs, so a neighbour's load that comes and goes hits both.
set -euo pipefail
build=${1:?usage: compare.sh BUILD_DIR [SECONDS] [PRIORITY] [CPU] [RATES...]}
seconds=${2:-60}
prio=${3:-80}
cpu=${4:-1}
shift $(( $# < 4 ? $# : 4 ))
rates=("$@")
((${#rates[@]})) || rates=(1000 5000)
command -v cyclictest >/dev/null || { echo "compare.sh: cyclictest missing (scripts/setup.sh --bench)" >&2; exit 1; }

# p50/p99/max from cyclictest's 1 us histogram (-h): "bucket count" lines, then "# Max Latencies".
cyclic() {
  local hz=$1 interval=$((1000000 / $1))
  cyclictest -m -p "$prio" -a "$cpu" -t 1 -i "$interval" -D "${seconds}s" -h 20000 -q 2>/dev/null |
    awk -v hz="$hz" -v s="$seconds" -v prio="$prio" -v cpu="$cpu" '
      /^[0-9]+[ \t]+[0-9]+/ { n[$1+0] += $2; total += $2 }
      /^# Min Latencies/ { min = $4 + 0 }
      /^# Max Latencies/ { max = $4 + 0 }
      /^# Histogram Overflows/ { over = $4 + 0 }
      END {
        total += over
        p50 = -1; p99 = -1; p999 = -1; c = 0
        for (b = 0; b <= 20000; b++) {
          c += n[b]
          if (p50 < 0 && c >= 0.5 * total) p50 = b
          if (p99 < 0 && c >= 0.99 * total) p99 = b
          if (p999 < 0 && c >= 0.999 * total) p999 = b
        }
        printf "cyclictest     %5d Hz %3d s  SCHED_FIFO %d, CPU %d, mlockall: wake-up latency us: min %d p50 %d p99 %d p99.9 %d max %d | samples %d\n", hz, s, prio, cpu, min, p50, p99, p999, max, total
      }'
}

for ((round = 1; round <= ${ROUNDS:-1}; round++)); do
  for hz in "${rates[@]}"; do
    "$build/benchmarks/rt/bench_rt_loop" --hz "$hz" --seconds "$seconds" --priority "$prio" --cpu "$cpu"
    cyclic "$hz"
  done
done
