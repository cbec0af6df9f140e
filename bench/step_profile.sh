#!/usr/bin/env bash
# Where a training step's time goes: a preset's step (BM_train_step, 1024 pixels at two poses, on a warmed
# model; PRESET fast, or splat for the Gaussians) sampled by `perf record` on one thread; each sample is given to the part of the step whose code
# it was in (the innermost of evnerf's frames on its stack names it: a memcpy called by the hash grid is the
# hash grid's). The benchmark's own scene simulation, before the timed steps, is left out. Prints the shares
# and writes bench/results/step_profile_ISA.csv (step_profile_splat_ISA.csv for PRESET=splat; RESULTS; empty:
# not copied) and docs/results.md.
# ISA=avx2 builds without AVX-512 (EVNERF_NO_AVX512) in build-bench-avx2. Usage: bench/step_profile.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-10}
case "${PRESET:-fast}" in
  fast) BENCH='BM_train_step<presets::Fast>/'; NAME=step_profile ;;
  splat) BENCH='BM_train_step<presets::Splat>/'; NAME=step_profile_splat ;;
  *) echo "step_profile: PRESET is fast or splat, not '$PRESET'" >&2; exit 2 ;;
esac
scripts/deps.sh libbenchmark-dev linux-perf
TARGET=evnerf_bench . bench/isa.sh  # B: the build for ISA
OUT=$B/results
mkdir -p "$OUT"
. bench/cpu.sh  # has, CPU_FEATURES
# perf samples its own processes where kernel.perf_event_paranoid ≤ 2 (the kernel's default).
OMP_NUM_THREADS=1 perf record -q -g -F 997 -o "$OUT/step.perf" -- "$B"/bench/evnerf_bench \
  --benchmark_filter="$BENCH" --benchmark_min_time="$SECS" >"$OUT/step_bench.txt" 2>&1 || {
  echo "step_profile: perf record failed (see $OUT/step_bench.txt; in a container perf may need kernel.perf_event_paranoid ≤ 2)" >&2
  exit 1
}
grep -q '^BM_train_step' "$OUT/step_bench.txt" || { echo "step_profile: the benchmark did not run:" >&2; cat "$OUT/step_bench.txt" >&2; exit 1; }
perf script -i "$OUT/step.perf" -F ip,sym > "$OUT/step.stacks" 2>/dev/null
python3 - "$OUT/step.stacks" "$OUT/step_profile.csv" "${ISA:-native}" "$CPU_FEATURES" <<'PY'
import csv, re, sys
src, dst, isa, cpu = sys.argv[1:]
def plain(name):
    """A frame's function without template arguments, parameters or lambdas: Field::forward_at."""
    out, depth = [], 0
    for ch in name.split("(", 1)[0] if not name.startswith("(") else name:
        if ch == "<":
            depth += 1
        elif ch == ">":
            depth -= 1
        elif depth == 0:
            out.append(ch)
    return "".join(out)
REST = "MLP: the rest (bias gradients, transposes, one-row products)"
# Matrix products by their kernel's template arguments (the innermost gemm frame); the rest by name.
GEMM = [
    ("MLP products: weight gradients (dW += dZ·Xᵀ)", re.compile(r"^evnerf::nn::gemm::\S*(product(_unchecked)?<true|block8<\d, \d, true)")),
    ("MLP products: forward (W·X + b, activation)", re.compile(r"^evnerf::nn::gemm::\S*<.*BiasActivation")),
    ("MLP products: input gradients (Wᵀ·dZ ⊙ act')", re.compile(r"^evnerf::nn::gemm::\S*<.*ActivationGrad")),
]
PARTS = [
    ("Gaussians: projection", re.compile(r"evnerf::splat::(detail::project_shape|project)$")),
    ("Gaussians: projection backward", re.compile(r"evnerf::splat::project_backward")),
    ("Gaussians: binning into tiles", re.compile(r"evnerf::splat::Rasterizer::bin")),
    ("Gaussians: compositing", re.compile(r"evnerf::splat::Rasterizer::forward")),
    ("Gaussians: compositing backward", re.compile(r"evnerf::splat::Rasterizer::backward")),
    ("Gaussians: the pass's grouping by pose", re.compile(r"evnerf::splat::TrainingPass")),
    ("Gaussians: parameters in and out of their units", re.compile(r"evnerf::Splatting::")),
    ("hash grid: encode", re.compile(r"HashGrid::(forward|encode)")),
    ("hash grid: backward", re.compile(r"HashGrid::(backward|flush|scatter)")),
    (REST, re.compile(r"evnerf::nn::(Mlp|gemm)")),
    ("Adam", re.compile(r"Adam")),
    ("sampling and compositing", re.compile(r"evnerf::render::|Field::")),
    ("objective (windows, thresholds, regularisers)", re.compile(r"evnerf::loss::|evnerf::model::|EvNerf::|evnerf::Model::")),
]
SETUP = re.compile(r"evnerf::(sim|events|io)::|bench_data")  # the benchmark's recording and its slicing
count, total, setup = {}, 0, 0
for block in open(src).read().split("\n\n"):
    frames = [l.strip().split(None, 1)[1] for l in block.splitlines() if len(l.strip().split(None, 1)) > 1]
    ours = [f for f in frames if f.startswith("evnerf::") or "BM_train_step" in f]
    if not ours:
        continue  # start-up, the runtime's own work
    if any(SETUP.search(plain(f)) for f in ours):
        setup += 1
        continue
    part = "other"
    for f in ours:
        if f.startswith("evnerf::nn::gemm::"):
            part = next((name for name, rx in GEMM if rx.search(f)), REST)
            break
        name = plain(f)
        if name.startswith("evnerf::parallel_"):  # a thread helper: the caller is named in its template arguments
            inner = re.search(r"(evnerf::splat::\w+)<[^()]*?>::(\w+)\(", f)
            name = f"{inner.group(1)}::{inner.group(2)}" if inner else name
        part = next((n for n, rx in PARTS if rx.search(name)), "other")
        if part != "other":
            break
    count[part] = count.get(part, 0) + 1
    total += 1
if total == 0:
    sys.exit("step_profile: no samples inside the training step (was the benchmark built with frame pointers?)")
rows = sorted(count.items(), key=lambda kv: -kv[1])
with open(dst, "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["isa", "cpu", "part", "share", "samples"])
    for part, n in rows:
        w.writerow([isa, cpu, part, f"{n / total:.4f}", n])
        print(f"{100 * n / total:5.1f} %  {part}")
print(f"{total} samples in the step; {setup} in the benchmark's scene simulation, left out")
PY
grep -m1 'BM_train_step' "$OUT/step_bench.txt" || true
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then
  mkdir -p "$RESULTS" && cp "$OUT/step_profile.csv" "$RESULTS/${NAME}_${ISA:-native}.csv" && echo "copied to $RESULTS/${NAME}_${ISA:-native}.csv"
  python3 bench/results.py
fi
