// io/rosbag.hpp — event recordings in ROS bags (format 2.0), read from the published format specification
// without ROS: records (a header of `name=value` fields, then data), connection records (topic, type and the
// full message definition), chunks (uncompressed, bz2 or lz4 frames, through Debian's libbz2 and liblz4),
// and the index at the end (chunk infos: which chunk holds messages of which connection).
//
// Messages are decoded from their definition text, not from compiled-in layouts: any event message whose
// definition has an array `events` of fixed-size structs with integer `x`, `y`, a `time ts` and a
// boolean or integer `polarity` is read (dvs_msgs/EventArray, prophesee_event_msgs/EventArray, ...), and
// the fields of sensor_msgs/Image, sensor_msgs/CameraInfo, geometry_msgs/PoseStamped,
// geometry_msgs/TransformStamped and nav_msgs/Odometry are found by name. Topics are chosen
// automatically when one topic has the role, by name (BagOptions) otherwise.
//
// Times: ROS time (seconds since 1970) loses its nanoseconds in a double, so every time read is relative
// to `origin_sec`, the whole second of the first time decoded, and is the double nearest the exact number
// of nanoseconds (as a text reader of the time with nine decimals gets it). Memory: one chunk at a time (a few MB),
// plus what is kept (events, frames in memory, poses). Every error names the file and the record, chunk,
// topic or message. A bag cut short (a recorder that crashed or lost power: no index, or an index that lies or
// runs past the end of the file) is read to its last whole record, with a warning. Compiled only where CMake found libbz2
// and liblz4 (EVNERF_HAVE_ROSBAG).
// Its line of the format table is rosbag_format(). Depends on core/, geometry/, events/ and io/ only.
// The parts: rosbag/records.hpp (bytes, records, chunks), rosbag/messages.hpp (message definitions),
// rosbag/read.hpp (index, topics, read_rosbag), rosbag/write.hpp (write_rosbag); this header loads and
// writes a Dataset and is the format's line.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "../core/warn.hpp"
#include "recording.hpp"
#include "rosbag/read.hpp"
#include "rosbag/write.hpp"

namespace evnerf::io {

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
    else if (!rec.frames.empty()) w = rec.frames[0].width, h = rec.frames[0].height, from = "the first frame on " + rec.images_topic;
    else w = static_cast<int>(rec.max_x + 1), h = static_cast<int>(rec.max_y + 1), from = "the events' extent";
  }
  check_sensor_size(w, h, file + " (" + from + ")");
  if (rec.max_x >= w || rec.max_y >= h) {
    for (std::size_t i = 0; i < rec.events.size(); ++i)
      if (rec.events.x[i] >= w || rec.events.y[i] >= h)
        throw Error(file, 0,
                    "event " + std::to_string(i) + " of topic " + rec.events_topic + ": pixel (" + std::to_string(rec.events.x[i]) + ", " +
                        std::to_string(rec.events.y[i]) + ") lies outside the " + std::to_string(w) + "x" + std::to_string(h) +
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
    if (fs::exists(calib)) {
      d.camera = read_calib_txt(calib, w, h);
    } else if (opt.calibration_optional) {
      d.camera = uncalibrated_camera(w, h);
      d.uncalibrated = true;
    } else {
      throw Error(
          file, 0,
          "no camera info topic and no " + calib.string() + " beside the bag: give the calibration (fx fy cx cy [k1 k2 p1 p2 [k3]])");
    }
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

/// Writes a recording as a ROS bag (io::write_rosbag: DAVIS topics, `compression` chunks), stamped at the
/// recording's time origin, so that io::load reads it back.
inline void write_rosbag_recording(const std::filesystem::path& path, const Dataset& d, const std::string& compression = "lz4") {
  std::vector<Image> frames;
  for (std::size_t f = 0; f < d.frames.size(); ++f) frames.push_back(frame_image(d.frames, f));
  BagWriteOptions o;
  o.compression = compression;
  o.origin_sec = d.time_origin;
  o.camera_info = !d.uncalibrated;  // a guessed camera is not written as if it were known
  write_rosbag(path, d.events, d.camera, d.trajectory, d.frames.t, frames, o);
}

/// inspect's lines for a bag: its topics with their message counts and types. inspect reads the bag itself
/// too, and that read warns of a bag cut short, so the listing keeps its own warnings to itself.
inline std::string rosbag_summary(const std::filesystem::path& path) {
  std::string out = "ROS bag topics (messages, type):\n";
  std::vector<BagTopic> topics;
  {
    const WarningCollector once;
    topics = rosbag_topics(path);
  }
  for (const auto& t : topics) {
    char line[512];
    std::snprintf(line, sizeof line, "  %-32s %9llu  %s\n", t.topic.c_str(), static_cast<unsigned long long>(t.messages), t.type.c_str());
    out += line;
  }
  return out;
}

/// The format's line in io::formats(): written for an output ending in .bag; inspect lists its topics.
inline Format rosbag_format() {
  return {"rosbag",
          false,
          kRosbagDescription,
          &is_rosbag,
          &load_rosbag,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions& o) { write_rosbag_recording(p, d, o.compression); },
          {".bag"},
          &rosbag_summary};
}

}  // namespace evnerf::io
