// python/convert.hpp — what the Python module (python/module.hpp) is built from: the Python-side Dataset and
// Model, numpy arrays to and from images, poses and event arrays (checked: dtypes, shapes, values, with
// messages naming the argument), a Dataset made from numpy arrays, train()'s keywords as a train::Config
// (the settings table), simulate()'s sensor keywords. Needs pybind11. Depends on io/, sim/, train/, eval/.
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
#include "../evnerf.hpp"
#include "../sim/simulate.hpp"

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
  py::dict run;  ///< what train() did: steps, seconds, final_loss, stopped, collapse checks, refractory
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
py::array_t<T, py::array::c_style> array_of(py::handle obj, const std::string& name, const std::string& kinds,
                                            const std::string& expected) {
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
      throw Error(what + ": expected shape (" + std::to_string(height) + ", " + std::to_string(width) + ") or (" + std::to_string(height) +
                  ", " + std::to_string(width) + ", 3), got " + shape_text(a));
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
  if (static_cast<std::size_t>(ay.shape(0)) != n || static_cast<std::size_t>(at.shape(0)) != n ||
      static_cast<std::size_t>(ap.shape(0)) != n)
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
      if (qn < 0.5 || qn > 1.5)
        throw Error("poses: row " + std::to_string(i) + ": quaternion is far from unit length (norm " + short_number(qn) + ")");
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

/// simulate()'s sensor keywords as sim::SensorOptions; an unknown keyword is an error naming the known ones.
inline sim::SensorOptions sensor_options(const std::string& model, const py::kwargs& kw) {
  sim::SensorOptions o;
  o.model = model;
  for (const auto& [key, value] : kw) {
    const auto k = key.cast<std::string>();
    bool known = false;
    sim::sensor_params([&](const auto& p) {
      if (k != p.name) return;
      using T = typename std::remove_reference_t<decltype(o.*p.given)>::value_type;
      o.*p.given = value.template cast<T>();
      known = true;
    });
    if (!known) throw Error("simulate: unknown keyword '" + k + "' (the sensor's: " + sim::sensor_param_names() + ")");
  }
  return o;
}

/// Images from a list or an N×H×W[×3] array, at the size of the first.
inline std::vector<Image> image_list(py::handle obj, const std::string& name) {
  const auto items = image_items(obj, name);
  if (items.empty()) throw Error(name + ": no images");
  if (!items.front() || items.front().ndim() < 2) type_error(name + "[0]: expected an H x W (x 3) array");
  return images_of(obj, name, static_cast<int>(items.front().shape(1)), static_cast<int>(items.front().shape(0)));
}

}  // namespace detail

}  // namespace evnerf::python
