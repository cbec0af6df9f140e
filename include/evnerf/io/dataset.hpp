// io/dataset.hpp — one recording (camera, events, poses, optional frames and depth) loaded from an IJRR-
// layout folder, as written by the real dataset and by evnerf's simulator. Depends on core/, geometry/,
// events/ and io/ only.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <stb_image.h>

#include "../geometry/bayer.hpp"
#include "colmap.hpp"
#include "eventnerf.hpp"
#include "robust_e_nerf.hpp"
#include "ijrr.hpp"
#include "image_io.hpp"
#include "npy.hpp"
#ifdef EVNERF_HAVE_HDF5
#include "hdf5.hpp"
#endif
#ifdef EVNERF_HAVE_ROSBAG
#include "rosbag.hpp"
#endif

namespace evnerf::io {

struct LoadOptions {
  int width = 0, height = 0;  ///< sensor size; 0 = from sensor.txt, else the first frame, else 240×180
  bool use_cache = true;      ///< cache the parsed events.txt as .npy for the next load
  std::filesystem::path cache_root = default_cache_root();
  /// Calibration and poses in the IJRR text formats, used instead of the recording's own. Empty: the
  /// recording's (an IJRR folder's files; a bag's camera info and pose topic), else, for a recording in
  /// one file (HDF5, bag), calib.txt (required) and groundtruth.txt (optional) in its folder.
  std::filesystem::path calib, poses;
  /// ROS bags: the topics to read (empty: the one topic of each role; "none": skip frames, camera info or
  /// poses). See io/rosbag.hpp.
  std::string events_topic, images_topic, camera_info_topic, poses_topic;
  /// Read an HDF5 file in a child process first, so that a crash of the HDF5 library on a corrupt file is
  /// an Error (io::read_hdf5_checked; costs a second read of the file).
  bool hdf5_check_in_child = true;
  /// Only the events with t_begin ≤ t < t_end (seconds, on the loaded clock: a bag's relative to its
  /// time_origin). Every reader drops the others after reading; the HDF5 reader of the DSEC layout reads
  /// only the window's events, found through ms_to_idx.
  double t_begin = -INFINITY, t_end = INFINITY;
  /// The reader, where the content does not decide it (a folder holding two layouts): "ijrr", "eventnerf",
  /// "robust-e-nerf", "hdf5", "rosbag"; empty = from the content.
  std::string format;
};

/// The names LoadOptions::format takes.
inline const std::vector<std::string>& load_formats() {
  static const std::vector<std::string> f{"ijrr", "eventnerf", "robust-e-nerf", "hdf5", "rosbag"};
  return f;
}

struct Dataset {
  std::filesystem::path folder;
  geometry::Camera camera;
  events::EventStream events;
  geometry::Trajectory trajectory;  ///< empty when the folder has no groundtruth.txt
  Frames frames;                    ///< empty when the folder has no images.txt
  std::vector<std::filesystem::path> depth;  ///< per-frame ground-truth depth (.npy), simulator only
  std::vector<std::filesystem::path> linear; ///< per-frame linear radiance (.npy, unclipped): HDR truth, simulator only
  double linear_log_offset = 0;              ///< the sensor's dark end, log(I + offset), with `linear`
  /// The recording's own clock at t = 0, in seconds: 0 for IJRR folders and HDF5 files (their times are
  /// kept); a bag's times are relative to the whole second of its first message read (ROS time).
  std::int64_t time_origin = 0;
  /// The colour filter the events come through ("rggb", ...), where the recording says; "" otherwise.
  std::string bayer_pattern;
  /// Per pixel of the camera, 1 where the events come from (channel_dataset's green at the full sensor: the
  /// green sites of the mosaic); empty: every pixel. Training draws its pixels among these only.
  std::vector<std::uint8_t> sites;
  bool from_cache = false;
};

/// The colour filter of a recording's events: the one it names, else RGGB (the Color-DAVIS346's, and the
/// simulator's with --bayer); a name no pattern has is an error naming the recording.
inline geometry::BayerPattern bayer_of(const Dataset& d) {
  geometry::BayerPattern p;
  if (!d.bayer_pattern.empty() && !geometry::BayerPattern::parse(d.bayer_pattern, p))
    throw Error(d.folder.string() + ": unknown Bayer pattern '" + d.bayer_pattern + "' (known: rggb, bggr, grbg, gbrg)");
  return p;
}

/// Which of green's two sites per 2×2 block a per-channel green model trains on.
enum class GreenSites {
  First,  ///< the first one only: a quarter-resolution sensor like red's and blue's (the paper's geometry)
  Both    ///< both: the full sensor, trained at the green sites only (Dataset::sites); twice the events
};
inline GreenSites parse_green_sites(const std::string& s) {
  if (s == "first") return GreenSites::First;
  if (s == "both") return GreenSites::Both;
  throw Error("green sites '" + s + "': expected first or both");
}
inline const char* green_sites_name(GreenSites g) { return g == GreenSites::Both ? "both" : "first"; }

/// The paper's colour geometry: the events of one channel's sites (geometry::site_of) as a grey recording
/// of a quarter-resolution sensor (geometry::site_camera), event (2x'+ox, 2y'+oy) at (x', y'). With
/// GreenSites::Both, green instead keeps the full sensor and the events of both its sites, and
/// Dataset::sites marks them. Poses and frames stay the recording's (the frames' times still cut the
/// slices; they are not at the new sensor's size, so evaluate against the full recording); depth and linear
/// truth are dropped.
inline Dataset channel_dataset(const Dataset& d, const geometry::BayerPattern& p, int channel, GreenSites green = GreenSites::First) {
  Dataset c;
  c.folder = d.folder;
  c.trajectory = d.trajectory;
  c.frames = d.frames;
  c.time_origin = d.time_origin;
  if (channel == 1 && green == GreenSites::Both) {
    c.camera = d.camera;
    c.events.width = d.events.width;
    c.events.height = d.events.height;
    const int W = d.camera.width(), H = d.camera.height();
    c.sites.assign(static_cast<std::size_t>(W) * H, 0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) c.sites[static_cast<std::size_t>(y) * W + x] = p.at(x, y) == 1 ? 1 : 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < d.events.size(); ++i) n += p.at(d.events.x[i], d.events.y[i]) == 1;
    c.events.reserve(n);
    for (std::size_t i = 0; i < d.events.size(); ++i)
      if (p.at(d.events.x[i], d.events.y[i]) == 1) c.events.push_back(d.events.t[i], d.events.x[i], d.events.y[i], d.events.polarity[i]);
    return c;
  }
  const auto s = geometry::site_of(p, channel);
  c.camera = geometry::site_camera(d.camera, s);
  c.events.width = c.camera.width();
  c.events.height = c.camera.height();
  std::size_t n = 0;
  for (std::size_t i = 0; i < d.events.size(); ++i) n += (d.events.x[i] & 1) == s.ox && (d.events.y[i] & 1) == s.oy;
  c.events.reserve(n);
  for (std::size_t i = 0; i < d.events.size(); ++i)
    if ((d.events.x[i] & 1) == s.ox && (d.events.y[i] & 1) == s.oy)
      c.events.push_back(d.events.t[i], d.events.x[i] / 2, d.events.y[i] / 2, d.events.polarity[i]);
  return c;
}

/// The most pixels a sensor may have (8192 × 8192): per-pixel counts per slice are allocated from it.
inline constexpr long long kMaxSensorPixels = 1LL << 26;

/// Refuses a sensor of more than kMaxSensorPixels pixels or a side outside 1 … 65535 (before anything is
/// allocated per pixel); `where` names what announced the size.
inline void check_sensor_size(long long w, long long h, const std::string& where, std::size_t line = 0) {
  if (w <= 0 || h <= 0 || w > 65535 || h > 65535)
    throw Error(where, line, "sensor size " + std::to_string(w) + "x" + std::to_string(h) + " out of range (1 to 65535 per side)");
  if (w * h > kMaxSensorPixels)
    throw Error(where, line, "sensor size " + std::to_string(w) + "x" + std::to_string(h) + " has more than " +
                                 std::to_string(kMaxSensorPixels) + " pixels (refused before allocating per-pixel counts)");
}

/// The poses a user names (LoadOptions::poses): a pose text file (`t px py pz qx qy qz qw`, camera to world;
/// its times moved by `shift` seconds), or a COLMAP text model (its folder, or its images.txt). COLMAP's
/// images have no times: each gets the time of the recording's frame whose file name (or path ending) is
/// the image's NAME, so COLMAP run on the recording's frames gives a trajectory through the frames' times.
/// Images that match no frame are left out (and counted in the error when none match).
inline geometry::Trajectory read_pose_source(const std::filesystem::path& p, const Frames& frames, double shift = 0) {
  namespace fs = std::filesystem;
  const bool colmap = fs::is_directory(p) || p.filename() == "images.txt";
  if (!colmap) {
    const auto tr = read_poses_txt(p);
    if (shift == 0) return tr;
    std::vector<double> t = tr.times();
    for (double& v : t) v -= shift;
    return geometry::Trajectory(std::move(t), tr.poses(), p.string());
  }
  const fs::path images = fs::is_directory(p) ? p / "images.txt" : p;
  if (!fs::exists(images)) throw Error(images.string(), 0, "missing (a COLMAP text model's images.txt)");
  const auto ims = parse_colmap_images(read_file(images), images.string());
  if (frames.paths.empty())
    throw Error(images.string(), 0, "COLMAP poses are matched to the recording's frame files by name, and this recording has no frame files");
  std::vector<std::pair<double, geometry::Pose>> timed;
  for (const auto& im : ims) {
    int found = -1;
    for (std::size_t f = 0; f < frames.paths.size(); ++f) {
      const std::string path = frames.paths[f].generic_string();
      const bool match = path == im.name || (path.size() > im.name.size() && path.compare(path.size() - im.name.size(), im.name.size(), im.name) == 0 &&
                                             path[path.size() - im.name.size() - 1] == '/');
      if (!match) continue;
      if (found >= 0) throw Error(images.string(), 0, "image '" + im.name.substr(0, 60) + "' matches two frames");
      found = static_cast<int>(f);
    }
    if (found >= 0) timed.emplace_back(frames.t[static_cast<std::size_t>(found)], im.c2w);
  }
  if (timed.size() < 2)
    throw Error(images.string(), 0, std::to_string(timed.size()) + " of its " + std::to_string(ims.size()) +
                                        " images match a frame of the recording by file name (at least 2 needed)");
  std::vector<std::size_t> order(timed.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return timed[a].first < timed[b].first; });
  std::vector<double> t;
  std::vector<geometry::Pose> poses;
  for (auto i : order) {
    if (!t.empty() && timed[i].first == t.back()) throw Error(images.string(), 0, "two images map to frames of the same time");
    t.push_back(timed[i].first);
    poses.push_back(timed[i].second);
  }
  return geometry::Trajectory(std::move(t), std::move(poses), images.string() + " (COLMAP, at the frames' times)");
}

/// The calibration a user names (LoadOptions::calib): calib.txt's format, or COLMAP's cameras.txt (one
/// camera, of the sensor's size).
inline geometry::Camera read_calib_source(const std::filesystem::path& p, int w, int h) {
  if (p.filename() != "cameras.txt") return read_calib_txt(p, w, h);
  const auto cams = parse_colmap_cameras(read_file(p), p.string());
  if (cams.size() != 1) throw Error(p.string(), 0, "holds " + std::to_string(cams.size()) + " cameras; one is read");
  const auto& c = cams.begin()->second;
  if (c.width() != w || c.height() != h)
    throw Error(p.string(), 0, "camera of " + std::to_string(c.width()) + "x" + std::to_string(c.height()) + " for a " + std::to_string(w) + "x" +
                                   std::to_string(h) + " sensor");
  return c;
}

/// Parses sensor.txt: "width height".
inline std::pair<int, int> parse_sensor_size(std::string_view text, const std::string& file) {
  LineScanner s(text, file);
  if (!s.next_line()) throw Error(file, 0, "empty sensor.txt (expected 'width height')");
  const long long sw = s.integer("width"), sh = s.integer("height");
  s.expect_end();
  check_sensor_size(sw, sh, file, s.line_number());
  if (s.next_line()) s.fail("unexpected second line in sensor.txt");
  return {static_cast<int>(sw), static_cast<int>(sh)};
}

/// Sensor size: explicit, else `sensor.txt` ("width height"), else the first frame's size, else DAVIS240C.
inline std::pair<int, int> sensor_size(const std::filesystem::path& folder, const Frames& frames, int w, int h) {
  if (w > 0 && h > 0) {
    check_sensor_size(w, h, folder.string() + " (the sensor size given)");
    return {w, h};
  }
  if (std::filesystem::exists(folder / "sensor.txt")) {
    const auto path = folder / "sensor.txt";
    const std::string text = read_file(path);
    return parse_sensor_size(text, path.string());
  }
  if (frames.size() > 0) {
    int fw = 0, fh = 0, c = 0;
    if (stbi_info(frames.paths[0].c_str(), &fw, &fh, &c)) {
      check_sensor_size(fw, fh, frames.paths[0].string() + " (the first frame, which gives the sensor size)");
      return {fw, fh};
    }
  }
  return {240, 180};
}

/// Loads an IJRR-layout folder. events.txt and calib.txt are required; groundtruth.txt, images.txt and
/// depth/ are optional. Every parse error names file and line.
inline Dataset load_ijrr(const std::filesystem::path& folder, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(folder)) throw Error(folder.string(), 0, "not a folder (missing recording?)");
  Dataset d;
  d.folder = folder;
  if (fs::exists(folder / "images.txt")) d.frames = read_frames_txt(folder / "images.txt");
  const auto [w, h] = sensor_size(folder, d.frames, opt.width, opt.height);
  d.camera = opt.calib.empty() ? read_calib_txt(folder / "calib.txt", w, h) : read_calib_source(opt.calib, w, h);
  const fs::path ev_path = folder / "events.txt";
  if (!fs::exists(ev_path)) throw Error(ev_path.string(), 0, "missing events file");
  bool loaded = false;
  fs::path cache_dir;
  std::string stamp;
  if (opt.use_cache) {
    const auto abs = fs::absolute(ev_path).lexically_normal().string();
    const auto size = fs::file_size(ev_path);
    const auto mtime = fs::last_write_time(ev_path).time_since_epoch().count();
    stamp = std::to_string(size) + "-" + std::to_string(mtime) + "-" + std::to_string(w) + "x" + std::to_string(h);
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a64(abs)));
    cache_dir = opt.cache_root / hex;
    try {
      loaded = load_event_cache(cache_dir, stamp, d.events);
    } catch (const Error&) {
      loaded = false;  // a damaged cache is rebuilt from the source, never trusted
    }
  }
  if (!loaded) {
    d.events = read_events_txt(ev_path, w, h);
    if (opt.use_cache) {
      try {
        save_event_cache(cache_dir, d.events, stamp);
      } catch (const std::exception&) {
        // An unwritable cache only costs speed next time.
      }
    }
  }
  d.from_cache = loaded;
  if (!opt.poses.empty())
    d.trajectory = read_pose_source(opt.poses, d.frames);
  else if (fs::exists(folder / "groundtruth.txt"))
    d.trajectory = read_poses_txt(folder / "groundtruth.txt");
  if (fs::is_directory(folder / "depth"))
    for (std::size_t i = 0; i < d.frames.size(); ++i) {
      char name[64];
      std::snprintf(name, sizeof name, "depth/frame_%08zu.npy", i);
      if (fs::exists(folder / name)) d.depth.push_back(folder / name);
    }
  if (fs::is_directory(folder / "linear")) {
    for (std::size_t i = 0; i < d.frames.size(); ++i) {
      char name[64];
      std::snprintf(name, sizeof name, "linear/frame_%08zu.npy", i);
      if (fs::exists(folder / name)) d.linear.push_back(folder / name);
    }
    if (d.linear.size() != d.frames.size())
      throw Error((folder / "linear").string(), 0,
                  "has " + std::to_string(d.linear.size()) + " of the " + std::to_string(d.frames.size()) + " frames' linear truth");
    const auto off = folder / "linear" / "log_offset.txt";
    if (!fs::exists(off)) throw Error(off.string(), 0, "missing (the sensor's log offset, written with the linear truth)");
    const std::string text = read_file(off);  // the scanner views it: it must outlive the scanner
    LineScanner sc(text, off.string());
    if (!sc.next_line()) sc.fail("empty: expected the sensor's log offset");
    d.linear_log_offset = sc.real("log offset");
    if (!(d.linear_log_offset > 0) || !std::isfinite(d.linear_log_offset)) sc.fail("the log offset must be positive and finite");
  }
  return d;
}

/// Frame i of a recording, from memory or from its PNG file.
inline Image frame_image(const Frames& f, std::size_t i) {
  require(i < f.size(), "frame_image: frame " + std::to_string(i) + " of " + std::to_string(f.size()));
  return f.images.empty() ? read_png(f.paths[i]) : f.images[i];
}

/// The calibration as calib.txt holds it (fx fy cx cy k1 k2 p1 p2 k3).
inline std::string calib_text(const geometry::Camera& c) {
  const auto& k = c.distortion();
  char buf[320];
  std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", c.fx(), c.fy(), c.cx(), c.cy(), k[0], k[1],
                k[2], k[3], k[4]);
  return buf;
}

/// Writes a recording as an IJRR-layout folder: events.txt (9 decimals of seconds), calib.txt, sensor.txt,
/// groundtruth.txt when there are poses, images.txt and images/frame_*.png when there are frames. Every
/// file is written atomically.
inline void write_ijrr(const std::filesystem::path& dir, const Dataset& d) {
  namespace fs = std::filesystem;
  std::string ev;
  ev.reserve(d.events.size() * 24);
  char buf[160];
  for (std::size_t i = 0; i < d.events.size(); ++i) {
    const int k = std::snprintf(buf, sizeof buf, "%.9f %d %d %d\n", d.events.t[i], d.events.x[i], d.events.y[i], d.events.polarity[i] > 0 ? 1 : 0);
    ev.append(buf, static_cast<std::size_t>(k));
  }
  write_file_atomic(dir / "events.txt", ev);
  write_file_atomic(dir / "calib.txt", calib_text(d.camera));
  write_file_atomic(dir / "sensor.txt", std::to_string(d.camera.width()) + " " + std::to_string(d.camera.height()) + "\n");
  if (!d.trajectory.empty()) write_poses_txt(dir / "groundtruth.txt", d.trajectory);
  if (d.frames.size() > 0) {
    std::string list;
    for (std::size_t f = 0; f < d.frames.size(); ++f) {
      char name[64];
      std::snprintf(name, sizeof name, "images/frame_%08zu.png", f);
      write_png(dir / name, frame_image(d.frames, f));
      std::snprintf(buf, sizeof buf, "%.9f %s\n", d.frames.t[f], name);
      list += buf;
    }
    write_file_atomic(dir / "images.txt", list);
  }
}

#ifdef EVNERF_HAVE_HDF5
/// Loads an event HDF5 file (io/hdf5.hpp: event_utils/HQF or DSEC layout) with the calibration and poses
/// LoadOptions names, or calib.txt and groundtruth.txt beside it. Frames, when the file has them, are
/// kept in memory.
inline Dataset load_hdf5(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  auto rec = opt.hdf5_check_in_child ? read_hdf5_checked(path, opt.width, opt.height, opt.t_begin, opt.t_end)
                                     : read_hdf5(path, opt.width, opt.height, opt.t_begin, opt.t_end);
  check_sensor_size(rec.width, rec.height, path.string() + " (the sensor size it gives)");
  Dataset d;
  d.folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  const fs::path calib = opt.calib.empty() ? d.folder / "calib.txt" : opt.calib;
  if (!fs::exists(calib))
    throw Error(calib.string(), 0, "missing: an HDF5 recording takes its calibration from calib.txt beside it (fx fy cx cy [k1 k2 p1 p2 [k3]])");
  d.camera = read_calib_source(calib, rec.width, rec.height);
  d.events = std::move(rec.events);
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  if (!opt.poses.empty())
    d.trajectory = read_pose_source(opt.poses, d.frames);
  else if (fs::exists(d.folder / "groundtruth.txt"))
    d.trajectory = read_poses_txt(d.folder / "groundtruth.txt");
  return d;
}
#endif

#ifdef EVNERF_HAVE_HDF5
/// Writes a recording as an event_utils/HQF HDF5 file (write_hdf5) with calib.txt and, when there are
/// poses, groundtruth.txt beside it, so that io::load reads it back.
inline void write_hdf5_recording(const std::filesystem::path& path, const Dataset& d) {
  std::vector<double> times = d.frames.t;
  std::vector<Image> frames;
  for (std::size_t f = 0; f < d.frames.size(); ++f) frames.push_back(frame_image(d.frames, f));
  write_hdf5(path, d.events, d.camera.width(), d.camera.height(), times, frames);
  const auto dir = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  write_file_atomic(dir / "calib.txt", calib_text(d.camera));
  if (!d.trajectory.empty()) write_poses_txt(dir / "groundtruth.txt", d.trajectory);
}
#endif

#ifdef EVNERF_HAVE_ROSBAG
/// Loads a ROS bag (io/rosbag.hpp). The sensor size is the one given, else the camera info's, else the
/// event messages' own, else the first frame's, else the events' extent. Calibration: LoadOptions::calib,
/// else the camera info, else calib.txt beside the bag. Poses: LoadOptions::poses, else the pose topic,
/// else groundtruth.txt beside the bag (when present); a pose file's times are read in the bag's clock
/// (ROS time, seconds) and moved to the recording's origin like the bag's own.
inline Dataset load_rosbag(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  auto rec = read_rosbag(path, BagOptions{opt.events_topic, opt.images_topic, opt.camera_info_topic, opt.poses_topic});
  const std::string file = path.string();
  int w = opt.width, h = opt.height;
  std::string from = "the size given";
  if (w <= 0 || h <= 0) {
    if (rec.has_camera_info && rec.info_width > 0 && rec.info_height > 0)
      w = rec.info_width, h = rec.info_height, from = "the camera info on " + rec.camera_info_topic;
    else if (rec.array_width > 0 && rec.array_height > 0)
      w = rec.array_width, h = rec.array_height, from = "the event messages on " + rec.events_topic;
    else if (!rec.frames.empty())
      w = rec.frames[0].width, h = rec.frames[0].height, from = "the first frame on " + rec.images_topic;
    else
      w = static_cast<int>(rec.max_x + 1), h = static_cast<int>(rec.max_y + 1), from = "the events' extent";
  }
  check_sensor_size(w, h, file + " (" + from + ")");
  if (rec.max_x >= w || rec.max_y >= h) {
    for (std::size_t i = 0; i < rec.events.size(); ++i)
      if (rec.events.x[i] >= w || rec.events.y[i] >= h)
        throw Error(file, 0, "event " + std::to_string(i) + " of topic " + rec.events_topic + ": pixel (" + std::to_string(rec.events.x[i]) +
                                 ", " + std::to_string(rec.events.y[i]) + ") lies outside the " + std::to_string(w) + "x" + std::to_string(h) +
                                 " sensor (" + from + ")");
  }
  Dataset d;
  d.folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  d.time_origin = rec.origin_sec;
  // Frames in a Bayer encoding come through the colour filter the events do (CED's Color-DAVIS346).
  if (rec.frame_encoding.rfind("bayer_", 0) == 0) d.bayer_pattern = rec.frame_encoding.substr(6, 4);
  if (!opt.calib.empty()) {
    d.camera = read_calib_source(opt.calib, w, h);
  } else if (rec.has_camera_info) {
    d.camera = geometry::Camera(w, h, rec.fx, rec.fy, rec.cx, rec.cy, rec.distortion);
  } else {
    const fs::path calib = d.folder / "calib.txt";
    if (!fs::exists(calib))
      throw Error(file, 0, "no camera info topic and no " + calib.string() + " beside the bag: give the calibration (fx fy cx cy [k1 k2 p1 p2 [k3]])");
    d.camera = read_calib_txt(calib, w, h);
  }
  d.frames.t = rec.frame_times;
  if (!opt.poses.empty()) {
    d.trajectory = read_pose_source(opt.poses, d.frames, static_cast<double>(rec.origin_sec));
  } else if (!rec.poses.empty()) {
    d.trajectory = geometry::Trajectory(std::move(rec.pose_times), std::move(rec.poses), file + " (topic " + rec.poses_topic + ")");
  } else if (fs::exists(d.folder / "groundtruth.txt")) {
    d.trajectory = read_pose_source(d.folder / "groundtruth.txt", d.frames, static_cast<double>(rec.origin_sec));
  }
  rec.events.width = w;
  rec.events.height = h;
  d.events = std::move(rec.events);
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  return d;
}
#endif

#ifdef EVNERF_HAVE_ROSBAG
/// Writes a recording as a ROS bag (io::write_rosbag: DAVIS topics, `compression` chunks), stamped at the
/// recording's time origin, so that io::load reads it back.
inline void write_rosbag_recording(const std::filesystem::path& path, const Dataset& d, const std::string& compression = "lz4") {
  std::vector<Image> frames;
  for (std::size_t f = 0; f < d.frames.size(); ++f) frames.push_back(frame_image(d.frames, f));
  BagWriteOptions o;
  o.compression = compression;
  o.origin_sec = d.time_origin;
  write_rosbag(path, d.events, d.camera, d.trajectory, d.frames.t, frames, o);
}
#endif

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

/// Loads a recording whatever its format (all its events; io::load applies LoadOptions' time window): an IJRR-layout folder, an EventNeRF scene folder, a Robust e-NeRF
/// sequence folder, an event HDF5 file or a ROS bag (where built with HDF5, libbz2 and liblz4). The reader is picked from the content, not the name.
/// A folder that holds more than one layout is refused unless `opt.format` names the one to read.
inline Dataset load_whole(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  const std::string& f = opt.format;
  if (!f.empty()) {
    const auto& known = load_formats();
    if (std::find(known.begin(), known.end(), f) == known.end())
      throw Error(path.string(), 0, "unknown format '" + f + "' (known: ijrr, eventnerf, robust-e-nerf, hdf5, rosbag)");
    const bool folder_format = f == "ijrr" || f == "eventnerf" || f == "robust-e-nerf";
    if (folder_format != fs::is_directory(path))
      throw Error(path.string(), 0, "format '" + f + "' is " + (folder_format ? "a folder" : "a file") + ", and this is " +
                                        (fs::exists(path) ? (folder_format ? "a file" : "a folder") : "missing"));
    if (f == "ijrr") return load_ijrr(path, opt);
    if (f == "eventnerf") return load_eventnerf(path, opt);
    if (f == "robust-e-nerf") return load_robust_e_nerf(path, opt);
#ifdef EVNERF_HAVE_HDF5
    if (f == "hdf5") return load_hdf5(path, opt);
#endif
#ifdef EVNERF_HAVE_ROSBAG
    if (f == "rosbag") return load_rosbag(path, opt);
#endif
    throw Error(path.string(), 0, "this build of evnerf does not read format '" + f + "'");
  }
  if (fs::is_directory(path)) {
    std::vector<std::string> found;
    if (fs::exists(path / "events.txt")) found.push_back("ijrr");
    if (is_eventnerf(path)) found.push_back("eventnerf");
    if (is_robust_e_nerf(path)) found.push_back("robust-e-nerf");
    if (found.size() > 1) {
      std::string list;
      for (const auto& k : found) list += (list.empty() ? "" : ", ") + k;
      throw Error(path.string(), 0, "the folder holds several layouts (" + list + "): choose one with --format");
    }
    if (!found.empty() && found[0] == "robust-e-nerf") return load_robust_e_nerf(path, opt);
    if (!found.empty() && found[0] == "eventnerf") return load_eventnerf(path, opt);
    return load_ijrr(path, opt);
  }
  if (!fs::exists(path)) throw Error(path.string(), 0, "no such recording (expected an IJRR-layout folder, an event HDF5 file or a ROS bag)");
#ifdef EVNERF_HAVE_HDF5
  if (is_hdf5(path)) return load_hdf5(path, opt);
#endif
#ifdef EVNERF_HAVE_ROSBAG
  if (is_rosbag(path)) return load_rosbag(path, opt);
#endif
  std::string missing;
#ifndef EVNERF_HAVE_HDF5
  missing += " This build reads no HDF5 (install libhdf5-dev and rebuild).";
#endif
#ifndef EVNERF_HAVE_ROSBAG
  missing += " This build reads no ROS bags (install libbz2-dev and liblz4-dev and rebuild).";
#endif
  throw Error(path.string(), 0, "not a recording evnerf reads (an IJRR-layout folder, an event HDF5 file or a ROS bag 2.0)." + missing);
}

/// load_whole, then only the events of the time window LoadOptions names (an error when none are left).
inline Dataset load(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  if (!(opt.t_begin < opt.t_end))
    throw Error(path.string(), 0, "time window [" + short_number(opt.t_begin) + ", " + short_number(opt.t_end) + ") s is empty");
  auto d = load_whole(path, opt);
  if (std::isfinite(opt.t_begin) || std::isfinite(opt.t_end)) {
    d.events.keep_time_window(opt.t_begin, opt.t_end);
    if (d.events.empty())
      throw Error(path.string(), 0, "no events in the time window [" + short_number(opt.t_begin) + ", " + short_number(opt.t_end) + ") s");
  }
  return d;
}

}  // namespace evnerf::io
