// evnerf view's page script. The camera lives here (camera to world: x right, y down, z forward); frames
// come from the evnerf process (GET /frame). At most one frame is in flight and it carries the latest
// camera; while the camera moves the page asks for a coarser frame (info.moving_scale), and once it has
// rested for 150 ms for the full resolution. window.evnerfViewer exposes the state to tests.
"use strict";

const $ = (id) => document.getElementById(id);
const canvas = $("view");
const ctx = canvas.getContext("2d");

// 3-vectors and row-major 3 × 3 matrices.
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const mul = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const norm = (a) => Math.hypot(a[0], a[1], a[2]);
const col = (R, j) => [R[0][j], R[1][j], R[2][j]];
const matVec = (R, v) => [0, 1, 2].map((i) => R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2]);
const matMul = (A, B) => [0, 1, 2].map((i) => [0, 1, 2].map((j) => A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j]));
// Rotation by angle a about the unit axis u (Rodrigues).
function axisAngle(u, a) {
  const n = norm(u), [x, y, z] = [u[0] / n, u[1] / n, u[2] / n], c = Math.cos(a), s = Math.sin(a), t = 1 - c;
  return [
    [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
    [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
    [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
  ];
}
// Keeps R a rotation after many small steps (Gram–Schmidt on its columns).
function orthonormal(R) {
  let x = col(R, 0), y = col(R, 1);
  x = mul(x, 1 / norm(x));
  y = sub(y, mul(x, x[0] * y[0] + x[1] * y[1] + x[2] * y[2]));
  y = mul(y, 1 / norm(y));
  const z = [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]];
  return [0, 1, 2].map((i) => [x[i], y[i], z[i]]);
}
const fromNumbers = (p) => ({ R: [[p[0], p[1], p[2]], [p[4], p[5], p[6]], [p[8], p[9], p[10]]], t: [p[3], p[7], p[11]] });
const toNumbers = (c) => [0, 1, 2].flatMap((i) => [c.R[i][0], c.R[i][1], c.R[i][2], c.t[i]]);

const state = {
  info: null,
  camera: null,           // { R, t }
  target: null,           // the point the camera orbits
  show: "intensity",
  dirty: true,            // the camera or the view changed since the last request
  inFlight: false,
  lastMove: -1e9,
  shownScale: 0,          // the scale of the frame on the canvas (0: none yet)
  framesReceived: 0,
  lastFrameMs: null,      // the server's time for the last frame
  lastPose: null,         // the pose of the frame on the canvas (the numbers sent)
  lastQuery: null,        // the query of the frame on the canvas
  lastError: null,
  times: [],              // arrival times of the last frames (frames per second received)
};
window.evnerfViewer = state;

function setPose(numbers) {
  state.camera = fromNumbers(numbers);
  state.target = add(state.camera.t, mul(col(state.camera.R, 2), state.info.focus));
  changed();
}
function changed() {
  state.dirty = true;
  state.lastMove = performance.now();
}

function orbit(dx, dy) {
  const c = state.camera, k = 0.006;
  const Q = matMul(axisAngle(state.info.up, -dx * k), axisAngle(col(c.R, 0), -dy * k));
  c.R = orthonormal(matMul(Q, c.R));
  c.t = add(state.target, matVec(Q, sub(c.t, state.target)));
  changed();
}
function pan(dx, dy) {
  const c = state.camera, k = Math.max(norm(sub(c.t, state.target)), 1e-3) / canvas.clientHeight;
  const move = add(mul(col(c.R, 0), -dx * k), mul(col(c.R, 1), -dy * k));
  c.t = add(c.t, move);
  state.target = add(state.target, move);
  changed();
}
function zoom(delta) {
  const c = state.camera, f = Math.exp(delta * 0.001);
  c.t = add(state.target, mul(sub(c.t, state.target), f));
  changed();
}

let drag = null;
canvas.addEventListener("contextmenu", (e) => e.preventDefault());
canvas.addEventListener("pointerdown", (e) => {
  drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 };
  canvas.setPointerCapture(e.pointerId);
});
canvas.addEventListener("pointermove", (e) => {
  if (!drag || !state.camera) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX;
  drag.y = e.clientY;
  if (drag.pan) pan(dx, dy);
  else orbit(dx, dy);
});
canvas.addEventListener("pointerup", () => (drag = null));
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  if (state.camera) zoom(e.deltaY);
}, { passive: false });

function pathPoses() { return state.info[$("which").value]; }
function onPath() {
  const poses = pathPoses(), i = Math.min(Number($("path").value), poses.length - 1);
  $("path").max = String(poses.length - 1);
  $("pathIndex").textContent = `${i + 1} / ${poses.length}`;
  setPose(poses[i]);
}
$("path").addEventListener("input", onPath);
$("which").addEventListener("change", () => { $("path").value = "0"; onPath(); });
$("show").addEventListener("change", () => { state.show = $("show").value; changed(); });

async function request(scale) {
  state.inFlight = true;
  state.dirty = false;
  const numbers = toNumbers(state.camera);
  const query = `pose=${numbers.map((x) => x.toPrecision(9)).join(",")}&scale=${scale}&show=${state.show}`;
  try {
    const res = await fetch(`frame?${query}`, { cache: "no-store" });
    if (!res.ok) throw new Error(await res.text());
    const ms = Number(res.headers.get("X-Frame-Ms"));
    const bitmap = await createImageBitmap(await res.blob());
    ctx.imageSmoothingEnabled = true;
    ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
    state.shownScale = scale;
    state.lastFrameMs = ms;
    state.lastPose = numbers;
    state.lastQuery = query;
    state.framesReceived += 1;
    const now = performance.now();
    state.times.push(now);
    while (state.times.length && now - state.times[0] > 1000) state.times.shift();
    $("stats").textContent = `${bitmap.width}×${bitmap.height} in ${ms.toFixed(0)} ms · ${state.times.length} frames/s`;
    $("status").textContent = "";
    state.lastError = null;
  } catch (err) {
    state.lastError = String(err.message || err);
    $("status").textContent = state.lastError;
  } finally {
    state.inFlight = false;
  }
}

function tick() {
  if (state.camera && !state.inFlight) {
    const moving = performance.now() - state.lastMove < 150;
    if (state.dirty) request(moving ? state.info.moving_scale : 1);
    else if (!moving && state.shownScale !== 1) request(1);
  }
  requestAnimationFrame(tick);
}

async function start() {
  try {
    const res = await fetch("info", { cache: "no-store" });
    if (!res.ok) throw new Error(await res.text());
    state.info = await res.json();
  } catch (err) {
    $("status").textContent = `cannot read the scene: ${err.message || err}`;
    return;
  }
  const info = state.info;
  canvas.width = info.width;
  canvas.height = info.height;
  canvas.style.width = `${Math.min(2, Math.max(1, Math.floor(900 / info.width))) * info.width}px`;
  $("title").textContent = `${info.name} (${info.kind})`;
  $("path").max = String(info.recorded.length - 1);
  onPath();
  requestAnimationFrame(tick);
}
start();
