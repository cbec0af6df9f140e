#!/usr/bin/env bash
# The Gaussian rasterizer's kernels and the Gaussians' training step, each beside its reference in the same
# run: a 346 × 260 view of 2 k, 50 k and 200 k random Gaussians (the forward's Gaussian·pixel pairs per
# second, and its share of the FMA peak the same binary measures, at the 47 floating-point operations its
# compositing loop does per pair), the plain reference view (every Gaussian at every pixel), a training pass
# over 4096 pixels (forward kept, backward, projection backward), and the Splat preset's training step against
# the Fast preset's on the same recording and pixels (bench/bench_main.cpp). The benchmark binary runs REPS
# times; medians over the runs, the step ratio taken per run. Writes $OUT/splat_kernels.csv, copies it to
# bench/results/ (RESULTS; empty: not copied) and regenerates docs/results.md.
# Usage: bench/splat_kernels.sh [REPS]   (default 5)   Environment: OUT (build-bench/splat), RESULTS.
set -euo pipefail
cd "$(dirname "$0")/.."
REPS=${1:-5}
scripts/deps.sh libbenchmark-dev
cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_BENCH=ON -DEVNERF_BUILD_TESTS=OFF \
  -DEVNERF_BUILD_EXAMPLES=OFF >/dev/null
cmake --build build-bench -j"$(nproc)" --target evnerf_bench >/dev/null
OUT=${OUT:-build-bench/splat}
mkdir -p "$OUT"
rm -f "$OUT"/run_*.json
FILTER='^(BM_fma_peak|BM_splat_render|BM_splat_reference|BM_splat_train_pass|BM_train_step<presets::(Fast|Splat)>)/'
for r in $(seq "$REPS"); do
  OMP_NUM_THREADS=2 build-bench/bench/evnerf_bench --benchmark_filter="$FILTER" --benchmark_format=json \
    --benchmark_out="$OUT/run_$r.json" --benchmark_out_format=json >/dev/null
done
python3 - "$OUT" > "$OUT/splat_kernels.csv" <<'PY'
import glob, json, statistics, sys
FLOPS_PER_PAIR = 47  # the compositing loop's adds and multiplies per (Gaussian, pixel) pair, an FMA as two
runs = [{b["name"]: b for b in json.load(open(f))["benchmarks"]} for f in sorted(glob.glob(f"{sys.argv[1]}/run_*.json"))]
def get(prefix, key="real_time"):
    return [next(b[key] for n, b in run.items() if n.startswith(prefix)) for run in runs]
med = statistics.median
peak = get("BM_fma_peak", "gflops")
print("what,ms,ms_min,ms_max,pairs_per_s,peak_share,ratio,ratio_min,ratio_max,reps")
for n in (2000, 50000, 200000):
    ms, pairs = get(f"BM_splat_render/{n}/"), get(f"BM_splat_render/{n}/", "pairs_per_s")
    share = [p * FLOPS_PER_PAIR / 1e9 / k for p, k in zip(pairs, peak)]
    ratio = [r / m for r, m in zip(get("BM_splat_reference/2000/"), ms)] if n == 2000 else []
    rr = f"{med(ratio):.2f},{min(ratio):.2f},{max(ratio):.2f}" if ratio else ",,"
    print(f"view {n},{med(ms):.2f},{min(ms):.2f},{max(ms):.2f},{med(pairs):.4g},{med(share):.3f},{rr},{len(runs)}")
ms, pairs = get("BM_splat_train_pass/50000/"), get("BM_splat_train_pass/50000/", "pairs_per_s")
print(f"training pass 50000,{med(ms):.2f},{min(ms):.2f},{max(ms):.2f},{med(pairs):.4g},,,,,{len(runs)}")
fast, splat = get("BM_train_step<presets::Fast>/"), get("BM_train_step<presets::Splat>/")
ratio = [f / s for f, s in zip(fast, splat)]
print(f"step splat,{med(splat):.2f},{min(splat):.2f},{max(splat):.2f},,,{med(ratio):.2f},{min(ratio):.2f},{max(ratio):.2f},{len(runs)}")
print(f"step fast,{med(fast):.2f},{min(fast):.2f},{max(fast):.2f},,,,,,{len(runs)}")
print(f"fma peak gflops,{med(peak):.1f},{min(peak):.1f},{max(peak):.1f},,,,,,{len(runs)}")
PY
cat "$OUT/splat_kernels.csv"
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then mkdir -p "$RESULTS" && cp "$OUT/splat_kernels.csv" "$RESULTS/" && python3 bench/results.py; fi
