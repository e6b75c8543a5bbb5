#!/usr/bin/env bash
# README.md, "Adding a physical effect", followed as written in a scratch copy of the tree:
#   readme_effect_test.sh HILBENCH_WITH_EFFECT SOURCE_DIR
# HILBENCH_WITH_EFFECT is hilbench with the section's C++ block compiled in (tests/readme/
# CMakeLists.txt), standing in for what `scripts/build.sh hilbench` makes; the section's plant file
# is written where its first line says, and its shell block runs line by line from the tree's top
# (scripts/build.sh there says what it would do: the program is built already). Then: `effects`
# listed the parameter with its range and default, and diagnose found the deposit the sim put in.
set -euo pipefail
exe=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# The section, then its blocks by language.
section=$(awk '/^### Adding a physical effect$/ {on = 1; next} on && /^###? / {exit} on' "$src/README.md")
[[ -n $section ]] || fail "README.md has no section 'Adding a physical effect'"
block() { awk -v lang="$1" '$0 == "```" lang {on = 1; next} on && /^```/ {exit} on' <<<"$section"; }
plant=$(block yaml)
commands=$(block sh)
[[ -n $plant && -n $commands ]] || fail "the section needs a yaml and a sh block"
grep -q 'scripts/build.sh hilbench' <<<"$commands" || fail "the commands do not rebuild hilbench (scripts/build.sh hilbench)"

# The tree as a user has it: the configs and the shipped examples, build/bench/hilbench the one with the effect.
mkdir -p "$work/build/bench" "$work/scripts"
cp -r "$src/configs" "$src/examples" "$work/"
ln -s "$exe" "$work/build/bench/hilbench"
printf '#!/bin/sh\necho "build: done (build/bench/hilbench, built by the test with the effect)"\n' >"$work/scripts/build.sh"
chmod +x "$work/scripts/build.sh"
plant_file=$(head -1 <<<"$plant" | sed -n 's/^# *\([^ ]*\.yaml\).*/\1/p')
[[ -n $plant_file ]] || fail "the plant block's first line must name its file (# path.yaml): $(head -1 <<<"$plant")"
mkdir -p "$work/$(dirname "$plant_file")"
printf '%s\n' "$plant" >"$work/$plant_file"

cd "$work"
log=$work/commands.log
while IFS= read -r line; do
  [[ -z ${line// /} ]] && continue
  echo "\$ $line" >>"$log"
  bash -c "$line" >>"$log" 2>&1 || { cat "$log" >&2; fail "the README's command failed: $line"; }
done <<<"$commands"
cat "$log"

grep -Eq '^ +blockage +\[0, 0\.9\] +default 0 ' "$log" || fail "hilbench effects did not list blockage with its range and default"
result=$(find out -name diagnosis.json | head -1)
[[ -n $result ]] || fail "no diagnosis.json under out/"
python3 - "$result" <<'PY' || fail "diagnose did not find the deposit"
import json, sys
d = json.load(open(sys.argv[1]))
added = d.get("added", [])
assert added and added[0]["effect"] == "throat_deposit", [a.get("effect") for a in added]
value = {p["key"]: p["value"] for p in added[0]["parameters"]}["blockage"]
assert abs(value - 0.08) < 0.012, value
print(f"diagnose found throat_deposit, blockage {value:.4f} (the plant file's 0.08)")
PY
