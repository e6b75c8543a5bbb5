#!/usr/bin/env bash
# Rooms a newcomer can read (issue 39): no source file of the product (C++, JavaScript, outside
# tests/ and third-party code) is longer than 700 lines. A file listed in
# tests/style/file_size_exceptions.txt may be longer, but never longer than the count written
# there: the list only shrinks. Prints every offender with its length.
set -euo pipefail
cd "$(dirname "$0")/../.."
limit_lines=700
exceptions=tests/style/file_size_exceptions.txt
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  files=$(git ls-files -- '*.cpp' '*.hpp' '*.h' '*.js' '*.mjs' | grep -v -E '^(tests|third_party)/' || true)
else  # an exported tree (no .git)
  files=$(find . -type f \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' -o -name '*.js' -o -name '*.mjs' \) \
    -not -path './tests/*' -not -path './build*' -not -path '*/node_modules/*' -not -path './third_party/*' | sed 's|^\./||')
fi
declare -A allowed=()
if [[ -f "$exceptions" ]]; then
  while read -r path lines _; do
    [[ -z "$path" || "$path" == \#* ]] && continue
    allowed[$path]=$lines
  done <"$exceptions"
fi
bad=0
# One wc for every file (a process per file is slow on a loaded machine); its last line is the total.
while read -r n f; do
  [[ "$f" == total ]] && continue
  cap=${allowed[$f]:-$limit_lines}
  if ((n > cap)); then
    if [[ -n "${allowed[$f]:-}" ]]; then
      echo "$f: $n lines, more than the $cap its exception allows (split it; the list only shrinks)"
    else
      echo "$f: $n lines, more than $limit_lines (split it along its seams)"
    fi
    bad=1
  fi
done < <(printf '%s\n' $files | xargs wc -l)
for f in "${!allowed[@]}"; do
  [[ -f "$f" ]] || { echo "$exceptions: $f no longer exists (remove its line)"; bad=1; continue; }
  n=$(wc -l <"$f")
  ((n <= limit_lines)) && { echo "$exceptions: $f is $n lines now (remove its line)"; bad=1; }
done
((bad == 0)) && echo "every product source file is within $limit_lines lines (or its listed exception)"
exit $bad
