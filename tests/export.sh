#!/usr/bin/env bash
# `evnerf export` read by an independent parser: a small object scene trained briefly by the splat preset
# and by the default field, exported, and each file read here in Python (struct and json, not evnerf's
# reader): gaussians.ply has 3D Gaussian splatting's header and property order, unit quaternions, no
# Gaussian under 1/255 opacity, centres inside the scene; points.ply's points lie in front of the cameras;
# a field's mesh.ply has triangles over its vertices, near its points; transforms.json has one
# camera-to-world matrix per slice boundary, a rotation with OpenGL's axes. A
# checkpoint that is not one is refused by name, and nothing is written. ctest runs this as cli.export.
# Usage: tests/export.sh EVNERF_BINARY
set -euo pipefail
EV=$1
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_export.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EV" simulate object --out "$work/rec" --width 48 --height 36 > /dev/null 2>&1
for preset in splat fast; do
  "$EV" train "$work/rec" --preset "$preset" --out "$work/$preset" --iterations 150 --pixels 256 --quiet > "$work/$preset.log" 2>&1 ||
    fail "train $preset: $(tail -3 "$work/$preset.log")"
  "$EV" export "$work/$preset/model.ckpt" --out "$work/$preset/export" --stride 2 --min-opacity 0.5 > "$work/$preset.export.log" 2>&1 ||
    fail "export $preset: $(cat "$work/$preset.export.log")"
done
[ -f "$work/splat/export/gaussians.ply" ] || fail "no gaussians.ply for a Gaussian scene"
[ ! -e "$work/fast/export/gaussians.ply" ] || fail "gaussians.ply for a field"
[ -f "$work/fast/export/mesh.ply" ] || fail "no mesh.ply for a field: $(cat "$work/fast.export.log")"
[ ! -e "$work/splat/export/mesh.ply" ] || fail "mesh.ply for a Gaussian scene"
python3 - "$work" <<'PY'
import json, math, struct, sys
w = sys.argv[1]

def ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode().splitlines()
    assert head[0] == "ply" and head[1] == "format binary_little_endian 1.0", head[:2]
    n = next(int(l.split()[2]) for l in head if l.startswith("element vertex"))
    nf = next((int(l.split()[2]) for l in head if l.startswith("element face")), 0)
    props = [(l.split()[1], l.split()[2]) for l in head if l.startswith("property") and not l.startswith("property list")]
    if nf:
        assert head[-2] == "property list uchar uint vertex_indices", head[-2]
    fmt = "<" + "".join("f" if t == "float" else "B" for t, _ in props)
    size = struct.calcsize(fmt)
    assert len(data) - end == n * size + 13 * nf, (path, n, size, nf, len(data) - end)
    rows = [struct.unpack_from(fmt, data, end + i * size) for i in range(n)]
    faces = [struct.unpack_from("<BIII", data, end + n * size + 13 * i) for i in range(nf)]
    assert all(f[0] == 3 and max(f[1:]) < n for f in faces)
    if nf:
        return [name for _, name in props], rows, [f[1:] for f in faces]
    return [name for _, name in props], rows

names, rows = ply(f"{w}/splat/export/gaussians.ply")
want = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
        "rot_0", "rot_1", "rot_2", "rot_3"]
assert names == want, names
assert len(rows) > 100, len(rows)
col = {n: i for i, n in enumerate(names)}
for r in rows:
    q = [r[col[f"rot_{k}"]] for k in range(4)]
    assert abs(math.sqrt(sum(v * v for v in q)) - 1) < 1e-5, q
    assert 1 / (1 + math.exp(-r[col["opacity"]])) >= 1 / 255 - 1e-9
    assert r[col["f_dc_0"]] == r[col["f_dc_1"]] == r[col["f_dc_2"]]  # grey
    assert all(math.isfinite(v) for v in r)
    assert all(abs(r[col[a]]) < 50 for a in "xyz")

cams = json.load(open(f"{w}/splat/export/transforms.json"))
assert cams["camera_model"] == "OPENCV" and cams["w"] == 48 and cams["h"] == 36, cams
frames = cams["frames"]
assert len(frames) >= 2
for f in frames:
    m = f["transform_matrix"]
    R = [row[:3] for row in m[:3]]
    det = (R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1]) - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0]) +
           R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0]))
    assert abs(det - 1) < 1e-6, det
    assert m[3] == [0, 0, 0, 1], m[3]

for model in ("splat", "fast"):
    names, rows = ply(f"{w}/{model}/export/points.ply")
    assert names == ["x", "y", "z", "luminance", "red", "green", "blue"], names
    assert len(rows) > 0, model
    # Every point lies in front of the first camera that sees it: behind no camera's image plane at once.
    f0 = frames[0]["transform_matrix"]
    c = [f0[k][3] for k in range(3)]
    back = [-f0[k][2] for k in range(3)]  # OpenGL's camera looks along -z: the viewing direction
    ahead = sum(1 for r in rows if sum((r[k] - c[k]) * back[k] for k in range(3)) > 0)
    assert ahead > 0.5 * len(rows), (model, ahead, len(rows))
# The field's surface: triangles over its vertices, and its vertices near the points at the rendered depth
# (within a tenth of the points' extent for most of them: the mesh is of the same surface).
names, verts, tris = ply(f"{w}/fast/export/mesh.ply")
assert names == ["x", "y", "z", "luminance", "red", "green", "blue"], names
assert len(tris) > 50, len(tris)
_, pts = ply(f"{w}/fast/export/points.ply")
ext = max(max(p[k] for p in pts) - min(p[k] for p in pts) for k in range(3))
sample = pts[:: max(1, len(pts) // 300)]
near = sum(1 for v in verts[:: max(1, len(verts) // 300)]
           if min(sum((v[k] - p[k]) ** 2 for k in range(3)) for p in sample) < (0.1 * ext) ** 2)
assert near > 0.5 * len(verts[:: max(1, len(verts) // 300)]), (near, len(verts), ext)
print("export: gaussians.ply, points.ply, mesh.ply and transforms.json read by an independent parser")
PY
# gaussians.ply rendered by an independent 3DGS rasterizer (numpy, 3D Gaussian splatting's forward pass: each
# covariance carried to the image by the projection's Jacobian and widened by 0.3 px², α = o·exp(−½ dᵀΣ⁻¹d)
# skipped under 1/255 and capped at 0.99, front to back until the transmittance would fall under 10⁻⁴) at the
# first camera of transforms.json, against `evnerf render`'s depth there (the expected depth times the
# opacity): the silhouettes (where the depth passes half the opaque pixels' median) overlap by IoU ≥ 0.8 and
# the depths agree.
"$EV" render "$work/splat/model.ckpt" --out "$work/splat/render" --novel 0 > /dev/null 2>&1 || fail "render splat"
/usr/bin/python3 - "$work" <<'PY' || fail "gaussians.ply rendered by an independent rasterizer differs from evnerf's render"
import json, sys
import numpy as np
w = sys.argv[1]
data = open(f"{w}/splat/export/gaussians.ply", "rb").read()
end = data.index(b"end_header\n") + len(b"end_header\n")
g = np.frombuffer(data[end:], dtype="<f4").reshape(-1, 17).astype(np.float64)
mu, opacity, scale, q = g[:, 0:3], 1 / (1 + np.exp(-g[:, 9])), np.exp(g[:, 10:13]), g[:, 13:17]
cams = json.load(open(f"{w}/splat/export/transforms.json"))
fx, fy, cx, cy, W, H = cams["fl_x"], cams["fl_y"], cams["cx"], cams["cy"], cams["w"], cams["h"]
m = np.array(cams["frames"][0]["transform_matrix"])
R = m[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # back to the OpenCV axes
p = (mu - m[:3, 3]) @ R  # camera frame
qw, qx, qy, qz = q.T
rot = np.stack([1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy),
                2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx),
                2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)], 1).reshape(-1, 3, 3)
M = rot * scale[:, None, :]
cov3 = np.einsum("nij,nkj->nik", M, M)
x, y, z = p.T
keep = z > 1e-3
zs = np.where(keep, z, 1.0)
J = np.zeros((len(z), 2, 3))
J[:, 0, 0], J[:, 0, 2] = fx / zs, -fx * x / zs**2
J[:, 1, 1], J[:, 1, 2] = fy / zs, -fy * y / zs**2
T = J @ R.T
cov2 = np.einsum("nij,njk,nlk->nil", T, cov3, T) + 0.3 * np.eye(2)
det = cov2[:, 0, 0] * cov2[:, 1, 1] - cov2[:, 0, 1] ** 2
keep &= det > 0
conic = np.stack([cov2[:, 1, 1], -cov2[:, 0, 1], cov2[:, 0, 0]], 1) / np.where(det > 0, det, 1)[:, None]
u, v = fx * x / zs + cx, fy * y / zs + cy
px, py = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
trans, depth, done = np.ones((H, W)), np.zeros((H, W)), np.zeros((H, W), bool)
for i in np.argsort(z):
    if not keep[i]:
        continue
    dx, dy = px - u[i], py - v[i]
    a = np.minimum(0.99, opacity[i] * np.exp(-0.5 * (conic[i, 0] * dx * dx + 2 * conic[i, 1] * dx * dy + conic[i, 2] * dy * dy)))
    a = np.where((a >= 1 / 255) & ~done, a, 0.0)
    stop = trans * (1 - a) < 1e-4
    done |= stop
    a = np.where(stop, 0.0, a)
    depth += trans * a * z[i]
    trans *= 1 - a
ours = np.load(f"{w}/splat/render/boundary_0000_depth.npy")
assert ours.shape == (H, W), ours.shape
opaque = (1 - trans) > 0.5
assert opaque.sum() > 0.05 * W * H, "the exported Gaussians cover almost nothing"
level = 0.5 * np.median(depth[opaque] / (1 - trans[opaque]))
a, b = depth > level, ours > level
iou = (a & b).sum() / max(1, (a | b).sum())
rel = np.abs(depth - ours).mean() / max(1e-9, np.abs(ours).mean())
print(f"export: gaussians.ply by an independent 3DGS rasterizer: silhouette IoU {iou:.3f}, depth differs by {100 * rel:.2f} %")
assert iou >= 0.8 and rel < 0.05, (iou, rel)
PY
# A checkpoint that is not one: refused by name, nothing written.
echo "not a checkpoint" > "$work/bad.ckpt"
if "$EV" export "$work/bad.ckpt" --out "$work/bad" > "$work/bad.log" 2>&1; then fail "export read a file that is no checkpoint"; fi
grep -q "bad.ckpt" "$work/bad.log" || fail "the error does not name the file: $(cat "$work/bad.log")"
[ ! -e "$work/bad/transforms.json" ] || fail "export wrote a file for a checkpoint it could not read"
echo "export: the files other tools open, checked"
