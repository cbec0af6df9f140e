#!/usr/bin/env python3
"""Stacks the montages `evnerf eval` writes (ground truth | ours | direct integration | high-pass filter at
the middle frame, each aligned as eval scores it) into one labelled picture for the README.

Usage: bench/montage.py OUT.png LABEL MONTAGE.png [LABEL MONTAGE.png ...]
Each row is scaled to TILE pixels per panel width (environment, default 160) so the picture stays small."""
import os
import sys

from PIL import Image, ImageDraw

COLUMNS = ("ground truth", "evnerf (fast)", "direct integration", "high-pass filter")


def main(argv):
    if len(argv) < 3 or len(argv) % 2 == 0:
        sys.exit(__doc__)
    out, pairs = argv[0], list(zip(argv[1::2], argv[2::2]))
    tile = int(os.environ.get("TILE", "160"))
    rows = []
    for label, path in pairs:
        im = Image.open(path).convert("RGB")
        # eval's montage: the panels side by side, 2 white pixels between them (io::montage).
        w = (im.width - 2 * (len(COLUMNS) - 1)) // len(COLUMNS)
        if w * len(COLUMNS) + 2 * (len(COLUMNS) - 1) != im.width:
            sys.exit(f"{path}: {im.width} pixels wide is not {len(COLUMNS)} panels 2 pixels apart")
        h = round(im.height * tile / w)
        panels = [im.crop((k * (w + 2), 0, k * (w + 2) + w, im.height)).resize((tile, h), Image.LANCZOS) for k in range(len(COLUMNS))]
        row = Image.new("RGB", (tile * len(COLUMNS), h), "white")
        for k, panel in enumerate(panels):
            row.paste(panel, (k * tile, 0))
        rows.append((label, row))
    left, top, gap = 64, 16, 4
    width = left + tile * len(COLUMNS)
    height = top + sum(r.height + gap for _, r in rows)
    canvas = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(canvas)
    for i, c in enumerate(COLUMNS):
        draw.text((left + i * tile + 4, 2), c, fill="black")
    y = top
    for label, r in rows:
        canvas.paste(r, (left, y))
        draw.text((4, y + r.height // 2 - 5), label, fill="black")
        y += r.height + gap
    tmp = out + ".tmp.png"
    canvas.save(tmp, optimize=True)
    os.replace(tmp, out)
    print(f"wrote {out} ({width}x{height})")


if __name__ == "__main__":
    main(sys.argv[1:])
