#!/usr/bin/env bash
# Events per second read from each recording format (bench/bench_formats.cpp: 2 M events written by evnerf's
# writers; IJRR text is the reference, read in the same run), REPS repetitions interleaved by Google
# Benchmark; the medians and ranges are printed and written to bench/results/formats_ISA.csv (RESULTS; empty:
# not copied) and docs/results.md. ISA=avx2 builds without AVX-512 (EVNERF_NO_AVX512) in build-bench-avx2.
# Usage: bench/formats.sh [REPS]
set -euo pipefail
cd "$(dirname "$0")/.."
REPS=${1:-5}
scripts/deps.sh libbenchmark-dev
TARGET=evnerf_bench_formats . bench/isa.sh  # B: the build for ISA
OUT=$B/results
mkdir -p "$OUT"
. bench/cpu.sh  # has, CPU_FEATURES
OMP_NUM_THREADS=2 "$B"/bench/evnerf_bench_formats --benchmark_repetitions="$REPS" --benchmark_enable_random_interleaving=true \
  --benchmark_format=json --benchmark_out="$OUT/formats.json" --benchmark_out_format=json >/dev/null
python3 - "$OUT/formats.json" "$OUT/formats.csv" "${ISA:-native}" "$CPU_FEATURES" <<'PY'
import csv, json, statistics, sys
src, dst, isa, cpu = sys.argv[1:]
runs = [r for r in json.load(open(src))["benchmarks"] if r.get("run_type") == "iteration"]
names = list(dict.fromkeys(r["run_name"].replace("/real_time", "") for r in runs))
rate = {n: [r["items_per_second"] for r in runs if r["run_name"].replace("/real_time", "") == n] for n in names}
text = statistics.median(rate["BM_read_text"])
rows = []
print(f"{'format':<18} {'M events/s':>10} {'range':>13} {'vs text':>8} {'file MB':>8}")
for n in names:
    v = rate[n]
    mb = next((r["MB"] for r in runs if r["run_name"].replace("/real_time", "") == n and "MB" in r), "")
    row = dict(isa=isa, cpu=cpu, format=n.replace("BM_read_", ""), reps=len(v), meps=f"{statistics.median(v) / 1e6:.1f}",
               meps_min=f"{min(v) / 1e6:.1f}", meps_max=f"{max(v) / 1e6:.1f}", vs_text=f"{statistics.median(v) / text:.2f}",
               file_mb=f"{mb:.1f}" if mb != "" else "")
    rows.append(row)
    print(f"{row['format']:<18} {row['meps']:>10} {row['meps_min'] + '-' + row['meps_max']:>13} {row['vs_text']:>7}x {row['file_mb']:>8}")
with open(dst, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
PY
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then
  mkdir -p "$RESULTS" && cp "$OUT/formats.csv" "$RESULTS/formats_${ISA:-native}.csv" && echo "copied to $RESULTS/formats_${ISA:-native}.csv"
  python3 bench/results.py
fi
