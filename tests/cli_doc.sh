#!/usr/bin/env bash
# docs/cli.md is the tool's --help, verb by verb: this writes it (--write) or checks that it is what the
# tool prints (ctest docs.cli), failing with the difference.
# Usage: tests/cli_doc.sh EVNERF_BINARY [--write]
set -euo pipefail
EV=$1
DOC="$(cd "$(dirname "$0")/.." && pwd)/docs/cli.md"
generate() {
  echo "# The command line"
  echo
  echo "After this page you know every verb of \`evnerf\` and every flag, with its default and what it"
  echo "accepts. It is the tool's own \`--help\`, written by \`tests/cli_doc.sh build/examples/evnerf --write\`;"
  echo "ctest \`docs.cli\` fails when the two differ. The training settings are one table (\`train::settings()\`):"
  echo "the same names are the Python module's keywords and \`settings.json\`'s keys."
  for verb in "" inspect simulate baselines train render eval export view convert; do
    echo
    if [ -z "$verb" ]; then echo "## evnerf"; else echo "## evnerf $verb"; fi
    echo
    echo '```'
    # CLI11 names the program as it was started: the build's path becomes `evnerf`.
    "$EV" $verb --help | sed -e "s|$EV|evnerf|g" -e 's/[[:space:]]*$//'
    echo '```'
  done
}
if [ "${2:-}" = --write ]; then
  generate > "$DOC.tmp" && mv "$DOC.tmp" "$DOC"
  echo "wrote $DOC"
  exit 0
fi
if ! diff -u "$DOC" <(generate); then
  echo "docs/cli.md differs from the tool's --help (above); regenerate it: tests/cli_doc.sh $EV --write" >&2
  exit 1
fi
echo "docs/cli.md: every verb's --help, as the tool prints it"
