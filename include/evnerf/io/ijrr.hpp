// io/ijrr.hpp — readers for the IJRR "Event Camera Dataset" text layout (events.txt, images.txt,
// groundtruth.txt, calib.txt), TUM pose files, and the Dataset that bundles them.
// Depends on core/, geometry/, events/ and io/ only.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "../core/fileio.hpp"
#include "../events/event_stream.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/trajectory.hpp"
#include "text.hpp"

namespace evnerf::io {

namespace fs = std::filesystem;

/// Parses `t x y p` lines (t seconds, p ∈ {1, 0} or {1, -1}) into a stream for a width×height sensor.
/// Errors name file and line: truncated or extra fields, non-numeric or non-finite values, unknown
/// polarity codes, pixels outside the sensor, timestamps going backwards, an empty file.
inline events::EventStream parse_events(std::string_view text, const std::string& file, int width, int height) {
  events::EventStream ev;
  ev.width = width;
  ev.height = height;
  ev.reserve(text.size() / 24);  // a typical IJRR line is 22–26 bytes
  LineScanner s(text, file);
  double last_t = -INFINITY;
  while (s.next_line()) {
    const double t = s.real("t");
    const long long x = s.integer("x"), y = s.integer("y"), p = s.integer("polarity");
    s.expect_end();
    if (t < last_t) s.fail("timestamp " + std::to_string(t) + " goes back in time (previous " + std::to_string(last_t) + ")");
    if (x < 0 || x >= width || y < 0 || y >= height)
      s.fail("pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") lies outside the " + std::to_string(width) +
             "x" + std::to_string(height) + " sensor");
    if (p != 0 && p != 1 && p != -1) s.fail("unknown polarity code " + std::to_string(p) + " (expected 1 or 0)");
    last_t = t;
    ev.push_back(t, static_cast<int>(x), static_cast<int>(y), p == 1 ? 1 : -1);
  }
  if (ev.empty()) throw Error(file, 0, "no events in file (empty or only comments)");
  return ev;
}

inline events::EventStream read_events_txt(const fs::path& path, int width, int height) {
  const std::string text = read_file(path);
  return parse_events(text, path.string(), width, height);
}

/// Parses `t px py pz qx qy qz qw` (IJRR groundtruth.txt, TUM trajectories): camera-to-world poses.
inline geometry::Trajectory parse_poses(std::string_view text, const std::string& file) {
  std::vector<double> ts;
  std::vector<geometry::Pose> poses;
  LineScanner s(text, file);
  while (s.next_line()) {
    const double t = s.real("t");
    geometry::Pose p;
    p.t.x() = s.real("px");
    p.t.y() = s.real("py");
    p.t.z() = s.real("pz");
    const double qx = s.real("qx"), qy = s.real("qy"), qz = s.real("qz"), qw = s.real("qw");
    s.expect_end();
    const double n = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
    if (n < 0.5 || n > 1.5) s.fail("quaternion is far from unit length (norm " + std::to_string(n) + ")");
    if (!ts.empty() && !(t > ts.back())) s.fail("pose timestamps must increase strictly");
    p.q = Quat(qw / n, qx / n, qy / n, qz / n);
    ts.push_back(t);
    poses.push_back(p);
  }
  if (ts.empty()) throw Error(file, 0, "no poses in file (empty or only comments)");
  return geometry::Trajectory(std::move(ts), std::move(poses), file);
}
inline geometry::Trajectory read_poses_txt(const fs::path& path) { return parse_poses(read_file(path), path.string()); }
/// TUM RGB-D trajectory format: `t tx ty tz qx qy qz qw`, camera-to-world; the same layout as IJRR's.
inline geometry::Trajectory read_tum(const fs::path& path) { return read_poses_txt(path); }

/// Writes a trajectory in the same format, atomically.
inline void write_poses_txt(const fs::path& path, const geometry::Trajectory& tr) {
  std::string out;
  char buf[256];
  for (std::size_t i = 0; i < tr.size(); ++i) {
    const auto& p = tr.poses()[i];
    std::snprintf(buf, sizeof buf, "%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", tr.times()[i], p.t.x(), p.t.y(), p.t.z(),
                  p.q.x(), p.q.y(), p.q.z(), p.q.w());
    out += buf;
  }
  write_file_atomic(path, out);
}

/// Parses calib.txt: `fx fy cx cy [k1 k2 p1 p2 [k3]]` (4, 8 or 9 numbers on one line).
inline geometry::Camera parse_calib(std::string_view text, const std::string& file, int width, int height) {
  LineScanner s(text, file);
  if (!s.next_line()) throw Error(file, 0, "calibration file is empty");
  std::vector<double> v;
  while (!s.at_end_of_line()) v.push_back(s.real("calibration value"));
  if (v.size() != 4 && v.size() != 8 && v.size() != 9)
    s.fail("calibration needs 4, 8 or 9 numbers (fx fy cx cy [k1 k2 p1 p2 [k3]]), found " + std::to_string(v.size()));
  if (v[0] <= 0 || v[1] <= 0) s.fail("focal lengths must be positive");
  std::array<double, 5> k{0, 0, 0, 0, 0};
  for (std::size_t i = 4; i < v.size(); ++i) k[i - 4] = v[i];
  if (s.next_line()) s.fail("unexpected second line in calibration file");
  return geometry::Camera(width, height, v[0], v[1], v[2], v[3], k);
}
inline geometry::Camera read_calib_txt(const fs::path& path, int width, int height) {
  return parse_calib(read_file(path), path.string(), width, height);
}

/// Intensity frames listed in images.txt (`t relative/path.png`); evaluation only, never training.
struct Frames {
  std::vector<double> t;
  std::vector<fs::path> paths;  ///< absolute
  std::size_t size() const { return t.size(); }
};
inline Frames parse_frames(std::string_view text, const std::string& file, const fs::path& folder) {
  Frames f;
  LineScanner s(text, file);
  while (s.next_line()) {
    const double t = s.real("t");
    const std::string_view name = s.rest("image path");
    if (!f.t.empty() && t < f.t.back()) s.fail("frame timestamps go back in time");
    f.t.push_back(t);
    f.paths.push_back(folder / std::string(name));
  }
  return f;
}
inline Frames read_frames_txt(const fs::path& path) {
  return parse_frames(read_file(path), path.string(), path.parent_path());
}

}  // namespace evnerf::io
