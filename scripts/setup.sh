#!/usr/bin/env bash
# Installs the Debian 12 packages hilbench needs, only those missing.
#   scripts/setup.sh          build and run (compiler, libraries, dygraphs for the operator console)
#   scripts/setup.sh --test   also what the test suites use (Chromium, qemu for vcan, socat, pymodbus, mbpoll,
#                             clang 14 with its sanitizer and libFuzzer runtimes and llvm-symbolizer, Node.js
#                             and npm for the Foxglove client and console browser tests, slurm-wlm and munge
#                             for the single-node Slurm of tests/slurm, python3-junitparser to read the
#                             JUnit XML of `hilbench sim --junit` as a CI would)
#   scripts/setup.sh --bench  also what the benchmarks compare against (rt-tests for cyclictest)
set -euo pipefail

build_pkgs=(build-essential cmake ninja-build ccache pkg-config git libjs-dygraphs
  libboost-dev libspdlog-dev libfmt-dev libyaml-cpp-dev nlohmann-json3-dev libmodbus-dev libcli11-dev libzstd-dev
  libgtest-dev libgmock-dev libbenchmark-dev)
test_pkgs=(chromium qemu-system-x86 busybox-static cpio can-utils iproute2 kmod socat
  python3 python3-pymodbus python3-serial python3-serial-asyncio python3-junitparser mbpoll procps
  clang-14 libclang-rt-14-dev llvm-14 clang-format-14 nodejs npm
  slurm-wlm munge)
bench_pkgs=(rt-tests)

want=("${build_pkgs[@]}")
for arg in "$@"; do
  case "$arg" in
    --test) want+=("${test_pkgs[@]}") ;;
    --bench) want+=("${test_pkgs[@]}" "${bench_pkgs[@]}") ;;
    *) echo "setup.sh: unknown option '$arg' (use --test or --bench)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${want[@]}"; do
  # A Node.js installed from elsewhere (NodeSource, nvm) serves as well, and Debian's would clash with it.
  if [[ "$p" == nodejs || "$p" == npm ]] && command -v node >/dev/null && command -v npm >/dev/null; then continue; fi
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "setup: all ${#want[@]} packages present"
  exit 0
fi

sudo=()
if ((EUID != 0)); then
  command -v sudo >/dev/null || { echo "setup: missing packages (${missing[*]}) and not root; run as root" >&2; exit 1; }
  sudo=(sudo)
fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
# Daemon packages (munge, slurmctld, slurmd) start their service from postinst. The tests start
# their own daemons with their own key and config, and in a container without an init system the
# start fails and with it the install; a policy-rc.d that answers 101 ("action forbidden") keeps
# the packages from starting anything. An existing policy (as in Docker images) is left alone.
policy=/usr/sbin/policy-rc.d
own_policy=0
if [[ ! -e $policy ]]; then
  printf '#!/bin/sh\nexit 101\n' | "${sudo[@]}" tee "$policy" >/dev/null
  "${sudo[@]}" chmod 755 "$policy"
  own_policy=1
  trap '"${sudo[@]}" rm -f "$policy"' EXIT
fi
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
((own_policy == 0)) || { "${sudo[@]}" rm -f "$policy"; trap - EXIT; }
echo "setup: done"
