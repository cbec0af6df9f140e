"""A client of `evnerf view` that asks for frames as its page does (bench/view.sh): the camera starts at
the first recorded pose and orbits the scene's focus about the page's up axis by 1 degree a frame, one
request in flight, each at info's moving_scale; then it rests and asks for the full-resolution frame. Prints
one JSON object: the frames a second while moving (frames over the wall time waited), the server's median
milliseconds per moving frame (X-Frame-Ms), the full-resolution frame's wall milliseconds, and the sizes.
Usage: view_client.py PORT FRAMES"""
import json
import math
import statistics
import sys
import time
import urllib.request

import numpy as np


def main():
    port, frames = int(sys.argv[1]), int(sys.argv[2])
    base = f"http://127.0.0.1:{port}/"
    info = json.loads(urllib.request.urlopen(base + "info", timeout=60).read())
    p = np.array(info["recorded"][0], dtype=float).reshape(3, 4)
    R, t = p[:, :3], p[:, 3]
    target = t + R[:, 2] * info["focus"]
    up = np.array(info["up"], dtype=float)
    up /= np.linalg.norm(up)

    def rot(axis, a):  # Rodrigues
        x, y, z = axis
        K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
        return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K

    def ask(R, t, scale):
        pose = np.hstack([R, t[:, None]]).reshape(-1)
        q = "pose=" + ",".join(repr(float(v)) for v in pose) + f"&scale={scale}&show=intensity"
        with urllib.request.urlopen(base + "frame?" + q, timeout=120) as r:
            r.read()
            return float(r.headers["X-Frame-Ms"]), r.headers["X-Frame-Size"]

    ask(R, t, info["moving_scale"])  # a first frame: connections and caches warm
    server, size = [], None
    start = time.perf_counter()
    for _ in range(frames):
        Q = rot(up, math.radians(1.0))
        R, t = Q @ R, target + Q @ (t - target)
        ms, size = ask(R, t, info["moving_scale"])
        server.append(ms)
    moving = time.perf_counter() - start
    rest = []
    for _ in range(3):
        t0 = time.perf_counter()
        ask(R, t, 1)
        rest.append(1e3 * (time.perf_counter() - t0))
    mw, mh = (int(v) for v in size.split("x"))
    print(json.dumps({"width": info["width"], "height": info["height"], "moving_width": mw, "moving_height": mh,
                      "moving_fps": frames / moving, "moving_server_ms": statistics.median(server),
                      "rest_ms": statistics.median(rest)}))


if __name__ == "__main__":
    main()
