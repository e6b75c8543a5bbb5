#!/usr/bin/env bash
# `hilbench sweep --slurm` on a real Slurm: starts a single-node cluster of this host
# (scripts/slurm-local: own munge, slurmctld, slurmd, all under a temp folder), submits the small
# sweep of this folder as a job array of 3 shards plus the aggregation job, waits for both (Slurm
# must report every task and the aggregation COMPLETED), and checks that
#   - sweep.csv is byte for byte the one a local sweep of the same file writes,
#   - `hilbench sweep --status` reports every point done and each task's last progress line,
#   - a resubmission with --time and --cpus-per-task reaches Slurm with both (scontrol show job);
#     its task 1 fails (its rows file lost and a folder in its place): --status exits 1 naming
#     the task and the aggregation's error, and says the command that resubmits; that command,
#     once the folder is gone, runs that shard only (the other shards' rows files are not
#     touched), gives the same sweep.csv again, and the failed attempt's log survives,
#   - resubmitting a complete sweep submits nothing.
# The daemons are always stopped; on failure their logs and the jobs' logs are printed.
#   run_slurm_sweep.sh HILBENCH SOURCE_DIR
set -euo pipefail

(($# == 2)) || {
  echo "usage: $0 HILBENCH SOURCE_DIR" >&2
  exit 2
}
hilbench=$1
src=$(cd "$2" && pwd)
here=$src/tests/slurm
cluster_cmd=$src/scripts/slurm-local
wait_s=${HIL_SLURM_WAIT_S:-300}

for tool in slurmctld slurmd sbatch squeue munged; do
  command -v "$tool" >/dev/null || {
    echo "FAIL: '$tool' is not installed; run scripts/setup.sh --test (installs slurm-wlm and munge)" >&2
    exit 1
  }
done
((EUID == 0)) || {
  echo "FAIL: the single-node Slurm needs root (slurmd starts the jobs)" >&2
  exit 1
}

work=$(mktemp -d /tmp/hil-slurm-test.XXXXXX)
chmod 755 "$work" # munged's socket lies below: every folder above it must be searchable by all
cluster=$work/cluster
local_out=$work/local
slurm_out=$work/sweep
passed=0

finish() {
  local rc=$?
  if ((!passed)); then
    echo "===== the test failed (exit $rc); what Slurm and the jobs said ====="
    if [[ -f "$cluster/slurm.conf" ]]; then
      echo "----- squeue -----"
      SLURM_CONF=$cluster/slurm.conf squeue 2>&1 || true
    fi
    "$cluster_cmd" logs "$cluster" 2>&1 || true
    local f
    for f in "$slurm_out"/slurm/jobs.json "$slurm_out"/slurm/logs/*; do
      [[ -f "$f" ]] || continue
      echo "----- $f -----"
      tail -n 40 "$f"
    done
  fi
  "$cluster_cmd" stop "$cluster" || true
  if ((passed)); then
    rm -rf "$work"
  else
    echo "(kept $work)"
  fi
}
trap finish EXIT
trap 'exit 130' INT TERM

fail() {
  echo "FAIL: $*" >&2
  exit 1
}

# Every job of this private cluster has left the queue (bounded: the machine may be busy).
wait_for_queue_empty() {
  local what=$1 deadline_s=$((SECONDS + wait_s)) queue
  while true; do
    queue=$(squeue --noheader --format='%i %T' 2>&1) || fail "squeue failed: $queue"
    [[ -z "$queue" ]] && return 0
    ((SECONDS < deadline_s)) || break
    sleep 0.5
  done
  fail "$what: jobs still queued or running after $wait_s s: $queue"
}

# Submits the sweep (sbatch options after the log's name); sets array_id (empty when nothing was submitted).
submit() {
  local log=$1
  shift
  "$hilbench" sweep "$here/small.yaml" --out "$slurm_out" --slurm --tasks 3 "$@" >"$log.out" 2>"$log.err" ||
    fail "hilbench sweep --slurm failed: $(cat "$log.out" "$log.err")"
  cat "$log.out" "$log.err"
  array_id=$(awk '$1 == "array" { print $2 }' "$log.out")
  aggregate_id=$(awk '$1 == "aggregate" { print $2 }' "$log.out")
}

# Every job (every task of an array) with id $1 completed with exit code 0, as Slurm saw it.
completed() {
  local states
  states=$(scontrol show job "$1" | grep -o 'JobState=[A-Z_]*' | sort -u)
  [[ "$states" == "JobState=COMPLETED" ]] || fail "job $1 did not complete: ${states//$'\n'/ }"
}

# The array tasks Slurm itself ran for job $1 (completed jobs stay known to slurmctld for
# MinJobAge, 300 s), as "0 1 2".
array_tasks() {
  scontrol show job "$1" | grep -o 'ArrayTaskId=[0-9]*' | cut -d= -f2 | sort -n | tr '\n' ' ' | sed 's/ $//'
}

echo "== local sweep"
"$hilbench" sweep "$here/small.yaml" --out "$local_out" --jobs 2 --quiet ||
  fail "the local sweep failed"
[[ -s "$local_out/sweep.csv" ]] || fail "the local sweep wrote no sweep.csv"
points=$(($(wc -l <"$local_out/sweep.csv") - 1))
((points == 8)) || fail "the local sweep has $points points, the sweep file has 4 x 2 = 8"

echo "== single-node Slurm"
"$cluster_cmd" start "$cluster"
eval "$("$cluster_cmd" env "$cluster")"

echo "== hilbench sweep --slurm --tasks 3"
submit "$work/submit1"
[[ -n "$array_id" && -n "$aggregate_id" ]] || fail "hilbench sweep --slurm printed no 'array <id>' and 'aggregate <id>' lines"
wait_for_queue_empty "first submission"
completed "$array_id"
completed "$aggregate_id"
[[ "$(array_tasks "$array_id")" == "0 1 2" ]] ||
  fail "array job $array_id ran tasks '$(array_tasks "$array_id")', expected 0 1 2"
[[ -f "$slurm_out/sweep.csv" ]] || fail "the aggregation job wrote no sweep.csv"
cmp "$local_out/sweep.csv" "$slurm_out/sweep.csv" ||
  fail "sweep.csv from Slurm differs from the local one: $(diff "$local_out/sweep.csv" "$slurm_out/sweep.csv" | head -20)"
for f in sweep.json report.html; do
  [[ -s "$slurm_out/$f" ]] || fail "the aggregation job wrote no $f"
done
status=$("$hilbench" sweep --status "$slurm_out" 2>&1) || fail "hilbench sweep --status failed: $status"
echo "$status"
grep -q "8 of 8 points done" <<<"$status" || fail "--status does not report 8/8 points done"
# Each task's own progress line, from its log: 8 points in 3 shards are 3, 3 and 2.
for task in "0 3" "1 3" "2 2"; do
  read -r i n <<<"$task"
  grep -Eq "^  task $i: sweep slurm_small shard $i/3: 100% \($n/$n points, [0-9.]+ points/s\), took [0-9]+ s$" <<<"$status" ||
    fail "--status does not show task $i's last progress line (100 %, $n/$n points)"
done

echo "== a task that fails: shard 1's rows lost, and a folder where its rows file goes"
rows=$slurm_out/rows
for i in 0 1 2; do
  [[ -s "$rows/shard-$i-of-3.jsonl" ]] || fail "no rows file $rows/shard-$i-of-3.jsonl after the array ran"
done
before0=$(stat -c '%y %s' "$rows/shard-0-of-3.jsonl")
before2=$(stat -c '%y %s' "$rows/shard-2-of-3.jsonl")
shard1_rows=$(wc -l <"$rows/shard-1-of-3.jsonl")
rm "$rows/shard-1-of-3.jsonl"
mkdir "$rows/shard-1-of-3.jsonl"
status=$("$hilbench" sweep --status "$slurm_out" 2>&1) && fail "--status exited 0 with points missing: $status"
echo "$status"
grep -q "$((8 - shard1_rows)) of 8 points done" <<<"$status" ||
  fail "--status does not report $((8 - shard1_rows))/8 points done after deleting shard 1's rows"
# sbatch options pass through: a time limit, and two CPUs per task (one on a one-CPU machine).
cpus=$(($(nproc) >= 2 ? 2 : 1))
submit "$work/submit2" --time 10 --cpus-per-task "$cpus"
[[ -n "$array_id" ]] || fail "the resubmission submitted no array job"
job=$(scontrol show job "$array_id")
grep -q "TimeLimit=00:10:00" <<<"$job" || fail "--time 10 did not reach the array job: $(grep -o 'TimeLimit=[^ ]*' <<<"$job")"
grep -q "CPUs/Task=$cpus" <<<"$job" || fail "--cpus-per-task $cpus did not reach the array job: $(grep -o 'CPUs/Task=[^ ]*' <<<"$job")"
wait_for_queue_empty "the failing resubmission"
failed_array=$array_id
failed_log=$slurm_out/slurm/logs/shard-${failed_array}_1.err
[[ -s "$failed_log" ]] || fail "the failed task left no log $failed_log"
set +e
status=$("$hilbench" sweep --status "$slurm_out" 2>&1)
rc=$?
set -e
echo "$status"
((rc == 1)) || fail "--status exited $rc with a failed task and points missing (expected 1)"
grep -q "FAILED: array job ${failed_array}_1 FAILED" <<<"$status" || fail "--status does not name the failed task ${failed_array}_1"
grep -q "aggregation job $aggregate_id said: .*points missing" <<<"$status" || fail "--status does not show the aggregation's error"
resubmit=$(grep -A1 "to run what is missing:" <<<"$status" | tail -n 1 | sed 's/^ *hilbench //')
[[ "$resubmit" == "sweep --out "* ]] || fail "--status does not say the command that resubmits: $resubmit"
grep -q -- "--time '10' --cpus-per-task $cpus" <<<"$resubmit" || fail "the resubmit command lost the sbatch options: $resubmit"
failed_text=$(cat "$failed_log")

echo "== the resubmit command --status gave, after the cause is removed"
rmdir "$rows/shard-1-of-3.jsonl"
eval "\"\$hilbench\" $resubmit" >"$work/submit3.out" 2>"$work/submit3.err" ||
  fail "the resubmit command failed: $(cat "$work/submit3.out" "$work/submit3.err")"
array_id=$(awk '$1 == "array" { print $2 }' "$work/submit3.out")
aggregate_id=$(awk '$1 == "aggregate" { print $2 }' "$work/submit3.out")
[[ -n "$array_id" ]] || fail "the resubmit command submitted no array job"
wait_for_queue_empty "resubmission"
completed "$array_id"
completed "$aggregate_id"
[[ "$(array_tasks "$array_id")" == "1" ]] ||
  fail "the resubmitted array job $array_id ran tasks '$(array_tasks "$array_id")', expected only 1"
[[ "$(stat -c '%y %s' "$rows/shard-0-of-3.jsonl")" == "$before0" ]] || fail "the resubmission touched shard 0"
[[ "$(stat -c '%y %s' "$rows/shard-2-of-3.jsonl")" == "$before2" ]] || fail "the resubmission touched shard 2"
[[ "$(wc -l <"$rows/shard-1-of-3.jsonl")" == "$shard1_rows" ]] ||
  fail "the resubmission did not run shard 1's $shard1_rows points again"
cmp "$local_out/sweep.csv" "$slurm_out/sweep.csv" || fail "sweep.csv after the resubmission differs from the local one"
[[ "$(cat "$failed_log")" == "$failed_text" ]] || fail "the failed attempt's log $failed_log did not survive the resubmission"
status=$("$hilbench" sweep --status "$slurm_out" 2>&1) || fail "--status exited $? on a complete sweep: $status"
grep -q "task 1: .*\[attempt 3; earlier logs kept\]" <<<"$status" || fail "--status does not say task 1 ran three times: $status"

echo "== resubmit a complete sweep: nothing to run"
jobs_before=$(scontrol show jobs --oneliner | grep -c '^JobId=')
submit "$work/submit4"
[[ -z "$array_id" ]] || fail "a complete sweep was submitted again (array job $array_id)"
jobs_after=$(scontrol show jobs --oneliner | grep -c '^JobId=')
((jobs_after == jobs_before)) || fail "a complete sweep submitted $((jobs_after - jobs_before)) jobs"
cmp "$local_out/sweep.csv" "$slurm_out/sweep.csv" || fail "sweep.csv after the third submission differs"

passed=1
echo "PASS: the Slurm sweep equals the local sweep; a resubmission runs only what is missing"
