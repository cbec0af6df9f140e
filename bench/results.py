#!/usr/bin/env python3
"""Writes docs/results.md and the README's results table from the benchmarks' current CSV files in
bench/results (quality.csv from bench/quality.sh, robustness.csv from bench/robustness.sh,
time_to_quality[_avx2].csv from bench/time_to_quality.sh, speed_ISA.csv from bench/pairs.sh, formats_ISA.csv from bench/formats.sh, step_profile[_splat]_ISA.csv from bench/step_profile.sh,
mesh.csv from bench/mesh_suite.sh, mesh_export.csv from bench/mesh_export.sh, sensor_factors.csv from bench/sensor_factors.sh, render.csv from bench/render.sh, view.csv from bench/view.sh, splat_kernels.csv from bench/splat_kernels.sh), so both say the same and neither is
edited by hand.

Usage: bench/results.py [--results DIR] [--check]
--check writes nothing and fails when a page differs from what the CSV files give (ctest docs.results)."""
import argparse
import csv
import os
import statistics
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BEGIN = "<!-- results: written by bench/results.py from bench/results/*.csv -->"
END = "<!-- end of results -->"

# The rows of the quality suite in the order shown, with what each is.
RECORDINGS = [
    ("planes", "simulated `planes`"),
    ("noise0.5", "simulated `planes`, 50 % added noise events"),
    ("noise0.9", "simulated `planes`, 90 % added noise events"),
    ("holdout", "simulated `planes`, every 5th boundary held out (novel views only)"),
    ("room", "simulated `room`"),
    ("object", "simulated `object`"),
    ("hdr", "simulated `object --hdr` (scored against the linear truth)"),
    ("slider", "real IJRR `slider_depth` chunk (`--near 0.1 --far 5`)"),
    ("blocks", "simulated `blocks`, colour (RGB, per-channel alignment), `colour` preset"),
    ("blocks-per-channel", "the same, the paper's colour method (`train --per-channel`, 1 thread)"),
]
ABLATION = [("planes", "`fast`"), ("no-joint", "thresholds fixed at ±0.3 (`no-joint`)"),
            ("no-noise", "no noise injection (`no-noise`)"), ("fast-no-tv", "no total-variation term (`fast-no-tv`)")]
# The Gaussians' rows (the splat preset, from its own start and from fast's field) and fast's rows of the same scenes.
GAUSSIANS = [("planes", "splat", "splat-field", "`planes`"), ("object", "splat-object", "splat-field-object", "`object`"),
             ("room", "splat-room", "splat-field-room", "`room`")]
TIMED = [("planes", "`planes`"), ("object", "`object`"), ("room", "`room`"), ("slider", "the real chunk")]
CPU = {"avx512": "2 cores with AVX-512", "avx2+fma": "2 cores with AVX2 + FMA (no AVX-512)", "sse": "2 cores without AVX2"}


def read(path):
    return list(csv.DictReader(open(path))) if os.path.exists(path) else []


def score(r):
    return f"{float(r['psnr']):.2f} / {float(r['ssim']):.3f}"


class Quality:
    def __init__(self, rows):
        self.rows = rows

    def get(self, row, method="ours"):
        """{seed: csv row} of one suite row and method, in seed order."""
        out = {int(r["seed"]): r for r in self.rows if r["row"] == row and r["method"] == method}
        return dict(sorted(out.items()))

    def baseline(self, row, method):
        """A baseline does not depend on the training seed: the first seed's."""
        got = self.get(row, method)
        return next(iter(got.values()), None)

    def seeds_cell(self, row):
        ours = self.get(row)
        if not ours:
            return None
        first, *rest = ours.values()
        cell = f"**{score(first)}**"
        return cell + "".join(f", {score(r)}" for r in rest)

    def mean(self, row, seeds=None):
        ours = [r for s, r in self.get(row).items() if seeds is None or s in seeds]
        return (statistics.mean(float(r["psnr"]) for r in ours), statistics.mean(float(r["ssim"]) for r in ours)) if ours else None

    def any_row(self):
        """The row that names the suite's settings: planes' first seed, else the first."""
        return next(iter(self.get("planes").values()), next(iter(self.rows), None))


def seeds_text(seeds):
    seeds = list(seeds)
    if len(seeds) == 1:
        return f"seed {seeds[0]}"
    if seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"seeds {seeds[0]}–{seeds[-1]}"
    return "seeds " + ", ".join(map(str, seeds))


def ablation(q):
    """The ablation's rows that were run and the seeds all of them have."""
    ab = [(row, what) for row, what in ABLATION if q.get(row)]
    common = sorted(set.intersection(*(set(q.get(row)) for row, _ in ab))) if ab else []
    return (ab, common) if common else ([], [])


# The protocol of the suites whose recordings come from the ideal simulated sensor (no refractory period): their
# rows were trained with the counts read as they are.
PLAIN_COUNTS = ("Recordings of the ideal simulated sensor (no refractory period) were trained with `train --refractory 0`, the "
                "counts read as they are; the default learns the period, which on such a sensor stays at 0 or within "
                "microseconds of it (the random scenes' table in `docs/results.md` shows both).")


def headline(q):
    """The README's table and the lines under it."""
    first = q.any_row()
    if first is None:
        return ["No quality results yet: `bench/quality.sh` writes them."]
    lines = [f"PSNR dB / SSIM against the recording's frames, **{first['alignment']} alignment** (one log-affine map per",
             f"channel over the sequence, `eval`'s default); `{first['preset']}` preset, {first['steps']} steps, {first['threads']} threads",
             "unless named, the first seed in bold; the two baselines (direct integration, high-pass filter) integrate",
             "the same events with a threshold of 0.2. " + PLAIN_COUNTS, "",
             "| recording | seeds | ours | direct integration | high-pass filter |", "|---|---|---|---|---|"]
    for row, what in RECORDINGS:
        cell = q.seeds_cell(row)
        if cell is None:
            continue
        ours = q.get(row)
        di, hp = q.baseline(row, "direct_integration"), q.baseline(row, "high_pass_filter")
        lines.append(f"| {what} | {','.join(map(str, ours))} | {cell} | {score(di) if di else ''} | {score(hp) if hp else ''} |")
    ab, common = ablation(q)
    if len(ab) > 1:
        lines += ["", f"The ablation on `planes`, {seeds_text(common)}{' (means)' if len(common) > 1 else ''}: " +
                  "; ".join(f"{what} {q.mean(row, common)[0]:.2f} / {q.mean(row, common)[1]:.3f}" for row, what in ab) + "."]
    timed = [(what, q.get(row).get(1)) for row, what in TIMED if q.get(row).get(1)]
    if timed:
        cpu = CPU.get(timed[0][1]["cpu"], timed[0][1]["cpu"])
        lines += ["", f"Training ({first['steps']} steps, `evnerf train`'s wall time, seed 1) takes " +
                  ", ".join(f"{float(r['train_seconds']):.0f} s ({what})" for what, r in timed) + f" on {cpu} (a shared",
                  "machine: 5–25 % between runs)."]
    return lines


# The tables whose runs had no backdrop say so: their runs are what `--no-learn-background`
# trains, bit for bit.
NO_BACKDROP = ("These runs had no backdrop behind the samples (what `train --no-learn-background` trains, bit for bit); "
               "the learned backdrop, the default, is not measured on them yet.")


def ttq_reach(ttq):
    """Per build and scene with more than one preset: the first preset's PSNR at its last step, and the training
    seconds at which each preset first reaches it (None: not within its steps)."""
    out = []
    for isa, scene in dict.fromkeys((r["isa"], r["scene"]) for r in ttq):
        rs = [r for r in ttq if (r["isa"], r["scene"]) == (isa, scene)]
        presets = list(dict.fromkeys(r["preset"] for r in rs))
        if len(presets) < 2:
            continue
        target = float([r for r in rs if r["preset"] == presets[0]][-1]["psnr"])
        secs = {}
        for pr in presets:
            hit = [float(r["train_seconds"]) for r in rs if r["preset"] == pr and float(r["psnr"]) >= target - 1e-9]
            secs[pr] = hit[0] if hit else None
        out.append((isa, scene, target, secs))
    return out


def mesh_section(rows):
    """The mesh suite's table: per asset and mode, the training path against both baselines and the held-out views,
    each of ours the mean over the training seeds with every seed's PSNR beside it; runs that knew the backdrop's
    brightness (the field's protocol) in a second table beside the tool's defaults."""
    splats = [r for r in rows if r.get("preset", "").startswith("splat")]
    rows = [r for r in rows if not r.get("preset", "").startswith("splat")]
    known = [r for r in rows if r.get("background") not in ("", "learned")]
    rows = [r for r in rows if r.get("background") in ("", "learned")] or known
    if rows is known:
        known = []

    def runs(asset, mode, view, al, method="ours"):
        return [r for r in rows if (r["asset"], r["mode"], r["view"], r["alignment"], r["method"]) == (asset, mode, view, al, method)]

    def cell(asset, mode, view, al, method="ours"):
        rs = runs(asset, mode, view, al, method)
        if not rs:
            return "", None
        p, q = (statistics.mean(float(r[k]) for r in rs) for k in ("psnr", "ssim"))
        per_seed = f" ({', '.join(r['psnr'] for r in sorted(rs, key=lambda r: int(r['seed'])))})" if method == "ours" and len(rs) > 1 else ""
        return f"{p:.2f} / {q:.3f}{per_seed}", rs[0]
    first = rows[0]
    bg = first.get("background", "")
    given = ("the backdrop learned (`train`'s default), " if bg == "learned" else
             f"`train --background {bg}` (the backdrop's known luminance, as EventNeRF's runs know theirs), " if bg else
             "no backdrop (the last sample stops every ray), ")
    p = ["", "## Mesh scenes (`bench/mesh_suite.sh`)", "",
         "Real 3-D assets from Debian's `assimp-testmodels`, each normalised into the unit sphere and recorded by",
         "`evnerf simulate mesh` (346 × 260, one revolution of an orbit at 30° in one second, a grey background); grey",
         "with the default preset, colour (`--bayer`, an RGGB mosaic) with the `colour` preset; " + f"{first['steps']} steps, {first['threads']} threads, "
         "training " + "; ".join(f"{seeds_text(sorted({int(r['seed']) for r in rows if r['mode'] == m}))} in {m}"
                                 for m in dict.fromkeys(r["mode"] for r in rows)) + ", " + given +
         f"`--near {first.get('near', '0.3')} --far {first.get('far', '7.0')}`, an ideal sensor (the refractory period learned, as by default: it stays at or near 0). The held-out views lie on a second orbit at 50°, never trained on; only the model",
         "renders them, and beside it a flat frame (one brightness per channel, which the alignment fits) scores what",
         "rendering nothing of the object would. Ours is the mean over the seeds (each seed's PSNR in brackets); the",
         "baselines and the flat frame do not depend on the training seed. Three alignments: `global-log-affine` (eval's default), `eventnerf` (EventNeRF's fit) and",
         "`global-log-offset` (one log offset per channel, E-3DGS's correction). Training seconds are `train`'s wall time",
         "on a shared machine (other work running beside a run can make it 2–3 times as slow). A montage per asset and mode is in `bench/results/mesh/`: the",
         "training path's middle frame (truth | ours | direct integration | high-pass filter) above a held-out view",
         "(truth | ours), at the first seed.", "",
         "| asset | mode | path: ours | direct integration | high-pass filter | held-out: ours | flat frame | eventnerf | global-log-offset | training s | samples/ray |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    means, flats, spreads = {}, {}, {}
    for asset, mode in dict.fromkeys((r["asset"], r["mode"]) for r in rows):
        ours, r = cell(asset, mode, "path", "global-log-affine")
        novel, nr = cell(asset, mode, "novel", "global-log-affine")
        flat, fr = cell(asset, mode, "novel", "global-log-affine", "flat")
        held = [float(x["psnr"]) for x in runs(asset, mode, "novel", "global-log-affine")]
        if held:
            means.setdefault(mode, []).append(statistics.mean(held))
            if len(held) > 1:
                spreads.setdefault(mode, []).append(max(held) - min(held))
        if fr:
            flats.setdefault(mode, []).append(float(fr["psnr"]))
        timed = runs(asset, mode, "path", "global-log-affine")
        secs = statistics.mean(float(x["train_seconds"]) for x in timed) if timed else float("nan")
        p.append(f"| {asset} ({r['kind'] if r else ''}) | {mode} | {ours} | {cell(asset, mode, 'path', 'global-log-affine', 'direct_integration')[0]} | "
                 f"{cell(asset, mode, 'path', 'global-log-affine', 'high_pass_filter')[0]} | {novel} | {flat} | {cell(asset, mode, 'novel', 'eventnerf')[0]} | "
                 f"{cell(asset, mode, 'novel', 'global-log-offset')[0]} | {secs:.0f} | {r['samples_per_ray']} |")
    p.append("")
    for mode, v in means.items():
        flat = f" (a flat frame: {statistics.mean(flats[mode]):.2f} dB)" if len(flats.get(mode, [])) == len(v) else ""
        spread = f"; the seeds differ by {statistics.mean(spreads[mode]):.2f} dB per asset on average" if spreads.get(mode) else ""
        p.append(f"- {mode}: held-out views {statistics.mean(v):.2f} dB on average over {len(v)} assets{flat}{spread} (global-log-affine).")
    if known:
        p += protocols_table(rows, known)
    if splats:
        p += splat_mesh_table(rows, splats)
    return p


def splat_mesh_table(default, splats):
    """Gaussians (the `splat` preset, from its own start and, where run, from the default preset's field:
    preset `splat-from-field`) on the mesh suite beside the default preset's grey runs, held-out views and the
    training path, global-log-affine, at the seeds all ran (per-seed PSNRs in brackets)."""
    def pick(rs, asset, view, seeds):
        return sorted((r for r in rs if (r["asset"], r["mode"], r["view"], r["alignment"], r["method"]) ==
                       (asset, "grey", view, "global-log-affine", "ours") and int(r["seed"]) in seeds), key=lambda r: int(r["seed"]))
    def cell(rs):
        if not rs:
            return "", None
        m = statistics.mean(float(r["psnr"]) for r in rs)
        return f"{m:.2f} ({', '.join(r['psnr'] for r in rs)})" if len(rs) > 1 else f"{m:.2f}", m
    own = [r for r in splats if not r["preset"].endswith("-from-field")]
    taught = [r for r in splats if r["preset"].endswith("-from-field")]
    seeds = sorted({int(r["seed"]) for r in own} & {int(r["seed"]) for r in default if r["mode"] == "grey"})
    preset = own[0]["preset"] if own else "splat"
    p = ["", f"### Gaussians on the mesh suite (`PRESET_GREY={preset} MODES=grey bench/mesh_suite.sh`)", "",
         f"The grey recordings above trained by `{preset}` beside the default preset's runs of them, {seeds_text(seeds)}, the same steps, threads",
         "and backdrop (learned), global-log-affine; training seconds are `train`'s wall time on a shared machine. From the field:",
         f"`{preset}` started from and taught by the default preset's field of the same asset and seed (`START_FROM=OUT PRESET_GREY={preset}`,",
         "`train --start-from`; its seconds are its own, after the field's).", "",
         "| asset | held-out: default | held-out: splat | held-out: splat from the field | path: default | path: splat | path: splat from the field | training s: default / splat / from the field |",
         "|---|---|---|---|---|---|---|---|"]
    held = {"default": [], "splat": [], "taught": []}
    for asset in dict.fromkeys(r["asset"] for r in splats):
        d_novel, d_path = pick(default, asset, "novel", seeds), pick(default, asset, "path", seeds)
        s_novel, s_path = pick(own, asset, "novel", seeds), pick(own, asset, "path", seeds)
        t_novel, t_path = pick(taught, asset, "novel", seeds), pick(taught, asset, "path", seeds)
        if not (d_novel and (s_novel or t_novel)):
            continue
        (dn, dm), (sn, sm), (tn, tm) = cell(d_novel), cell(s_novel), cell(t_novel)
        if sm is not None:
            held["default"].append(dm), held["splat"].append(sm)
        if tm is not None:  # compared with the default at the seeds the taught runs have
            t_seeds = {int(r["seed"]) for r in t_novel}
            held["taught"].append((cell(pick(default, asset, "novel", t_seeds))[1], tm))
            if len(t_novel) < len(seeds):
                tn += f" (seed {', '.join(str(s) for s in sorted(t_seeds))})"
        secs = [f"{statistics.mean(float(r['train_seconds']) for r in rs):.0f}" if rs else "" for rs in (d_path, s_path, t_path)]
        p.append(f"| {asset} | {dn} | {sn} | {tn} | {cell(d_path)[0]} | {cell(s_path)[0]} | {cell(t_path)[0]} | {' / '.join(secs)} |")
    if held["splat"]:
        p += ["", f"- held-out views on average over {len(held['splat'])} assets: default {statistics.mean(held['default']):.2f} dB, "
              f"`{preset}` {statistics.mean(held['splat']):.2f} dB."]
    if held["taught"]:
        p += [f"- held-out views on average over the {len(held['taught'])} assets run from the field: default "
              f"{statistics.mean(d for d, _ in held['taught']):.2f} dB, `{preset}` from the field {statistics.mean(t for _, t in held['taught']):.2f} dB."]
    return p


def kernels_section(rows):
    """bench/splat_kernels.sh: the rasterizer's throughput and the Gaussians' step against Fast's, medians of one run."""
    by = {r["what"]: r for r in rows}
    p = ["", "## The Gaussian rasterizer and the Gaussians' step (`bench/splat_kernels.sh`)", "",
         f"`bench/bench_main.cpp` run {rows[0]['reps']} times, 2 threads, medians (range in brackets). A view: 346 × 260 random Gaussians about",
         "20 deep per pixel, projected, binned and composited; pairs are the (Gaussian, pixel) pairs the compositing tested, and the",
         "share of the FMA peak (measured by the same binary) counts the 47 adds and multiplies a pair costs (an FMA as two;",
         "compares, selects and the exponent's integer work not counted). The training pass renders 4096 scattered pixels of",
         "the 50 k view, keeps their lists and runs backward through compositing and projection. The step: the `splat` and",
         "`fast` presets' training step (1024 pixels at two poses) on the same short `planes` recording.", "",
         "| what | ms | pairs per second | of the FMA peak | ratio |", "|---|---|---|---|---|"]
    for what, label, ratio in [("view 2000", "view, 2 k Gaussians", "× the plain reference (every Gaussian at every pixel)"),
                               ("view 50000", "view, 50 k Gaussians", ""), ("view 200000", "view, 200 k Gaussians", ""),
                               ("training pass 50000", "training pass, 4096 pixels of 50 k", ""),
                               ("step splat", "`splat` training step", "× the speed of `fast`'s step"), ("step fast", "`fast` training step", "")]:
        r = by.get(what)
        if not r:
            continue
        pairs = f"{float(r['pairs_per_s']) / 1e6:.0f} M" if r["pairs_per_s"] else ""
        share = f"{100 * float(r['peak_share']):.0f} %" if r["peak_share"] else ""
        rat = f"{r['ratio']} ({r['ratio_min']}–{r['ratio_max']}) {ratio}" if r["ratio"] else ""
        p.append(f"| {label} | {r['ms']} ({r['ms_min']}–{r['ms_max']}) | {pairs} | {share} | {rat} |")
    if "fma peak gflops" in by:
        p += ["", f"The FMA peak of the same runs: {by['fma peak gflops']['ms']} GFLOP/s (2 threads)."]
    return p


def render_section(rows):
    """bench/render.sh: a whole view's render time per preset, alternating evals, with the quality it renders."""
    first = rows[0]
    p = ["", f"## Rendering a view (`bench/render.sh {first['asset']}`)", "",
         f"The mesh suite's `{first['asset']}` ({first['width']} × {first['height']}) trained by each preset with its defaults (seed {first['seed']}), then",
         f"scored by `evnerf eval` {first['reps']} times, the presets alternating, {first['threads']} threads; eval's seconds per render of the training",
         "path's frames, the median over the repetitions (range in brackets), and the ratio to the first preset's time taken per",
         "repetition (median, range). PSNR: the training path's frames and the held-out views, " + first["alignment"] + ".", "",
         "| preset | ms per view | speed vs first | path PSNR | held-out PSNR | training s |", "|---|---|---|---|---|---|"]
    for r in rows:
        p.append(f"| `{r['preset']}` | {r['ms_per_view']} ({r['ms_min']}–{r['ms_max']}) | {r['ratio_to_first']}× ({r['ratio_min']}–{r['ratio_max']}) | "
                 f"{r['path_psnr']} | {r['novel_psnr']} | {float(r['train_seconds']):.0f} |")
    return p


def view_section(rows):
    """bench/view.sh: evnerf view's frames a second while the camera moves, and the full-resolution frame at rest."""
    first = rows[0]
    p = ["", "## Viewing a scene (`bench/view.sh`)", "",
         f"The built-in `{first['scene']}` recorded at {first['width']} × {first['height']}, trained by `fast` (seed {first['seed']}) and by `splat` started from",
         f"that field, each served by `evnerf view` ({first['threads']} threads) and asked for frames by `bench/view_client.py` as the page asks:",
         "the camera orbits by 1° a frame, one frame in flight, at the resolution the page asks for while moving; then it rests",
         "and the full-resolution frame is timed (the page asks for it 150 ms after the camera stops, so a field's full frame arrives 150 ms plus that time after the camera rests). The viewers take turns,",
         f"{first['reps']} rounds; frames a second are the client's (HTTP, render and JPEG), medians with the range in brackets.", "",
         "| preset | while moving: size | frames a second | server ms a frame | full-resolution frame at rest, ms |", "|---|---|---|---|---|"]
    for r in rows:
        p.append(f"| `{r['preset']}` | {r['moving_width']} × {r['moving_height']} | {r['moving_fps']} ({r['moving_fps_min']}–{r['moving_fps_max']}) | "
                 f"{r['moving_server_ms']} | {r['rest_ms']} ({r['rest_ms_min']}–{r['rest_ms_max']}) |")
    return p


def protocols_table(default, known):
    """The tool's defaults (nothing known of the backdrop) beside the field's protocol (`train --background L`, the
    backdrop's brightness known, as EventNeRF's synthetic runs assume), global-log-affine, at the seeds both ran."""
    def psnr(rs, asset, mode, view, seeds, method="ours"):
        v = [float(r["psnr"]) for r in rs if (r["asset"], r["mode"], r["view"], r["alignment"], r["method"]) ==
             (asset, mode, view, "global-log-affine", method) and int(r["seed"]) in seeds]
        return statistics.mean(v) if v else None
    bg = known[0]["background"]
    pairs = [(a, m) for a, m in dict.fromkeys((r["asset"], r["mode"]) for r in known)]
    seeds = sorted({int(r["seed"]) for r in known} & {int(r["seed"]) for r in default})
    p = ["", f"### Two protocols: the backdrop learned (the tool's defaults) and known (`train --background {bg}`)", "",
         "The field's synthetic benchmarks give training the backdrop's brightness (EventNeRF composites its known",
         "background); the tool's defaults learn it. Same recordings, presets and steps as above, " + seeds_text(seeds) +
         ", global-log-affine; the flat frame scores rendering nothing of the object.", "",
         "| asset | mode | path: learned | path: known | held-out: learned | held-out: known | flat frame |", "|---|---|---|---|---|---|---|"]
    sums = {}
    for asset, mode in pairs:
        cells = [psnr(default, asset, mode, "path", seeds), psnr(known, asset, mode, "path", seeds),
                 psnr(default, asset, mode, "novel", seeds), psnr(known, asset, mode, "novel", seeds),
                 psnr(default + known, asset, mode, "novel", seeds, "flat")]
        for i, c in enumerate(cells):
            if c is not None:
                sums.setdefault((mode, i), []).append(c)
        p.append(f"| {asset} | {mode} | " + " | ".join("" if c is None else f"{c:.2f}" for c in cells) + " |")
    p.append("")
    for mode in dict.fromkeys(m for _, m in pairs):
        n = len(sums.get((mode, 3), []))
        if n and all(len(sums.get((mode, i), [])) == n for i in (2, 3, 4)):
            p.append(f"- {mode}: held-out views {statistics.mean(sums[(mode, 2)]):.2f} dB learned, {statistics.mean(sums[(mode, 3)]):.2f} dB known, "
                     f"flat frame {statistics.mean(sums[(mode, 4)]):.2f} dB (means over {n} assets).")
    return p


FORMAT_ORDER = ["text", "prophesee/evt2", "prophesee/evt3", "aedat4/lz4", "aedat4/zstd", "hdf5", "rosbag/none", "rosbag/lz4", "rosbag/bz2"]
FORMAT_NAMES = {"text": "IJRR events.txt (the reference)", "prophesee/evt2": "Prophesee EVT 2.0", "prophesee/evt3": "Prophesee EVT 3.0",
                "aedat4/lz4": "AEDAT4, LZ4 packets", "aedat4/zstd": "AEDAT4, Zstd packets", "hdf5": "HQF HDF5 (uncompressed)",
                "rosbag/none": "ROS bag, plain chunks", "rosbag/lz4": "ROS bag, lz4 chunks", "rosbag/bz2": "ROS bag, bz2 chunks"}


def formats_section(rows):
    """Reading speed per format, from bench/formats.sh."""
    p = ["", "## Reading speed per format (`bench/formats.sh`)", "",
         "Events per second a whole-file read delivers (`io` readers, times in seconds, checked), 2 M events of a 240 × 180",
         "sensor written by evnerf's writers and read from the page cache, `OMP_NUM_THREADS=2` (AEDAT4 decodes its packets",
         "on both threads; the other readers run on one); the median of the repetitions, interleaved, and their range; the",
         "IJRR text reader read in the same run is the reference.", "",
         "| build | CPU | format | M events/s (range) | against text | file MB |", "|---|---|---|---|---|---|"]
    key = {n: i for i, n in enumerate(FORMAT_ORDER)}
    for r in sorted(rows, key=lambda r: (r["isa"], key.get(r["format"], 99))):
        p.append(f"| {r['isa']} | {r['cpu']} | {FORMAT_NAMES.get(r['format'], r['format'])} | {r['meps']} ({r['meps_min']}–{r['meps_max']}) | "
                 f"{r['vs_text']}× | {r['file_mb']} |")
    return p


def factors_section(rows):
    """One effect of a real sensor at a time, from bench/sensor_factors.sh."""
    scenes = sorted({r["scene_seed"] for r in rows})
    p = ["", "## One sensor effect at a time (`bench/sensor_factors.sh`)", "",
         f"Random scene {', '.join(scenes)} recorded by an ideal sensor with one effect of the random sensor added, then by the",
         "realistic, the random and the DAVIS-like sensor whole; the default preset and steps, training seed 1, 2 threads, global-log-affine.",
         "By default training learns the refractory period, downward from the recording's bound; rows with `train --refractory`",
         "give it the sensor's and fix it (`docs/method.md`). The period column is the one each run ended with.", NO_BACKDROP, "",
         "| sensor | train | events | period µs | ours | direct integration | high-pass filter |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        p.append(f"| {r['what'].replace(', train --refractory', '')} | {('`' + r['train_flags'] + '`') if r['train_flags'] else 'default'} | "
                 f"{int(r['events']) / 1e6:.2f} M | {r.get('period_us', '')} | {r['psnr']} / {r['ssim']} | {r['di_psnr']} / {r['di_ssim']} | "
                 f"{r['hpf_psnr']} / {r['hpf_ssim']} |")
    return p


def poses_section(rows):
    """Poses only roughly known, from bench/poses.sh."""
    p = ["", "## Poses only roughly known (`bench/poses.sh`)", "",
         "Each scene simulated with the recorded poses perturbed (`simulate --pose-noise T,R --time-offset 0.01`: RMS",
         "error T world units and R degrees over the pose knots, half independent per knot and half a slow drift, the",
         "first pose exact; the pose clock 10 ms ahead), trained with the default preset and steps (training seed =",
         "simulation seed, 2 threads) without and with `train --refine-poses --learn-time-offset`, scored against the",
         "recording's frames (global-log-affine). The pose error is the mean at the slice boundaries against the true",
         "poses, of the recording's poses without refinement and of the refined ones with it. `slider` is the real IJRR",
         "chunk on its motion-capture poses (`--near 0.1 --far 5`), which has no true poses to score them against.", "",
         "| scene | seed | pose noise | refinement | ours | pose error | clock offset learned |",
         "|---|---|---|---|---|---|---|"]
    for r in rows:
        noise = "none" if float(r["noise_translation"]) == 0 and float(r["noise_rotation_deg"]) == 0 and float(r["offset_s"]) == 0 else \
            f"{float(r['noise_translation']) * 100:g} cm, {float(r['noise_rotation_deg']):g}°, {float(r['offset_s']) * 1e3:g} ms"
        if r["scene"] == "slider":
            noise = "as recorded (motion capture)"
        err = f"{float(r['error_translation']) * 100:.2f} cm, {float(r['error_rotation_deg']):.2f}°" if noise.endswith("ms") else ""
        off = f"{float(r['learned_offset_s']) * 1e3:.2f} ms" if r["refine"] == "1" else ""
        p.append(f"| {r['scene']} | {r['seed']} | {noise} | {'on' if r['refine'] == '1' else 'off'} | {r['psnr']} / {r['ssim']} | {err} | {off} |")
    return p


def surfaces_section(rows):
    """bench/mesh_export.sh: how close export's mesh.ply and points.ply lie to the true surface."""
    first = rows[0]
    p = ["", "## Exported surfaces (`bench/mesh_export.sh`)", "",
         "Mesh-suite assets (grey) trained with the default preset (`--near 0.3 --far 7.0`, training seed "
         f"{first['seed']}, {first['threads']} threads), then `evnerf export` with its defaults (mesh lattice "
         f"{first['resolution']} cells along the longest side). Each exported vertex or point against the true surface that the",
         "recording's depth maps see (every other pixel of every frame, back-projected): accuracy is the distance from an exported",
         "point to the nearest true one, completeness from a true point to the nearest exported one; median and 90th percentile",
         "in % of the true surface's bounding-box diagonal (the diagonal in world units beside them). Accuracy's upper tail is",
         "the fog a field leaves in an object scene's empty space (no event forbids it; the points of background pixels end in it)",
         "and the object's underside, which no camera saw and no true point covers.", "",
         "| asset | file | elements | accuracy median / 90 % | completeness median / 90 % | diagonal |", "|---|---|---|---|---|---|"]
    for r in rows:
        p.append(f"| {r['asset']} | `{r['file']}` | {int(r['elements'])} | {r['accuracy_median_pct']} / {r['accuracy_p90_pct']} % | "
                 f"{r['completeness_median_pct']} / {r['completeness_p90_pct']} % | {r['diagonal']} |")
    return p


def results_page(q, robust, ttq, speed=(), mesh=(), formats=(), factors=(), profile=(), poses=(), render=(), kernels=(), surfaces=(),
                 viewer=()):
    first = q.any_row()
    p = ["# Results at the current defaults", "",
         "After this page you know how well the default preset reconstructs each suite, against what, measured",
         "how, and how fast its network runs against PyTorch. The page is written by `bench/results.py` from the CSV",
         "files the benchmarks leave in `bench/results/` (`bench/quality.sh`, `bench/robustness.sh`,",
         "`bench/time_to_quality.sh`, `bench/pairs.sh`, `bench/formats.sh`, `bench/mesh_suite.sh`, `bench/mesh_export.sh`, `bench/sensor_factors.sh`, `bench/step_profile.sh`, `bench/poses.sh`, `bench/render.sh`, `bench/view.sh`, `bench/splat_kernels.sh`); the README's table comes from the same files. Every quality",
         "figure is PSNR dB / SSIM against the recording's frames under the named alignment",
         "(`global-log-affine`, `eval`'s default: one log-affine map per channel fitted over the sequence); the",
         "baselines are `evnerf baselines`, direct integration and the high-pass filter of the same events with a",
         "contrast of 0.2. A run's bits depend on its thread count, so the figures compare across machines only at",
         "the thread count named.", "", "## Built-in scenes and the real chunk", ""]
    if first is None:
        p += ["Not measured yet: `bench/quality.sh` writes `bench/results/quality.csv`.", ""]
    else:
        cpu = CPU.get(first["cpu"], first["cpu"])
        p += [f"`bench/quality.sh` (every row: `evnerf simulate` → `evnerf train --seed S --threads {first['threads']}` → `evnerf eval`),",
              f"`{first['preset']}` preset unless named, {first['steps']} steps, on {cpu}. " + PLAIN_COUNTS, "",
              "| recording | seed | ours | direct integration | high-pass filter | alignment |", "|---|---|---|---|---|---|"]
        for row, what in RECORDINGS:
            ours = q.get(row)
            for i, (seed, r) in enumerate(ours.items()):
                di, hp = (q.get(row, "direct_integration").get(seed), q.get(row, "high_pass_filter").get(seed)) if i == 0 else (None, None)
                p.append(f"| {what if i == 0 else ''} | {seed} | {score(r)} | {score(di) if di else ''} | {score(hp) if hp else ''} | "
                         f"{r['alignment'] if i == 0 else ''} |")
        oracle = [float(r["oracle_both_psnr"]) for r in q.get("planes").values() if r.get("oracle_both_psnr")]
        if oracle:
            p += ["", "What limits `planes`: a slider moving along x never shows the events how bright one image row is",
                  "against the next. `eval`'s row and column offset oracle (offsets per row and column fitted to the truth,",
                  f"a diagnosis and never a score) lifts `planes` to {min(oracle):.2f}{'' if min(oracle) == max(oracle) else f'–{max(oracle):.2f}'} dB: the gap to the",
                  "truth is brightness no event observes."]
        ab, common = ablation(q)
        if len(ab) > 1:
            p += ["", f"## Ablation (`planes`, the tool's presets, {seeds_text(common)})", "", "| variant | mean PSNR / SSIM | per seed |",
                  "|---|---|---|"]
            for row, what in ab:
                m = q.mean(row, common)
                p.append(f"| {what} | {m[0]:.2f} / {m[1]:.3f} | " +
                         ", ".join(f"{s}: {float(r['psnr']):.2f}" for s, r in q.get(row).items() if s in common) + " |")
        gauss = [(row, sp, sf, what, sorted(set(q.get(row)) & set(q.get(sp)))) for row, sp, sf, what in GAUSSIANS if q.get(sp)]
        if gauss:
            p += ["", "## Gaussians (`splat`) beside `fast`", "",
                  "The same scenes trained by the `splat` preset from its own start (`bench/quality.sh splat splat-object splat-room`) and",
                  "started from and taught by `fast`'s field of the same seed (`train --start-from`; `bench/quality.sh splat-field",
                  "splat-field-object splat-field-room`), the seeds both presets have, the same steps, threads and alignment; the seconds",
                  "are `evnerf train`'s wall time (a shared machine; the Gaussians from the field add theirs to the field's).",
                  "", "| scene | seed | `fast` | `splat` | `splat` from `fast` | seconds `fast` / `splat` / from `fast` |", "|---|---|---|---|---|---|"]
            for row, sp, sf, what, seeds in gauss:
                for i, seed in enumerate(seeds):
                    f, g, h = q.get(row)[seed], q.get(sp)[seed], q.get(sf).get(seed)
                    from_field = f"{float(h['train_seconds']):.0f}" if h else ""
                    p.append(f"| {what if i == 0 else ''} | {seed} | {score(f)} | {score(g)} | {score(h) if h else ''} | "
                             f"{float(f['train_seconds']):.0f} / {float(g['train_seconds']):.0f} / {from_field} |")
        timed = [(what, q.get(row).get(1)) for row, what in TIMED if q.get(row).get(1)]
        if timed:
            p += ["", "## Training time", "", f"`evnerf train`'s wall time for {first['steps']} steps at seed 1, {first['threads']} threads, on {cpu}, "
                  "from the same runs: " + ", ".join(f"{what} {float(r['train_seconds']):.1f} s" for what, r in timed) + ". The machine",
                  "is shared: the same run's time varies by 5–25 % from run to run; speed claims are ratios measured in one run",
                  "(`bench/README.md`)."]
    p += ["", "## Random scenes (`bench/robustness.sh`)", ""]
    if not robust:
        p += ["Not measured at the current defaults yet: `bench/robustness.sh` writes `bench/results/robustness.csv`."]
    else:
        p += ["Procedural scenes (`simulate random --seed N`), each recorded by every sensor named (`--sensor`), the",
              "default preset and steps, training seed 1, eval's default alignment; a scene passes when ours beats both",
              "baselines by 3 dB PSNR and 0.10 SSIM. The refractory period: the sensor's, and the one training learned.",
              "The backdrop: `learned` is the default; `none` marks a run without one (what `train --no-learn-background`",
              "trains, bit for bit), beside the default where both were run; a sensor with `none` rows only is not measured",
              "with the backdrop yet.", "",
              "| scene | sensor | path | period µs: sensor / learned | backdrop | ours | direct integration | high-pass filter | passes |",
              "|---|---|---|---|---|---|---|---|---|"]
        for r in robust:
            period = f"{r['sensor_period_us']} / {r['period_us']}" if r.get("period_us") else ""
            p.append(f"| {r['scene_seed']} | {r['sensor']} | {r['path']} | {period} | {r.get('backdrop') or 'none'} | {r['psnr']} / {r['ssim']} | "
                     f"{r['di_psnr']} / {r['di_ssim']} | {r['hpf_psnr']} / {r['hpf_ssim']} | {'yes' if r['pass'] == '1' else 'no'} |")
        p.append("")
        for sensor, backdrop in dict.fromkeys((r["sensor"], r.get("backdrop") or "none") for r in robust):
            rs = [r for r in robust if r["sensor"] == sensor and (r.get("backdrop") or "none") == backdrop]
            p.append(f"- {sensor} sensor, backdrop {backdrop}: {sum(r['pass'] == '1' for r in rs)} of {len(rs)} pass, mean {statistics.mean(float(r['psnr']) for r in rs):.2f} dB / "
                     f"{statistics.mean(float(r['ssim']) for r in rs):.3f}; the collapse check fired on {sum(r['collapse_fired'] == '1' for r in rs)}.")
    if factors:
        p += factors_section(factors)
    if mesh:
        p += mesh_section(mesh)
    if surfaces:
        p += surfaces_section(surfaces)
    if render:
        p += render_section(render)
    if viewer:
        p += view_section(viewer)
    if kernels:
        p += kernels_section(kernels)
    if poses:
        p += poses_section(poses)
    if speed:
        p += ["", "## Network speed against PyTorch (`bench/pairs.sh`)", "",
              "The fused MLP's forward + backward (samples per second) right next to the PyTorch peer's same network in its",
              "best configuration for the CPU, 2 threads; the median of the pairs' ratios and their range, and ours as a",
              "share of the FMA peak the same build measures. `ISA=avx2` is the AVX2 + FMA build (`-DEVNERF_NO_AVX512=ON`)",
              "on the same CPU, against OpenBLAS's AVX2 kernels.", "",
              "| build | CPU | peer's kernels | width | pairs | ours / PyTorch (range) | ours samples/s | of the FMA peak |",
              "|---|---|---|---|---|---|---|---|"]
        for r in speed:
            p.append(f"| {r['isa']} | {r['cpu']} | {r['peer_core']} | {r['width']} | {r['pairs']} | {r['ratio']}× ({r['ratio_min']}–{r['ratio_max']}) | "
                     f"{int(r['ours_samples_per_s']):,} | {100 * float(r['peak_fraction']):.0f} % of {float(r['peak_gflops']):.0f} GFLOP/s |")
    splat_profile = [r for r in profile if r.get("preset") == "splat"]
    profile = [r for r in profile if r.get("preset") != "splat"]
    if profile:
        isas = list(dict.fromkeys(r["isa"] for r in profile))
        share = {(r["isa"], r["part"]): float(r["share"]) for r in profile}
        parts = sorted(dict.fromkeys(r["part"] for r in profile), key=lambda q: -max(share.get((i, q), 0) for i in isas))
        p += ["", "## Where a training step's time goes (`bench/step_profile.sh`)", "",
              "The `fast` preset's training step (1024 pixels at two poses, a warmed model) sampled by `perf` on one thread,",
              "each sample given to the part of the step whose code it was in; shares of the step's samples per build",
              f"(CPU: {profile[0]['cpu']}).", "",
              "| part | " + " | ".join(isas) + " |", "|---|" + "---|" * len(isas)]
        for q in parts:
            p.append(f"| {q} | " + " | ".join(f"{100 * share.get((i, q), 0):.1f} %" for i in isas) + " |")
    if splat_profile:
        p += ["", "The `splat` preset's step on the same recording and pixels (`PRESET=splat bench/step_profile.sh`), build "
              f"{splat_profile[0]['isa']}:", "", "| part | share |", "|---|---|"]
        for r in splat_profile:
            p.append(f"| {r['part']} | {100 * float(r['share']):.1f} % |")
    if formats:
        p += formats_section(formats)
    if ttq:
        p += ["", "## Time to quality (`bench/time_to_quality.sh`)", "",
              "One run per scene and preset scored at regular steps (`bench/results/time_to_quality.png`, the CSV beside it), `--refractory 0` (an ideal sensor),",
              "seed 1, 2 threads; the presets take turns on each scene, so their seconds compare within a build. The backdrop column says whether one was",
              "learned behind the scene (the default) or none was (`train --no-learn-background`);",
              "build `avx2` is the same runs on the AVX2 + FMA path (`ISA=avx2`, `-DEVNERF_NO_AVX512=ON`; `time_to_quality_avx2.png`), from a run of its own:",
              "training seconds of separate runs on this shared machine compare only roughly (`bench/README.md`).", "",
              "| build | scene | preset | backdrop | steps | training s | ours | best baseline |", "|---|---|---|---|---|---|---|---|"]
        for r in ttq:
            p.append(f"| {r['isa']} | {r['scene']} | {r['preset']} | {r.get('backdrop') or 'none'} | {r['steps']} | {float(r['train_seconds']):.0f} | "
                     f"{float(r['psnr']):.2f} / {float(r['ssim']):.3f} | {float(r['best_baseline_psnr']):.2f} / {float(r['best_baseline_ssim']):.3f} |")
        reach = ttq_reach(ttq)
        if reach:
            p += ["", "Seconds each preset takes to reach the first preset's score at its last step (the first row of a scene is that preset; "
                  "a dash: not reached within the steps run):", "", "| build | scene | target (first preset, last step) | " +
                  " | ".join(f"`{x}` s" for x in reach[0][3]) + " |", "|---|---|---|" + "---|" * len(reach[0][3])]
            for isa, scene, target, secs in reach:
                p.append(f"| {isa} | {scene} | {target:.2f} dB | " + " | ".join("–" if v is None else f"{v:.0f}" for v in secs.values()) + " |")
    return "\n".join(p) + "\n"


def readme(text, block):
    if BEGIN not in text or END not in text:
        sys.exit(f"README.md: no '{BEGIN}' … '{END}' block to fill")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return head + BEGIN + "\n" + "\n".join(block) + "\n" + END + tail


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default=os.path.join(ROOT, "bench", "results"))
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()
    q = Quality(read(os.path.join(a.results, "quality.csv")))
    robust = read(os.path.join(a.results, "robustness.csv"))
    ttq = [dict(r, isa=isa) for isa, name in (("native", "time_to_quality"), ("avx2", "time_to_quality_avx2"))
           for r in read(os.path.join(a.results, f"{name}.csv"))]
    speed = [r for isa in ("native", "avx2") for r in read(os.path.join(a.results, f"speed_{isa}.csv"))]
    mesh = read(os.path.join(a.results, "mesh.csv"))
    formats = [r for isa in ("native", "avx2") for r in read(os.path.join(a.results, f"formats_{isa}.csv"))]
    factors = read(os.path.join(a.results, "sensor_factors.csv"))
    profile = [dict(r, preset=preset) for preset, name in (("fast", "step_profile"), ("splat", "step_profile_splat"))
               for isa in ("native", "avx2") for r in read(os.path.join(a.results, f"{name}_{isa}.csv"))]
    poses = read(os.path.join(a.results, "poses.csv"))
    render = read(os.path.join(a.results, "render.csv"))
    kernels = read(os.path.join(a.results, "splat_kernels.csv"))
    surfaces = read(os.path.join(a.results, "mesh_export.csv"))
    viewer = read(os.path.join(a.results, "view.csv"))
    pages = {os.path.join(ROOT, "docs", "results.md"): results_page(q, robust, ttq, speed, mesh, formats, factors, profile, poses, render,
                                                                    kernels, surfaces, viewer)}
    rd = os.path.join(ROOT, "README.md")
    pages[rd] = readme(open(rd).read(), headline(q))
    stale = []
    for path, want in pages.items():
        have = open(path).read() if os.path.exists(path) else ""
        if have == want:
            continue
        if a.check:
            stale.append(os.path.relpath(path, ROOT))
        else:
            tmp = path + ".tmp"
            open(tmp, "w").write(want)
            os.replace(tmp, path)
            print(f"wrote {os.path.relpath(path, ROOT)}")
    if stale:
        sys.exit("results: " + ", ".join(stale) + " differ from bench/results/*.csv; run bench/results.py")


if __name__ == "__main__":
    main()
