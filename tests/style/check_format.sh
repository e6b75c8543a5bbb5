#!/usr/bin/env bash
# Every C++ file of the tree is in the house format (.clang-format at the top). Lists the files
# that are not, and the command that fixes them.
set -euo pipefail
cd "$(dirname "$0")/../.."
command -v clang-format-14 >/dev/null || { echo "clang-format-14 is missing (scripts/setup.sh installs it)"; exit 1; }
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h')
if clang-format-14 --dry-run --Werror "${files[@]}" >/dev/null 2>&1; then
  echo "${#files[@]} files in the house format"
  exit 0
fi
bad=()
for f in "${files[@]}"; do
  clang-format-14 --dry-run --Werror "$f" >/dev/null 2>&1 || bad+=("$f")
done
if ((${#bad[@]})); then
  printf 'not in the house format: %s\n' "${bad[@]}"
  echo "fix: clang-format-14 -i ${bad[*]}"
fi
exit 1
