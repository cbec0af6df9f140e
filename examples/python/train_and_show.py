"""Train evnerf from Python and look at what it learned, notebook style.

    PYTHONPATH=build/examples/python /usr/bin/python3 examples/python/train_and_show.py [RECORDING] [--iterations N]

RECORDING is anything evnerf.load reads (IJRR folder, HDF5, ROS bag, EventNeRF or Robust e-NeRF folder);
without one, the built-in `planes` scene is simulated in memory. The figure (views, depth, the frames, the
loss curve) is shown on screen where there is a display and saved as PNG (--figure) either way.
"""
import argparse
import os

import numpy as np
import matplotlib

if not os.environ.get("DISPLAY"):
    matplotlib.use("Agg")  # no screen: draw into the PNG only
import matplotlib.pyplot as plt

import evnerf

# %% The recording: events as numpy arrays, without a copy.
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("recording", nargs="?")
parser.add_argument("--iterations", type=int, default=1500)
parser.add_argument("--preset", default="fast", choices=evnerf.variants)
parser.add_argument("--threads", type=int, default=0)
parser.add_argument("--figure", default="evnerf_python.png")
args = parser.parse_args()

data = evnerf.load(args.recording) if args.recording else evnerf.simulate("planes")
print(data)
ev = data.events
print(f"events: {len(ev.t)} over {ev.t[-1] - ev.t[0]:.2f} s, {np.mean(ev.p > 0):.0%} ON")

# %% Train, watching the loss through the callback (returning False would stop the run).
losses = []


def every_step(step, loss, thresholds):
    losses.append(loss)
    if step % 250 == 0:
        print(f"step {step:5d}  loss {np.mean(losses[-250:]):.4f}  mean B+ {thresholds[:, 0].mean():.3f}  B- {thresholds[:, 1].mean():.3f}")


model = evnerf.train(data, preset=args.preset, iterations=args.iterations, threads=args.threads, callback=every_step)
print(model, f"{model.run['seconds']:.1f} s")

# %% Render at recorded poses and at a novel one (halfway between two boundaries, shifted sideways).
poses = model.boundary_poses
picks = [poses[0], poses[len(poses) // 2], poses[-1]]
novel = poses[len(poses) // 3].copy()
novel[:3, 3] += 0.05 * novel[:3, 0]  # 5 cm along the camera's x axis
views = [model.render(p) for p in picks + [novel]]

# %% Score against the frames (evaluation only) where the recording has them.
scores = None
if len(data.frame_times):
    result = evnerf.evaluate(model, data)
    scores = {name: (m["psnr"], m["ssim"]) for name, m in result["methods"].items()}
    print(f"scores ({result['alignment']}):", {k: f"{p:.2f} dB / {s:.3f}" for k, (p, s) in scores.items()})

# %% The figure: intensity in log scale (what the events constrain), depth, and the loss.
fig, ax = plt.subplots(3, 4, figsize=(13, 8))
for k, (img, depth) in enumerate(views):
    title = "novel" if k == len(picks) else f"boundary {[0, len(poses) // 2, len(poses) - 1][k]}"
    ax[0, k].imshow(np.log(np.clip(img, 1e-3, None)), cmap="gray")
    ax[0, k].set_title(title)
    ax[1, k].imshow(depth, cmap="viridis")
for k in range(min(3, len(data.frame_times))):
    ax[2, k].imshow(data.frame(len(data.frame_times) * (k + 1) // 4), cmap="gray", vmin=0, vmax=1)
    ax[2, k].set_title("a frame (evaluation only)")
ax[2, 3].plot(losses)
ax[2, 3].set_yscale("log")
ax[2, 3].set_title("loss per step")
for a in ax.flat[:-1]:
    a.axis("off")
if scores:
    fig.suptitle("  ".join(f"{k}: {p:.1f} dB" for k, (p, _) in scores.items()))
fig.tight_layout()
fig.savefig(args.figure, dpi=80)
print("wrote", args.figure)
if matplotlib.get_backend().lower() != "agg":
    plt.show()
