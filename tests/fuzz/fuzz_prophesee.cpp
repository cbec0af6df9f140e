// Prophesee files (io::read_prophesee_events: the '%' header, the sensor size it gives, EVT 2.0 and EVT 3.0
// words, .dat records), whole and in a time window. The input is written to a file in /dev/shm (the reader
// opens paths); a read's events must lie inside the sensor, in time order, within the window. A whole read by
// the serial decoder and by EVT 3.0's two-pass decode (in parts of a few words) must give the same events and
// counts, or the same error.
#include <algorithm>
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
  // The two-pass decode in 2 to 9 parts (chosen by the input) of blocks of a few words, on this one thread,
  // against the serial state machine: the cuts, each part's summary and starting state, and the fallback to
  // the serial decode are what can go wrong; the threads themselves are test_io's (one and two compared).
  auto read = [&](int parts) {
    evnerf::io::detail::evt3_parallel_parts = parts;
    evnerf::io::PropheseeInfo info;
    try {
      const auto ev = evnerf::io::read_prophesee_events(path, {}, info);
      return std::to_string(info.events) + " " + std::to_string(info.triggers) + " " + std::to_string(info.other_words) + " " +
             std::string(reinterpret_cast<const char*>(ev.t.data()), ev.t.size() * sizeof(double)) +
             std::string(reinterpret_cast<const char*>(ev.x.data()), ev.x.size() * 2) +
             std::string(reinterpret_cast<const char*>(ev.y.data()), ev.y.size() * 2) +
             std::string(reinterpret_cast<const char*>(ev.polarity.data()), ev.polarity.size());
    } catch (const evnerf::Error& e) {
      return std::string("error: ") + e.what();
    }
  };
  evnerf::io::detail::evt3_parallel_words = std::max<std::size_t>(8, size / 16);
  const std::string serial = read(1);
  evfuzz::expect(serial == read(2 + static_cast<int>(size % 8)), "the two-pass decode differs from the serial one");
  return 0;
}
