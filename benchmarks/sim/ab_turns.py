#!/usr/bin/env python3
# Before/after in turns for bench_sim on a shared machine (docs/benchmarks.md, "A faster period"):
#   benchmarks/sim/ab_turns.py OLD_BENCH_SIM NEW_BENCH_SIM [rounds] [filter]
# Alternates the two binaries (ABBA...), each under SCHED_FIFO 20 pinned to CPU 1 (needs root), and
# prints per benchmark the lowest, the 10th percentile and the median of the per-round medians of
# real time. On a host busy with other tenants (one binary's run time doubling from run to run),
# many short rounds show more than a few long ones: AB_REPS=1 AB_MIN_TIME=0.05 with 60 rounds
# (docs/benchmarks.md, "Ninth round").
import subprocess, sys, json, statistics, collections, os
old, new = sys.argv[1], sys.argv[2]
rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 4
flt = sys.argv[4] if len(sys.argv) > 4 else 'BM_Step|BM_Run'
reps = int(os.environ.get('AB_REPS', '3'))
min_time = os.environ.get('AB_MIN_TIME', '0.2')
res = {old: collections.defaultdict(list), new: collections.defaultdict(list)}
loads = []
for r in range(rounds):
    for b in (old, new) if r % 2 == 0 else (new, old):
        loads.append(float(open('/proc/loadavg').read().split()[0]))
        out = subprocess.run(['chrt', '-f', '20', 'taskset', '-c', '1', b, f'--benchmark_filter={flt}', f'--benchmark_repetitions={reps}',
                              f'--benchmark_min_time={min_time}', '--benchmark_report_aggregates_only=true', '--benchmark_format=json'],
                             capture_output=True, text=True).stdout
        for bm in json.loads(out)['benchmarks']:
            # One repetition has no aggregates: the run itself is the round's figure.
            if bm.get('aggregate_name') == 'median' or (reps == 1 and bm.get('run_type') == 'iteration'):
                res[b][bm['run_name']].append((bm['real_time'], bm['time_unit']))
print(f"load avg during runs: min {min(loads):.2f} max {max(loads):.2f}")
p10 = lambda xs: sorted(xs)[len(xs) // 10]
for name in res[old]:
    o = [t for t, u in res[old][name]]; n = [t for t, u in res[new][name]]; u = res[old][name][0][1]
    print(f"{name:32s} old min {min(o):8.3f} p10 {p10(o):8.3f} med {statistics.median(o):8.3f} | "
          f"new min {min(n):8.3f} p10 {p10(n):8.3f} med {statistics.median(n):8.3f} {u}  ratio(min) {min(o)/min(n):.2f}")
