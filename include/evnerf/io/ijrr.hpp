// io/ijrr.hpp — readers for the IJRR "Event Camera Dataset" text layout (events.txt, images.txt,
// groundtruth.txt, calib.txt), TUM pose files, and the Dataset that bundles them.
// Depends on core/, geometry/, events/ and io/ only.
#pragma once
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "../core/fileio.hpp"
#include "../core/parallel.hpp"
#include "../core/types.hpp"
#include "../core/warn.hpp"
#include "../events/event_stream.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/trajectory.hpp"
#include "text.hpp"

namespace evnerf::io {

namespace fs = std::filesystem;

namespace detail {

/// A recording cut short (a recorder that crashed or lost power) ends inside its last line: a last line
/// without its line break that does not hold the four fields is dropped, with one warning naming its line
/// and bytes. A whole last line without a line break is kept: it is an event like any other.
inline std::string_view drop_cut_last_line(std::string_view text, const std::string& file) {
  if (!text.empty() && text.back() != '\n') {
    const std::size_t nl = text.rfind('\n'), start = nl == std::string_view::npos ? 0 : nl + 1;
    LineScanner last(text.substr(start), file);
    bool cut = false;
    if (start > 0 && last.next_line()) try {
        last.real("t"), last.integer("x"), last.integer("y"), last.integer("polarity");
        last.expect_end();
      } catch (const Error&) {
        cut = true;
      }
    if (cut) {
      const auto line = 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(start), '\n'));
      warn(file + ":" + std::to_string(line) + ": the file ends inside this line (a recording cut short); read to the line before, " +
           std::to_string(text.size() - start) + " bytes dropped");
      return text.substr(0, start);
    }
  }
  return text;
}

}  // namespace detail

/// The plain reference parser for `t x y p` lines: one LineScanner field at a time. It defines what is
/// accepted and every error message; the fast path below must agree with it bit for bit. A cut last line
/// is dropped first (detail::drop_cut_last_line).
inline events::EventStream parse_events_reference(std::string_view text, const std::string& file, int width, int height) {
  text = detail::drop_cut_last_line(text, file);
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
    if (t < last_t) s.fail("timestamp " + short_number(t) + " goes back in time (previous " + short_number(last_t) + ")");
    if (x < 0 || x >= width || y < 0 || y >= height)
      s.fail("pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") lies outside the " + std::to_string(width) + "x" +
             std::to_string(height) + " sensor");
    if (p != 0 && p != 1 && p != -1) s.fail("unknown polarity code " + std::to_string(p) + " (expected 1 or 0)");
    last_t = t;
    ev.push_back(t, static_cast<int>(x), static_cast<int>(y), p == 1 ? 1 : -1);
  }
  if (ev.empty()) throw Error(file, 0, "no events in file (empty or only comments)");
  return ev;
}

namespace detail {

inline bool is_digit(char c) { return static_cast<unsigned char>(c - '0') < 10; }

/// Exact powers of ten up to 1e22 (every one is a double without rounding).
inline constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/// Parses an unsigned decimal `ddd[.ddd]` at p, ending before ' ' or '\t'. With at most 15 significant
/// digits the value is m / 10^k with both operands exact, so the one division rounds correctly and the
/// result equals std::from_chars (Clinger's fast path); longer numbers go to std::from_chars itself.
/// Returns nullptr on anything else (sign, exponent, other separators), which sends the caller to the
/// reference parser.
inline const char* fast_time(const char* p, const char* end, double& out) {
  const char* b = p;
  std::uint64_t m = 0;
  int digits = 0, frac = 0;
  bool dot = false;
  while (p < end && is_digit(*p) && digits < 19) m = m * 10 + static_cast<unsigned>(*p++ - '0'), ++digits;
  if (digits == 0) return nullptr;
  if (p < end && *p == '.') {
    ++p;
    dot = true;
    while (p < end && is_digit(*p) && digits < 19) m = m * 10 + static_cast<unsigned>(*p++ - '0'), ++digits, ++frac;
  }
  if (p < end && (*p == ' ' || *p == '\t') && digits <= 15 && (!dot || frac > 0)) {
    out = static_cast<double>(m) / kPow10[frac];
    return p;
  }
  // Long or unusual token: let from_chars decide, on exactly the bytes the reference parser would see.
  const char* e = b;
  while (e < end && *e != ' ' && *e != '\t' && *e != ',' && *e != '\n' && *e != '\r') ++e;
  if (e == end || (*e != ' ' && *e != '\t')) return nullptr;
  if (*b == '-' || *b == '+') return nullptr;
  auto [q, ec] = std::from_chars(b, e, out);
  if (ec != std::errc() || q != e || !std::isfinite(out)) return nullptr;
  return e;
}

/// Parses a small unsigned integer below `limit`, at most 5 digits; nullptr otherwise.
inline const char* fast_index(const char* p, const char* end, unsigned limit, unsigned& out) {
  unsigned v = 0;
  int n = 0;
  while (p < end && is_digit(*p) && n < 6) v = v * 10 + static_cast<unsigned>(*p++ - '0'), ++n;
  if (n == 0 || n > 5 || v >= limit) return nullptr;
  out = v;
  return p;
}

inline const char* skip_blanks(const char* p, const char* end) {
  const char* b = p;
  while (p < end && (*p == ' ' || *p == '\t')) ++p;
  return p == b ? nullptr : p;
}

/// Events from one run of whole lines [b, e) of an events.txt.
struct EventChunk {
  std::vector<double> t;
  std::vector<std::uint16_t> x, y;
  std::vector<std::int8_t> p;
  bool ok = true;
};

/// The fast path: well-formed `t x y p` lines, blank lines and '#' comments. Anything else — and every
/// error — returns false, and the caller reruns the reference parser, which then reports it exactly.
inline bool fast_parse_chunk(const char* p, const char* end, int width, int height, EventChunk& out) {
  const std::size_t guess = static_cast<std::size_t>(end - p) / 22 + 16;
  out.t.reserve(guess);
  out.x.reserve(guess);
  out.y.reserve(guess);
  out.p.reserve(guess);
  double last_t = -INFINITY;
  while (p < end) {
    if (*p == '\n') {
      ++p;
      continue;
    }
    if (*p == '#') {
      const void* nl = std::memchr(p, '\n', static_cast<std::size_t>(end - p));
      p = nl ? static_cast<const char*>(nl) + 1 : end;
      continue;
    }
    double t;
    unsigned x, y;
    if (!(p = fast_time(p, end, t)) || !(p = skip_blanks(p, end))) return false;
    if (!(p = fast_index(p, end, static_cast<unsigned>(width), x)) || !(p = skip_blanks(p, end))) return false;
    if (!(p = fast_index(p, end, static_cast<unsigned>(height), y)) || !(p = skip_blanks(p, end))) return false;
    std::int8_t pol;
    if (p < end && *p == '1') pol = 1, ++p;
    else if (p < end && *p == '0') pol = -1, ++p;
    else if (end - p >= 2 && p[0] == '-' && p[1] == '1') pol = -1, p += 2;
    else return false;
    while (p < end && (*p == ' ' || *p == '\t')) ++p;
    if (p < end && *p == '\r') ++p;
    if (p < end) {
      if (*p != '\n') return false;
      ++p;
    }
    if (t < last_t) return false;
    last_t = t;
    out.t.push_back(t);
    out.x.push_back(static_cast<std::uint16_t>(x));
    out.y.push_back(static_cast<std::uint16_t>(y));
    out.p.push_back(pol);
  }
  return true;
}

}  // namespace detail

/// Parses `t x y p` lines (t seconds, p ∈ {1, 0} or {1, -1}) into a stream for a width×height sensor.
/// Errors name file and line: truncated or extra fields, non-numeric or non-finite values, unknown
/// polarity codes, pixels outside the sensor, timestamps going backwards, an empty file.
///
/// Speed: the text is cut at line breaks into one piece per thread, and each piece goes through a
/// hand-written scanner for the common line shape. Whenever a piece holds anything the scanner does not
/// handle (including every error), the whole text goes through parse_events_reference instead, so the
/// accepted inputs, the values and the error messages are exactly the reference's.
///
/// A recording cut short loses its cut last line with one warning (detail::drop_cut_last_line), in both
/// parsers alike.
inline events::EventStream parse_events(std::string_view text, const std::string& file, int width, int height) {
  text = detail::drop_cut_last_line(text, file);
  constexpr std::size_t kMinPerThread = std::size_t{1} << 20;
  const std::size_t n = text.size();
  const int pieces = static_cast<int>(std::clamp<std::size_t>(n / kMinPerThread, 1, static_cast<std::size_t>(thread_count())));
  std::vector<std::size_t> cut(static_cast<std::size_t>(pieces) + 1, n);
  cut[0] = 0;
  for (int k = 1; k < pieces; ++k) {
    const std::size_t guess =
        std::max(cut[static_cast<std::size_t>(k) - 1], n * static_cast<std::size_t>(k) / static_cast<std::size_t>(pieces));
    const std::size_t nl = text.find('\n', guess);
    cut[static_cast<std::size_t>(k)] = nl == std::string_view::npos ? n : nl + 1;
  }
  std::vector<detail::EventChunk> chunks(static_cast<std::size_t>(pieces));
  parallel_blocks(static_cast<std::size_t>(pieces), 1, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t k = b; k < e; ++k)
      chunks[k].ok = detail::fast_parse_chunk(text.data() + cut[k], text.data() + cut[k + 1], width, height, chunks[k]);
  });
  bool ok = true;
  std::size_t total = 0;
  double last_t = -INFINITY;
  for (const auto& c : chunks) {
    ok = ok && c.ok && (c.t.empty() || c.t.front() >= last_t);
    if (!c.t.empty()) last_t = c.t.back();
    total += c.t.size();
  }
  if (!ok || total == 0) return parse_events_reference(text, file, width, height);

  events::EventStream ev;
  ev.width = width;
  ev.height = height;
  if (pieces == 1) {
    ev.t = std::move(chunks[0].t);
    ev.x = std::move(chunks[0].x);
    ev.y = std::move(chunks[0].y);
    ev.polarity = std::move(chunks[0].p);
    return ev;
  }
  ev.t.resize(total);
  ev.x.resize(total);
  ev.y.resize(total);
  ev.polarity.resize(total);
  std::vector<std::size_t> offset(chunks.size() + 1, 0);
  for (std::size_t k = 0; k < chunks.size(); ++k) offset[k + 1] = offset[k] + chunks[k].t.size();
  parallel_blocks(chunks.size(), 1, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t k = b; k < e; ++k) {
      std::copy(chunks[k].t.begin(), chunks[k].t.end(), ev.t.begin() + static_cast<std::ptrdiff_t>(offset[k]));
      std::copy(chunks[k].x.begin(), chunks[k].x.end(), ev.x.begin() + static_cast<std::ptrdiff_t>(offset[k]));
      std::copy(chunks[k].y.begin(), chunks[k].y.end(), ev.y.begin() + static_cast<std::ptrdiff_t>(offset[k]));
      std::copy(chunks[k].p.begin(), chunks[k].p.end(), ev.polarity.begin() + static_cast<std::ptrdiff_t>(offset[k]));
    }
  });
  return ev;
}

inline events::EventStream read_events_txt(const fs::path& path, int width, int height, const ReadProgress& progress = {}) {
  const std::string text = read_file(path, progress);
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
    if (n < 0.5 || n > 1.5) s.fail("quaternion is far from unit length (norm " + short_number(n) + ")");
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
    std::snprintf(buf, sizeof buf, "%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", tr.times()[i], p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(),
                  p.q.z(), p.q.w());
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

/// Intensity frames: listed in images.txt (`t relative/path.png`), or held in memory when the recording's
/// file holds them (HDF5); evaluation only, never training.
struct Frames {
  std::vector<double> t;
  std::vector<fs::path> paths;  ///< absolute; empty when the frames are in memory
  std::vector<Image> images;    ///< in memory; empty when the frames are files
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
inline Frames read_frames_txt(const fs::path& path) { return parse_frames(read_file(path), path.string(), path.parent_path()); }

}  // namespace evnerf::io
