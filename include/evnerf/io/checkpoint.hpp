// io/checkpoint.hpp — the checkpoint format and its one parser. A checkpoint is
//   "EVNERFCK" | u64 version | str variant name | u64 parameter count | u64 slices | i64 step |
//   f64×6 box (centre, scale, near, far) | f64 density length | f64 background (NaN: none) | u64 backdrop learned (0, 1) |
//   f64 refractory period (seconds; negative: counts read as they are) + f64×2 its Adam moments + u64 learned (0, 1) |
//   str loss | str architecture |
//   f32 parameters | f32 Adam m | f32 Adam v |
//   u64 average count (0 or the parameter count) + f64 its decay + f32 average |
//   str sampler state (the occupancy grid) |
//   pose refinement: u64 what is learned (bit 0 the corrections, bit 1 the clock offset) | f64 offset (seconds) + f64×2 its
//            Adam moments | u64 knots (0, or one per slice boundary) + per knot f64×7 correction (px py pz qx qy qz qw),
//            f64×12 its Adam moments, f64×7 the refined pose |
//   the run: str recording | u64 shards per step | i64 width, height + f64 fx, fy, cx, cy, k1, k2, p1, p2, k3 |
//            u64 boundaries + per boundary f64 t, px, py, pz, qx, qy, qz, qw |
//   u64 FNV-1a of everything before it
// (u64/i64/f64 little-endian as stored by this machine; str = u64 length + bytes). One version is read: the
// one written. The architecture (the model's types: encodings, networks, sampler) and the loss decide which
// model loads a file; the variant's name is a label. The run (CheckpointRun) is what `render` and `eval`
// need without the recording, and what a resume must match. EvNerf::serialize writes the format,
// EvNerf::deserialize and the command line (which variant wrote this file?) read it through this header.
// Depends on core/ and geometry/.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"

namespace evnerf::io {

inline constexpr std::uint64_t kCheckpointVersion = 11;

/// Bounds-checked reading of a checkpoint's bytes; every error names the file.
class CheckpointReader {
 public:
  /// Checks the magic and the checksum.
  CheckpointReader(const std::string& bytes, std::string file) : b_(bytes), file_(std::move(file)) {
    if (b_.size() < 16 || std::memcmp(b_.data(), "EVNERFCK", 8) != 0) fail("not an evnerf checkpoint");
    std::uint64_t sum = 0;
    std::memcpy(&sum, b_.data() + b_.size() - 8, 8);
    if (sum != fnv1a64(std::string_view(b_).substr(0, b_.size() - 8))) fail("checksum mismatch (truncated or damaged)");
    pos_ = 8;
  }
  [[noreturn]] void fail(const std::string& why) const { throw Error(file_, 0, "corrupt or mismatched checkpoint: " + why); }
  void get(void* p, std::size_t n) {
    if (n > b_.size() - 8 || pos_ > b_.size() - 8 - n) fail("truncated");
    std::memcpy(p, b_.data() + pos_, n);
    pos_ += n;
  }
  void skip(std::size_t n) {
    if (n > b_.size() - 8 || pos_ > b_.size() - 8 - n) fail("truncated");
    pos_ += n;
  }
  std::uint64_t u64() {
    std::uint64_t v = 0;
    get(&v, 8);
    return v;
  }
  double f64() {
    double v = 0;
    get(&v, 8);
    return v;
  }
  std::string str() {
    const auto n = u64();
    if (n > b_.size()) fail("bad string length");
    std::string s(n, '\0');
    get(s.data(), n);
    return s;
  }
  const std::string& file() const { return file_; }
  /// Bytes left before the checksum.
  std::size_t remaining() const { return b_.size() - 8 - pos_; }

 private:
  const std::string& b_;
  std::string file_;
  std::size_t pos_ = 0;
};

/// Everything before the parameters.
struct CheckpointHeader {
  std::uint64_t version = kCheckpointVersion;
  std::string name;  ///< the variant's name as the writer gave it
  std::uint64_t n_params = 0, n_slices = 0;
  std::int64_t step = 0;
  double box[6] = {0, 0, 0, 1, 0, 1};  ///< centre x y z, scale, near, far
  double density_length = 1.0;
  double background = std::numeric_limits<double>::quiet_NaN();  ///< the box's background luminance, NaN for none
  bool background_learned = false;                               ///< the box's backdrop is learned (its values are parameters)
  double refractory = -1, refractory_m = 0, refractory_v = 0;    ///< the period (negative: none) and its Adam moments
  bool refractory_learned = false;
  std::string loss;
  std::string architecture;
};

/// What a checkpoint records of the run that trained it: the recording's path, the shards per step (a
/// resume must use as many), the sensor, and the slice boundaries' times and poses. A model saved outside
/// a training run records none (a 0 x 0 camera, no boundaries); render and eval refuse such a file.
struct CheckpointRun {
  std::string recording;
  std::uint64_t shards = 1;
  geometry::Camera camera;
  std::vector<double> times;
  std::vector<geometry::Pose> poses;  ///< camera to world at each time
};

/// Reads the header; the reader is left at the parameters.
inline CheckpointHeader read_checkpoint_header(CheckpointReader& r) {
  CheckpointHeader h;
  h.version = r.u64();
  if (h.version != kCheckpointVersion)
    r.fail("format version " + std::to_string(h.version) + "; this build reads version " + std::to_string(kCheckpointVersion) +
           " only (retrain, or load it with the build that wrote it)");
  h.name = r.str();
  h.n_params = r.u64();
  h.n_slices = r.u64();
  r.get(&h.step, 8);
  r.get(h.box, sizeof h.box);
  h.density_length = r.f64();
  if (!(h.density_length > 0) || !std::isfinite(h.density_length)) r.fail("density length is not a positive number");
  h.background = r.f64();
  if (!std::isnan(h.background) && !(h.background >= 0 && std::isfinite(h.background)))
    r.fail("the background luminance is " + short_number(h.background) + " (a number >= 0, or NaN for none)");
  const std::uint64_t backdrop = r.u64();
  if (backdrop > 1) r.fail("the backdrop's flag is " + std::to_string(backdrop) + " (0: not learned, 1: learned)");
  h.background_learned = backdrop == 1;
  h.refractory = r.f64();
  h.refractory_m = r.f64();
  h.refractory_v = r.f64();
  const std::uint64_t learned = r.u64();
  if (!std::isfinite(h.refractory) || h.refractory > 1 || !std::isfinite(h.refractory_m) || !(h.refractory_v >= 0) ||
      !std::isfinite(h.refractory_v) || learned > 1)
    r.fail("the refractory period's record (" + short_number(h.refractory) + " s, moments " + short_number(h.refractory_m) + ", " +
           short_number(h.refractory_v) + ", learned " + std::to_string(learned) + ") is not one training writes");
  h.refractory_learned = learned == 1;
  h.loss = r.str();
  h.architecture = r.str();
  return h;
}

/// Reads the run; the reader is left at the checksum.
inline CheckpointRun read_checkpoint_run(CheckpointReader& r) {
  CheckpointRun run;
  run.recording = r.str();
  run.shards = r.u64();
  if (run.shards < 1 || run.shards > 4096) r.fail("the run's shards per step (" + std::to_string(run.shards) + ") are not in 1..4096");
  std::int64_t wh[2];
  r.get(wh, sizeof wh);
  double c[9];
  r.get(c, sizeof c);
  if (wh[0] == 0 && wh[1] == 0) {  // a model saved outside a training run: no sensor, no boundaries
    for (double v : c)
      if (v != 0) r.fail("the run has no sensor but camera intrinsics");
    if (r.u64() != 0) r.fail("the run has no sensor but slice boundaries");
    return run;
  }
  if (wh[0] < 1 || wh[1] < 1 || wh[0] > 65536 || wh[1] > 65536)
    r.fail("the run's sensor is " + std::to_string(wh[0]) + " x " + std::to_string(wh[1]) + " pixels");
  for (double v : c)
    if (!std::isfinite(v)) r.fail("the run's camera has a non-finite intrinsic");
  if (!(c[0] > 0 && c[1] > 0)) r.fail("the run's camera has a focal length that is not positive");
  run.camera = geometry::Camera(static_cast<int>(wh[0]), static_cast<int>(wh[1]), c[0], c[1], c[2], c[3], {c[4], c[5], c[6], c[7], c[8]});
  const std::uint64_t n = r.u64();
  if (n > r.remaining() / 64) r.fail("the run's " + std::to_string(n) + " boundaries need more bytes than remain");
  run.times.resize(n);
  run.poses.resize(n);
  for (std::uint64_t i = 0; i < n; ++i) {
    double v[8];
    r.get(v, sizeof v);
    for (double x : v)
      if (!std::isfinite(x)) r.fail("boundary " + std::to_string(i) + " of the run has a non-finite time or pose");
    const Quat q(v[7], v[4], v[5], v[6]);
    const double norm = q.norm();  // overflows to infinity for components near the largest double
    if (!(norm > 1e-12) || !std::isfinite(norm))
      r.fail("boundary " + std::to_string(i) + " of the run has a rotation quaternion of norm " + short_number(norm) +
             " (a rotation needs a finite, nonzero one)");
    if (i > 0 && !(v[0] > run.times[i - 1])) r.fail("the run's boundary times do not increase at boundary " + std::to_string(i));
    run.times[i] = v[0];
    run.poses[i].t = Vec3(v[1], v[2], v[3]);
    run.poses[i].q = q.normalized();
  }
  return run;
}

/// Pose refinement's record (model/poses.hpp): what is learned, the clock offset, and per knot the
/// correction, its Adam moments and the refined pose that render and eval use for the training path.
struct CheckpointPoses {
  bool poses = false, offset = false;
  double time_offset = 0, offset_m = 0, offset_v = 0;
  std::vector<geometry::Pose> correction, refined;
  std::vector<std::array<double, 6>> m, v;
};

/// What a checkpoint holds besides its header and run: the parameters with Adam's two moments (n floats
/// each), the parameter average (n floats, or null for none) and its decay, and the sampler's state.
struct CheckpointBody {
  const float *params = nullptr, *adam_m = nullptr, *adam_v = nullptr;
  std::size_t n = 0;
  const float* average = nullptr;
  double average_decay = 0;
  std::string sampler_state;
  CheckpointPoses poses;
};

/// Reads pose refinement's record for a model of `n_slices` slices.
inline CheckpointPoses read_checkpoint_poses(CheckpointReader& r, std::uint64_t n_slices) {
  CheckpointPoses p;
  const std::uint64_t what = r.u64();
  if (what > 3) r.fail("pose refinement's record says it learns " + std::to_string(what) + " (0 to 3: corrections, offset)");
  p.poses = (what & 1) != 0;
  p.offset = (what & 2) != 0;
  double o[3];
  r.get(o, sizeof o);
  if (!std::isfinite(o[0]) || !std::isfinite(o[1]) || !(o[2] >= 0) || !std::isfinite(o[2]) || std::abs(o[0]) > 1e6)
    r.fail("pose refinement's clock offset (" + short_number(o[0]) + " s, moments " + short_number(o[1]) + ", " + short_number(o[2]) +
           ") is not one training writes");
  p.time_offset = o[0];
  p.offset_m = o[1];
  p.offset_v = o[2];
  const std::uint64_t n = r.u64();
  if (n != 0 && n != n_slices + 1)
    r.fail("pose refinement has " + std::to_string(n) + " knots for " + std::to_string(n_slices) + " slices (one per boundary)");
  if ((n != 0) != (what != 0)) r.fail("pose refinement's knots (" + std::to_string(n) + ") do not match what it learns");
  if (n > r.remaining() / (26 * 8)) r.fail("pose refinement's " + std::to_string(n) + " knots need more bytes than remain");
  auto pose_of = [&](const double* v, std::uint64_t i, const char* what_pose) {
    for (int k = 0; k < 7; ++k)
      if (!std::isfinite(v[k])) r.fail(std::string("pose refinement's ") + what_pose + " at knot " + std::to_string(i) + " is not finite");
    const Quat q(v[6], v[3], v[4], v[5]);
    const double norm = q.norm();
    if (!(norm > 1e-12) || !std::isfinite(norm))
      r.fail(std::string("pose refinement's ") + what_pose + " at knot " + std::to_string(i) + " has a rotation quaternion of norm " +
             short_number(norm));
    geometry::Pose pose;
    pose.t = Vec3(v[0], v[1], v[2]);
    pose.q = q.normalized();
    return pose;
  };
  for (std::uint64_t i = 0; i < n; ++i) {
    double v[26];
    r.get(v, sizeof v);
    p.correction.push_back(pose_of(v, i, "correction"));
    std::array<double, 6> m{}, s{};
    for (int k = 0; k < 6; ++k) {
      m[k] = v[7 + k];
      s[k] = v[13 + k];
      if (!std::isfinite(m[k]) || !std::isfinite(s[k]) || s[k] < 0)
        r.fail("pose refinement's Adam moments at knot " + std::to_string(i) + " are not ones training writes");
    }
    p.m.push_back(m);
    p.v.push_back(s);
    p.refined.push_back(pose_of(v + 19, i, "refined pose"));
  }
  return p;
}

/// The bytes of a checkpoint (header.version and n_params are set from here).
inline std::string write_checkpoint(const CheckpointHeader& h, const CheckpointBody& body, const CheckpointRun& run) {
  std::string b;
  auto put = [&](const void* p, std::size_t n) { b.append(static_cast<const char*>(p), n); };
  auto put_u64 = [&](std::uint64_t v) { put(&v, 8); };
  auto put_f64 = [&](double v) { put(&v, 8); };
  auto put_str = [&](const std::string& s) {
    put_u64(s.size());
    put(s.data(), s.size());
  };
  put("EVNERFCK", 8);
  put_u64(kCheckpointVersion);
  put_str(h.name);
  put_u64(body.n);
  put_u64(h.n_slices);
  put(&h.step, 8);
  put(h.box, sizeof h.box);
  put_f64(h.density_length);
  put_f64(h.background);
  put_u64(h.background_learned ? 1 : 0);
  put_f64(h.refractory);
  put_f64(h.refractory_m);
  put_f64(h.refractory_v);
  put_u64(h.refractory_learned ? 1 : 0);
  put_str(h.loss);
  put_str(h.architecture);
  put(body.params, body.n * 4);
  put(body.adam_m, body.n * 4);
  put(body.adam_v, body.n * 4);
  put_u64(body.average ? body.n : 0);
  put_f64(body.average ? body.average_decay : 0.0);
  if (body.average) put(body.average, body.n * 4);
  put_str(body.sampler_state);
  const auto& pr = body.poses;
  put_u64((pr.poses ? 1u : 0u) | (pr.offset ? 2u : 0u));
  for (double v : {pr.time_offset, pr.offset_m, pr.offset_v}) put_f64(v);
  require(pr.correction.size() == pr.refined.size() && pr.m.size() == pr.correction.size() && pr.v.size() == pr.correction.size(),
          "write_checkpoint: pose refinement's knots differ in count");
  put_u64(pr.correction.size());
  auto put_pose = [&](const geometry::Pose& p) {
    for (double v : {p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(), p.q.w()}) put_f64(v);
  };
  for (std::size_t i = 0; i < pr.correction.size(); ++i) {
    put_pose(pr.correction[i]);
    for (double v : pr.m[i]) put_f64(v);
    for (double v : pr.v[i]) put_f64(v);
    put_pose(pr.refined[i]);
  }
  require(run.times.size() == run.poses.size(), "write_checkpoint: the run has " + std::to_string(run.times.size()) + " times and " +
                                                    std::to_string(run.poses.size()) + " poses");
  put_str(run.recording);
  put_u64(run.shards);
  const std::int64_t wh[2] = {run.camera.width(), run.camera.height()};
  put(wh, sizeof wh);
  const auto& c = run.camera;  // a default camera (0 x 0: no run) writes zeros
  for (double v : {c.fx(), c.fy(), c.cx(), c.cy()}) put_f64(wh[0] > 0 ? v : 0.0);
  for (double v : c.distortion()) put_f64(wh[0] > 0 ? v : 0.0);
  put_u64(run.times.size());
  for (std::size_t i = 0; i < run.times.size(); ++i) {
    const auto& p = run.poses[i];
    for (double v : {run.times[i], p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(), p.q.w()}) put_f64(v);
  }
  put_u64(fnv1a64(b));
  return b;
}

/// The header of a checkpoint file (the whole file is read and its checksum checked).
inline CheckpointHeader peek_checkpoint(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  CheckpointReader r(bytes, path.string());
  return read_checkpoint_header(r);
}

}  // namespace evnerf::io
