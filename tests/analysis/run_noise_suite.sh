#!/usr/bin/env bash
# The noise suite (issue 49; analysis/README.md "The noise as a spectrum"): builds hil_hidden_suite,
# draws N healthy files and M with one to three hidden effects per noise class from the seed,
# diagnoses them in K processes side by side (one core each) and writes OUT/noise_suite.md per
# shard and OUT/all.txt (every file's line). Not part of CI; the light ctest is test_analysis_noise_suite.
#   tests/analysis/run_noise_suite.sh                 seed 49, 19 healthy + 0 per class, 2 processes
#   tests/analysis/run_noise_suite.sh --hits 5 --healthy 0 --seed 50 --out out/noise_hits
set -euo pipefail
cd "$(dirname "$0")/../.."
seed=49 healthy=19 hits=0 procs=2 out=out/noise_suite duration=30
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seed) seed=$2 ;; --healthy) healthy=$2 ;; --hits) hits=$2 ;; --procs) procs=$2 ;;
    --out) out=$2 ;; --duration) duration=$2 ;;
    *) echo "run_noise_suite.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift 2
done
[[ -n "${HIL_NO_BUILD:-}" ]] || scripts/build.sh hil_hidden_suite >/dev/null
mkdir -p "$out"
for ((i = 0; i < procs; i++)); do
  build/tests/analysis/hil_hidden_suite --seed "$seed" --noise-healthy "$healthy" --noise-hits "$hits" \
    --duration "$duration" --threads 1 --shard "$i/$procs" --out "$out/shard$i" >"$out/shard$i.log" 2>&1 &
done
wait
grep -h " kPa (read " "$out"/shard*.log | sort >"$out/all.txt"
echo "$(wc -l <"$out/all.txt") files; false alarms: $(grep -c 'FALSE ALARM' "$out/all.txt" || true);" \
  "missed: $(grep -c 'MISSED' "$out/all.txt" || true); tables: $out/shard*/noise_suite.md"
# Per class: healthy files, false alarms, noise read within 25 % of the truth (worst ratio), files
# with effects that are identifiable, found in full.
cat "$out"/shard*/scores.tsv | awk -F'\t' '
  { c = $1; cls[c] = 1
    if ($2 == 0) { h[c]++; fa[c] += ($4 == 0); r = $6 > 0 ? $5 / $6 : 0; ok[c] += (r >= 0.75 && r <= 1.25)
                   d = r > 1 ? r - 1 : 1 - r; if (d > wd[c]) { wd[c] = d; w[c] = r } }
    else if ($3 == 1) { e[c]++; hit[c] += ($4 == 1) } else ni[c]++ }
  END { printf "| class | healthy | false alarms | noise within 25 %% | worst read/truth | identifiable with effects | found in full | not identifiable |\n|---|---|---|---|---|---|---|---|\n"
        for (c in cls) { printf "| %s | %d | %d | %d/%d | %.2f | %d | %d | %d |\n", c, h[c], fa[c], ok[c], h[c], w[c], e[c], hit[c], ni[c]
                         H += h[c]; FA += fa[c]; OK += ok[c]; E += e[c]; HIT += hit[c]; NI += ni[c] }
        printf "| all | %d | %d (%.1f %%) | %d/%d | | %d | %d (%.1f %%) | %d |\n", H, FA, H ? 100 * FA / H : 0, OK, H, E, HIT, E ? 100 * HIT / E : 0, NI }' \
  | tee "$out/summary.md"
