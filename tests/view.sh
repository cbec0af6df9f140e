#!/usr/bin/env bash
# `evnerf view`: a small object scene trained briefly by the default field and by the splat preset from it, each
# served on a free loopback port and asked over HTTP by Python's urllib (not evnerf's code):
#   - the page and its script are served; /info holds the sensor, the recorded and novel paths and the tone;
#   - the frame at a recorded pose equals `evnerf render`'s luminance there (its .npy through /info's tone)
#     within JPEG error, at full and at quarter resolution, and depth frames come back in colour;
#   - bad requests (no pose, eleven numbers, a reflection, a scale of 99, show=colour) get 400 and a reason;
#   - a client that sends a request and hangs up mid-frame leaves the server answering;
#   - a second viewer on the same port, and a file that is not a checkpoint, are refused by name.
# Where Debian's chromium and chromium-driver are installed, the same page is then opened in headless Chromium,
# driven through chromedriver's WebDriver protocol (urllib again): the canvas shows the recorded pose as
# `render` does; a mouse drag turns the camera (the pose the page last asked for differs, the canvas
# changes and is not blank), and once the camera rests the canvas holds the full-resolution frame the
# server gives for that pose; the frames a second the page received while dragging are printed. Without
# them that part is left out, saying so (scripts/test.sh installs both). ctest runs this as cli.view.
# Usage: tests/view.sh EVNERF_BINARY
set -euo pipefail
EV=$(realpath "$1")
BROWSER=0
if command -v chromium > /dev/null && command -v chromedriver > /dev/null; then BROWSER=1
else echo "view: chromium or chromedriver is not installed: the browser's part is left out, the HTTP part runs"; fi
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_view.XXXXXX")
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Starts a viewer of $1 on a free port; sets PORT.
start_view() {
  "$EV" view "$1" --port 0 > "$work/view.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 1 300); do
    PORT=$(grep -o '127\.0\.0\.1:[0-9]*' "$work/view.log" | head -1 | cut -d: -f2 || true)
    [ -n "$PORT" ] && return 0
    kill -0 "${pids[-1]}" 2> /dev/null || fail "view $1 ended: $(cat "$work/view.log")"
    sleep 0.2
  done
  fail "view $1 did not start: $(cat "$work/view.log")"
}

"$EV" simulate object --out "$work/rec" --width 64 --height 48 > /dev/null 2>&1
for preset in fast splat; do
  from=()
  [ "$preset" = splat ] && from=(--start-from "$work/fast/model.ckpt")  # Gaussians on the field's surfaces
  "$EV" train "$work/rec" --preset "$preset" "${from[@]}" --out "$work/$preset" --iterations 200 --pixels 512 --quiet > "$work/$preset.log" 2>&1 ||
    fail "train $preset: $(tail -3 "$work/$preset.log")"
  "$EV" render "$work/$preset/model.ckpt" --out "$work/$preset/render" --novel 0 > /dev/null 2>&1 || fail "render $preset"
  start_view "$work/$preset/model.ckpt"
  # Debian's interpreter, whose numpy and PIL scripts/test.sh installs.
  /usr/bin/python3 - "$work/$preset" "$PORT" "$preset" "$BROWSER" <<'PY' || fail "view $preset"
import base64, io, json, socket, subprocess, sys, time, urllib.error, urllib.request
import numpy as np
from PIL import Image

run, port, preset, browser = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4] == "1"
base = f"http://127.0.0.1:{port}/"

def get(path):
    with urllib.request.urlopen(base + path, timeout=60) as r:
        return r.status, r.headers, r.read()

def refused(path, words):
    try:
        get(path)
    except urllib.error.HTTPError as e:
        body = e.read().decode()
        assert e.code == 400 and words in body, (path, e.code, body)
        return
    raise AssertionError(f"{path}: accepted")

status, head, page = get("")
assert status == 200 and b"<canvas" in page and head["Content-Type"].startswith("text/html"), head
assert b"evnerfViewer" in get("viewer.js")[2]
info = json.loads(get("info")[2])
W, H = info["width"], info["height"]
assert (W, H) == (64, 48) and info["kind"] == ("gaussians" if preset == "splat" else "field"), info
assert len(info["recorded"]) >= 2 and len(info["novel"]) == 60 and all(len(p) == 12 for p in info["recorded"])

def tone(x):  # /info's tone, as the page's frames are toned
    t = info["tone"]
    if t["kind"] == "clamp":
        return np.clip(x, 0, 1)
    return np.clip((np.log(np.maximum(x, 0) + t["offset"]) - t["lo"]) / (t["hi"] - t["lo"]), 0, 1)

def query(pose, scale=1, show="intensity"):
    return "pose=" + ",".join(repr(float(v)) for v in pose) + f"&scale={scale}&show={show}"

def frame(q):
    status, head, body = get("frame?" + q)
    assert status == 200 and head["Content-Type"] == "image/jpeg" and float(head["X-Frame-Ms"]) >= 0, head
    return np.asarray(Image.open(io.BytesIO(body)).convert("L"), dtype=np.float64) / 255, head

truth = tone(np.load(f"{run}/render/boundary_0000.npy"))
got, head = frame(query(info["recorded"][0]))
assert got.shape == (H, W) and head["X-Frame-Size"] == f"{W}x{H}", (got.shape, head["X-Frame-Size"])
err = np.abs(got - truth).mean()
assert err < 0.02, f"the frame at recorded pose 0 differs from render's by {err:.4f} on average"
small, head = frame(query(info["recorded"][0], scale=4))
assert small.shape == (H // 4, W // 4) and head["X-Frame-Size"] == f"{W // 4}x{H // 4}", small.shape
status, head, body = get("frame?" + query(info["recorded"][-1], show="depth"))
depth = np.asarray(Image.open(io.BytesIO(body)).convert("RGB"), dtype=np.float64)
assert depth.shape == (H, W, 3) and np.abs(depth[..., 0] - depth[..., 2]).max() > 30, "a depth frame is not in colour"

p = info["recorded"][0]
refused("frame?scale=1", "no pose")
refused("frame?pose=" + ",".join(["1"] * 11), "twelve numbers")
refused("frame?" + query([-v if i in (0, 4, 8) else v for i, v in enumerate(p)]), "not a rotation")
refused("frame?" + query(p, scale=99), "scale '99'")
refused("frame?" + query(p, show="colour"), "show 'colour'")
refused("frame?pose=" + ",".join(["nan"] * 12), "not a finite number")

# A client that asks for a frame and hangs up before it comes.
for _ in range(3):
    s = socket.create_connection(("127.0.0.1", port))
    s.sendall(("GET /frame?" + query(info["recorded"][1]) + " HTTP/1.1\r\nHost: x\r\n\r\n").encode())
    s.close()
assert get("info")[0] == 200

if browser:
    import shutil
    drv_port = socket.socket()
    drv_port.bind(("127.0.0.1", 0))
    dport = drv_port.getsockname()[1]
    drv_port.close()
    driver = subprocess.Popen(["chromedriver", f"--port={dport}"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wd = f"http://127.0.0.1:{dport}"

    def call(method, path, body=None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(wd + path, data=data, method=method, headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as r:
            return json.loads(r.read())["value"]

    try:
        for _ in range(100):
            try:
                call("GET", "/status")
                break
            except Exception:
                time.sleep(0.1)
        caps = {"capabilities": {"alwaysMatch": {"browserName": "chrome", "goog:chromeOptions": {
            "binary": shutil.which("chromium"), "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=900,700"]}}}}
        sid = call("POST", "/session", caps)["sessionId"]
        js = lambda script: call("POST", f"/session/{sid}/execute/sync", {"script": script, "args": []})

        def wait(cond, what, seconds=120):
            end = time.time() + seconds
            while time.time() < end:
                v = js(f"const s = window.evnerfViewer; return s ? ({cond}) : null;")
                if v:
                    return v
                time.sleep(0.1)
            raise AssertionError(f"the page never reached: {what}; its state: {js('return JSON.stringify(window.evnerfViewer)')}")

        def canvas():
            url = js("return document.getElementById('view').toDataURL('image/png');")
            return np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("L"), dtype=np.float64) / 255

        call("POST", f"/session/{sid}/url", {"url": base})
        wait("s.shownScale === 1 && !s.inFlight && !s.dirty", "a full-resolution frame")
        first = canvas()
        assert first.shape == (H, W), first.shape
        err = np.abs(first - truth).mean()
        assert err < 0.03, f"the page's first frame differs from render's by {err:.4f} on average"
        pose0 = js("return window.evnerfViewer.lastQuery;")
        before = js("return window.evnerfViewer.framesReceived;")
        el = call("POST", f"/session/{sid}/element", {"using": "css selector", "value": "#view"})
        key = next(iter(el))
        steps = [{"type": "pointerMove", "duration": 0, "origin": {key: el[key]}, "x": 0, "y": 0}, {"type": "pointerDown", "button": 0}]
        steps += [{"type": "pointerMove", "duration": 100, "origin": "pointer", "x": 4, "y": 1}] * 20
        steps += [{"type": "pointerUp", "button": 0}]
        t0 = time.time()
        call("POST", f"/session/{sid}/actions", {"actions": [{"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"}, "actions": steps}]})
        dragged = time.time() - t0
        during = js("return window.evnerfViewer.framesReceived;") - before
        wait("s.shownScale === 1 && !s.inFlight && !s.dirty && performance.now() - s.lastMove > 300", "rest after the drag")
        q = js("return window.evnerfViewer.lastQuery;")
        assert q != pose0, "the drag did not move the camera"
        after = canvas()
        assert after.std() > 0.02, "the canvas is blank after the drag"
        assert np.abs(after - first).mean() > 0.005, "the canvas did not change with the camera"
        server, _ = frame(q)
        err = np.abs(after - server).mean()
        assert err < 0.02, f"the canvas differs from the server's frame for its pose by {err:.4f} on average"
        print(f"browser: {during} frames in a {dragged:.1f} s drag ({during / dragged:.1f} a second), {preset}, {W}x{H}")
        call("DELETE", f"/session/{sid}")
    finally:
        driver.terminate()
        driver.wait(timeout=30)
    assert get("info")[0] == 200  # the closed tab leaves the server up
print(f"view {preset}: ok")
PY
  if [ "$preset" = fast ]; then
    # The same port again, while the first viewer holds it; a file that is not a checkpoint.
    if "$EV" view "$work/fast/model.ckpt" --port "$PORT" > "$work/second.log" 2>&1; then fail "a second viewer took port $PORT"; fi
    grep -q "127.0.0.1:$PORT: cannot listen there" "$work/second.log" || fail "second viewer: $(cat "$work/second.log")"
    if "$EV" view "$work/rec/events.txt" --port 0 > "$work/bad.log" 2>&1; then fail "view took events.txt as a checkpoint"; fi
    grep -q "events.txt.*not an evnerf checkpoint" "$work/bad.log" || fail "bad checkpoint: $(cat "$work/bad.log")"
  fi
  kill "${pids[-1]}"
  wait "${pids[-1]}" 2> /dev/null || true
done
echo "view: ok"
