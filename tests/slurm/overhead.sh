#!/usr/bin/env bash
# Slurm overhead per task (docs/benchmarks.md): on a single-node Slurm of this host
# (scripts/slurm-local), the wall time of a sweep of K one-point shards submitted with
# `hilbench sweep --slurm --tasks K` (submission to the aggregation job's end) against the same
# sweep run locally with as many jobs as the node has CPUs; overhead per task =
# (wall_slurm - wall_local) / K. For scale, the same for a bare `sbatch --array` of K `true`
# tasks against K `true` runs. Prints one line per repetition and the medians. With SWEEP.yaml,
# that sweep in K shards instead of the K trivial points.
#   overhead.sh HILBENCH [K=16] [REPETITIONS=3] [SWEEP.yaml]
set -euo pipefail

(($# >= 1)) || {
  echo "usage: $0 HILBENCH [K] [REPETITIONS] [SWEEP.yaml]" >&2
  exit 2
}
hilbench=$(realpath "$1")
tasks=${2:-16}
reps=${3:-3}
sweep=${4:+$(realpath "$4")}
src=$(cd "$(dirname "$0")/../.." && pwd)
cluster_cmd=$src/scripts/slurm-local

work=$(mktemp -d /tmp/hil-slurm-bench.XXXXXX)
chmod 755 "$work" # munged wants the folders above its socket searchable by all
trap '"$cluster_cmd" stop "$work/cluster"; rm -rf "$work"' EXIT

now_s() { date +%s.%N; }
elapsed_s() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }

wait_for_queue_empty() {
  local deadline_s=$((SECONDS + 600))
  while [[ -n "$(squeue --noheader --format=%i)" ]]; do
    ((SECONDS < deadline_s)) || {
      echo "jobs still queued after 600 s" >&2
      exit 1
    }
    sleep 0.1
  done
}

# K points of a 1 s campaign (one run), one per seed.
sed -e "s|^plant: .*|plant: $src/configs/plant/nominal.yaml|" -e 's/^duration_s: .*/duration_s: 1/' \
  "$src/tests/slurm/campaign.yaml" | sed '/^  - name: adaptive/,$d' >"$work/campaign.yaml"
{
  echo "name: slurm_overhead"
  echo "description: $tasks trivial points, one per array task"
  echo "campaign: campaign.yaml"
  echo "axes:"
  echo "  - path: campaign.seed"
  echo "    values: [$(seq -s ', ' 1 "$tasks")]"
} >"$work/sweep.yaml"
[[ -n "$sweep" ]] || sweep=$work/sweep.yaml

setup_start=$(now_s)
"$cluster_cmd" start "$work/cluster" >/dev/null
setup_s=$(elapsed_s "$setup_start" "$(now_s)")
eval "$("$cluster_cmd" env "$work/cluster")"
cpus=$(nproc)
echo "$(basename "$sweep"); cluster start: $setup_s s; K = $tasks tasks, $cpus CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg)"

results=()
for ((r = 1; r <= reps; r++)); do
  rm -rf "$work/local" "$work/slurm"
  t0=$(now_s)
  "$hilbench" sweep "$sweep" --out "$work/local" --jobs "$cpus" --quiet >/dev/null
  local_s=$(elapsed_s "$t0" "$(now_s)")

  t0=$(now_s)
  "$hilbench" sweep "$sweep" --out "$work/slurm" --slurm --tasks "$tasks" >/dev/null
  wait_for_queue_empty
  slurm_s=$(elapsed_s "$t0" "$(now_s)")
  cmp -s "$work/local/sweep.csv" "$work/slurm/sweep.csv" || {
    echo "the Slurm sweep.csv differs from the local one" >&2
    exit 1
  }

  t0=$(now_s)
  xargs -P "$cpus" -n 1 true < <(seq "$tasks")
  bare_local_s=$(elapsed_s "$t0" "$(now_s)")
  t0=$(now_s)
  sbatch --parsable --array=0-$((tasks - 1)) --output=/dev/null --wrap true >/dev/null
  wait_for_queue_empty
  bare_slurm_s=$(elapsed_s "$t0" "$(now_s)")

  line=$(awk -v k="$tasks" -v l="$local_s" -v s="$slurm_s" -v bl="$bare_local_s" -v bs="$bare_slurm_s" \
    'BEGIN { printf "%s %s %.3f %s %s %.3f", l, s, (s - l) / k, bl, bs, (bs - bl) / k }')
  results+=("$line")
  read -r l s o bl bs bo <<<"$line"
  echo "rep $r: sweep local $l s, slurm $s s, overhead $o s/task; sbatch --array true: local $bl s, slurm $bs s, overhead $bo s/task"
done

median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
col() { printf '%s\n' "${results[@]}" | awk -v c="$1" '{ print $c }' | median; }
echo "median of $reps: sweep local $(col 1) s, slurm $(col 2) s, overhead $(col 3) s/task;" \
  "sbatch --array true: local $(col 4) s, slurm $(col 5) s, overhead $(col 6) s/task"
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
