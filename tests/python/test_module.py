"""The Python module: numpy in and out, training with a callback, rendering, scoring, errors.

Run by ctest (python.module) with PYTHONPATH at the built module; by hand:
    PYTHONPATH=build/examples/python /usr/bin/python3 -m pytest tests/python
"""
import json
import os
import signal
import threading
import time

import numpy as np
import pytest

import evnerf

W, H = 48, 36


@pytest.fixture(scope="module")
def planes():
    return evnerf.simulate("planes", width=W, height=H, seed=1)


def arrays_of(d):
    """The dataset as the plain numpy arrays a user's own loader would hand over."""
    e = d.events
    frames = np.stack([d.frame(i) for i in range(len(d.frame_times))])
    return dict(x=np.array(e.x, dtype=np.int32), y=np.array(e.y, dtype=np.int64), t=np.array(e.t), p=(np.array(e.p) > 0),
                width=d.width, height=d.height, intrinsics=np.array(d.intrinsics[:4]), poses=d.poses,
                frame_times=d.frame_times, frames=frames)


def test_events_are_views_not_copies(planes):
    e = planes.events
    assert e.x.dtype == np.uint16 and e.y.dtype == np.uint16 and e.t.dtype == np.float64 and e.p.dtype == np.int8
    assert len(e.x) == len(planes) > 1000
    again = planes.events
    assert np.shares_memory(e.x, again.x) and np.shares_memory(e.t, again.t)  # the same memory each time
    assert not e.t.flags.writeable  # the stream's invariants (time order, sensor) cannot be broken from Python
    with pytest.raises(ValueError):
        e.t[0] = 1.0
    assert set(np.unique(e.p)) <= {-1, 1}
    assert np.all(np.diff(e.t) >= 0) and e.x.max() < W and e.y.max() < H


def test_views_keep_the_dataset_alive():
    d = evnerf.simulate("planes", width=16, height=12)
    t = d.events.t
    first = t.copy()
    del d
    import gc
    gc.collect()
    assert np.array_equal(t, first)


def test_round_trip_numpy_train_render_numpy(planes):
    d = evnerf.Dataset(**arrays_of(planes))
    assert len(d) == len(planes) and np.array_equal(d.events.t, planes.events.t)
    assert np.array_equal(d.events.p, planes.events.p)
    m = evnerf.train(d, iterations=20, threads=2, seed=3)
    assert m.variant == "fast" and m.step == 20 and m.run["steps"] == 20
    assert 0 <= m.run["refractory"] <= 0.005  # learned by default; a given one stays, 0 reads the counts as they are
    assert evnerf.train(d, iterations=2, threads=2, seed=3, refractory=2e-4).run["refractory"] == 2e-4
    assert evnerf.train(d, iterations=2, threads=2, seed=3, refractory=0).run["refractory"] is None
    img, depth = m.render(m.boundary_poses[5])
    assert img.shape == (H, W) and depth.shape == (H, W) and img.dtype == np.float32
    # Depth is the samples' weighted depth: a ray that passes them all to the backdrop (learned by default) has less.
    assert np.all(np.isfinite(img)) and np.all(depth >= 0) and depth.max() > 0 and img.std() > 0
    # Any pose: a 7-vector is the same pose as its matrix.
    P = m.boundary_poses[5]
    q = np.array([P[0, 3], P[1, 3], P[2, 3], *quaternion_of(P[:3, :3])])
    assert np.allclose(m.render(q)[0], img, atol=1e-5)
    # Determinism: same seed and threads, same model.
    m2 = evnerf.train(d, iterations=20, threads=2, seed=3)
    assert np.array_equal(m2.render(P)[0], img) and np.array_equal(m2.thresholds, m.thresholds)
    # The total-variation weight is a keyword: it changes the model; a negative one is refused.
    m3 = evnerf.train(d, iterations=20, threads=2, seed=3, tv=0.3)
    assert not np.array_equal(m3.render(P)[0], img)
    with pytest.raises(evnerf.Error, match="train: tv must be >= 0, got -1"):
        evnerf.train(d, iterations=2, threads=1, tv=-1.0)
    # fast's own weight given by hand is the same model; off, another; a variant without the term refuses one.
    m9 = evnerf.train(d, iterations=20, threads=2, seed=3, tv=0.1)
    assert np.array_equal(m9.render(P)[0], img)
    m10 = evnerf.train(d, iterations=20, threads=2, seed=3, tv=0.0)
    assert not np.array_equal(m10.render(P)[0], img)
    with pytest.raises(evnerf.Error, match="weight of 0.3 for a variant without the term"):
        evnerf.train(d, iterations=2, threads=1, tv=0.3, preset="paper")
    # The parameter average is a keyword: off, training takes the same steps (the same thresholds) but the
    # renders are those of the trained parameters; a decay of 1 is refused.
    m4 = evnerf.train(d, iterations=20, threads=2, seed=3, average=0.0)
    assert np.array_equal(m4.thresholds, m.thresholds) and not np.array_equal(m4.render(P)[0], img)
    with pytest.raises(evnerf.Error, match=r"train: average must be in \[0, 1\), got 1"):
        evnerf.train(d, iterations=2, threads=1, average=1.0)


def quaternion_of(R):
    w = np.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    return [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]


def test_callback_sees_every_step_and_can_stop(planes):
    seen = []

    def cb(step, loss, thresholds):
        seen.append((step, loss, thresholds.copy()))
        return step < 7

    m = evnerf.train(planes, iterations=50, threads=1, callback=cb)
    assert [s for s, _, _ in seen] == list(range(1, 8))
    assert m.step == 7 and m.run["stopped"]
    assert all(np.isfinite(l) and l > 0 for _, l, _ in seen)
    n = len(m.boundary_times) - 1
    assert seen[-1][2].shape == (n, 2) and np.array_equal(seen[-1][2], m.thresholds)
    assert np.all(seen[-1][2][:, 0] > 0) and np.all(seen[-1][2][:, 1] < 0)  # B+ > 0, B- < 0


def test_callback_exception_stops_training_and_propagates(planes):
    def cb(step, loss, thresholds):
        if step == 3:
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        evnerf.train(planes, iterations=50, threads=1, callback=cb)


def test_ctrl_c_stops_training(planes):
    def cb(step, loss, thresholds):
        if step == 2:
            signal.raise_signal(signal.SIGINT)

    # Python's own handler, whatever the test runner inherited: a shell starts background jobs with SIGINT
    # ignored, and an ignored signal would let the run go to its end.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            evnerf.train(planes, iterations=50, threads=1, callback=cb)
    finally:
        signal.signal(signal.SIGINT, previous)


def test_training_releases_the_gil(planes):
    done = threading.Event()
    result = {}

    def work():
        result["m"] = evnerf.train(planes, iterations=40, threads=1)
        done.set()

    th = threading.Thread(target=work)
    th.start()
    ticks = 0
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    th.join()
    assert result["m"].step == 40
    assert ticks > 20, "the main thread barely ran while training: the GIL was held"


def test_save_load_resume(planes, tmp_path):
    m = evnerf.train(planes, iterations=10, threads=1, out=tmp_path / "run")
    assert (tmp_path / "run" / "model.ckpt").exists() and (tmp_path / "run" / "log.jsonl").exists()
    loaded = evnerf.load_model(tmp_path / "run" / "model.ckpt")
    P = m.boundary_poses[2]
    assert loaded.variant == "fast" and loaded.step == 10
    assert np.array_equal(loaded.render(P)[0], m.render(P)[0])
    m.save(tmp_path / "copy.ckpt")
    assert np.array_equal(evnerf.load_model(tmp_path / "copy.ckpt").thresholds, m.thresholds)
    # Resume to 20 steps = 20 steps straight.
    resumed = evnerf.train(planes, iterations=20, threads=1, out=tmp_path / "run", resume=True)
    straight = evnerf.train(planes, iterations=20, threads=1)
    assert resumed.step == 20 and np.array_equal(resumed.render(P)[0], straight.render(P)[0])
    # settings.json records both calls: the library's defaults, and where each began.
    runs = json.loads((tmp_path / "run" / "settings.json").read_text())["runs"]
    assert [r["from_step"] for r in runs] == [0, 10] and [r["iterations"] for r in runs] == [10, 20]
    assert all(r["threads"] == 1 and r["pixels"] == 1024 for r in runs)
    # Without out nothing is written.
    before = set(tmp_path.iterdir())
    evnerf.train(planes, iterations=2, threads=1)
    assert set(tmp_path.iterdir()) == before


def test_gaussians_train_save_load_resume_and_render(planes, tmp_path):
    m = evnerf.train(planes, preset="splat", iterations=10, threads=2, out=tmp_path / "splat")
    assert m.variant == "splat" and m.step == 10
    P = m.boundary_poses[2]
    img, depth = m.render(P)
    assert img.shape == (H, W) and np.all(np.isfinite(img)) and np.all(np.isfinite(depth))
    loaded = evnerf.load_model(tmp_path / "splat" / "model.ckpt")
    assert loaded.variant == "splat" and np.array_equal(loaded.render(P)[0], img)
    resumed = evnerf.train(planes, preset="splat", iterations=20, threads=2, out=tmp_path / "splat", resume=True)
    straight = evnerf.train(planes, preset="splat", iterations=20, threads=2)
    assert resumed.step == 20 and np.array_equal(resumed.render(P)[0], straight.render(P)[0])


def test_evaluate_and_baselines(planes):
    m = evnerf.train(planes, iterations=30, threads=2)
    r = evnerf.evaluate(m, planes)
    assert r["alignment"] == "global-log-affine"
    assert set(r["methods"]) == {"evnerf_fast", "direct_integration", "high_pass_filter"}
    assert all(np.isfinite(v["psnr"]) for v in r["methods"].values())
    assert len(r["renders"]) == len(r["frames"]) > 10 and r["renders"][0].shape == (H, W)
    b = evnerf.baselines(planes, alignment="min-max")
    assert b["alignment"] == "min-max" and set(b["images"]) == {"direct_integration", "high_pass_filter"}
    assert b["frames"] == r["frames"][: len(b["frames"])] or len(b["frames"]) >= len(r["frames"])
    truth = [planes.frame(i) for i in b["frames"]]
    s = evnerf.score(b["images"]["direct_integration"], truth, alignment="min-max")
    assert s["psnr"] == pytest.approx(b["methods"]["direct_integration"]["psnr"], abs=1e-9)
    assert evnerf.score(truth, truth, alignment="none")["mse"] == 0
    # The offset oracle: eval's, from evaluate(); on request, score()'s for any images. A gain per row
    # constant over the sequence is what it removes.
    assert {"oracle_rows_psnr", "oracle_columns_psnr", "oracle_both_psnr"} <= set(r["error_scales"]["methods"]["evnerf_fast"])
    assert "oracle" not in s
    t = np.stack(truth).astype(np.float32) * 0.8 + 0.1
    rows = np.exp(0.2 * np.sin(np.arange(t.shape[1]) * 0.3))[None, :, None]
    o = evnerf.score((t + 1e-3) * rows - 1e-3, t, alignment="none", oracle=True)
    assert o["psnr"] < 40 and o["oracle"]["rows_psnr"] > 80 and o["oracle"]["both_psnr"] > 80
    assert o["oracle"]["columns_psnr"] < 45


def test_colour_and_a_time_window(tmp_path):
    assert evnerf.simulate("blocks", width=32, height=24).bayer == "rggb"
    d = evnerf.simulate("blocks", width=32, height=24, out=tmp_path / "blocks")
    assert d.frame(0).shape == (24, 32, 3)  # an IJRR folder names no mosaic: RGGB, the simulator's
    m = evnerf.train(d, preset="colour", iterations=5, threads=1)
    assert m.channels == 3 and m.render(m.boundary_poses[0])[0].shape == (24, 32, 3)
    t = d.events.t
    w = evnerf.load(tmp_path / "blocks", time_window=(t[0] + 0.1, t[0] + 0.3))
    assert 0 < len(w) < len(d) and w.events.t[0] >= t[0] + 0.1 and w.events.t[-1] < t[0] + 0.3


def test_a_load_reports_its_progress_and_can_be_stopped(tmp_path):
    # Two IJRR folders written here (so no event cache of them exists: a load reads events.txt).
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "events.txt").write_text("".join(f"{0.1 + 1e-4 * k:.6f} {k % 32} {k % 24} {k % 2}\n" for k in range(5000)))
        (tmp_path / name / "calib.txt").write_text("100 100 16 12\n")
        (tmp_path / name / "sensor.txt").write_text("32 24\n")
    calls = []
    back = evnerf.load(tmp_path / "a", progress=lambda done, total: calls.append((done, total)))
    assert len(back) == 5000 and calls
    assert all(a[0] <= b[0] and a[1] == b[1] for a, b in zip(calls, calls[1:]))
    assert calls[-1] == ((tmp_path / "a" / "events.txt").stat().st_size,) * 2

    def stop(done, total):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        evnerf.load(tmp_path / "b", progress=stop)
    with pytest.raises(evnerf.Error, match="progress must be a callable"):
        evnerf.load(tmp_path / "b", progress=3)


def test_channel_upsampling_is_checked(tmp_path):
    with pytest.raises(evnerf.Error, match="channel upsampling 'nearest': expected volume or sites"):
        evnerf.load_model(tmp_path / "channels.json", channel_upsampling="nearest")


def test_a_users_own_variant():
    my = pytest.importorskip("my_evnerf")
    assert my.variants == ["mine", "fast"]
    m = my.train(my.simulate("planes", width=24, height=18), iterations=5, threads=1)
    assert m.variant == "mine" and m.render(m.boundary_poses[0])[0].shape == (18, 24)


# ---- errors: Python exceptions with the library's messages --------------------------------------------------
def base():
    return dict(x=np.array([1, 2, 3]), y=np.array([1, 1, 2]), t=np.array([0.1, 0.2, 0.3]), p=np.array([1, -1, 1]),
                width=10, height=8, intrinsics=[10.0, 10.0, 5.0, 4.0])


def test_good_arrays_make_a_dataset():
    d = evnerf.Dataset(**base())
    assert len(d) == 3 and list(d.events.p) == [1, -1, 1]
    zero_one = dict(base(), p=np.array([1, 0, 1], dtype=np.uint8))
    assert list(evnerf.Dataset(**zero_one).events.p) == [1, -1, 1]


@pytest.mark.parametrize("field,value,message", [
    ("x", np.array([1.0, 2.0, 3.0]), "x: expected integer pixel columns, got float64"),
    ("y", np.array(["a", "b", "c"]), "y: expected integer pixel rows, got <U1"),
    ("t", np.array([1, 2, 3]), "t: expected floating-point seconds (divide integer timestamps by their unit first), got int64"),
    ("p", np.array([0.5, 1.0, 1.0]), "p: expected polarities: bool, 0/1 or -1/+1, got float64"),
])
def test_wrong_dtypes(field, value, message):
    with pytest.raises(TypeError) as e:
        evnerf.Dataset(**dict(base(), **{field: value}))
    assert str(e.value) == message


def test_wrong_shapes():
    with pytest.raises(evnerf.Error, match=r"^x: expected a 1-D array, got shape \(3, 1\)$"):
        evnerf.Dataset(**dict(base(), x=np.array([[1], [2], [3]])))
    with pytest.raises(evnerf.Error, match=r"arrays differ in length \(x 2, y 3, t 3, p 3\)"):
        evnerf.Dataset(**dict(base(), x=np.array([1, 2])))
    with pytest.raises(evnerf.Error, match=r"poses: expected shape \(N, 8\)"):
        evnerf.Dataset(**dict(base(), poses=np.zeros((4, 7))))
    with pytest.raises(evnerf.Error, match=r"frames\[0\]: expected shape \(8, 10\) or \(8, 10, 3\), got \(10, 8\)"):
        evnerf.Dataset(**dict(base(), frame_times=np.array([0.1]), frames=[np.zeros((10, 8), np.float32)]))
    with pytest.raises(evnerf.Error, match="intrinsics: expected"):
        evnerf.Dataset(**dict(base(), intrinsics=[1.0, 2.0, 3.0]))


def test_bad_values_carry_the_cpp_messages():
    # The same text as the C++ EventStream::validate (tests/test_io.cpp checks it for the file readers).
    with pytest.raises(evnerf.Error) as e:
        evnerf.Dataset(**dict(base(), x=np.array([1, 10, 3])))
    assert str(e.value) == "arrays: event 1 lies outside the 10x8 sensor"
    assert isinstance(e.value, ValueError)
    with pytest.raises(evnerf.Error, match="^arrays: event 0 lies outside the 10x8 sensor$"):
        evnerf.Dataset(**dict(base(), y=np.array([-1, 1, 1])))
    with pytest.raises(evnerf.Error, match="^arrays: event 2 has polarity 2$"):
        evnerf.Dataset(**dict(base(), p=np.array([1, -1, 2])))
    with pytest.raises(evnerf.Error, match="^arrays: event 1 has polarity 0$"):
        evnerf.Dataset(**dict(base(), p=np.array([1, 0, -1])))
    with pytest.raises(evnerf.Error, match="^arrays: event 2 goes back in time$"):
        evnerf.Dataset(**dict(base(), t=np.array([0.1, 0.3, 0.2])))
    with pytest.raises(evnerf.Error, match="quaternion is far from unit length"):
        evnerf.Dataset(**dict(base(), poses=np.array([[0.0, 0, 0, 0, 0, 0, 0, 0.1]])))
    with pytest.raises(evnerf.Error, match=r"pose times must increase strictly \(pose 1\)"):
        evnerf.Dataset(**dict(base(), poses=np.array([[0.2, 0, 0, 0, 0, 0, 0, 1], [0.1, 0, 0, 0, 0, 0, 0, 1]])))
    with pytest.raises(evnerf.Error, match="unknown Bayer pattern 'xyzw'"):
        evnerf.Dataset(**dict(base(), bayer="xyzw"))


def test_errors_from_files_and_settings(tmp_path, planes):
    missing = tmp_path / "nowhere"
    with pytest.raises(evnerf.Error, match="nowhere"):
        evnerf.load(missing)
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(evnerf.Error, match="bad.ckpt"):
        evnerf.load_model(bad)
    with pytest.raises(evnerf.Error, match="unknown variant 'nope'"):
        evnerf.train(planes, preset="nope", iterations=1)
    with pytest.raises(TypeError, match="unknown setting 'iters'"):
        evnerf.train(planes, iters=1)
    with pytest.raises(evnerf.Error, match="train: far must be greater than near"):
        evnerf.train(planes, iterations=1, near=2.0, far=1.0)
    with pytest.raises(evnerf.Error, match="train: iterations must be > 0, got 0"):
        evnerf.train(planes, iterations=0)
    m = evnerf.train(planes, iterations=1, threads=1)
    with pytest.raises(evnerf.Error, match="pose: the upper-left 3x3 block is not a rotation"):
        m.render(np.eye(4) * 2)
    with pytest.raises(evnerf.Error, match=r"pose: expected a 4x4 camera-to-world matrix .* got shape \(3,\)"):
        m.render(np.zeros(3))
    with pytest.raises(evnerf.Error, match="no poses"):
        evnerf.train(evnerf.Dataset(**base()), iterations=1)


def test_every_setting_of_the_table(planes, tmp_path):
    """Walks the settings table: each setting is a keyword (its default accepted and recorded under its name
    in settings.json), and a value outside its interval is refused with a message naming it."""
    rows = evnerf.settings()
    assert [r["name"] for r in rows][:3] == ["iterations", "pixels", "seed"]
    for r in rows:
        name = r["name"]
        value = 1 if name == "iterations" else r["default"]
        if value is None:  # unset: the variant's own (tv), or learned (the refractory period): give it one
            value = 1e-4 if name == "refractory" else 0.05
        out = tmp_path / name
        kwargs = {"iterations": 1, "threads": 1, name: value}
        evnerf.train(planes, out=out, **kwargs)
        recorded = json.loads((out / "settings.json").read_text())["runs"][0][name]
        assert recorded == value or (name == "shards" and recorded == 1), (name, recorded, value)
        if not r["numeric"]:
            continue
        bad = []
        if r["lo"] is not None:
            bad.append(r["lo"] if r["lo_open"] else r["lo"] - 1)
        if r["hi"] is not None:
            bad.append(r["hi"] if r["hi_open"] else r["hi"] + 1)
        for b in bad:
            b = int(b) if r["integer"] else float(b)
            with pytest.raises((evnerf.Error, TypeError, OverflowError), match=name):
                evnerf.train(planes, **{"iterations": 1, "threads": 1, name: b})


def test_the_sensor_of_a_simulation(tmp_path):
    ideal = evnerf.sensor_model()
    assert (ideal["threshold_pos"], ideal["threshold_neg"], ideal["refractory"], ideal["hot_pixels"]) == (0.25, 0.25, 0.0, 0)
    drawn = evnerf.sensor_model("random", seed=4)
    assert drawn == evnerf.sensor_model("random", seed=4) != evnerf.sensor_model("random", seed=5)
    assert 0.15 <= drawn["threshold_pos"] <= 0.5 and 0.7 <= drawn["threshold_neg"] / drawn["threshold_pos"] <= 1.4
    assert evnerf.sensor_model("realistic", refractory=0.0005)["refractory"] == 0.0005
    d = evnerf.simulate("planes", width=24, height=18, sensor="random", seed=4, out=tmp_path / "rec")
    written = dict(line.split() for line in (tmp_path / "rec" / "sensor_model.txt").read_text().splitlines())
    assert float(written["threshold_pos"]) == pytest.approx(drawn["threshold_pos"], rel=1e-8)
    assert int(written["hot_pixels"]) == drawn["hot_pixels"]
    assert len(d) > 0
    with pytest.raises(evnerf.Error, match=r"--threshold-pos must be in \(0, 5\], got -0.1"):
        evnerf.simulate("planes", width=24, height=18, threshold_pos=-0.1)
    with pytest.raises(evnerf.Error, match="unknown keyword 'refractory_period'"):
        evnerf.simulate("planes", width=24, height=18, refractory_period=0.001)



BOX = "/usr/share/assimp/models/glTF2/BoxTextured-glTF/BoxTextured.gltf"


@pytest.mark.skipif(not os.path.exists(BOX), reason="Debian's assimp-testmodels is not installed")
def test_a_mesh_is_simulated_along_an_orbit_with_held_out_views(tmp_path):
    d = evnerf.simulate("mesh", mesh=BOX, width=32, height=24, out=tmp_path / "box")
    assert (d.width, d.height) == (32, 24) and len(d) > 100
    assert len((tmp_path / "box" / "novel" / "poses.txt").read_text().splitlines()) == 25  # a comment, 24 views
    assert "path orbit 0 0 0 3 30 1 0" in (tmp_path / "box" / "scene.txt").read_text()
    with pytest.raises(evnerf.Error, match="the mesh file is missing"):
        evnerf.simulate("mesh", width=32, height=24)
    with pytest.raises(evnerf.Error, match="mesh= goes with the scene 'mesh'"):
        evnerf.simulate("planes", mesh=BOX)

PROPHESEE = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "prophesee_evt2_sample", "evt2.raw")


@pytest.mark.skipif(not os.path.exists(PROPHESEE), reason="../shared/data/prophesee_evt2_sample is absent")
def test_a_prophesee_recording_gives_the_independent_decoders_digests(tmp_path):
    import hashlib
    calib = tmp_path / "calib.txt"
    calib.write_text("500 500 320 240\n")
    d = evnerf.load(PROPHESEE, calib=calib)
    e = d.events
    assert len(d) == 521252 and d.width == 640 and d.height == 480
    digest = lambda a: hashlib.sha3_224(a.tobytes()).hexdigest()
    assert digest(np.rint(e.t * 1e6).astype("<u8")) == "9855ba39c1baea316ae623b72466e420df60a7510248391856eb4eaf"
    assert digest(e.x.astype("<u2")) == "93fc6cff19b483fd48ca53345c6c1cf05123681d7b7272a1717e9303"
    assert digest(e.y.astype("<u2")) == "07cfaef58e5fa71ce9910ed5b88fb7e9fcf71e4a8654cc2c4666f1ae"
    assert digest((e.p > 0).astype(np.bool_)) == "d2b5e9c4047f4c431937b24cd46c8b504e055372b0ded1df77f0ffa1"
    w = evnerf.load(PROPHESEE, calib=calib, time_window=(913.75, 913.76))
    assert len(w) == int(np.count_nonzero((e.t >= 913.75) & (e.t < 913.76)))
    with pytest.raises(evnerf.Error, match="sensor_size must be"):
        evnerf.load(PROPHESEE, calib=calib, sensor_size=(0, 480))
