#!/usr/bin/env bash
# The project speaks of itself in the present: no tracked file (git keeps the history) says "session"
# followed by a number. Skips (77) outside a git work tree, as in an unpacked source archive.
set -euo pipefail
cd "$(dirname "$0")/.."
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "not a git work tree: skipped"; exit 77; }
if git grep -n -i -E 'sessions? [0-9]' -- . ':!tests/no_history.sh'; then
  echo "the lines above speak of development sessions; say what the thing is now (git keeps the history)" >&2
  exit 1
fi
echo "no tracked file speaks of development sessions"
