// io/ijrr_layout.hpp — the IJRR layout as a recording folder (the Event Camera Dataset's, the simulator's):
// events.txt, calib.txt, sensor.txt, groundtruth.txt, images.txt with images/, depth/ and the held-out views
// of views/, read into and written from an io::Dataset; its line of the format table (ijrr_format). The
// files' parsers are io/ijrr.hpp's. Depends on io/recording.hpp.
#pragma once
#include <cstdio>
#include <filesystem>
#include <string>

#include "recording.hpp"

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
    if (!fs::exists(dir / name))
      throw Error((dir / "poses.txt").string(), 0, std::string("view ") + std::to_string(k) + ": its image " + name + " is missing");
    v.images.push_back(dir / name);
    std::snprintf(name, sizeof name, "depth/view_%08zu.npy", k);
    if (fs::exists(dir / name)) v.depth.push_back(dir / name);
  }
  if (!v.depth.empty() && v.depth.size() != v.poses.size())
    throw Error((dir / "depth").string(), 0,
                "has " + std::to_string(v.depth.size()) + " of the " + std::to_string(v.poses.size()) + " views' depth");
  return v;
}

/// Loads an IJRR-layout folder. events.txt and calib.txt are required (calib.txt not where the calibration is
/// optional: LoadOptions::calibration_optional); groundtruth.txt, images.txt and depth/ are optional. Every parse error names file and line.
inline Dataset load_ijrr(const std::filesystem::path& folder, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(folder)) throw Error(folder.string(), 0, "not a folder (missing recording?)");
  Dataset d;
  d.folder = folder;
  if (fs::exists(folder / "images.txt")) d.frames = read_frames_txt(folder / "images.txt");
  const auto [w, h] = sensor_size(folder, d.frames, opt.width, opt.height);
  if (!opt.calib.empty()) {
    d.camera = read_calib_source(opt.calib, w, h);
  } else if (opt.calibration_optional && !fs::exists(folder / "calib.txt")) {
    d.camera = uncalibrated_camera(w, h);
    d.uncalibrated = true;
  } else {
    d.camera = read_calib_txt(folder / "calib.txt", w, h);
  }
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
  if (!opt.poses.empty()) d.trajectory = read_pose_source(opt.poses, d.frames);
  else if (fs::exists(folder / "groundtruth.txt")) d.trajectory = read_poses_txt(folder / "groundtruth.txt");
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
  if (fs::exists(folder / "groundtruth_true.txt")) d.true_trajectory = read_poses_txt(folder / "groundtruth_true.txt");
  return d;
}

/// Writes a recording as an IJRR-layout folder: events.txt (9 decimals of seconds), calib.txt (unless the
/// recording has none: Dataset::uncalibrated), sensor.txt,
/// groundtruth.txt when there are poses, images.txt and images/frame_*.png when there are frames. Every
/// file is written atomically.
inline void write_ijrr(const std::filesystem::path& dir, const Dataset& d) {
  namespace fs = std::filesystem;
  std::string ev;
  ev.reserve(d.events.size() * 24);
  char buf[160];
  for (std::size_t i = 0; i < d.events.size(); ++i) {
    const int k =
        std::snprintf(buf, sizeof buf, "%.9f %d %d %d\n", d.events.t[i], d.events.x[i], d.events.y[i], d.events.polarity[i] > 0 ? 1 : 0);
    ev.append(buf, static_cast<std::size_t>(k));
  }
  write_file_atomic(dir / "events.txt", ev);
  if (!d.uncalibrated) write_file_atomic(dir / "calib.txt", calib_text(d.camera));  // a guess is not written as known
  write_file_atomic(dir / "sensor.txt", std::to_string(d.camera.width()) + " " + std::to_string(d.camera.height()) + "\n");
  if (!d.trajectory.empty()) write_poses_txt(dir / "groundtruth.txt", d.trajectory);
  if (!d.true_trajectory.empty()) write_poses_txt(dir / "groundtruth_true.txt", d.true_trajectory);
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

/// The format's line in io::formats(): a folder holding events.txt (and any folder no other layout claims);
/// convert writes it for an output with none of the table's extensions.
inline Format ijrr_format() {
  return {"ijrr",
          true,
          "an IJRR-layout folder (events.txt, calib.txt, groundtruth.txt, images.txt: the Event Camera Dataset's, the simulator's)",
          [](const std::filesystem::path& p) { return std::filesystem::exists(p / "events.txt"); },
          &load_ijrr,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions&) { write_ijrr(p, d); }};
}

}  // namespace evnerf::io
