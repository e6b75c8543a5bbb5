#!/usr/bin/env bash
# Every relative link of the Markdown documents resolves to a file (or folder) of the repository:
# README.md, docs/*.md, bench/SERVER.md, analysis/README.md and every other tracked *.md. Checked:
# inline links and images `[text](target)`, `![alt](target)` and reference definitions
# `[id]: target`, outside fenced code blocks and code spans. Ignored: links with a scheme
# (http:, https:, mailto:, ...) and pure anchors (`#section`); an anchor after a path is cut
# off. A target resolves from the document's own folder (a leading / from the repository's
# top), must stay inside the repository and, in a git checkout, be tracked (a file only on this
# machine is missing for whoever clones). A code span that names another document by its path
# (a `/` in it, ending in .md, no wildcard) counts as a reference too: it must name a tracked
# document, from the document's folder or from the top. Lists every broken one as
# file:line: target: why.
set -euo pipefail
cd "$(dirname "$0")/../.."
top=$(pwd -P)
in_git=false
git rev-parse --is-inside-work-tree >/dev/null 2>&1 && in_git=true
declare -A tracked=()  # every tracked file and every folder that holds one
if $in_git; then
  while IFS= read -r f; do
    while [[ -z "${tracked[$f]:-}" ]]; do
      tracked[$f]=1
      [[ "$f" == */* ]] || break
      f="${f%/*}"
    done
  done < <(git ls-files)
fi

docs=(README.md docs/*.md bench/SERVER.md analysis/README.md)
if $in_git; then
  while IFS= read -r f; do docs+=("$f"); done < <(git ls-files '*.md')
fi
mapfile -t docs < <(for f in "${docs[@]}"; do [[ -f "$f" ]] && echo "$f"; done | sort -u)

# file<TAB>line<TAB>target<TAB>link or span, for every link and document path of the given documents.
extract() {
  awk '
    FNR == 1 { fence = 0 }
    /^[ \t]*(```|~~~)/ { fence = !fence; next }
    fence { next }
    {
      line = $0
      while (match(line, /`+/)) {  # drop code spans: `...`, ``...``
        tick = substr(line, RSTART, RLENGTH)
        rest = substr(line, RSTART + RLENGTH)
        end = index(rest, tick)
        if (end == 0) break
        span = substr(rest, 1, end - 1)
        gsub(/^[ \t]+|[ \t]+$/, "", span)
        if (span ~ /\// && span ~ /^[^ \t*?<>]+\.md(#[^ \t]*)?$/) print FILENAME "\t" FNR "\t" span "\tspan"
        line = substr(line, 1, RSTART - 1) " " substr(rest, end + length(tick))
      }
      if (match(line, /^ ? ? ?\[[^]]+\]:[ \t]+[^ \t]+/)) {  # [id]: target
        def = substr(line, RSTART, RLENGTH)
        sub(/^ ? ? ?\[[^]]+\]:[ \t]+/, "", def)
        print FILENAME "\t" FNR "\t" def "\tlink"
      }
      while (match(line, /\]\([^)]*\)/)) {  # [text](target "title")
        target = substr(line, RSTART + 2, RLENGTH - 3)
        line = substr(line, RSTART + RLENGTH)
        sub(/^[ \t]+/, "", target)
        if (target ~ /^</) { sub(/^</, "", target); sub(/>.*$/, "", target) }
        else sub(/[ \t].*$/, "", target)
        print FILENAME "\t" FNR "\t" target "\tlink"
      }
    }' "$@"
}

# Sets `why` to why the path `rel` (from the repository's top, may hold . and ..) is no document
# of the repository, or to "" when it is one. Pure bash: a fork per link is slow on a busy host.
check() {
  local seg out=()
  local -a segs
  why=""
  IFS=/ read -ra segs <<<"$1"
  for seg in "${segs[@]}"; do
    case "$seg" in
      "" | .) ;;
      ..)
        if ((${#out[@]} == 0)); then
          why="outside the repository"
          return
        fi
        unset 'out[${#out[@]}-1]'
        ;;
      *) out+=("$seg") ;;
    esac
  done
  local IFS=/ norm
  norm="${out[*]}"
  if [[ ! -e "$top/$norm" ]]; then
    why="no such file"
  elif $in_git && [[ -n "$norm" && -z "${tracked[$norm]:-}" ]]; then
    why="not tracked by git"
  fi
}

broken=0
checked=0
while IFS=$'\t' read -r file line target kind; do
  [[ "$target" =~ ^[A-Za-z][A-Za-z0-9+.-]*: ]] && continue  # http:, https:, mailto:, ...
  path="${target%%#*}"
  [[ -z "$path" ]] && continue  # an anchor in the same document
  path="${path//%20/ }"
  checked=$((checked + 1))
  folder=.
  [[ "$file" == */* ]] && folder="${file%/*}"
  if [[ "$kind" == span ]]; then  # a document named in a code span: from here or from the top
    check "$folder/$path"
    [[ -z "$why" ]] || check "$path"
    [[ -z "$why" ]] || why="$why (a document named in a code span)"
  elif [[ "$path" == /* ]]; then
    check "$path"
  else
    check "$folder/$path"
  fi
  if [[ -n "$why" ]]; then
    echo "$file:$line: $target: $why"
    broken=$((broken + 1))
  fi
done < <(extract "${docs[@]}")

if ((broken)); then
  echo "$broken of $checked relative links and document paths do not resolve inside the repository"
  exit 1
fi
echo "$checked relative links and document paths in ${#docs[@]} Markdown files resolve inside the repository"
