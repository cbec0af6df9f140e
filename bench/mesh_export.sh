#!/usr/bin/env bash
# How close `evnerf export`'s surfaces lie to the true ones: mesh-suite assets recorded by `evnerf simulate
# mesh` (as bench/mesh_suite.sh records them), trained with the default preset (`--near 0.3 --far 7.0`, the
# suite's), exported, and each export's vertices (mesh.ply) and points (points.ply) measured against the
# true surface the recording's depth maps see (every visible pixel of every frame, back-projected at its
# pose): the distance from each exported vertex to the nearest true point (accuracy) and from each true
# point to the nearest vertex (completeness), median and 90th percentile, in % of the true surface's
# bounding-box diagonal. Reuses bench/mesh_suite.sh's recording and seed-S run where OUT_MESH holds them.
# Writes $OUT/mesh_export.csv, copies it to bench/results/ (RESULTS; empty: not copied) and regenerates
# docs/results.md. About 4 minutes an asset on 2 cores when it trains.
# Usage: bench/mesh_export.sh [ASSET ...]   (default: duck)
# Environment: SEED (1), THREADS (2), OUT (out/mesh_export), OUT_MESH (out/mesh), BUILD (build), EVNERF
#              (the binary), EXPORT_FLAGS (more export options, split at spaces).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/mesh_export}
OUT_MESH=${OUT_MESH:-out/mesh}
SEED=${SEED:-1}
THREADS=${THREADS:-2}
RESULTS=${RESULTS-bench/results}
read -r -a EXPORT_EXTRA <<<"${EXPORT_FLAGS:-}"
. bench/evnerf_bin.sh  # EV
scripts/deps.sh assimp-testmodels python3-numpy python3-scipy
M=/usr/share/assimp/models
declare -A FILES=([duck]=Collada/duck.dae [mrfixit]=IQM/mrfixit.iqm [milktruck]=glTF/CesiumMilkTruck/CesiumMilkTruck.gltf
                  [jeep]=MS3D/jeep1.ms3d [engine]=glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb [spider]=OBJ/spider.obj)
ASSETS=("$@")
[ ${#ASSETS[@]} -gt 0 ] || ASSETS=(duck)
mkdir -p "$OUT"
CSV="$OUT/mesh_export.csv"
echo "asset,seed,threads,resolution,file,elements,accuracy_median_pct,accuracy_p90_pct,completeness_median_pct,completeness_p90_pct,diagonal" > "$CSV"
for key in "${ASSETS[@]}"; do
  [ -n "${FILES[$key]:-}" ] || { echo "mesh_export: unknown asset '$key' (${!FILES[*]})" >&2; exit 2; }
  rec="$OUT_MESH/$key-grey/rec"
  run="$OUT_MESH/$key-grey/s$SEED/run"
  if [ ! -f "$rec/events.txt" ] || [ ! -f "$run/model.ckpt" ]; then
    rec="$OUT/$key/rec"
    run="$OUT/$key/s$SEED/run"
    [ -f "$rec/events.txt" ] || "$EV" simulate mesh "$M/${FILES[$key]}" --out "$rec" > "$OUT/$key.simulate.txt" 2>&1
    [ -f "$run/model.ckpt" ] || "$EV" train "$rec" --out "$run" --seed "$SEED" --threads "$THREADS" --near 0.3 --far 7.0 --quiet \
      --allow-collapse > "$OUT/$key.train.txt" 2>&1
  fi
  exp="$OUT/$key/s$SEED/export"
  "$EV" export "$run/model.ckpt" --out "$exp" "${EXPORT_EXTRA[@]}" > "$OUT/$key.export.txt"
  res=$(sed -n 's/.*--mesh-resolution \([0-9]*\).*/\1/p' <<<"${EXPORT_FLAGS:-}")
  /usr/bin/python3 bench/surface_distance.py "$rec" "$exp" "$key" "$SEED" "$THREADS" "${res:-192}" >> "$CSV"
  tail -n 2 "$CSV"
done
if [ -n "$RESULTS" ]; then
  cp "$CSV" "$RESULTS/mesh_export.csv"
  echo "copied to $RESULTS/mesh_export.csv"
  python3 bench/results.py
fi
