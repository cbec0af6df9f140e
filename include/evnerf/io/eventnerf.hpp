// io/eventnerf.hpp — the published dataset layout of EventNeRF (Rudnev et al., CVPR 2023; inherited from
// NeRF++), and the .npz (zip) archives it keeps its events in.
//
//   <scene>/train/events/*.npz      one archive with arrays x, y, t, p (any numeric types; p in {-1, 1} or {0, 1})
//   <scene>/train/pose/*.txt        one camera-to-world 4×4 matrix per view (OpenCV axes), sorted by name
//   <scene>/train/intrinsics/*.txt  one 4×4 K per view, or 5×4 with a distortion row (k1 k2 . .)
//   <scene>/train/rgb/*.png         optional, one frame per view (here: evaluation only)
// The timestamp mapping is EventNeRF's own: view i of N is at time i / (N − 1) · max(t), the views spread
// evenly over the stream from t = 0 to its last event. The sensor is the frames' size, else EventNeRF's
// DAVIS346 (346×260). EventNeRF's distortion row is a division model (undistorted = distorted /
// (1 + k1 r_d² + k2 r_d⁴)); it is converted to the radial coefficients of evnerf's camera by a least-squares
// fit over the image, refused when the fit is off by more than 0.05 pixel. Only the train split is read:
// the other splits' views are not on the trajectory in time.
// Depends on core/, geometry/, events/ and io/ only (stb's inflate for compressed archives).
#pragma once
#include <stb_image.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../events/event_stream.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/trajectory.hpp"
#include "ijrr.hpp"
#include "npy.hpp"
#include "recording.hpp"

namespace evnerf::io {

inline constexpr std::uint64_t kNpzMaxMember = std::uint64_t{1} << 34;  ///< 16 GB uncompressed per array

namespace detail {
inline std::uint32_t zip_crc32(const unsigned char* p, std::size_t n) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) c = table[(c ^ p[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}
inline std::uint64_t zip_le(const std::string& b, std::size_t at, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = v << 8 | static_cast<unsigned char>(b[at + static_cast<std::size_t>(i)]);
  return v;
}
}  // namespace detail

/// The members of a .npz archive (numpy's savez or savez_compressed: a zip of .npy files, stored or
/// deflated, zip64 for large ones), by name without ".npy", each as its .npy bytes. Sizes are checked
/// against the archive before anything is allocated, and every member's CRC-32.
inline std::map<std::string, std::string> read_npz(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string b = read_file(path);
  auto fail = [&](const std::string& what) -> void { throw Error(file, 0, "cannot read .npz: " + what); };
  // The end of central directory record: the last 22 + up to 65535 comment bytes.
  std::size_t eocd = std::string::npos;
  for (std::size_t i = b.size() >= 22 ? b.size() - 22 : 0, lo = b.size() > 22 + 65535 ? b.size() - 22 - 65535 : 0; b.size() >= 22; --i) {
    if (b.compare(i, 4, "PK\x05\x06") == 0) {
      eocd = i;
      break;
    }
    if (i == lo) break;
  }
  if (eocd == std::string::npos) fail("not a zip archive (no end of central directory)");
  std::uint64_t entries = detail::zip_le(b, eocd + 10, 2), cd_size = detail::zip_le(b, eocd + 12, 4),
                cd_off = detail::zip_le(b, eocd + 16, 4);
  if (entries == 0xFFFF || cd_size == 0xFFFFFFFF || cd_off == 0xFFFFFFFF) {  // zip64: the locator just before
    if (eocd < 20 || b.compare(eocd - 20, 4, "PK\x06\x07") != 0) fail("zip64 archive without its locator");
    const std::uint64_t z = detail::zip_le(b, eocd - 20 + 8, 8);
    if (b.size() < 56 || z > b.size() - 56 || b.compare(z, 4, "PK\x06\x06") != 0) fail("zip64 end of central directory not found");
    entries = detail::zip_le(b, z + 32, 8);
    cd_size = detail::zip_le(b, z + 40, 8);
    cd_off = detail::zip_le(b, z + 48, 8);
  }
  if (cd_off > b.size() || cd_size > b.size() - cd_off || entries > cd_size / 46) fail("central directory outside the archive");
  std::map<std::string, std::string> out;
  std::size_t p = cd_off;
  for (std::uint64_t e = 0; e < entries; ++e) {
    if (p + 46 > cd_off + cd_size || b.compare(p, 4, "PK\x01\x02") != 0) fail("corrupt central directory entry " + std::to_string(e));
    const auto flags = detail::zip_le(b, p + 8, 2), method = detail::zip_le(b, p + 10, 2), crc = detail::zip_le(b, p + 16, 4);
    std::uint64_t csize = detail::zip_le(b, p + 20, 4), usize = detail::zip_le(b, p + 24, 4);
    const auto nlen = detail::zip_le(b, p + 28, 2), xlen = detail::zip_le(b, p + 30, 2), clen = detail::zip_le(b, p + 32, 2);
    std::uint64_t local = detail::zip_le(b, p + 42, 4);
    if (p + 46 + nlen + xlen + clen > cd_off + cd_size) fail("corrupt central directory entry " + std::to_string(e));
    const std::string name = b.substr(p + 46, nlen);
    for (std::size_t x = p + 46 + nlen; x + 4 <= p + 46 + nlen + xlen;) {  // zip64 extra field: the 0xFFFFFFFF sizes
      const auto id = detail::zip_le(b, x, 2), len = detail::zip_le(b, x + 2, 2);
      if (x + 4 + len > p + 46 + nlen + xlen) break;
      if (id == 1) {
        std::size_t q = x + 4;
        auto take = [&](std::uint64_t& v) {
          if (v == 0xFFFFFFFF && q + 8 <= x + 4 + len) v = detail::zip_le(b, q, 8), q += 8;
        };
        take(usize);
        take(csize);
        take(local);
      }
      x += 4 + len;
    }
    p += 46 + nlen + xlen + clen;
    const std::string member = "member '" + name.substr(0, 60) + "'";
    if (flags & 1) fail(member + " is encrypted");
    if (local > b.size() - 30 || b.compare(local, 4, "PK\x03\x04") != 0) fail(member + ": local header outside the archive");
    const std::uint64_t data = local + 30 + detail::zip_le(b, local + 26, 2) + detail::zip_le(b, local + 28, 2);
    if (data > b.size() || csize > b.size() - data) fail(member + " runs past the end of the archive (truncated?)");
    if (usize > kNpzMaxMember) fail(member + " claims " + std::to_string(usize) + " bytes uncompressed");
    std::string bytes;
    if (method == 0) {
      if (usize != csize) fail(member + " is stored with two different sizes");
      bytes = b.substr(data, csize);
    } else if (method == 8) {
      if (usize > 1032 * csize + 1024) fail(member + " claims more than deflate can expand its " + std::to_string(csize) + " bytes to");
      if (usize > 0x7FFFFFFF || csize > 0x7FFFFFFF) fail(member + " is too large for the inflater (2 GB)");
      bytes.resize(usize);
      // stb's inflater may look a few bytes past the stream's last bits: it gets zeros there, not the next member.
      std::string packed = b.substr(data, csize);
      packed.append(8, '\0');
      const int n = stbi_zlib_decode_noheader_buffer(bytes.data(), static_cast<int>(usize), packed.data(), static_cast<int>(packed.size()));
      if (n < 0 || static_cast<std::uint64_t>(n) != usize) fail(member + ": corrupt deflate data");
    } else {
      fail(member + " uses compression method " + std::to_string(method) + " (read: stored, deflate)");
    }
    if (detail::zip_crc32(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size()) != crc)
      fail(member + ": CRC-32 mismatch (corrupt)");
    std::string key = name;
    if (key.size() > 4 && key.compare(key.size() - 4, 4, ".npy") == 0) key.resize(key.size() - 4);
    out[key] = std::move(bytes);
  }
  return out;
}

namespace detail {
/// Files of a folder with the given extension, sorted by name.
inline std::vector<std::filesystem::path> sorted_files(const std::filesystem::path& dir, const std::string& ext) {
  std::vector<std::filesystem::path> v;
  if (!std::filesystem::is_directory(dir)) return v;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ext) v.push_back(e.path());
  std::sort(v.begin(), v.end());
  return v;
}
/// All the numbers of a small text file, at most `max` of them.
inline std::vector<double> numbers_of(const std::filesystem::path& p, std::size_t max) {
  const std::string text = read_file(p);
  LineScanner s(text, p.string());
  std::vector<double> v;
  while (s.next_line())
    while (!s.at_end_of_line()) {
      if (v.size() == max) s.fail("more than " + std::to_string(max) + " numbers");
      v.push_back(s.real("matrix entry"));
    }
  return v;
}
}  // namespace detail

/// Whether `folder` is an EventNeRF scene (train/events/) or one split of it (events/ with pose/).
inline bool is_eventnerf(const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  return fs::is_directory(folder / "train" / "events") || (fs::is_directory(folder / "events") && fs::is_directory(folder / "pose"));
}

/// The radial coefficients (k1 k2 . . k3) of evnerf's camera closest to EventNeRF's division model
/// (a, b) over radii up to r_max (normalised); the worst error, in pixels at focal length f, goes to `err_px`.
inline std::array<double, 5> radial_from_division(double a, double b, double r_max, double f, double& err_px) {
  err_px = 0;
  if (a == 0 && b == 0) return {0, 0, 0, 0, 0};
  Eigen::MatrixXd A(400, 3);
  Eigen::VectorXd y(400), ru(400), rd(400);
  for (int i = 0; i < 400; ++i) {
    const double r = r_max * (i + 1) / 400.0, D = 1 + a * r * r + b * r * r * r * r;
    if (!(D > 0.05)) throw Error("EventNeRF distortion (k1 " + short_number(a) + ", k2 " + short_number(b) + ") folds the image over");
    const double u = r / D;
    A.row(i) << u * u, u * u * u * u, u * u * u * u * u * u;
    y(i) = D - 1;
    ru(i) = u;
    rd(i) = r;
  }
  const Eigen::Vector3d k = A.colPivHouseholderQr().solve(y);
  for (int i = 0; i < 400; ++i) {
    const double u2 = ru(i) * ru(i);
    err_px = std::max(err_px, f * std::abs(ru(i) * (1 + k(0) * u2 + k(1) * u2 * u2 + k(2) * u2 * u2 * u2) - rd(i)));
  }
  return {k(0), k(1), 0, 0, k(2)};
}

/// What an EventNeRF scene holds, in evnerf's terms.
struct EventNerfScene {
  events::EventStream events;
  geometry::Camera camera;
  geometry::Trajectory trajectory;
  std::vector<double> frame_times;
  std::vector<std::filesystem::path> frames;  ///< rgb/*.png, one per view (empty when absent)
};

/// Reads an EventNeRF scene folder (its train split) or a split folder; see the file's comment.
inline EventNerfScene read_eventnerf(const std::filesystem::path& folder, int width = 0, int height = 0) {
  namespace fs = std::filesystem;
  const fs::path split = fs::is_directory(folder / "train" / "events") ? folder / "train" : folder;
  const auto npz = detail::sorted_files(split / "events", ".npz");
  if (npz.size() != 1)
    throw Error((split / "events").string(), 0, "expected one .npz archive of events, found " + std::to_string(npz.size()));
  const auto poses = detail::sorted_files(split / "pose", ".txt");
  const auto intr = detail::sorted_files(split / "intrinsics", ".txt");
  if (poses.size() < 2)
    throw Error((split / "pose").string(), 0, "expected a 4x4 pose file per view, found " + std::to_string(poses.size()));
  if (intr.empty()) throw Error((split / "intrinsics").string(), 0, "no intrinsics files (a 4x4 or 5x4 matrix per view)");
  if (intr.size() != 1 && intr.size() != poses.size())
    throw Error((split / "intrinsics").string(), 0,
                std::to_string(intr.size()) + " intrinsics files for " + std::to_string(poses.size()) + " poses");
  EventNerfScene s;
  s.frames = detail::sorted_files(split / "rgb", ".png");
  if (!s.frames.empty() && s.frames.size() != poses.size())
    throw Error((split / "rgb").string(), 0, std::to_string(s.frames.size()) + " frames for " + std::to_string(poses.size()) + " poses");

  int w = width, h = height;
  if (w <= 0 || h <= 0) {
    w = 346, h = 260;  // EventNeRF's DAVIS346
    int c = 0;
    if (!s.frames.empty() && !stbi_info(s.frames[0].c_str(), &w, &h, &c))
      throw Error(s.frames[0].string(), 0, "cannot read the frame's size (not a PNG?)");
  }

  // Intrinsics: the first view's (EventNeRF's views share one camera); the others must agree.
  const auto K = detail::numbers_of(intr[0], 20);
  if (K.size() != 16 && K.size() != 20)
    throw Error(intr[0].string(), 0, "expected a 4x4 or 5x4 matrix, found " + std::to_string(K.size()) + " numbers");
  for (std::size_t i = 1; i < intr.size(); ++i)
    if (detail::numbers_of(intr[i], 20) != K)
      throw Error(intr[i].string(), 0, "differs from " + intr[0].filename().string() + " (one camera is read)");
  const double fx = K[0], fy = K[5], cx = K[2], cy = K[6];
  if (!(fx > 0) || !(fy > 0) || !std::isfinite(cx) || !std::isfinite(cy))
    throw Error(intr[0].string(), 0, "focal lengths must be positive and the centre finite");
  std::array<double, 5> dist{0, 0, 0, 0, 0};
  if (K.size() == 20) {
    const double r_max = std::hypot(std::max(cx, w - cx) / fx, std::max(cy, h - cy) / fy);
    double err = 0;
    dist = radial_from_division(K[16], K[17], r_max, std::max(fx, fy), err);
    if (err > 0.05)
      throw Error(intr[0].string(), 0,
                  "its division-model distortion (k1 " + short_number(K[16]) + ", k2 " + short_number(K[17]) +
                      ") has no radial equivalent within 0.05 px (" + short_number(err, 3) + " px); give --calib");
  }
  s.camera = geometry::Camera(w, h, fx, fy, cx, cy, dist);

  // Events.
  const auto members = read_npz(npz[0]);
  auto array = [&](const char* key) {
    const auto it = members.find(key);
    if (it == members.end()) throw Error(npz[0].string(), 0, std::string("no array '") + key + "' (expected x, y, t, p)");
    auto a = parse_npy_numeric(it->second, npz[0].string() + " (array '" + key + "')");
    if (a.shape.size() != 1) throw Error(npz[0].string(), 0, std::string("array '") + key + "' is not one-dimensional");
    return a;
  };
  const auto x = array("x"), y = array("y"), t = array("t"), p = array("p");
  const std::size_t n = x.data.size();
  if (y.data.size() != n || t.data.size() != n || p.data.size() != n)
    throw Error(npz[0].string(), 0,
                "arrays x, y, t, p differ in length (" + std::to_string(n) + ", " + std::to_string(y.data.size()) + ", " +
                    std::to_string(t.data.size()) + ", " + std::to_string(p.data.size()) + ")");
  if (n == 0) throw Error(npz[0].string(), 0, "no events");
  s.events.width = w;
  s.events.height = h;
  s.events.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double xi = x.data[i], yi = y.data[i], ti = t.data[i], pi = p.data[i];
    const std::string ev = "event " + std::to_string(i);
    if (!(xi >= 0 && yi >= 0 && xi < w && yi < h) || xi != std::floor(xi) || yi != std::floor(yi))
      throw Error(npz[0].string(), 0,
                  ev + ": pixel (" + short_number(xi) + ", " + short_number(yi) + ") is not a pixel of the " + std::to_string(w) + "x" +
                      std::to_string(h) + " sensor");
    if (!std::isfinite(ti)) throw Error(npz[0].string(), 0, ev + ": time is not finite");
    if (i > 0 && ti < s.events.t.back())
      throw Error(npz[0].string(), 0, ev + ": time " + short_number(ti) + " goes back (previous " + short_number(s.events.t.back()) + ")");
    if (pi != 1 && pi != 0 && pi != -1) throw Error(npz[0].string(), 0, ev + ": polarity " + short_number(pi) + " (expected -1/1 or 0/1)");
    s.events.push_back(ti, static_cast<int>(xi), static_cast<int>(yi), pi > 0 ? 1 : -1);
  }

  // Poses, at EventNeRF's times i / (N − 1) · max(t).
  const double t_max = s.events.t.back();
  if (!(t_max > 0)) throw Error(npz[0].string(), 0, "the last event's time must be positive (views are spread over 0 .. max t)");
  std::vector<double> times;
  std::vector<geometry::Pose> ps;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto m = detail::numbers_of(poses[i], 16);
    if (m.size() != 16)
      throw Error(poses[i].string(), 0, "expected a 4x4 camera-to-world matrix, found " + std::to_string(m.size()) + " numbers");
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) M(r, c) = m[static_cast<std::size_t>(4 * r + c)];
    const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
    if (!M.allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 || R.determinant() < 0)
      throw Error(poses[i].string(), 0, "the upper-left 3x3 is not a rotation");
    ps.push_back(geometry::Pose::from_matrix(M));
    times.push_back(t_max * static_cast<double>(i) / static_cast<double>(poses.size() - 1));
  }
  s.trajectory = geometry::Trajectory(times, std::move(ps), (split / "pose").string());
  if (!s.frames.empty()) s.frame_times = times;
  return s;
}

/// Loads an EventNeRF scene (io/eventnerf.hpp: its train split, views spread evenly over the events' time),
/// with the calibration and poses LoadOptions names instead of the scene's own where given.
inline Dataset load_eventnerf(const std::filesystem::path& folder, const LoadOptions& opt = {}) {
  auto s = read_eventnerf(folder, opt.width, opt.height);
  check_sensor_size(s.camera.width(), s.camera.height(),
                    opt.width > 0 && opt.height > 0 ? folder.string() + " (the sensor size given)"
                    : s.frames.empty()              ? folder.string() + " (EventNeRF's DAVIS346 size)"
                                                    : s.frames[0].string() + " (the first frame, which gives the sensor size)");
  Dataset d;
  d.folder = folder;
  d.camera = opt.calib.empty() ? s.camera : read_calib_source(opt.calib, s.camera.width(), s.camera.height());
  d.events = std::move(s.events);
  d.frames.t = std::move(s.frame_times);
  d.frames.paths = std::move(s.frames);
  d.trajectory = opt.poses.empty() ? std::move(s.trajectory) : read_pose_source(opt.poses, d.frames);
  return d;
}

/// The format's line in io::formats().
inline Format eventnerf_format() {
  return {"eventnerf", true, "an EventNeRF scene folder (train/events/*.npz, train/pose, train/intrinsics)", &is_eventnerf,
          &load_eventnerf};
}

}  // namespace evnerf::io
