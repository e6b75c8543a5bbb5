#!/usr/bin/env bash
# examples/measurements, as its README promises:
#   shipped_measurements_test.sh HILBENCH SOURCE_DIR
#  1. its documented command (make.sh) makes every shipped .csv again, byte for byte;
#  2. every file of its table diagnoses against the nominal plant as the table's "hidden" column
#     says: "nothing" -> nothing added; "EFFECT.KEY: VALUE" -> EFFECT added first, KEY within 10 %
#     (and 0.02 absolute) of VALUE.
set -euo pipefail
exe=$1 src=$2
dir=$src/examples/measurements
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$dir/make.sh" "$exe" "$work" >"$work/make.log" 2>&1 || { cat "$work/make.log" >&2; fail "make.sh failed"; }
shipped=0
for f in "$dir"/*.csv; do
  name=$(basename "$f")
  cmp -s "$f" "$work/$name" || fail "$name: make.sh makes another file (run examples/measurements/make.sh and commit it)"
  shipped=$((shipped + 1))
done
((shipped >= 3)) || fail "only $shipped shipped measurements"

# The table's rows: | `FILE.csv` | ... | HIDDEN | ... |
rows=$(grep -E '^\| `[a-z_]+\.csv` \|' "$dir/README.md" || true)
[[ $(wc -l <<<"$rows") -eq $shipped ]] || fail "the README's table lists $(wc -l <<<"$rows") files, $shipped are shipped"
while IFS= read -r row; do
  file=$(sed -E 's/^\| `([a-z_]+\.csv)`.*/\1/' <<<"$row")
  hidden=$(awk -F'|' '{gsub(/^ +| +$|`/, "", $4); print $4}' <<<"$row")
  out=$work/diag-${file%.csv}
  "$exe" diagnose --model "$src/configs/plant/nominal.yaml" --data "$dir/$file" --out "$out" --quiet ||
    fail "$file: diagnose failed"
  python3 - "$out/diagnosis.json" "$file" "$hidden" <<'PY' || fail "$file: diagnose does not say what the README says ($hidden)"
import json, sys
d, file, hidden = json.load(open(sys.argv[1])), sys.argv[2], sys.argv[3]
added = d.get("added") or []
found = [(a["effect"], {p["key"]: p["value"] for p in a["parameters"]}) for a in added]
if hidden == "nothing":
    assert not found, f"{file}: added {found}"
    print(f"{file}: nothing added, fit {d['fit_after_pct']:.2f} % (noise floor {d['noise_floor_fit_pct']:.2f} %)")
else:
    what, value = hidden.split(":")
    effect, key = what.strip().split(".")
    value = float(value)
    assert found and found[0][0] == effect, f"{file}: added {found}, the README says {effect}"
    got = found[0][1][key]
    assert abs(got - value) <= max(0.1 * abs(value), 0.02), f"{file}: {key} = {got}, the README says {value}"
    print(f"{file}: {effect}.{key} = {got:.4g} (hidden {value:g}), fit {d['fit_after_pct']:.2f} %")
PY
done <<<"$rows"
