#!/usr/bin/env bash
# Every tracked C++ file is formatted as .clang-format says (Debian's clang-format 14). With --write, formats
# them. Skips (77) outside a git work tree, or where clang-format-14 is not installed (scripts/deps.sh
# clang-format-14 installs it; scripts/test.sh does).
set -euo pipefail
cd "$(dirname "$0")/.."
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "not a git work tree: skipped"; exit 77; }
command -v clang-format-14 >/dev/null || { echo "clang-format-14 is not installed: skipped"; exit 77; }
mapfile -t files < <(git ls-files '*.hpp' '*.cpp' '*.h')
if [ "${1:-}" = --write ]; then
  clang-format-14 -i --style=file "${files[@]}"
  echo "formatted ${#files[@]} files"
  exit 0
fi
log=$(mktemp)
trap 'rm -f "$log"' EXIT
if ! clang-format-14 --dry-run --Werror --style=file "${files[@]}" 2>"$log"; then
  grep -m 20 "error:" "$log" >&2 || true
  echo "the files above are not formatted as .clang-format says: tests/format.sh --write formats them" >&2
  exit 1
fi
echo "${#files[@]} files formatted as .clang-format says"
