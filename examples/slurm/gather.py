"""Gathers the metrics.json files of a sweep (examples/slurm/sweep.sh) into one table.

    python3 examples/slurm/gather.py OUT [--csv FILE] [--against PRESET]

One row per (scene, preset): the mean and spread over seeds of our PSNR and SSIM under metrics.json's primary
alignment, our error split by scale (eval's error_scales: the coarse and the fine part's PSNR; compare both
before adopting a change, the coarse part varies most between seeds), and the baselines'; the alignment is
printed with the table. Every run is also listed in the CSV.

--against PRESET adds a paired table: for every other preset, scene by scene, the differences from PRESET
at the seeds both ran (preset minus PRESET): their mean ± sd in PSNR, SSIM and the coarse and fine parts,
how many seeds gained PSNR, and each seed's PSNR difference. Two presets trained at one seed share the
recording and, where their parts agree, what the seed draws (the initial field, the windows, the pixels),
so the seed's share of the spread between seeds (often 0.5–1 dB) can cancel in the differences.
"""
import argparse
import csv
import json
import math
import pathlib
import statistics
import sys


def part(scales, key):
    """A part's PSNR from error_scales: JSON null is an error-free part (infinite PSNR); None where the
    evaluation predates the split."""
    if key not in scales:
        return None
    return float("inf") if scales[key] is None else scales[key]


def runs(out):
    for f in sorted(pathlib.Path(out).glob("*/*/seed*/metrics.json")):
        seed_dir = f.parent
        scene, preset, seed = seed_dir.parent.parent.name, seed_dir.parent.name, seed_dir.name[len("seed"):]
        m = json.loads(f.read_text())
        ours = [k for k in m["methods"] if k.startswith("evnerf_")]
        if len(ours) != 1:
            raise SystemExit(f"{f}: expected one evnerf_* method, found {ours}")
        scales = m.get("error_scales", {}).get("methods", {}).get(ours[0], {})
        yield dict(scene=scene, preset=preset, seed=int(seed), alignment=m["alignment"],
                   psnr=m["methods"][ours[0]]["psnr"], ssim=m["methods"][ours[0]]["ssim"],
                   coarse_psnr=part(scales, "coarse_psnr"), fine_psnr=part(scales, "fine_psnr"),
                   di_psnr=m["methods"]["direct_integration"]["psnr"], hpf_psnr=m["methods"]["high_pass_filter"]["psnr"])


def spread(v, digits=2, signed=False):
    if any(x is None for x in v):
        return "—"
    if any(math.isinf(x) for x in v):  # an error-free part's PSNR: the mean is infinite, the spread undefined
        return "inf"
    sign = "+" if signed else ""
    return f"{statistics.mean(v):{sign}.{digits}f} ± {statistics.stdev(v):.{digits}f}" if len(v) > 1 else f"{v[0]:{sign}.{digits}f}"


def diff(a, b):
    """a − b, or None where either is missing or infinite (an error-free part has no finite difference)."""
    if a is None or b is None or math.isinf(a) or math.isinf(b):
        return None
    return a - b


def paired(rows, reference):
    """The paired table's lines: per (scene, preset ≠ reference), the per-seed differences from the
    reference at the seeds both have."""
    lines = [f"Paired with {reference} (each preset minus {reference} at the same training seed; mean ± sd over seeds)\n",
             "| scene | preset | seeds | Δ PSNR | Δ SSIM | Δ coarse PSNR | Δ fine PSNR | PSNR higher | Δ PSNR per seed |",
             "|---|---|---|---|---|---|---|---|---|"]
    ref = {(r["scene"], r["seed"]): r for r in rows if r["preset"] == reference}
    if not ref:
        sys.exit(f"--against {reference}: no run of that preset")
    for scene, preset in sorted({(r["scene"], r["preset"]) for r in rows if r["preset"] != reference}):
        g = sorted((r for r in rows if (r["scene"], r["preset"]) == (scene, preset) and (scene, r["seed"]) in ref),
                   key=lambda r: r["seed"])
        if not g:
            continue
        d = {k: [diff(r[k], ref[(scene, r["seed"])][k]) for r in g] for k in ("psnr", "ssim", "coarse_psnr", "fine_psnr")}
        wins = sum(x is not None and x > 0 for x in d["psnr"])
        per_seed = ", ".join(f"{r['seed']}: " + ("—" if x is None else f"{x:+.2f}") for r, x in zip(g, d["psnr"]))
        lines.append(f"| {scene} | {preset} | {','.join(str(r['seed']) for r in g)} | {spread(d['psnr'], signed=True)} | "
                     f"{spread(d['ssim'], 3, signed=True)} | {spread(d['coarse_psnr'], signed=True)} | "
                     f"{spread(d['fine_psnr'], signed=True)} | {wins} of {len(g)} | {per_seed} |")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--csv")
    ap.add_argument("--against", metavar="PRESET", help="add the differences from this preset, paired by seed")
    a = ap.parse_args()
    rows = list(runs(a.out))
    if not rows:
        sys.exit(f"{a.out}: no metrics.json (is the sweep finished?)")
    aligns = sorted({r["alignment"] for r in rows})
    print(f"{len(rows)} runs from {a.out}; PSNR dB / SSIM, alignment {', '.join(aligns)}, mean ± sd over seeds\n")
    print("| scene | preset | seeds | PSNR | SSIM | coarse PSNR | fine PSNR | direct integration PSNR | high-pass filter PSNR |")
    print("|---|---|---|---|---|---|---|---|---|")
    for key in sorted({(r["scene"], r["preset"]) for r in rows}):
        g = [r for r in rows if (r["scene"], r["preset"]) == key]
        print(f"| {key[0]} | {key[1]} | {','.join(str(r['seed']) for r in g)} | {spread([r['psnr'] for r in g])} | "
              f"{spread([r['ssim'] for r in g], 3)} | {spread([r['coarse_psnr'] for r in g])} | {spread([r['fine_psnr'] for r in g])} | "
              f"{spread([r['di_psnr'] for r in g])} | {spread([r['hpf_psnr'] for r in g])} |")
    if a.against:
        print("\n" + "\n".join(paired(rows, a.against)))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"\nwrote {a.csv}")


if __name__ == "__main__":
    main()
