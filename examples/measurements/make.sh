#!/usr/bin/env bash
# Makes the shipped measurements of examples/measurements (README there): each campaign here
# simulated by `hilbench sim` (seeded, so the same bytes every time), its run's telemetry.csv
# kept to what a rig measures (its first five columns, the measurement format: the truth columns of
# a sim would give the hidden effect away) as NAME.csv.
#   examples/measurements/make.sh [HILBENCH [OUT_DIR]]   (defaults: build/bench/hilbench, this folder)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
hilbench=${1:-$here/../../build/bench/hilbench}
out=${2:-$here}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for name in nominal throat_erosion valve_offset; do
  "$hilbench" sim "$here/$name.yaml" --out "$tmp" --quiet
  cut -d, -f1-5 "$tmp/$name/measured/telemetry.csv" >"$out/$name.csv"
  echo "$out/$name.csv"
done
