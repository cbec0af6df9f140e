#!/usr/bin/env python3
"""Compares two training runs or two evaluations (tests/formats.sh, tests/rosbag.sh). Exit 0 when equal.
  compare_runs.py params A/model.ckpt B/model.ckpt    the parameters and Adam's moments are byte-identical
                                                      (the checkpoints may differ in the recorded source path)
  compare_runs.py metrics A/metrics.json B/metrics.json  every method's PSNR and SSIM agree to 1e-9"""
import json
import struct
import sys


def params(path):
    """io/checkpoint.hpp: magic, version, name, counts, step, box, density length, background, the refractory period's
    record (period, its Adam moments, learned), loss, architecture, then
    the parameters and Adam's m and v (the metadata with the source path follows)."""
    b = open(path, "rb").read()
    o = 16 + 8 + struct.unpack_from("<Q", b, 16)[0]
    count = struct.unpack_from("<Q", b, o)[0]
    o += 8 + 8 + 8 + 48 + 8 + 8 + 32
    for _ in range(2):  # loss, architecture
        o += 8 + struct.unpack_from("<Q", b, o)[0]
    return b[o:o + count * 12]


what, a, b = sys.argv[1:4]
if what == "params":
    sys.exit(0 if params(a) == params(b) else 1)
ma, mb = (json.load(open(p))["methods"] for p in (a, b))
sys.exit(0 if ma.keys() == mb.keys() and all(abs(ma[k]["psnr"] - mb[k]["psnr"]) < 1e-9 and abs(ma[k]["ssim"] - mb[k]["ssim"]) < 1e-9 for k in ma) else 1)
