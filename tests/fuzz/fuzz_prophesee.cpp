// Prophesee files (io::read_prophesee_events: the '%' header, the sensor size it gives, EVT 2.0 and EVT 3.0
// words, .dat records), whole and in a time window. The input is written to a file in /dev/shm (the reader
// opens paths); a read's events must lie inside the sensor, in time order, within the window.
#include <cmath>
#include <string>

#include <evnerf/io/prophesee.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "recording.raw");
  if (path.empty()) return 0;
  for (int window = 0; window < 2; ++window)
    evfuzz::run([&] {
      evnerf::io::LoadOptions o;
      if (window) o.t_begin = 0.001, o.t_end = 0.002;
      evnerf::io::PropheseeInfo info;
      const auto ev = evnerf::io::read_prophesee_events(path, o, info);
      evfuzz::expect(info.width > 0 && info.height > 0 && ev.size() <= info.events, "events without a sensor, or more than decoded");
      for (std::size_t i = 0; i < ev.size(); ++i) {
        evfuzz::expect(ev.x[i] < info.width && ev.y[i] < info.height, "an event outside the sensor");
        evfuzz::expect(i == 0 || ev.t[i] >= ev.t[i - 1], "events out of time order");
        evfuzz::expect(ev.t[i] >= o.t_begin && ev.t[i] < o.t_end, "an event outside the window");
      }
    });
  return 0;
}
