#!/usr/bin/env bash
# The whole hidden-effect suite (issue 37, acceptance 1; analysis/README.md "Hidden-effect suite"):
# builds hil_hidden_suite, draws the files from the seed, diagnoses each on one core and writes
# OUT/suite.md (headline, per noise colour and level, per class, every file). Not part of CI (about
# 15 min of one core for the default 48 files); the light ctest is test_analysis_suite.
#   tests/analysis/run_hidden_suite.sh                    seed 37, 18 healthy + 10 + 10 + 10 files, out/hidden_suite
#   tests/analysis/run_hidden_suite.sh --seed 38 --out out/s38 --keep-files
set -euo pipefail
cd "$(dirname "$0")/../.."
scripts/build.sh hil_hidden_suite >/dev/null
args=(--singles 10 --pairs 10 --triples 10 --threads 1 --out out/hidden_suite)
time build/tests/analysis/hil_hidden_suite "${args[@]}" "$@"
