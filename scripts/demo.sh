#!/usr/bin/env bash
# The main job on the built-in default: simulate a scene, train the Fast preset, render and evaluate.
# Installs missing Debian packages, builds, writes everything to ${OUT:-out/demo}.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
BUILD=${BUILD:-build}
OUT=${OUT:-out/demo}
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_TESTS=OFF -DEVNERF_BUILD_EXAMPLES=ON >/dev/null
cmake --build "$BUILD" -j"$(nproc)" --target evnerf_cli
EVNERF="$BUILD/examples/evnerf"
"$EVNERF" simulate planes --out "$OUT/scene"
"$EVNERF" train "$OUT/scene" --preset fast --iterations "${ITERS:-6000}" --out "$OUT/run" "$@"
"$EVNERF" eval "$OUT/run/model.ckpt" "$OUT/scene" --out "$OUT/eval"
echo "images and metrics: $OUT/eval"
