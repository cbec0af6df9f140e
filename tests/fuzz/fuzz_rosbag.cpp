// ROS bags (io::read_rosbag, io::rosbag_topics), as io::load reads them: records, chunks (bz2 and lz4
// through Debian's libraries, uninstrumented), the index, message definitions and the messages decoded from
// them. The input is written to a file in /dev/shm (the reader opens paths).
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>

#include <evnerf/io/rosbag.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "recording.bag");
  if (path.empty()) return 0;
  evfuzz::run([&] {
    for (const auto& t : evnerf::io::rosbag_topics(path))
      evfuzz::expect(!t.topic.empty() && !t.type.empty(), "a topic without a name or type");
  });
  evfuzz::run([&] {
    const auto rec = evnerf::io::read_rosbag(path);
    const auto& ev = rec.events;
    evfuzz::expect(ev.size() > 0, "a bag without events was accepted");
    evfuzz::expect(ev.x.size() == ev.size() && ev.y.size() == ev.size() && ev.polarity.size() == ev.size(),
                   "event columns differ in length");
    for (std::size_t i = 0; i < ev.size(); ++i) {
      evfuzz::expect(std::isfinite(ev.t[i]) && (i == 0 || ev.t[i] >= ev.t[i - 1]), "event times not finite and sorted");
      evfuzz::expect(ev.x[i] <= rec.max_x && ev.y[i] <= rec.max_y, "an event beyond the recorded extent");
      evfuzz::expect(ev.polarity[i] == 1 || ev.polarity[i] == -1, "a polarity other than ±1");
    }
    evfuzz::expect(rec.frames.size() == rec.frame_times.size(), "frames and times differ in number");
    for (std::size_t i = 0; i < rec.frames.size(); ++i) {
      const auto& im = rec.frames[i];
      evfuzz::expect(im.data.size() == im.pixels() * static_cast<std::size_t>(im.channels) && im.pixels() > 0, "a frame of the wrong size");
      evfuzz::expect(i == 0 || rec.frame_times[i] >= rec.frame_times[i - 1], "frames out of time order");
    }
    evfuzz::expect(rec.poses.size() == rec.pose_times.size(), "poses and times differ in number");
    for (std::size_t i = 1; i < rec.pose_times.size(); ++i)
      evfuzz::expect(rec.pose_times[i] > rec.pose_times[i - 1], "pose times not increasing");
    for (const auto& p : rec.poses)
      evfuzz::expect(std::abs(p.q.norm() - 1) < 1e-9 && p.t.allFinite(), "a pose not finite or not normalised");
    if (rec.has_camera_info)
      evfuzz::expect(rec.fx > 0 && rec.fy > 0 && std::isfinite(rec.cx) && std::isfinite(rec.cy), "bad intrinsics accepted");
  });
  return 0;
}
