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
# A checkpoint that is not one: refused by name, nothing written.
echo "not a checkpoint" > "$work/bad.ckpt"
if "$EV" export "$work/bad.ckpt" --out "$work/bad" > "$work/bad.log" 2>&1; then fail "export read a file that is no checkpoint"; fi
grep -q "bad.ckpt" "$work/bad.log" || fail "the error does not name the file: $(cat "$work/bad.log")"
[ ! -e "$work/bad/transforms.json" ] || fail "export wrote a file for a checkpoint it could not read"
echo "export: the files other tools open, checked"
