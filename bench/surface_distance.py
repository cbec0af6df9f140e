#!/usr/bin/env python3
"""How close an export's surfaces lie to a simulated recording's true surface (bench/mesh_export.sh).

The true surface: every finite pixel of every depth map of the recording (depth/frame_*.npy, z-depth along
the optical axis, the pixel centre at x + 0.5), back-projected with calib.txt's pinhole (the simulator's
cameras have no distortion) at the frame's pose (groundtruth.txt, interpolated: linear in position, slerp
in rotation). Prints two CSV rows (mesh.ply's vertices, points.ply's points): the asset, seed, threads,
resolution, the file, its element count, accuracy (each exported point to the nearest true point) and
completeness (each true point to the nearest exported point), median and 90th percentile, in % of the true
surface's bounding-box diagonal, and that diagonal.
Usage: surface_distance.py RECORDING EXPORT_DIR ASSET SEED THREADS RESOLUTION
"""
import os
import struct
import sys

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation, Slerp


def read_ply_xyz(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode().splitlines()
    n = next(int(l.split()[2]) for l in head if l.startswith("element vertex"))
    props = [l.split()[1] for l in head if l.startswith("property") and not l.startswith("property list")]
    fmt = "<" + "".join("f" if t == "float" else "B" for t in props)
    size = struct.calcsize(fmt)
    rows = np.array([struct.unpack_from(fmt, data, end + i * size)[:3] for i in range(n)], dtype=np.float64)
    return rows.reshape(-1, 3)


def true_surface(rec, pixel_stride=2):
    fx, fy, cx, cy = [float(v) for v in open(os.path.join(rec, "calib.txt")).read().split()[:4]]
    gt = np.loadtxt(os.path.join(rec, "groundtruth.txt"))
    slerp = Slerp(gt[:, 0], Rotation.from_quat(gt[:, 4:8]))
    frames = [l.split() for l in open(os.path.join(rec, "images.txt")) if l.strip()]
    pts = []
    for t, path in frames:
        t = min(max(float(t), gt[0, 0]), gt[-1, 0])
        name = os.path.splitext(os.path.basename(path))[0] + ".npy"
        depth_file = os.path.join(rec, "depth", name)
        if not os.path.exists(depth_file):
            continue
        z = np.load(depth_file)[::pixel_stride, ::pixel_stride].astype(np.float64)
        ys, xs = np.mgrid[0:z.shape[0], 0:z.shape[1]]
        xs = xs * pixel_stride + 0.5
        ys = ys * pixel_stride + 0.5
        ok = np.isfinite(z) & (z > 0)
        cam = np.stack([(xs[ok] - cx) / fx * z[ok], (ys[ok] - cy) / fy * z[ok], z[ok]], axis=1)
        pos = np.array([np.interp(t, gt[:, 0], gt[:, k]) for k in (1, 2, 3)])
        pts.append(slerp([t]).apply(cam) + pos)
    if not pts:
        sys.exit(f"surface_distance: {rec} has no depth maps")
    return np.concatenate(pts)


def main():
    rec, exp, asset, seed, threads, res = sys.argv[1:7]
    truth = true_surface(rec)
    rng = np.random.default_rng(0)
    if len(truth) > 400000:
        truth = truth[rng.choice(len(truth), 400000, replace=False)]
    diag = float(np.linalg.norm(truth.max(0) - truth.min(0)))
    t_tree = cKDTree(truth)
    for name in ("mesh.ply", "points.ply"):
        path = os.path.join(exp, name)
        if not os.path.exists(path):
            continue
        xyz = read_ply_xyz(path)
        if len(xyz) == 0:
            print(f"{asset},{seed},{threads},{res},{name},0,nan,nan,nan,nan,{diag:.4f}")
            continue
        acc = t_tree.query(xyz)[0] / diag * 100
        comp = cKDTree(xyz).query(truth)[0] / diag * 100
        print(f"{asset},{seed},{threads},{res},{name},{len(xyz)},{np.median(acc):.3f},{np.percentile(acc, 90):.3f},"
              f"{np.median(comp):.3f},{np.percentile(comp, 90):.3f},{diag:.4f}")


if __name__ == "__main__":
    main()
