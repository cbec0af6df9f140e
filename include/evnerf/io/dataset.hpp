// io/dataset.hpp — the formats evnerf reads and writes, as one table (formats()): an IJRR-layout folder,
// an EventNeRF scene, a Robust e-NeRF sequence, Prophesee .raw (EVT 2.0, 3.0) and .dat files, an event HDF5
// file, a ROS bag, an AEDAT4 file. io::load picks the reader from the content (or LoadOptions::format), io::convert the
// writer from the output's name; --format, inspect, convert and the error texts that list formats come from
// the table. A new format of evnerf's is one header (its reader, `<name>_format()` returning its Format) and
// one line in the table; a format of your own is registered from your own header (register_format), with no
// edit here. Depends on io/.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "eventnerf.hpp"
#include "prophesee.hpp"
#include "recording.hpp"
#include "robust_e_nerf.hpp"
#ifdef EVNERF_HAVE_HDF5
#include "hdf5.hpp"
#endif
#ifdef EVNERF_HAVE_ROSBAG
#include "rosbag.hpp"
#endif
#ifdef EVNERF_HAVE_AEDAT4
#include "aedat4.hpp"
#endif

namespace evnerf::io {

/// Held-out views as sim::write_views writes them: poses.txt (`index tx ty tz qx qy qz qw`, camera to world),
/// images/view_XXXXXXXX.png and depth/view_XXXXXXXX.npy; every view needs its image, depth is optional.
inline Dataset::Views read_views(const fs::path& dir) {
  Dataset::Views v;
  const auto tr = read_poses_txt(dir / "poses.txt");
  v.poses = tr.poses();
  for (std::size_t k = 0; k < v.poses.size(); ++k) {
    char name[64];
    std::snprintf(name, sizeof name, "images/view_%08zu.png", k);
    if (!fs::exists(dir / name)) throw Error((dir / "poses.txt").string(), 0, std::string("view ") + std::to_string(k) + ": its image " + name + " is missing");
    v.images.push_back(dir / name);
    std::snprintf(name, sizeof name, "depth/view_%08zu.npy", k);
    if (fs::exists(dir / name)) v.depth.push_back(dir / name);
  }
  if (!v.depth.empty() && v.depth.size() != v.poses.size())
    throw Error((dir / "depth").string(), 0, "has " + std::to_string(v.depth.size()) + " of the " + std::to_string(v.poses.size()) + " views' depth");
  return v;
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
    d.events = read_events_txt(ev_path, w, h, opt.progress);
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
  if (fs::is_directory(folder / "novel")) d.novel = read_views(folder / "novel");
  return d;
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
  auto rec = opt.hdf5_check_in_child ? read_hdf5_checked(path, opt.width, opt.height, opt.t_begin, opt.t_end, opt.progress)
                                     : read_hdf5(path, opt.width, opt.height, opt.t_begin, opt.t_end, opt.progress);
  check_sensor_size(rec.width, rec.height, path.string() + " (the sensor size it gives)");
  Dataset d;
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  attach_calibration_and_poses(path, opt, d, rec.width, rec.height, "an HDF5 recording");
  d.events = std::move(rec.events);
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
  write_calibration_and_poses_beside(path, d);
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
  auto rec = read_rosbag(path, BagOptions{opt.events_topic, opt.images_topic, opt.camera_info_topic, opt.poses_topic, opt.progress});
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

#ifdef EVNERF_HAVE_ROSBAG
/// inspect's lines for a bag: its topics with their message counts and types.
inline std::string rosbag_summary(const std::filesystem::path& path) {
  std::string out = "ROS bag topics (messages, type):\n";
  for (const auto& t : rosbag_topics(path)) {
    char line[512];
    std::snprintf(line, sizeof line, "  %-32s %9llu  %s\n", t.topic.c_str(), static_cast<unsigned long long>(t.messages), t.type.c_str());
    out += line;
  }
  return out;
}
#endif

/// What the formats that need a library are (their entries with and without it).
inline constexpr const char* kHdf5Description = "an event HDF5 file (event_utils/HQF or DSEC layout)";
inline constexpr const char* kAedat4Description = "an iniVation AEDAT 4.0 file (DV, dv-processing: DAVIS346, DVXplorer)";
inline constexpr const char* kRosbagDescription = "a ROS bag 2.0 (dvs_msgs or prophesee event arrays, images, camera info, poses)";

namespace detail {
/// The table io::formats() shows: evnerf's formats, then those registered (register_format).
inline std::vector<Format>& format_table() {
  namespace fs = std::filesystem;
  static std::vector<Format> table = {
      {"ijrr", true, "an IJRR-layout folder (events.txt, calib.txt, groundtruth.txt, images.txt: the Event Camera Dataset's, the simulator's)",
       [](const fs::path& p) { return fs::exists(p / "events.txt"); }, &load_ijrr,
       [](const fs::path& p, const Dataset& d, const WriteOptions&) { write_ijrr(p, d); }},
      {"eventnerf", true, "an EventNeRF scene folder (train/events/*.npz, train/pose, train/intrinsics)", &is_eventnerf, &load_eventnerf},
      {"robust-e-nerf", true, "a Robust e-NeRF sequence folder (raw_events.npz, camera_poses.npz, camera_calibration.npz)", &is_robust_e_nerf,
       &load_robust_e_nerf},
      evt2_format(), evt3_format(), dat_format(),
#ifdef EVNERF_HAVE_HDF5
      {"hdf5", false, kHdf5Description, &is_hdf5, &load_hdf5,
       [](const fs::path& p, const Dataset& d, const WriteOptions&) { write_hdf5_recording(p, d); }, {".h5", ".hdf5"}},
#else
      {"hdf5", false, kHdf5Description, nullptr, nullptr, nullptr, {".h5", ".hdf5"}, nullptr,
       "this build of evnerf has no HDF5 support (install libhdf5-dev and rebuild)"},
#endif
#ifdef EVNERF_HAVE_ROSBAG
      {"rosbag", false, kRosbagDescription, &is_rosbag, &load_rosbag,
       [](const fs::path& p, const Dataset& d, const WriteOptions& o) { write_rosbag_recording(p, d, o.compression); }, {".bag"},
       &rosbag_summary},
#else
      {"rosbag", false, kRosbagDescription, nullptr, nullptr, nullptr, {".bag"},
       nullptr, "this build of evnerf has no ROS bag support (install libbz2-dev and liblz4-dev and rebuild)"},
#endif
#ifdef EVNERF_HAVE_AEDAT4
      aedat4_format(),
#else
      {"aedat4", false, kAedat4Description, nullptr, nullptr, nullptr, {".aedat4"}, nullptr,
       "this build of evnerf has no AEDAT4 support (install liblz4-dev and libzstd-dev and rebuild)"},
#endif
  };
  return table;
}
}  // namespace detail

/// The formats, in the order detection tries them (the folder layouts first; a folder that holds none of
/// them is read as IJRR's, whose reader names what is missing), then the formats registered, in the order
/// they were.
inline const std::vector<Format>& formats() { return detail::format_table(); }

/// Adds a format of your own to the table: `io::load`, `convert` and every command (inspect, train, eval,
/// convert, --format NAME) then read it, detected by its `detect` after evnerf's own formats, and write it
/// when it has a writer and extensions (examples/parts/csv_events.hpp). Register before the first read, not
/// while another thread reads. Returns true, so that a header can register at static initialisation
/// (`inline const bool registered = io::register_format(...)`). An Error when the name is taken or the
/// entry has no name, description, detection or reader.
inline bool register_format(Format f) {
  require(f.name && *f.name && f.description && *f.description, "register_format: a format needs a name and a description");
  require(f.detect && f.load, std::string("register_format: format '") + f.name + "' needs `detect` and `load`");
  for (const auto& g : detail::format_table())
    require(std::string_view(g.name) != f.name, std::string("register_format: there is already a format '") + f.name + "'");
  f.unavailable = "";
  detail::format_table().push_back(std::move(f));
  return true;
}

/// The formats' names, as --format takes them.
inline std::vector<std::string> format_names() {
  std::vector<std::string> n;
  for (const auto& f : formats()) n.push_back(f.name);
  return n;
}
/// The names joined by ", ".
inline std::string format_list() {
  std::string s;
  for (const auto& f : formats()) s.append(s.empty() ? "" : ", ").append(f.name);
  return s;
}
/// The format called `name`; an Error naming `where` and every format when there is none.
inline const Format& format_named(const std::string& name, const std::filesystem::path& where) {
  for (const auto& f : formats())
    if (name == f.name) return f;
  throw Error(where.string(), 0, "unknown format '" + name + "' (known: " + format_list() + ")");
}
/// The format of the recording at `path` (LoadOptions::format, else its content); an Error naming the path
/// when it is none of them, a folder holds several layouts, or this build cannot read it.
inline const Format& detect_format(const std::filesystem::path& path, const std::string& format = {}) {
  namespace fs = std::filesystem;
  if (!format.empty()) {
    const Format& f = format_named(format, path);
    if (f.folder != fs::is_directory(path))
      throw Error(path.string(), 0, "format '" + format + "' is " + (f.folder ? "a folder" : "a file") + ", and this is " +
                                        (fs::exists(path) ? (f.folder ? "a file" : "a folder") : "missing"));
    if (!f.load) throw Error(path.string(), 0, std::string("format '") + f.name + "': " + f.unavailable);
    return f;
  }
  std::string kinds, missing;
  for (const auto& f : formats()) {
    kinds.append(kinds.empty() ? "" : "; ").append(f.description);
    if (!f.load) missing += std::string(" ") + f.unavailable + ".";
  }
  if (fs::is_directory(path)) {
    std::vector<const Format*> found;
    for (const auto& f : formats())
      if (f.folder && f.detect && f.load && f.detect(path)) found.push_back(&f);
    if (found.size() > 1) {
      std::string list;
      for (const auto* f : found) list.append(list.empty() ? "" : ", ").append(f->name);
      throw Error(path.string(), 0, "the folder holds several layouts (" + list + "): choose one with --format");
    }
    return found.empty() ? formats().front() : *found.front();
  }
  if (!fs::exists(path)) throw Error(path.string(), 0, "no such recording (expected " + kinds + ")");
  for (const auto& f : formats())
    if (!f.folder && f.detect && f.load && f.detect(path)) return f;
  throw Error(path.string(), 0, "not a recording evnerf reads (" + kinds + ")." + missing);
}

/// Loads a recording whatever its format (all its events; io::load applies LoadOptions' time window): the
/// reader is picked from the content, not the name (detect_format).
inline Dataset load_whole(const std::filesystem::path& path, const LoadOptions& opt = {}) { return detect_format(path, opt.format).load(path, opt); }

/// Writes a recording in the format `out`'s name chooses: the file format with the longest extension its
/// name ends in (`.evt2.raw` before `.raw`), else (a folder) the IJRR layout. Returns the format's name.
inline std::string convert(const std::filesystem::path& out, const Dataset& d, const WriteOptions& opt = {}) {
  const std::string name = out.filename().string();
  const Format* best = nullptr;
  std::size_t best_len = 0;
  for (const auto& f : formats())
    for (const auto& ext : f.extensions)
      if (name.size() > ext.size() && name.ends_with(ext) && ext.size() > best_len) best = &f, best_len = ext.size();
  if (best) {
    if (!best->write)
      throw Error(out.string(), 0, std::string("format '") + best->name + "': " + (*best->unavailable ? best->unavailable : "no writer"));
    best->write(out, d, opt);
    return best->name;
  }
  for (const auto& f : formats())
    if (f.folder && f.write) {
      f.write(out, d, opt);
      return f.name;
    }
  throw Error(out.string(), 0, "no format writes this");
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
