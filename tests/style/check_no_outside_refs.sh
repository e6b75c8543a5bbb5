#!/usr/bin/env bash
# The repository stands alone: no tracked file points at documents outside it. Whoever clones
# the project has only the tree, so a reference to a sibling folder of the checkout (the old
# home of the physics, architecture and vcan notes) is a dangling one; those documents live in
# docs/. Lists every offending line. The patterns are written as bracket expressions so that
# this script does not match itself.
set -euo pipefail
cd "$(dirname "$0")/../.."
patterns=(-e '[.][.]/shared' -e 'shared[/]docs[/]')
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  hits=$(git grep -n -I -E "${patterns[@]}" || true)
else  # an exported tree (no .git): every file but build outputs
  hits=$(grep -rnI -E "${patterns[@]}" --exclude-dir=.git --exclude-dir='build*' --exclude-dir=out --exclude-dir=runs . || true)
fi
if [[ -n "$hits" ]]; then
  printf '%s\n' "$hits"
  echo "these lines point outside the repository; point them at docs/ (physics.md, architecture.md, vcan-in-qemu.md) instead"
  exit 1
fi
echo "no reference outside the repository"
