#!/usr/bin/env bash
# `pip install .` of the repository without a package index: a fresh venv over Debian's Python (it sees
# Debian's numpy and setuptools), --no-build-isolation so that pip uses them, --no-index so that nothing is
# fetched. Then the installed module trains a few steps. Usage: pip.sh PYTHON
set -euo pipefail
PY=${1:-/usr/bin/python3}
SRC="$(cd "$(dirname "$0")/../.." && pwd)"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$PY" -m venv --system-site-packages "$work/venv"
# Where the build of the tests compiled through ccache (scripts/test.sh), pip's build goes through it too:
# the same source and flags, so the module's object comes from the cache and the test measures the
# packaging (setup.py's CMake build, the copy, the import) rather than a second compile.
launcher=()
command -v ccache >/dev/null && launcher=(env "EVNERF_CMAKE_ARGS=-DCMAKE_CXX_COMPILER_LAUNCHER=ccache")
"${launcher[@]}" "$work/venv/bin/pip" install --no-build-isolation --no-index --no-cache-dir -q "$SRC"
cd "$work"
"$work/venv/bin/python" - <<'PY'
import evnerf, numpy as np
assert evnerf.__file__.startswith(__import__("sys").prefix), evnerf.__file__
m = evnerf.train(evnerf.simulate("planes", width=24, height=18), iterations=3, threads=1)
img, depth = m.render(m.boundary_poses[1])
assert img.shape == (18, 24) and np.isfinite(img).all()
print("pip install: evnerf", evnerf.__version__, "from", evnerf.__file__)
PY
