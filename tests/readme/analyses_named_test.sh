#!/usr/bin/env bash
# compare and diagnose of two bench runs without --out: two folders named for their runs (and the
# model), reports titled so; the same inputs again reuse their folder; another input whose folder
# would be that name goes to NAME_2 (said on stderr), and the first result is left as it was.
#   analyses_named_test.sh HILBENCH SOURCE_DIR
set -euo pipefail
exe=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
cd "$work"
# Two run folders as hilbench serve makes them: run.json beside telemetry.csv (shipped measurements as their rows).
a=2026-12-08T03-10-00Z_paper_adaptive_adaptive b=2026-12-08T03-11-30Z_paper_adaptive_none
mkdir -p "runs/$a" "runs/$b" other/runs/"$a"
for r in "runs/$a" "runs/$b" "other/runs/$a"; do echo '{"outcome": "completed"}' >"$r/run.json"; done
cp "$src/examples/measurements/nominal.csv" "runs/$a/telemetry.csv"
cp "$src/examples/measurements/throat_erosion.csv" "runs/$b/telemetry.csv"
cp "$src/examples/measurements/valve_offset.csv" "other/runs/$a/telemetry.csv"
model=$src/configs/plant/nominal.yaml

data_of() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["data_file"])' "$1"; }
for kind in compare diagnose; do
  result=$([[ $kind == compare ]] && echo compare.json || echo diagnosis.json)
  for r in "$a" "$b"; do
    "$exe" "$kind" --model "$model" --data "runs/$r/telemetry.csv" --quiet || fail "$kind of $r"
    dir=out/$kind-$r-nominal
    [[ -f $dir/$result ]] || fail "$kind of $r: no $dir/$result (out/ has: $(ls out))"
    [[ $(data_of "$dir/$result") == "runs/$r/telemetry.csv" ]] || fail "$dir/$result is of $(data_of "$dir/$result")"
    title=$(sed -n 's:.*<title>\(.*\)</title>.*:\1:p' "$dir/report.html" | head -1)
    [[ $title == *"$r/telemetry.csv"* && $title == *nominal* ]] || fail "$dir/report.html's title: $title"
  done
  [[ $(ls -d out/$kind-* | wc -l) -eq 2 ]] || fail "$kind: $(ls -d out/$kind-*)"
done
# The same run again: its own folder, no second one.
"$exe" compare --model "$model" --data "runs/$a/telemetry.csv" --quiet 2>err.txt
[[ ! -e out/compare-$a-nominal_2 && ! -s err.txt ]] || fail "the same inputs again did not reuse their folder: $(cat err.txt)"
# Another run of the same folder name (another runs folder): beside it, never over it.
"$exe" compare --model "$model" --data "other/runs/$a/telemetry.csv" --quiet 2>err.txt
[[ -f out/compare-$a-nominal_2/compare.json ]] || fail "another input did not go to _2: $(ls out)"
grep -q "holds the compare of other inputs" err.txt || fail "not said on stderr: $(cat err.txt)"
[[ $(data_of "out/compare-$a-nominal/compare.json") == "runs/$a/telemetry.csv" ]] || fail "the first result was overwritten"
echo "compare and diagnose of two runs: $(ls out | tr '\n' ' ')"
