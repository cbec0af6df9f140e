// io/recording.hpp — one recording in memory (Dataset: camera, events, poses, optional frames and depth),
// what a reader is given (LoadOptions), the pieces every reader shares (calibration and pose files given
// instead of the recording's own, the sensor size, the colour filter), and what a format is (Format): its
// name, how it is detected, its reader and its writer. io/dataset.hpp holds the table of formats.
// Depends on core/, geometry/, events/ and io/'s text readers.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <stb_image.h>

#include "../geometry/bayer.hpp"
#include "colmap.hpp"
#include "ijrr.hpp"
#include "image_io.hpp"
#include "npy.hpp"

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
  /// The reader, where the content does not decide it (a folder holding two layouts): a name of
  /// io::formats(); empty = from the content.
  std::string format;
  /// A recording in one file without calibration beside it loads with a pinhole guess and
  /// Dataset::uncalibrated instead of an Error (inspect describes such a file; training needs --calib).
  bool calibration_optional = false;
  /// Called as a whole-file read goes on (bytes read of the file's size; see ReadProgress): events.txt,
  /// Prophesee .raw / .dat, AEDAT4, ROS bags and HDF5 (both its reads, each as half the file: io/hdf5.hpp)
  /// report. The command-line tool prints it for a read that takes more than a second.
  ReadProgress progress;
};

struct Dataset {
  std::filesystem::path folder;
  geometry::Camera camera;
  events::EventStream events;
  geometry::Trajectory trajectory;  ///< empty when the folder has no groundtruth.txt
  /// A simulated recording's true poses beside perturbed ones in `trajectory` (groundtruth_true.txt:
  /// simulate --pose-noise, --time-offset); empty otherwise. eval measures the pose error against them.
  geometry::Trajectory true_trajectory;
  Frames frames;                              ///< empty when the folder has no images.txt
  std::vector<std::filesystem::path> depth;   ///< per-frame ground-truth depth (.npy), simulator only
  std::vector<std::filesystem::path> linear;  ///< per-frame linear radiance (.npy, unclipped): HDR truth, simulator only
  double linear_log_offset = 0;               ///< the sensor's dark end, log(I + offset), with `linear`
  /// Held-out views (a simulated recording's novel/): camera poses never on the training path, with their
  /// frames (.png) and depth (.npy); eval scores them apart from the frames along the path.
  struct Views {
    std::vector<geometry::Pose> poses;
    std::vector<std::filesystem::path> images, depth;
  } novel;
  /// The recording's own clock at t = 0, in seconds: 0 for IJRR folders and HDF5 files (their times are
  /// kept); a bag's times are relative to the whole second of its first message read (ROS time).
  std::int64_t time_origin = 0;
  /// The colour filter the events come through ("rggb", ...), where the recording says; "" otherwise.
  std::string bayer_pattern;
  /// Per pixel of the camera, 1 where the events come from (channel_dataset's green at the full sensor: the
  /// green sites of the mosaic); empty: every pixel. Training draws its pixels among these only.
  std::vector<std::uint8_t> sites;
  bool from_cache = false;
  /// The camera is a guess: no calibration was found (LoadOptions::calibration_optional).
  bool uncalibrated = false;
  /// What the reader says of the file beyond the recording (a header's kind, skipped words): inspect shows it.
  std::vector<std::string> notes;
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
  c.true_trajectory = d.true_trajectory;
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
    throw Error(where, line,
                "sensor size " + std::to_string(w) + "x" + std::to_string(h) + " has more than " + std::to_string(kMaxSensorPixels) +
                    " pixels (refused before allocating per-pixel counts)");
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
    throw Error(images.string(), 0,
                "COLMAP poses are matched to the recording's frame files by name, and this recording has no frame files");
  std::vector<std::pair<double, geometry::Pose>> timed;
  for (const auto& im : ims) {
    int found = -1;
    for (std::size_t f = 0; f < frames.paths.size(); ++f) {
      const std::string path = frames.paths[f].generic_string();
      const bool match =
          path == im.name || (path.size() > im.name.size() && path.compare(path.size() - im.name.size(), im.name.size(), im.name) == 0 &&
                              path[path.size() - im.name.size() - 1] == '/');
      if (!match) continue;
      if (found >= 0) throw Error(images.string(), 0, "image '" + im.name.substr(0, 60) + "' matches two frames");
      found = static_cast<int>(f);
    }
    if (found >= 0) timed.emplace_back(frames.t[static_cast<std::size_t>(found)], im.c2w);
  }
  if (timed.size() < 2)
    throw Error(images.string(), 0,
                std::to_string(timed.size()) + " of its " + std::to_string(ims.size()) +
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
    throw Error(p.string(), 0,
                "camera of " + std::to_string(c.width()) + "x" + std::to_string(c.height()) + " for a " + std::to_string(w) + "x" +
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

/// What a writer is given besides the recording (convert's options).
struct WriteOptions {
  std::string compression = "lz4";  ///< ROS bag chunks: none, bz2 or lz4; AEDAT4 packets: none, lz4 or zstd
};

/// One format of recordings: its name (--format), whether it is a folder or one file, how its content is
/// recognised (`detect`, cheap: a magic number, a file name), its reader and, where there is one, its
/// writer with the output extensions that choose it in convert (a folder format's writer takes an output
/// with none of the table's extensions). `inspect`, where given, adds format-specific lines to inspect's
/// summary (a bag's topics). A format this build cannot read has no reader and says why in `unavailable`.
struct Format {
  const char* name;
  bool folder;
  const char* description;  ///< one line: what the format is (listed in errors and --help)
  bool (*detect)(const std::filesystem::path&) = nullptr;
  Dataset (*load)(const std::filesystem::path&, const LoadOptions&) = nullptr;
  void (*write)(const std::filesystem::path&, const Dataset&, const WriteOptions&) = nullptr;
  std::vector<std::string> extensions = {};
  std::string (*inspect)(const std::filesystem::path&) = nullptr;
  const char* unavailable = "";  ///< why this build has no reader (the Debian package to install), or ""
};

/// What the formats that need a library are: their table lines with and without it (`<name>_format()`,
/// unavailable_format) say it alike.
inline constexpr const char* kHdf5Description = "an event HDF5 file (event_utils/HQF or DSEC layout)";
inline constexpr const char* kAedat4Description = "an iniVation AEDAT 4.0 file (DV, dv-processing: DAVIS346, DVXplorer)";
inline constexpr const char* kRosbagDescription = "a ROS bag 2.0 (dvs_msgs or prophesee event arrays, images, camera info, poses)";

/// The table line of a format this build cannot read (CMake did not find its library): its name, what it
/// is and its extensions, no reader or writer, and `why` (the Debian package to install).
inline Format unavailable_format(const char* name, const char* description, std::vector<std::string> extensions, const char* why) {
  return {name, false, description, nullptr, nullptr, nullptr, std::move(extensions), nullptr, why};
}

/// The camera a recording without calibration gets where one is optional (LoadOptions::calibration_optional):
/// a pinhole guess, the focal length the sensor's width, centred. Writers leave it out (Dataset::uncalibrated).
inline geometry::Camera uncalibrated_camera(int width, int height) {
  return geometry::Camera(width, height, width, width, 0.5 * width, 0.5 * height);
}

/// A recording held in one file (HDF5, Prophesee): its calibration from LoadOptions::calib, else calib.txt
/// beside it; its poses from LoadOptions::poses, else groundtruth.txt beside it (when present). Without a
/// calibration, an Error naming the file to give, unless LoadOptions::calibration_optional: then a pinhole
/// guess (focal length the sensor's width, centred) and Dataset::uncalibrated. A pose file's times are in the
/// file's clock: `origin` (Dataset::time_origin) is taken off them.
inline void attach_calibration_and_poses(const std::filesystem::path& path, const LoadOptions& opt, Dataset& d, int width, int height,
                                         const char* what, double origin = 0) {
  d.folder = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  const std::filesystem::path calib = opt.calib.empty() ? d.folder / "calib.txt" : opt.calib;
  if (!opt.calib.empty() || std::filesystem::exists(calib)) {
    d.camera = read_calib_source(calib, width, height);
  } else if (opt.calibration_optional) {
    d.camera = uncalibrated_camera(width, height);
    d.uncalibrated = true;
  } else {
    throw Error(
        calib.string(), 0,
        std::string("missing: ") + what + " takes its calibration from calib.txt beside it (fx fy cx cy [k1 k2 p1 p2 [k3]]) or --calib");
  }
  if (!opt.poses.empty()) d.trajectory = read_pose_source(opt.poses, d.frames, origin);
  else if (std::filesystem::exists(d.folder / "groundtruth.txt"))
    d.trajectory = read_pose_source(d.folder / "groundtruth.txt", d.frames, origin);
}

/// Writes calib.txt (unless the recording has none: Dataset::uncalibrated) and, when there are poses,
/// groundtruth.txt beside a recording written as one file (pose times in the file's clock: `origin` added to
/// them).
inline void write_calibration_and_poses_beside(const std::filesystem::path& path, const Dataset& d, double origin = 0) {
  const auto dir = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  if (!d.uncalibrated) write_file_atomic(dir / "calib.txt", calib_text(d.camera));  // a guess is not written as known
  if (d.trajectory.empty()) return;
  if (origin == 0) return write_poses_txt(dir / "groundtruth.txt", d.trajectory);
  std::vector<double> t = d.trajectory.times();
  for (double& v : t) v += origin;
  write_poses_txt(dir / "groundtruth.txt", geometry::Trajectory(std::move(t), d.trajectory.poses(), (dir / "groundtruth.txt").string()));
}

}  // namespace evnerf::io
