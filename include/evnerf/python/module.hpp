// python/module.hpp — evnerf as a Python module (pybind11) over any list of variants, so that research code
// in Python loads recordings, trains, renders and scores without files in between:
//
//   #include <evnerf/python/module.hpp>
//   using Mine = evnerf::EvNerf<...>;
//   EVNERF_PYTHON_MODULE(evnerf, evnerf::Variant<evnerf::presets::Fast, "fast">, evnerf::Variant<Mine, "mine">)
//
// (or call evnerf::python::define<V...>(m) in a PYBIND11_MODULE of your own). The first variant is
// train()'s default. What Python sees:
//   load(path, ...)              any recording io::load reads → Dataset
//   Dataset(x=, y=, t=, p=, ...) a recording from numpy arrays (poses, intrinsics, optional frames)
//   Dataset.events.x/.y/.t/.p    read-only numpy views of the events (no copy; they keep the Dataset alive)
//   simulate(scene, ...)         a simulated recording (in memory, or written to `out` and loaded)
//   train(dataset, preset=, callback=, ...)  → Model; callback(step, loss, thresholds) may return False to stop
//   Model.render(pose)           intensity and depth as numpy arrays, at any camera-to-world pose
//   load_model(path), Model.save(path), evaluate(model, dataset), baselines(dataset), score(images, truth)
// Errors are evnerf.Error (a ValueError) with the C++ library's messages. Training and rendering release
// the GIL; a callback reacquires it, and Ctrl-C stops training after the current step.
// Needs pybind11 (Debian's pybind11-dev); not included by the umbrella header.
#pragma once
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "../eval/evaluate.hpp"
#include "../eval/load.hpp"
#include "../evnerf.hpp"
#include "../sim/simulate.hpp"
#include "../model/variants.hpp"

namespace evnerf::python {

namespace py = pybind11;
namespace fs = std::filesystem;

/// A recording held by Python; numpy views of its events point into it.
struct Dataset {
  std::shared_ptr<io::Dataset> d;
};

/// A trained or loaded model of any variant (type-erased): what renders, and what only a single model.ckpt
/// has (thresholds, step, save).
struct Model {
  std::string variant;
  evaluation::Renderable renderable;
  int channels = 1;
  std::function<std::vector<double>()> thresholds;  ///< per slice (B+, B−), row-major N×2; empty for channels.json
  std::function<long()> step;
  std::function<void(const fs::path&)> save;
  py::dict run;  ///< what train() did: steps, seconds, final_loss, stopped, collapse checks
};

namespace detail {

inline py::object json_to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

/// A C++ vector as a new numpy array (copied) of the given shape.
template <class T>
py::array_t<T> to_numpy(const std::vector<T>& v, std::vector<py::ssize_t> shape) {
  py::array_t<T> a(shape);
  if (!v.empty()) std::memcpy(a.mutable_data(), v.data(), v.size() * sizeof(T));
  return a;
}
inline py::array_t<float> image_to_numpy(const Image& im) {
  std::vector<py::ssize_t> shape{im.height, im.width};
  if (im.channels > 1) shape.push_back(im.channels);
  return to_numpy(im.data, shape);
}
/// A read-only numpy view of `v`, kept alive by `owner`.
template <class T>
py::array_t<T> view(const std::vector<T>& v, py::handle owner) {
  py::array_t<T> a({static_cast<py::ssize_t>(v.size())}, {static_cast<py::ssize_t>(sizeof(T))}, v.data(), owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

inline std::string dtype_name(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }
inline std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}
[[noreturn]] inline void type_error(const std::string& m) { throw py::type_error(m); }

/// `obj` as a numpy array whose dtype is of one of `kinds` ('i' signed, 'u' unsigned, 'f' floating, 'b'
/// bool), then converted to T. Never a silent conversion between kinds (floats are not truncated to pixels).
template <class T>
py::array_t<T, py::array::c_style> array_of(py::handle obj, const std::string& name, const std::string& kinds, const std::string& expected) {
  py::array a = py::array::ensure(obj);
  if (!a) type_error(name + ": expected a numpy array (" + expected + ")");
  const char kind = a.dtype().kind();
  if (kinds.find(kind) == std::string::npos) type_error(name + ": expected " + expected + ", got " + dtype_name(a));
  return py::array_t<T, py::array::c_style>::ensure(a);
}
inline void require_shape(const py::array& a, const std::string& name, std::vector<py::ssize_t> shape, const std::string& expected) {
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (std::size_t k = 0; ok && k < shape.size(); ++k) ok = shape[k] < 0 || a.shape(k) == shape[k];
  if (!ok) throw Error(name + ": expected shape " + expected + ", got " + shape_text(a));
}

/// A camera-to-world pose from a 4×4 matrix or [px, py, pz, qx, qy, qz, qw].
inline geometry::Pose pose_of(py::handle obj) {
  auto a = array_of<double>(obj, "pose", "fi", "a 4x4 camera-to-world matrix or [px, py, pz, qx, qy, qz, qw]");
  geometry::Pose p;
  if (a.ndim() == 2 && a.shape(0) == 4 && a.shape(1) == 4) {
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = a.at(r, c);
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        if (!std::isfinite(m(r, c))) throw Error("pose: the matrix has a non-finite entry");
    const Mat3 R = m.topLeftCorner<3, 3>();
    if ((R * R.transpose() - Mat3::Identity()).norm() > 1e-3 || R.determinant() < 0)
      throw Error("pose: the upper-left 3x3 block is not a rotation");
    return geometry::Pose::from_matrix(m);
  }
  if (a.ndim() == 1 && a.shape(0) == 7) {
    const double* v = a.data();
    for (int k = 0; k < 7; ++k)
      if (!std::isfinite(v[k])) throw Error("pose: a non-finite entry");
    const double n = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (n < 0.5 || n > 1.5) throw Error("pose: quaternion is far from unit length (norm " + short_number(n) + ")");
    p.t = Vec3(v[0], v[1], v[2]);
    p.q = Quat(v[6] / n, v[3] / n, v[4] / n, v[5] / n);
    return p;
  }
  throw Error("pose: expected a 4x4 camera-to-world matrix or [px, py, pz, qx, qy, qz, qw], got shape " + shape_text(a));
}
inline py::array_t<double> matrix_of(const geometry::Pose& p) {
  py::array_t<double> a({4, 4});
  const Eigen::Matrix4d m = p.matrix();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a.mutable_at(r, c) = m(r, c);
  return a;
}
inline py::array_t<double> matrices_of(const std::vector<geometry::Pose>& poses) {
  py::array_t<double> a({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Matrix4d m = poses[i].matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) a.mutable_at(static_cast<py::ssize_t>(i), r, c) = m(r, c);
  }
  return a;
}

/// The items of a list of images or of one N×H×W[×3] array.
inline std::vector<py::array> image_items(py::handle obj, const std::string& name) {
  std::vector<py::array> items;
  if (py::isinstance<py::array>(obj)) {
    const auto whole = py::reinterpret_borrow<py::array>(obj);
    if (whole.ndim() != 3 && whole.ndim() != 4) throw Error(name + ": expected N x H x W (x 3) images, got shape " + shape_text(whole));
    for (py::ssize_t i = 0; i < whole.shape(0); ++i) items.push_back(whole[py::int_(i)].cast<py::array>());
  } else if (py::isinstance<py::sequence>(obj) && !py::isinstance<py::str>(obj)) {
    for (auto it : py::reinterpret_borrow<py::sequence>(obj)) items.push_back(py::array::ensure(it));
  } else {
    type_error(name + ": expected a list of images or an N x H x W (x 3) array");
  }
  return items;
}

/// Images from a list of arrays or one N×H×W[×3] array (float in [0, 1], or uint8), each width × height.
inline std::vector<Image> images_of(py::handle obj, const std::string& name, int width, int height) {
  const auto items = image_items(obj, name);
  std::vector<Image> out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const std::string what = name + "[" + std::to_string(i) + "]";
    if (!items[i]) type_error(what + ": expected a numpy array");
    const char kind = items[i].dtype().kind();
    const bool u8 = kind == 'u' && items[i].itemsize() == 1;
    if (!u8 && kind != 'f') type_error(what + ": expected float (0 to 1) or uint8 pixels, got " + dtype_name(items[i]));
    const auto& a = items[i];
    if (!((a.ndim() == 2 || (a.ndim() == 3 && (a.shape(2) == 1 || a.shape(2) == 3))) && a.shape(0) == height && a.shape(1) == width))
      throw Error(what + ": expected shape (" + std::to_string(height) + ", " + std::to_string(width) + ") or (" +
                  std::to_string(height) + ", " + std::to_string(width) + ", 3), got " + shape_text(a));
    const auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
    Image im(width, height, a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1);
    std::memcpy(im.data.data(), f.data(), im.data.size() * sizeof(float));
    for (float& v : im.data) {
      if (u8) v /= 255.f;
      if (!std::isfinite(v)) throw Error(what + ": a pixel is not finite");
    }
    out.push_back(std::move(im));
  }
  return out;
}

/// The Dataset constructor: events from numpy arrays, the camera from intrinsics, optional poses and frames.
inline Dataset make_dataset(py::handle x, py::handle y, py::handle t, py::handle p, int width, int height, py::handle intrinsics,
                            py::handle poses, py::handle frame_times, py::handle frames, const std::string& bayer,
                            const std::string& name) {
  auto d = std::make_shared<io::Dataset>();
  d->folder = name;
  const auto ax = array_of<std::int64_t>(x, "x", "iu", "integer pixel columns");
  const auto ay = array_of<std::int64_t>(y, "y", "iu", "integer pixel rows");
  const auto at = array_of<double>(t, "t", "f", "floating-point seconds (divide integer timestamps by their unit first)");
  const auto ap = array_of<std::int64_t>(p, "p", "iub", "polarities: bool, 0/1 or -1/+1");
  for (auto [a, n] : {std::pair{py::array(ax), "x"}, {py::array(ay), "y"}, {py::array(at), "t"}, {py::array(ap), "p"}})
    if (a.ndim() != 1) throw Error(std::string(n) + ": expected a 1-D array, got shape " + shape_text(a));
  io::check_sensor_size(width, height, name);
  auto& ev = d->events;
  ev.width = width;
  ev.height = height;
  const auto n = static_cast<std::size_t>(ax.shape(0));
  if (static_cast<std::size_t>(ay.shape(0)) != n || static_cast<std::size_t>(at.shape(0)) != n || static_cast<std::size_t>(ap.shape(0)) != n)
    throw Error(name + ": arrays differ in length (x " + std::to_string(ax.shape(0)) + ", y " + std::to_string(ay.shape(0)) + ", t " +
                std::to_string(at.shape(0)) + ", p " + std::to_string(ap.shape(0)) + ")");
  const std::int64_t* px = ax.data();
  const std::int64_t* py_ = ay.data();
  const std::int64_t* pp = ap.data();
  bool has_zero = false, has_minus = false;
  for (std::size_t i = 0; i < n; ++i) {
    if (px[i] < 0 || px[i] >= width || py_[i] < 0 || py_[i] >= height) throw events::EventStream::outside_sensor(name, i, width, height);
    if (pp[i] != 0 && pp[i] != 1 && pp[i] != -1) throw events::EventStream::bad_polarity(name, i, pp[i]);
    has_zero |= pp[i] == 0;
    has_minus |= pp[i] == -1;
  }
  if (has_zero && has_minus)
    for (std::size_t i = 0; i < n; ++i)
      if (pp[i] == 0) throw events::EventStream::bad_polarity(name, i, 0);  // 0 and -1 both present: 0 means nothing
  ev.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(at.data()[i])) throw Error(name + ": event " + std::to_string(i) + " has a non-finite time");
    ev.push_back(at.data()[i], static_cast<int>(px[i]), static_cast<int>(py_[i]), pp[i] > 0 ? 1 : -1);
  }
  ev.validate(name);
  // Camera: fx fy cx cy [k1 k2 p1 p2 [k3]].
  const auto k = array_of<double>(intrinsics, "intrinsics", "fi", "[fx, fy, cx, cy] or [fx, fy, cx, cy, k1, k2, p1, p2[, k3]]");
  if (k.ndim() != 1 || (k.shape(0) != 4 && k.shape(0) != 8 && k.shape(0) != 9))
    throw Error("intrinsics: expected [fx, fy, cx, cy] or [fx, fy, cx, cy, k1, k2, p1, p2[, k3]], got shape " + shape_text(k));
  std::array<double, 5> dist{};
  for (py::ssize_t i = 4; i < k.shape(0); ++i) dist[static_cast<std::size_t>(i - 4)] = k.data()[i];
  d->camera = geometry::Camera(width, height, k.data()[0], k.data()[1], k.data()[2], k.data()[3], dist);
  if (!poses.is_none()) {
    const auto a = array_of<double>(poses, "poses", "fi", "an N x 8 array of t, px, py, pz, qx, qy, qz, qw (camera to world)");
    require_shape(a, "poses", {-1, 8}, "(N, 8): t, px, py, pz, qx, qy, qz, qw (camera to world)");
    std::vector<double> ts;
    std::vector<geometry::Pose> ps;
    for (py::ssize_t i = 0; i < a.shape(0); ++i) {
      const double* r = a.data() + 8 * i;
      for (int c = 0; c < 8; ++c)
        if (!std::isfinite(r[c])) throw Error("poses: row " + std::to_string(i) + " has a non-finite entry");
      const double qn = std::sqrt(r[4] * r[4] + r[5] * r[5] + r[6] * r[6] + r[7] * r[7]);
      if (qn < 0.5 || qn > 1.5) throw Error("poses: row " + std::to_string(i) + ": quaternion is far from unit length (norm " + short_number(qn) + ")");
      geometry::Pose q;
      q.t = Vec3(r[1], r[2], r[3]);
      q.q = Quat(r[7] / qn, r[4] / qn, r[5] / qn, r[6] / qn);
      ts.push_back(r[0]);
      ps.push_back(q);
    }
    d->trajectory = geometry::Trajectory(std::move(ts), std::move(ps), "poses");
  }
  if (frames.is_none() != frame_times.is_none()) throw Error("frames and frame_times go together: give both or neither");
  if (!frames.is_none()) {
    const auto ft = array_of<double>(frame_times, "frame_times", "f", "floating-point seconds");
    if (ft.ndim() != 1) throw Error("frame_times: expected a 1-D array, got shape " + shape_text(ft));
    d->frames.images = images_of(frames, "frames", width, height);
    if (d->frames.images.size() != static_cast<std::size_t>(ft.shape(0)))
      throw Error("frames: " + std::to_string(d->frames.images.size()) + " images for " + std::to_string(ft.shape(0)) + " frame_times");
    for (py::ssize_t i = 0; i < ft.shape(0); ++i) {
      if (!std::isfinite(ft.data()[i]) || (i > 0 && ft.data()[i] < ft.data()[i - 1]))
        throw Error("frame_times: frame " + std::to_string(i) + " is not finite or goes back in time");
      d->frames.t.push_back(ft.data()[i]);
    }
  }
  d->bayer_pattern = bayer;
  io::bayer_of(*d);  // an unknown pattern is an error now, not at training
  return Dataset{d};
}

/// The training Config from keyword arguments: each a setting of train::settings() under its name (the
/// command line's flag with underscores), or `progress`; an unknown key or a value of the wrong type is an
/// error naming it.
inline train::Config config_of(const py::kwargs& kw) {
  train::Config c;
  c.progress = false;
  for (auto [key, value] : kw) {
    const auto k = key.cast<std::string>();
    if (k == "progress") {
      c.progress = value.cast<bool>();
      continue;
    }
    const train::Setting* found = nullptr;
    try {
      found = &train::setting(k, "train");
    } catch (const Error& e) {
      throw py::type_error(e.what());  // an unexpected keyword, as Python's own calls say
    }
    const auto& s = *found;
    nlohmann::json j;
    if (value.is_none()) j = nullptr;
    else if (py::isinstance<py::bool_>(value)) j = value.cast<bool>();
    else if (py::isinstance<py::int_>(value)) j = value.cast<long long>();
    else if (py::isinstance<py::float_>(value)) j = value.cast<double>();
    else if (py::isinstance<py::str>(value)) j = value.cast<std::string>();
    else throw py::type_error("train: " + k + " must be a number, a bool or a string");
    if (s.numeric() && j.is_boolean()) throw py::type_error("train: " + k + " must be a number, got a bool");
    s.set(c, j, "train");
  }
  train::check(c);
  return c;
}

/// The names of the keyword settings, as train's docstring lists them.
inline std::string setting_names() {
  std::string names;
  for (const auto& s : train::settings()) names.append(names.empty() ? "" : ", ").append(s.name);
  return names + ", progress";
}

/// Every slice's thresholds (B+, B−), row-major N×2.
template <class M>
std::vector<double> thresholds_of(const M& model) {
  std::vector<double> v(2 * model.n_slices());
  for (std::size_t i = 0; i < model.n_slices(); ++i) {
    v[2 * i] = model.threshold_pos(i);
    v[2 * i + 1] = model.threshold_neg(i);
  }
  return v;
}

/// A Model around one model object of type M (shared with the closures).
template <class M>
Model wrap(std::shared_ptr<M> model, const std::string& variant, std::shared_ptr<const io::CheckpointRun> run) {
  Model m;
  m.variant = variant;
  m.channels = M::channels;
  m.renderable.name = variant;
  m.renderable.desc = *run;
  m.renderable.near = model->box().near;
  m.renderable.far = model->box().far;
  auto dirs = std::make_shared<const std::vector<Vec3f>>(render::pixel_directions(m.renderable.desc.camera));
  m.renderable.render = [model, dirs, cam = m.renderable.desc.camera](const geometry::Pose& pose) { return model->render(cam, *dirs, pose); };
  m.renderable.render_with = [model](const geometry::Camera& cam, const geometry::Pose& pose) {
    return model->render(cam, render::pixel_directions(cam), pose);
  };
  m.thresholds = [model] { return thresholds_of(*model); };
  m.step = [model] { return model->step(); };
  m.save = [model, variant, run](const fs::path& p) { train::save_checkpoint(p, *model, variant, *run); };
  return m;
}

template <class... V>
Model load_model(const fs::path& path, const std::string& channel_upsampling) {
  if (path.extension() == ".json") {  // train --per-channel: three grey models
    Model m;
    m.renderable = evaluation::load_renderable<V...>(path, evaluation::parse_channel_upsampling(channel_upsampling));
    m.variant = m.renderable.name;
    m.channels = 3;
    return m;
  }
  Model out;
  with_variant<V...>(checkpoint_variant<V...>(path), [&]<class M>(const std::string& name) {
    auto model = std::make_shared<M>();
    const auto run = std::make_shared<const io::CheckpointRun>(train::load_checkpoint(path, *model));
    if (run->times.empty())
      throw Error(path.string(), 0, "the checkpoint records no training run (no camera, no slice boundaries): a model needs one that "
                                    "train wrote");
    out = wrap(model, name, run);
    return 0;
  });
  return out;
}

template <class... V>
Model train_model(const Dataset& ds, const std::string& preset, py::object callback, const std::optional<fs::path>& out, bool resume,
                  const py::kwargs& kw) {
  const auto cfg = config_of(kw);
  if (resume && !out) throw Error("train: resume needs out (the folder whose model.ckpt to continue)");
  const fs::path dir = out ? *out : fs::path();
  Model result;
  with_variant<V...>(preset, [&]<class M>(const std::string& name) {
    struct Run {
      TrainingData td;
      std::unique_ptr<train::Trainer<M>> trainer;
    };
    auto run = std::make_shared<Run>();
    const auto described = std::make_shared<io::CheckpointRun>();
    {
      py::gil_scoped_release nogil;
      run->td = train::prepare(*ds.d, cfg);
      *described = train::describe(run->td, ds.d->folder.string());
      described->shards = static_cast<std::uint64_t>(cfg.shard_count());
      run->trainer = std::make_unique<train::Trainer<M>>(run->td, cfg, dir, name, *described);
    }
    if (resume) run->trainer->resume();
    std::exception_ptr raised;
    train::RunResult r;
    auto& model = run->trainer->model();
    {
      py::gil_scoped_release nogil;
      r = run->trainer->run([&](const train::StepReport& rep) -> bool {
        py::gil_scoped_acquire gil;
        try {
          if (PyErr_CheckSignals() != 0) throw py::error_already_set();
          if (callback.is_none()) return true;
          const py::object go =
              callback(rep.step, rep.stats.loss, to_numpy(thresholds_of(model), {static_cast<py::ssize_t>(model.n_slices()), 2}));
          return go.is_none() || go.cast<bool>();
        } catch (...) {
          raised = std::current_exception();
          return false;
        }
      });
    }
    if (raised) std::rethrow_exception(raised);
    if (r.diverged) throw Error("train: the run diverged at step " + std::to_string(model.step()) + " (see the message above)");
    if (r.collapsed && !cfg.allow_collapse)
      throw Error("train: the run collapsed (" + r.checks.back().describe() + "); pass allow_collapse=True to go on");
    // The model outlives the trainer (and its reference to the training data) in `run`.
    std::shared_ptr<M> shared(run, &model);
    result = wrap(shared, name, described);
    py::list checks;
    for (const auto& c : r.checks)
      checks.append(py::dict(py::arg("step") = c.step, py::arg("log_spread") = c.log_spread, py::arg("collapsed") = c.collapsed()));
    result.run = py::dict(py::arg("steps") = r.steps, py::arg("seconds") = r.seconds, py::arg("final_loss") = r.final_loss,
                          py::arg("rays_per_second") = r.rays_per_second, py::arg("stopped") = r.stopped,
                          py::arg("collapse_checks") = checks);
    return 0;
  });
  return result;
}

/// Images from a list or an N×H×W[×3] array, at the size of the first.
inline std::vector<Image> image_list(py::handle obj, const std::string& name) {
  const auto items = image_items(obj, name);
  if (items.empty()) throw Error(name + ": no images");
  if (!items.front() || items.front().ndim() < 2) type_error(name + "[0]: expected an H x W (x 3) array");
  return images_of(obj, name, static_cast<int>(items.front().shape(1)), static_cast<int>(items.front().shape(0)));
}

}  // namespace detail

/// Defines the module's functions and classes over the variants V... (the first is train()'s default).
template <class... V>
void define(py::module_& m) {
  using namespace detail;
  static_assert(sizeof...(V) >= 1, "evnerf::python::define needs at least one variant");
  const std::string default_variant = std::get<0>(std::tuple<V...>{}).name;
  std::vector<std::string> names{V::name...};

  // Module-local: a second module of one's own variants (examples/python/custom_module.cpp) keeps its own
  // Error and classes beside this one.
  py::register_local_exception<Error>(m, "Error", PyExc_ValueError);
  m.attr("__version__") = version;
  m.attr("variants") = names;
  m.attr("scenes") = sim::builtin_scenes();
  m.attr("alignments") = std::vector<std::string>{"global-log-affine", "log-affine", "eventnerf", "min-max", "none"};

  py::class_<Dataset> ds(m, "Dataset", "A recording: camera, events, poses, optional frames.", py::module_local());
  ds.def(py::init(&make_dataset), py::arg("x"), py::arg("y"), py::arg("t"), py::arg("p"), py::kw_only(), py::arg("width"),
         py::arg("height"), py::arg("intrinsics"), py::arg("poses") = py::none(), py::arg("frame_times") = py::none(),
         py::arg("frames") = py::none(), py::arg("bayer") = "", py::arg("name") = "arrays",
         "Events x, y (integer pixels), t (float seconds), p (bool, 0/1 or -1/+1) on a width x height sensor; intrinsics [fx, fy, cx, cy"
         "(, k1, k2, p1, p2(, k3))]; poses N x 8 (t, px, py, pz, qx, qy, qz, qw, camera to world); frames for evaluation only "
         "(N x H x W (x 3), float 0..1 or uint8) at frame_times; bayer: the colour filter of a colour sensor ('rggb', ...).");
  ds.def_property_readonly("width", [](const Dataset& s) { return s.d->camera.width(); });
  ds.def_property_readonly("height", [](const Dataset& s) { return s.d->camera.height(); });
  ds.def_property_readonly("name", [](const Dataset& s) { return s.d->folder.string(); });
  ds.def_property_readonly("bayer", [](const Dataset& s) { return s.d->bayer_pattern; });
  ds.def_property_readonly("intrinsics", [](const Dataset& s) {
    const auto& c = s.d->camera;
    const auto& k = c.distortion();
    return std::vector<double>{c.fx(), c.fy(), c.cx(), c.cy(), k[0], k[1], k[2], k[3], k[4]};
  }, "[fx, fy, cx, cy, k1, k2, p1, p2, k3]");
  ds.def_property_readonly("events", [](py::object self) {
    const auto& s = self.cast<const Dataset&>();
    const auto& e = s.d->events;
    py::dict v;
    v["x"] = view(e.x, self);
    v["y"] = view(e.y, self);
    v["t"] = view(e.t, self);
    v["p"] = view(e.polarity, self);
    return py::module_::import("types").attr("SimpleNamespace")(**v);
  }, "x, y (uint16), t (float64 seconds), p (int8, ±1): read-only numpy views of the recording's events, no copy");
  ds.def("__len__", [](const Dataset& s) { return s.d->events.size(); });
  ds.def_property_readonly("poses", [](const Dataset& s) {
    const auto& tr = s.d->trajectory;
    py::array_t<double> a({static_cast<py::ssize_t>(tr.size()), py::ssize_t{8}});
    for (std::size_t i = 0; i < tr.size(); ++i) {
      const auto& p = tr.poses()[i];
      const double r[8] = {tr.times()[i], p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(), p.q.w()};
      for (int c = 0; c < 8; ++c) a.mutable_at(static_cast<py::ssize_t>(i), c) = r[c];
    }
    return a;
  }, "N x 8: t, px, py, pz, qx, qy, qz, qw (camera to world)");
  ds.def("pose_at", [](const Dataset& s, double t) { return matrix_of(s.d->trajectory.pose_at(t)); }, py::arg("t"),
         "the 4x4 camera-to-world pose at time t (interpolated)");
  ds.def_property_readonly("frame_times", [](const Dataset& s) { return to_numpy(s.d->frames.t, {static_cast<py::ssize_t>(s.d->frames.size())}); });
  ds.def("frame", [](const Dataset& s, std::size_t i) { return image_to_numpy(io::frame_image(s.d->frames, i)); }, py::arg("i"),
         "frame i as an H x W (x 3) float array in [0, 1]");
  ds.def("__repr__", [](const Dataset& s) {
    const auto& d = *s.d;
    return "<evnerf.Dataset '" + d.folder.string() + "': " + std::to_string(d.camera.width()) + "x" + std::to_string(d.camera.height()) +
           ", " + std::to_string(d.events.size()) + " events, " + std::to_string(d.trajectory.size()) + " poses, " +
           std::to_string(d.frames.size()) + " frames>";
  });

  m.def(
      "load",
      [](const fs::path& path, std::optional<fs::path> calib, std::optional<fs::path> poses, std::optional<std::pair<double, double>> window,
         const std::string& format) {
        io::LoadOptions o;
        if (calib) o.calib = *calib;
        if (poses) o.poses = *poses;
        if (window) {
          o.t_begin = window->first;
          o.t_end = window->second;
        }
        o.format = format;
        py::gil_scoped_release nogil;
        return Dataset{std::make_shared<io::Dataset>(io::load(path, o))};
      },
      py::arg("path"), py::kw_only(), py::arg("calib") = py::none(), py::arg("poses") = py::none(), py::arg("time_window") = py::none(),
      py::arg("format") = "",
      "Any recording evnerf reads (IJRR folder, EventNeRF or Robust e-NeRF folder, event HDF5, ROS bag); calib and poses as "
      "the command line's --calib and --poses, time_window (t0, t1) seconds, format as --format.");

  m.def(
      "simulate",
      [](const std::string& scene, std::optional<fs::path> out, bool realistic, bool bayer, bool hdr, std::uint64_t seed, int width,
         int height, double focal, double noise_rate, double noise_ratio) {
        sim::SimulateOptions o;
        o.realistic = realistic;
        o.bayer = bayer;
        o.hdr = hdr;
        o.seed = seed;
        o.width = width;
        o.height = height;
        o.focal = focal;
        o.noise_rate = noise_rate;
        o.noise_ratio = noise_ratio;
        o.progress = false;
        py::gil_scoped_release nogil;
        std::string text;
        auto rec = sim::simulate(scene, o, &text);
        if (!out) return Dataset{std::make_shared<io::Dataset>(sim::to_dataset(std::move(rec), scene))};
        sim::write_recording(*out, rec);
        if (!text.empty()) write_file_atomic(*out / "scene.txt", text);
        return Dataset{std::make_shared<io::Dataset>(io::load(*out))};
      },
      py::arg("scene") = "planes", py::kw_only(), py::arg("out") = py::none(), py::arg("realistic") = false, py::arg("bayer") = false,
      py::arg("hdr") = false, py::arg("seed") = 1, py::arg("width") = 240, py::arg("height") = 180, py::arg("focal") = 0.0,
      py::arg("noise_rate") = 0.0, py::arg("noise_ratio") = 0.0,
      "A simulated recording of a built-in scene (evnerf.scenes), 'random' or a scene file, as `evnerf simulate` makes it. "
      "Without out it stays in memory (frames, no depth or linear truth); with out it is written there (IJRR layout) and loaded.");

  py::class_<Model> model(m, "Model", "A trained or loaded model of any of this module's variants.", py::module_local());
  model.def_readonly("variant", &Model::variant);
  model.def_readonly("channels", &Model::channels);
  model.def_readonly("run", &Model::run, "what train() did (steps, seconds, final_loss, stopped, collapse checks); empty when loaded");
  model.def_property_readonly("width", [](const Model& s) { return s.renderable.desc.camera.width(); });
  model.def_property_readonly("height", [](const Model& s) { return s.renderable.desc.camera.height(); });
  model.def_property_readonly("boundary_times", [](const Model& s) {
    return to_numpy(s.renderable.desc.times, {static_cast<py::ssize_t>(s.renderable.desc.times.size())});
  });
  model.def_property_readonly("boundary_poses", [](const Model& s) { return matrices_of(s.renderable.desc.poses); },
                              "N x 4 x 4 camera-to-world poses at the slice boundaries");
  model.def_property_readonly("step", [](const Model& s) -> py::object { return s.step ? py::object(py::int_(s.step())) : py::object(py::none()); });
  model.def_property_readonly("thresholds", [](const Model& s) -> py::object {
    if (!s.thresholds) return py::none();
    const auto v = s.thresholds();
    return to_numpy(v, {static_cast<py::ssize_t>(v.size() / 2), 2});
  }, "per slice (B+, B-) as an N x 2 array (None for a per-channel model)");
  model.def(
      "render",
      [](const Model& s, py::handle pose) {
        const auto p = pose_of(pose);
        Rendering r;
        {
          py::gil_scoped_release nogil;
          r = s.renderable.render(p);
        }
        return py::make_tuple(image_to_numpy(r.luminance), image_to_numpy(r.depth));
      },
      py::arg("pose"),
      "(intensity, depth) at a camera-to-world pose (4x4, or [px, py, pz, qx, qy, qz, qw]): H x W (x 3) linear intensity, H x W depth");
  model.def(
      "save",
      [](const Model& s, const fs::path& p) {
        if (!s.save) throw Error(p.string(), 0, "a per-channel model is saved by train --per-channel only");
        py::gil_scoped_release nogil;
        s.save(p);
      },
      py::arg("path"), "writes model.ckpt (atomically)");
  model.def("__repr__", [](const Model& s) {
    return "<evnerf.Model '" + s.variant + "': " + std::to_string(s.renderable.desc.camera.width()) + "x" +
           std::to_string(s.renderable.desc.camera.height()) + ", " + std::to_string(s.renderable.desc.times.size()) + " boundaries" +
           (s.step ? ", step " + std::to_string(s.step()) : std::string()) + ">";
  });

  static std::string train_doc;
  m.def(
      "settings",
      [] {
        nlohmann::json rows = nlohmann::json::array();
        const train::Config defaults;
        for (const auto& s : train::settings())
          rows.push_back({{"name", s.name}, {"default", s.get(defaults)}, {"allowed", s.numeric() ? s.range_text() : s.integral() ? "any" : "any of its kind"},
                          {"integer", s.integral()}, {"numeric", s.numeric()}, {"lo", s.lo}, {"hi", s.hi}, {"lo_open", s.lo_open},
                          {"hi_open", s.hi_open}, {"help", s.help}});
        return json_to_python(rows);
      },
      "the training settings train() takes as keywords: name, default, allowed values, help (train::settings(), the same table as "
      "the command line's flags)");
  m.def("load_model", &load_model<V...>, py::arg("path"), py::arg("channel_upsampling") = "volume",
        "a model.ckpt of any compiled-in variant, or channels.json of train --per-channel (channel_upsampling: 'volume' "
        "renders each channel's volume at every pixel, 'sites' renders its sites and interpolates)");
  m.def("train", &train_model<V...>, py::arg("dataset"), py::kw_only(), py::arg("preset") = default_variant, py::arg("callback") = py::none(),
        py::arg("out") = py::none(), py::arg("resume") = false,
        (train_doc = "Trains a variant (" + [&] {
          std::string s;
          for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
          return s;
        }() + ") on a dataset; returns the Model. Settings as keywords (evnerf.settings() describes each): " + setting_names() +
              ". callback(step, loss, thresholds) "
              "runs after every step; returning False stops the run. With out, settings.json, log.jsonl and model.ckpt are written there (resume "
              "continues from it); without, nothing is written.").c_str());

  m.def(
      "evaluate",
      [](const Model& s, const Dataset& d, const std::string& alignment, int holdout) {
        evaluation::Evaluation e;
        {
          py::gil_scoped_release nogil;
          e = evaluation::evaluate(s.renderable, *d.d, evaluation::alignments_from(alignment), holdout);
        }
        py::dict r = json_to_python(e.json);
        py::list images;
        for (const auto& im : e.methods.front().images) images.append(image_to_numpy(im));
        r["frames"] = e.ids;
        r["renders"] = images;
        return r;
      },
      py::arg("model"), py::arg("dataset"), py::kw_only(), py::arg("alignment") = "global-log-affine", py::arg("holdout") = 0,
      "Renders at the dataset's frames inside the trained time and scores it and both baselines: metrics.json as a dict "
      "(alignment, methods, secondary, ...), plus frames (their indices) and renders (the model's images).");
  m.def(
      "baselines",
      [](const Dataset& d, double contrast, const std::string& alignment) {
        require(contrast > 0 && std::isfinite(contrast), "baselines: the contrast must be positive");
        evaluation::BaselineRun b;
        {
          py::gil_scoped_release nogil;
          b = evaluation::run_baselines(*d.d, evaluation::alignments_from(alignment), contrast);
        }
        py::dict r = json_to_python(b.scored.json);
        py::dict images;
        for (const auto& meth : b.methods) {
          py::list l;
          for (const auto& im : meth.images) l.append(image_to_numpy(im));
          images[py::str(meth.name)] = l;
        }
        r["frames"] = b.ids;
        r["images"] = images;
        return r;
      },
      py::arg("dataset"), py::kw_only(), py::arg("contrast") = 0.2, py::arg("alignment") = "global-log-affine",
      "Direct integration and the high-pass filter at the frames inside the events' span, scored: metrics as a dict, "
      "frames, and images[name] (one array per frame).");
  m.def(
      "score",
      [](py::handle images, py::handle truth, const std::string& alignment, bool oracle) {
        const auto a = eval::parse_alignment(alignment);
        const auto pred = image_list(images, "images");
        const auto gt = image_list(truth, "truth");
        std::vector<Image> aligned, truths;
        const auto s = eval::score_sequence(pred, gt, a, &aligned);
        py::list per;
        for (const auto& x : s) per.append(py::dict(py::arg("mse") = x.mse, py::arg("psnr") = x.psnr, py::arg("ssim") = x.ssim));
        const auto mean = eval::mean(s);
        py::dict r(py::arg("alignment") = eval::to_string(a), py::arg("mse") = mean.mse, py::arg("psnr") = mean.psnr,
                   py::arg("ssim") = mean.ssim, py::arg("per_frame") = per);
        if (oracle && !gt.empty()) {
          for (const auto& g : gt) truths.push_back(eval::scored_truth(g, a));
          const auto o = eval::offset_oracle(aligned, truths);
          r["oracle"] = py::dict(py::arg("rows_psnr") = o.rows_psnr, py::arg("columns_psnr") = o.columns_psnr,
                                 py::arg("both_psnr") = o.both_psnr);
        }
        return r;
      },
      py::arg("images"), py::arg("truth"), py::kw_only(), py::arg("alignment") = "global-log-affine", py::arg("oracle") = false,
      "MSE, PSNR and SSIM of a sequence of images against the truth (N x H x W (x 3) arrays or lists) under an alignment. "
      "oracle=True adds eval's offset oracle (oracle: rows_psnr, columns_psnr, both_psnr): the PSNR with gains per image row, "
      "per column and both, constant over the sequence, fitted to the truth; what a straight motion never shows the events "
      "(a diagnosis, never a score).");
}

}  // namespace evnerf::python

/// A Python module named `name` over the variants `...` (evnerf::Variant<Model, "name">; the first is train()'s
/// default).
#define EVNERF_PYTHON_MODULE(name, ...) \
  PYBIND11_MODULE(name, m) { ::evnerf::python::define<__VA_ARGS__>(m); }
