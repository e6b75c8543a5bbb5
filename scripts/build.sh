#!/usr/bin/env bash
# Configures and builds hilbench (Release, Ninja) into build/. Safe to re-run.
#   scripts/build.sh             everything: the hilbench executable, tests, benchmarks
#   scripts/build.sh hilbench    only the named targets
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
# ccache, where installed, makes a rebuild after a small change cheap; the build is the same without it.
# CCACHE_BASEDIR makes the cache hit from another clone of the tree too (CI's fresh clone).
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR="$PWD"
fi
# HIL_WERROR=ON turns every warning into an error (the tree builds warning-free with Debian 12's GCC).
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DHIL_WERROR="${HIL_WERROR:-OFF}" "${launcher[@]}" >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build build -j"$(nproc)" "${targets[@]}"
echo "build: done (build/bench/hilbench)"
