#!/usr/bin/env bash
# Events per second read from each recording format (bench/bench_formats.cpp: 2 M events written by evnerf's
# writers; IJRR text is the reference), REPS repetitions interleaved by Google Benchmark, medians printed.
# Usage: bench/formats.sh [REPS]
set -euo pipefail
cd "$(dirname "$0")/.."
REPS=${1:-5}
scripts/deps.sh libbenchmark-dev
cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_BENCH=ON -DEVNERF_BUILD_TESTS=OFF \
  -DEVNERF_BUILD_EXAMPLES=OFF >/dev/null
cmake --build build-bench --target evnerf_bench_formats -j"$(nproc)" >/dev/null
OUT=build-bench/results
mkdir -p "$OUT"
OMP_NUM_THREADS=2 build-bench/bench/evnerf_bench_formats --benchmark_repetitions="$REPS" --benchmark_enable_random_interleaving=true \
  --benchmark_format=json --benchmark_out="$OUT/formats.json" --benchmark_out_format=json >/dev/null
python3 - "$OUT/formats.json" <<'PY'
import json, sys
runs = json.load(open(sys.argv[1]))["benchmarks"]
med = {r["run_name"].replace("/real_time", ""): r for r in runs if r.get("aggregate_name") == "median"}
order = ["BM_read_text", "BM_read_prophesee/evt2", "BM_read_prophesee/evt3", "BM_read_hdf5", "BM_read_rosbag/none", "BM_read_rosbag/lz4", "BM_read_rosbag/bz2"]
med = {k: med[k] for k in order if k in med}
text = med["BM_read_text"]["items_per_second"]
print(f"{'format':<22} {'M events/s':>10} {'vs text':>8} {'file MB':>8}")
for name, r in med.items():
    mb = f"{r['MB']:.1f}" if "MB" in r else ""
    print(f"{name.replace('BM_read_', ''):<22} {r['items_per_second'] / 1e6:>10.1f} {r['items_per_second'] / text:>7.2f}x {mb:>8}")
PY
