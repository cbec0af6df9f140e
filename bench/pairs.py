"""Prints bench/pairs.sh's results: per pair, ours against the peer right next to it; then medians, which
it also writes to OUT/pairs.csv (one row per width, with the build's vector ISA, the CPU's features and the
peer's OpenBLAS kernels). Usage: pairs.py OUT PAIRS [ISA CPU_FEATURES PEER_CORE]"""
import csv, json, statistics, sys

out, pairs = sys.argv[1], int(sys.argv[2])
isa, cpu, core = (sys.argv[3:6] + ["native", "", ""][len(sys.argv[3:6]):])
def ours(w, p):
    bs = json.load(open(f"{out}/ours_{w}_{p}.json"))["benchmarks"]
    rate = next(b["samples_per_s"] for b in bs if b["name"].startswith(f"BM_mlp_fused<{w}>"))
    peak = next(b["gflops"] for b in bs if b["name"].startswith("BM_fma_peak"))
    gf = next(b["gflops"] for b in bs if b["name"].startswith(f"BM_mlp_fused<{w}>"))
    return rate, gf / peak, peak
def peer(w, p):
    return json.loads(open(f"{out}/peer_{w}_{p}.json").read().strip().splitlines()[-1])["samples_per_s"]

summary = []
for w, target in ((256, 1.25), (64, 3.0)):
    rows = []
    for p in range(1, pairs + 1):
        (r, frac, peak), q = ours(w, p), peer(w, p)
        rows.append((r / q, r, q, frac, peak))
        print(f"W={w} pair {p}: ours {r:,.0f} samples/s ({100 * frac:.0f} % of {peak:.0f} GFLOP/s), "
              f"peer {q:,.0f}: {r / q:.2f}x")
    ratios = [x[0] for x in rows]
    med = lambda i: statistics.median(x[i] for x in rows)
    print(f"W={w}: median of the pair ratios {statistics.median(ratios):.2f}x (range {min(ratios):.2f}-{max(ratios):.2f}x, "
          f"{sum(x >= target for x in ratios)} of {len(ratios)} pairs >= {target}x); ours {med(1):,.0f}, "
          f"peer {med(2):,.0f} samples/s; ours at {100 * med(3):.0f} % of the FMA peak")
    summary.append({"isa": isa, "cpu": cpu, "peer_core": core, "width": w, "pairs": pairs,
                    "ratio": f"{statistics.median(ratios):.2f}", "ratio_min": f"{min(ratios):.2f}", "ratio_max": f"{max(ratios):.2f}",
                    "ours_samples_per_s": f"{med(1):.0f}", "peer_samples_per_s": f"{med(2):.0f}",
                    "peak_fraction": f"{med(3):.3f}", "peak_gflops": f"{med(4):.1f}"})
with open(f"{out}/pairs.csv", "w", newline="") as f:
    wr = csv.DictWriter(f, fieldnames=list(summary[0]))
    wr.writeheader()
    wr.writerows(summary)
