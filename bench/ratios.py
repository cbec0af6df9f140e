"""Prints bench/run.sh's ratios from medians: ours vs the plain reference, vs the PyTorch peer, vs FMA peak."""
import glob, json, statistics, sys

out = sys.argv[1]
runs = {}
for f in sorted(glob.glob(f"{out}/ours_*.json")):
    for b in json.load(open(f))["benchmarks"]:
        runs.setdefault(b["name"], []).append(b)
def load(name):
    return [json.loads(l) for l in open(f"{out}/{name}") if l.strip()] if glob.glob(f"{out}/{name}") else []
peer, peer_bf16 = load("peer.jsonl"), load("peer_bf16.jsonl")

def med(name, key):
    vals = [b[key] for n, bs in runs.items() if n.startswith(name) for b in bs if key in b]
    return statistics.median(vals) if vals else float("nan")

def peer_med(mode, width, key, runs=None):
    vals = [p[key] for p in (peer if runs is None else runs) if p["mode"] == mode and p["width"] == width]
    return statistics.median(vals) if vals else float("nan")

peak = med("BM_fma_peak", "gflops")
print(f"FP32 FMA peak (2 threads): {peak:.0f} GFLOP/s")
for w in (256, 64):
    f, r = med(f"BM_mlp_fused<{w}>", "samples_per_s"), med(f"BM_mlp_reference<{w}>", "samples_per_s")
    fg, ps = med(f"BM_mlp_fused<{w}>", "gflops"), peer_med("mlp", w, "samples_per_s")
    print(f"MLP W={w}: fused {f:,.0f} samples/s ({fg:.0f} GFLOP/s, {100 * fg / peak:.0f} % of peak); "
          f"reference {r:,.0f} ({f / r:.2f}x); PyTorch peer {ps:,.0f} ({f / ps:.2f}x)")
bpeak = med("BM_bf16_peak", "gflops")
if bpeak == bpeak:  # built with AVX-512 BF16
    print(f"BF16 dot-product peak (2 threads): {bpeak:.0f} GFLOP/s")
    for w in (256, 64):
        f, fg = med(f"BM_mlp_fused<{w}, nn::Bf16>", "samples_per_s"), med(f"BM_mlp_fused<{w}, nn::Bf16>", "gflops")
        ps, pb = peer_med("mlp", w, "samples_per_s"), peer_med("mlp", w, "samples_per_s", peer_bf16)
        print(f"MLP W={w} Bf16: fused {f:,.0f} samples/s ({fg:.0f} GFLOP/s, {100 * fg / bpeak:.0f} % of the BF16 peak); "
              f"PyTorch peer FP32 {ps:,.0f} ({f / ps:.2f}x); PyTorch peer bf16 autocast {pb:,.0f} ({f / pb:.2f}x)")
print("parse events.txt: %.0f MB/s vs naive %.0f MB/s (%.1fx); npy cache %.2f GB/s" % (
    med("BM_parse_events_fast", "bytes_per_second") / 1e6, med("BM_parse_events_naive", "bytes_per_second") / 1e6,
    med("BM_parse_events_fast", "bytes_per_second") / med("BM_parse_events_naive", "bytes_per_second"),
    med("BM_event_cache_load", "bytes_per_second") / 1e9))
for name, b in runs.items():
    if name.startswith("BM_train_step") or name.startswith("BM_render"):
        print(f"{name}: {statistics.median(x['real_time'] for x in b):.0f} ms")
peer64, peer256 = peer_med("step", 64, "ms_per_step"), peer_med("step", 256, "ms_per_step")
b64, b256 = peer_med("step", 64, "ms_per_step", peer_bf16), peer_med("step", 256, "ms_per_step", peer_bf16)
print(f"PyTorch peer steps: FP32 W=64 {peer64:.0f} ms, W=256 {peer256:.0f} ms; bf16 autocast W=64 {b64:.0f} ms, W=256 {b256:.0f} ms")
for suffix in ("", "Bf16"):
    fast = med(f"BM_train_step<presets::Fast{suffix}>", "real_time")
    paper = med(f"BM_train_step<presets::Paper{suffix}>", "real_time")
    print(f"Fast{suffix} step {fast:.0f} ms: {peer64 / fast:.1f}x the FP32 peer's W=64 32+32 step, {b64 / fast:.1f}x its bf16 autocast")
    print(f"Paper{suffix} step {paper:.0f} ms: {peer256 / paper:.2f}x the FP32 peer's paper step, {b256 / paper:.2f}x its bf16 autocast")
# The Gaussian rasterizer: whole 346×260 views (tiles) against its plain reference at 2 k Gaussians (its share
# of the FMA peak: bench/splat_kernels.sh).
for n in (2000, 50000, 200000):
    ms, pairs = med(f"BM_splat_render/{n}/", "real_time"), med(f"BM_splat_render/{n}/", "pairs_per_s")
    line = f"splat view 346x260, {n:,} Gaussians: {ms:.1f} ms ({pairs / 1e6:.0f} M Gaussian-pixel pairs/s)"
    if n == 2000:
        line += f"; {med('BM_splat_reference/2000/', 'real_time') / ms:.1f}x the plain reference"
    print(line)
print("splat training pass, 4096 pixels of 50,000 Gaussians: %.1f ms (%.0f M forward pairs/s through forward and backward)" % (
    med("BM_splat_train_pass/50000/", "real_time"), med("BM_splat_train_pass/50000/", "pairs_per_s") / 1e6))
fast, splat = med("BM_train_step<presets::Fast>/", "real_time"), med("BM_train_step<presets::Splat>/", "real_time")
print(f"Splat step {splat:.0f} ms: {fast / splat:.2f}x the speed of the Fast step on the same recording and pixels")
