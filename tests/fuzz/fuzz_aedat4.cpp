// AEDAT4 files (io::read_aedat4: the version line, the IOHeader flatbuffer and its XML description, packets
// compressed with LZ4 or Zstd, event and frame flatbuffers, the data table), whole and in a time window.
// The input is written to a file in /dev/shm (the reader opens paths); a read's events must lie inside the
// sensor, in time order, within the window, and its frames must hold the sensor's pixels.
#include <cmath>
#include <string>

#include <evnerf/io/aedat4.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "recording.aedat4");
  if (path.empty()) return 0;
  for (int window = 0; window < 2; ++window)
    evfuzz::run([&] {
      evnerf::io::LoadOptions o;
      if (window) o.t_begin = 0.001, o.t_end = 0.002;
      evnerf::io::Aedat4Info info;
      evnerf::io::Frames frames;
      std::int64_t origin = 0;
      const auto ev = evnerf::io::read_aedat4(path, o, info, frames, origin);
      evfuzz::expect(ev.width > 0 && ev.height > 0 && ev.size() <= info.events, "events without a sensor, or more than decoded");
      for (std::size_t i = 0; i < ev.size(); ++i) {
        evfuzz::expect(ev.x[i] < ev.width && ev.y[i] < ev.height, "an event outside the sensor");
        evfuzz::expect(i == 0 || ev.t[i] >= ev.t[i - 1], "events out of time order");
        evfuzz::expect(ev.t[i] >= o.t_begin && ev.t[i] < o.t_end, "an event outside the window");
      }
      evfuzz::expect(frames.t.size() == frames.images.size(), "frame times and images differ in number");
      for (const auto& im : frames.images)
        evfuzz::expect(im.width == ev.width && im.height == ev.height && im.data.size() == im.pixels() * im.channels,
                       "a frame not of the sensor");
    });
  return 0;
}
