#!/usr/bin/env bash
# The reliability build (docs/reliability.md): clang with AddressSanitizer + UndefinedBehaviorSanitizer
# (every report fatal) and libFuzzer's instrumentation, in build-san/. Builds the fast suites and
# the fuzz targets, then runs those suites (labels unit and physics, minus anything also labelled
# integration, slow, paper, modbus, vcan or browser) and the fuzz targets over their corpora (label fuzz).
#   scripts/sanitize.sh           build and run
#   scripts/sanitize.sh --build   only build (scripts/fuzz.sh uses this)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${HIL_SAN_BUILD:-build-san}

# The suites that run in seconds; the fuzz targets come from tests/fuzz (targets.txt, see below).
suites=(test_common test_controller test_plant_rt test_drivers_unit test_report
  test_bench_server_unit test_bench_server_realtime test_campaigns)

cxx=$(command -v clang++-14 || command -v clang++ || true)  # the same path every time: a changed compiler resets the cache
[[ -n "$cxx" ]] || { echo "sanitize: clang++ is missing (scripts/setup.sh --test installs it)" >&2; exit 1; }
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR="$PWD"  # hits from another clone of the tree too
fi
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER="$cxx" \
  -DHIL_FUZZ=ON -DHIL_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
targets=()
for t in "${suites[@]}"; do targets+=(--target "$t"); done
while read -r name _; do [[ -n "$name" ]] && targets+=(--target "fuzz_$name"); done <"$build/fuzz/targets.txt"
cmake --build "$build" -j"$(nproc)" "${targets[@]}"
[[ "${1:-}" == "--build" ]] && exit 0

# Reports are fatal (-fno-sanitize-recover=all); leaks are reported at exit; symbolized stacks.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:check_initialization_order=1:strict_init_order=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
symbolizer=$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)
[[ -n "$symbolizer" ]] && export ASAN_SYMBOLIZER_PATH="$symbolizer"
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" -L '^(unit|physics|fuzz)$' \
  -LE '^(integration|slow|paper|modbus|vcan|browser)$'
