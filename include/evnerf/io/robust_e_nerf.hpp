// io/robust_e_nerf.hpp — the dataset layout of Robust e-NeRF (Low & Lee, ICCV 2023): a sequence folder as its
// scripts/preprocess_esim.py and tum_vie_to_esim.py write it, three numpy archives:
//   raw_events.npz          position (N×2: x, y), timestamp (N, integer ns), polarity (N, bool or 0/1 or ±1)
//   camera_poses.npz        T_wc_position (M×3), T_wc_orientation (M×4: x y z w), T_wc_timestamp (M, integer ns):
//                           camera to world, OpenCV axes (ESIM's)
//   camera_calibration.npz  intrinsics (3×3), distortion_params (plumb_bob: k1 k2 p1 p2 [k3]; none),
//                           distortion_model (string), img_height, img_width, bayer_pattern ("" or "RGGB"...),
//                           contrast thresholds and refractory period (not read: evnerf learns its thresholds)
// Times are nanoseconds; they are read relative to the whole second of the first event (Dataset::
// time_origin), exactly. The posed images of views/ (NeRF's transforms_*.json) are not on the trajectory in
// time and are not read. Depends on core/, geometry/, events/ and io/ only.
#pragma once
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../events/event_stream.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/trajectory.hpp"
#include "eventnerf.hpp"
#include "npy.hpp"
#include "recording.hpp"

namespace evnerf::io {

/// Whether `folder` is a Robust e-NeRF sequence (raw_events.npz and camera_calibration.npz).
inline bool is_robust_e_nerf(const std::filesystem::path& folder) {
  return std::filesystem::is_regular_file(folder / "raw_events.npz") && std::filesystem::is_regular_file(folder / "camera_calibration.npz");
}

struct RobustENerfSequence {
  events::EventStream events;
  geometry::Camera camera;
  geometry::Trajectory trajectory;
  std::int64_t origin_sec = 0;
  std::string bayer_pattern;  ///< "" for a monochrome sensor
};

inline RobustENerfSequence read_robust_e_nerf(const std::filesystem::path& folder, int width = 0, int height = 0) {
  namespace fs = std::filesystem;
  RobustENerfSequence s;
  const fs::path cal_path = folder / "camera_calibration.npz", ev_path = folder / "raw_events.npz", pose_path = folder / "camera_poses.npz";
  const auto cal = read_npz(cal_path);
  auto member = [](const std::map<std::string, std::string>& m, const fs::path& p, const char* key) -> const std::string& {
    const auto it = m.find(key);
    if (it == m.end()) throw Error(p.string(), 0, std::string("no array '") + key + "'");
    return it->second;
  };
  auto numeric = [&](const std::map<std::string, std::string>& m, const fs::path& p, const char* key) {
    return parse_npy_numeric(member(m, p, key), p.string() + " (array '" + key + "')");
  };
  auto integers = [&](const std::map<std::string, std::string>& m, const fs::path& p,
                      const char* key) {  // exact (ns since 1970 exceed 2^53)
    return parse_npy_numeric<std::int64_t>(member(m, p, key), p.string() + " (array '" + key + "')");
  };
  const auto K = numeric(cal, cal_path, "intrinsics");
  if (K.data.size() != 9) throw Error(cal_path.string(), 0, "array 'intrinsics' is not a 3x3 matrix");
  const auto H = numeric(cal, cal_path, "img_height"), W = numeric(cal, cal_path, "img_width");
  if (H.data.size() != 1 || W.data.size() != 1) throw Error(cal_path.string(), 0, "img_height and img_width must be single numbers");
  int w = width, h = height;
  if (w <= 0 || h <= 0) {
    if (!(W.data[0] >= 1 && W.data[0] <= 65535 && H.data[0] >= 1 && H.data[0] <= 65535))
      throw Error(cal_path.string(), 0, "image size " + short_number(W.data[0]) + "x" + short_number(H.data[0]) + " out of range");
    w = static_cast<int>(W.data[0]), h = static_cast<int>(H.data[0]);
  }
  const std::string model = cal.count("distortion_model") ? parse_npy_string(cal.at("distortion_model"), cal_path.string()) : "";
  std::vector<double> D;
  if (cal.count("distortion_params")) D = numeric(cal, cal_path, "distortion_params").data;
  for (double v : D)
    if (!std::isfinite(v)) throw Error(cal_path.string(), 0, "a distortion parameter is not finite");
  const bool zero = std::all_of(D.begin(), D.end(), [](double v) { return v == 0; });
  std::array<double, 5> k{0, 0, 0, 0, 0};
  if (!zero) {
    if (model != "plumb_bob" || D.size() < 4 || D.size() > 5)
      throw Error(cal_path.string(), 0,
                  "distortion model '" + model.substr(0, 40) + "' with " + std::to_string(D.size()) +
                      " parameters is not read (plumb_bob: k1 k2 p1 p2 [k3]); give --calib");
    for (std::size_t i = 0; i < D.size(); ++i) k[i] = D[i];
  }
  const double fx = K.data[0], fy = K.data[4], cx = K.data[2], cy = K.data[5];
  if (!(fx > 0) || !(fy > 0) || !std::isfinite(cx) || !std::isfinite(cy))
    throw Error(cal_path.string(), 0, "intrinsics need positive focal lengths and a finite centre");
  s.camera = geometry::Camera(w, h, fx, fy, cx, cy, k);
  if (cal.count("bayer_pattern")) s.bayer_pattern = parse_npy_string(cal.at("bayer_pattern"), cal_path.string());

  // Events: integer nanoseconds, relative to the whole second of the first.
  const auto ev = read_npz(ev_path);
  const auto pos = numeric(ev, ev_path, "position"), pol = numeric(ev, ev_path, "polarity");
  const auto ts = integers(ev, ev_path, "timestamp");
  const std::size_t n = ts.data.size();
  if (pos.shape.size() != 2 || pos.shape[1] != 2 || pos.shape[0] != n || pol.data.size() != n)
    throw Error(ev_path.string(), 0, "expected position N×2, timestamp N and polarity N (N = " + std::to_string(n) + ")");
  if (n == 0) throw Error(ev_path.string(), 0, "no events");
  // The origin: the whole second at or before the first event (floor division, also for negative times).
  // The file's times may be any int64: the origin and every difference are computed with overflow checks
  // (a wrapped difference would put a time 584 years away at a plausible one).
  s.origin_sec = ts.data[0] / 1000000000 - (ts.data[0] % 1000000000 < 0 ? 1 : 0);
  std::int64_t origin_ns = 0;
  if (__builtin_mul_overflow(s.origin_sec, std::int64_t{1000000000}, &origin_ns))
    throw Error(ev_path.string(), 0, "event 0: time " + std::to_string(ts.data[0]) + " ns has no whole second within int64's range");
  auto relative = [&](std::int64_t t, const fs::path& p, const std::string& what) {
    std::int64_t d = 0;
    if (__builtin_sub_overflow(t, origin_ns, &d) || d > (std::int64_t{1} << 53) || d < -(std::int64_t{1} << 53))
      throw Error(p.string(), 0, what + ": time " + std::to_string(t) + " ns lies more than 104 days from the first event");
    return static_cast<double>(d) / 1e9;
  };
  s.events.width = w;
  s.events.height = h;
  s.events.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = pos.data[2 * i], y = pos.data[2 * i + 1], p = pol.data[i];
    const std::string e = "event " + std::to_string(i);
    if (!(x >= 0 && y >= 0 && x < w && y < h) || x != std::floor(x) || y != std::floor(y))
      throw Error(ev_path.string(), 0,
                  e + ": pixel (" + short_number(x) + ", " + short_number(y) + ") is not a pixel of the " + std::to_string(w) + "x" +
                      std::to_string(h) + " sensor");
    if (p != 0 && p != 1 && p != -1) throw Error(ev_path.string(), 0, e + ": polarity " + short_number(p) + " (expected bool, 0/1 or ±1)");
    const double tr = relative(ts.data[i], ev_path, e);
    if (i > 0 && tr < s.events.t.back()) throw Error(ev_path.string(), 0, e + ": time goes back");
    s.events.push_back(tr, static_cast<int>(x), static_cast<int>(y), p > 0 ? 1 : -1);
  }

  // Poses.
  if (fs::exists(pose_path)) {
    const auto pz = read_npz(pose_path);
    const auto P = numeric(pz, pose_path, "T_wc_position"), Q = numeric(pz, pose_path, "T_wc_orientation");
    const auto T = integers(pz, pose_path, "T_wc_timestamp");
    const std::size_t m = T.data.size();
    if (P.data.size() != 3 * m || Q.data.size() != 4 * m)
      throw Error(pose_path.string(), 0,
                  "expected T_wc_position M×3, T_wc_orientation M×4 and T_wc_timestamp M (M = " + std::to_string(m) + ")");
    std::vector<double> times;
    std::vector<geometry::Pose> poses;
    for (std::size_t i = 0; i < m; ++i) {
      const std::string e = "pose " + std::to_string(i);
      geometry::Pose pose;
      pose.t = Vec3(P.data[3 * i], P.data[3 * i + 1], P.data[3 * i + 2]);
      const double qx = Q.data[4 * i], qy = Q.data[4 * i + 1], qz = Q.data[4 * i + 2], qw = Q.data[4 * i + 3];
      const double nq = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
      if (!pose.t.allFinite() || !(nq > 0.5 && nq < 1.5))
        throw Error(pose_path.string(), 0, e + ": not finite, or its quaternion far from unit length");
      pose.q = Quat(qw / nq, qx / nq, qy / nq, qz / nq);
      const double t = relative(T.data[i], pose_path, e);
      if (!times.empty() && !(t > times.back())) throw Error(pose_path.string(), 0, e + ": pose times must increase strictly");
      times.push_back(t);
      poses.push_back(pose);
    }
    s.trajectory = geometry::Trajectory(std::move(times), std::move(poses), pose_path.string());
  }
  return s;
}

/// Loads a Robust e-NeRF sequence folder (io/robust_e_nerf.hpp), with the calibration and poses LoadOptions
/// names instead of its own where given (a pose file's times in the sequence's clock, seconds).
inline Dataset load_robust_e_nerf(const std::filesystem::path& folder, const LoadOptions& opt = {}) {
  auto s = read_robust_e_nerf(folder, opt.width, opt.height);
  check_sensor_size(s.camera.width(), s.camera.height(),
                    opt.width > 0 && opt.height > 0 ? folder.string() + " (the sensor size given)"
                                                    : (folder / "camera_calibration.npz").string() + " (its img_width and img_height)");
  Dataset d;
  d.folder = folder;
  d.time_origin = s.origin_sec;
  d.bayer_pattern = s.bayer_pattern;
  for (auto& c : d.bayer_pattern) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  d.camera = opt.calib.empty() ? s.camera : read_calib_source(opt.calib, s.camera.width(), s.camera.height());
  d.events = std::move(s.events);
  if (!opt.poses.empty()) {
    d.trajectory = read_pose_source(opt.poses, d.frames, static_cast<double>(s.origin_sec));
  } else {
    d.trajectory = std::move(s.trajectory);
  }
  return d;
}

/// The format's line in io::formats().
inline Format robust_e_nerf_format() {
  return {"robust-e-nerf", true, "a Robust e-NeRF sequence folder (raw_events.npz, camera_poses.npz, camera_calibration.npz)",
          &is_robust_e_nerf, &load_robust_e_nerf};
}

}  // namespace evnerf::io
