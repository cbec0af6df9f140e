// IJRR events.txt (`t x y p`): the fast parser against the plain reference, on a 240×180 sensor. Both
// must accept the same inputs with the same values, and refuse the rest with the same message.
#include <evnerf/io/ijrr.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto in = evfuzz::text(data, size);
  std::string fast_error, ref_error;
  evnerf::events::EventStream fast, ref;
  try {
    fast = evnerf::io::parse_events(in, "events.txt", 240, 180);
  } catch (const evnerf::Error& e) {
    fast_error = e.what();
  }
  try {
    ref = evnerf::io::parse_events_reference(in, "events.txt", 240, 180);
  } catch (const evnerf::Error& e) {
    ref_error = e.what();
  }
  evfuzz::expect(fast_error == ref_error, "the fast parser and the reference disagree about an error");
  evfuzz::expect(ref_error.size() < 700, "error message too long");
  if (!ref_error.empty()) return 0;
  evfuzz::expect(fast.t == ref.t && fast.x == ref.x && fast.y == ref.y && fast.polarity == ref.polarity,
                 "the fast parser and the reference read different events");
  for (std::size_t i = 0; i < ref.size(); ++i) {
    evfuzz::expect(ref.x[i] < 240 && ref.y[i] < 180, "event outside the sensor");
    evfuzz::expect(ref.polarity[i] == 1 || ref.polarity[i] == -1, "polarity not ±1");
    evfuzz::expect(std::isfinite(ref.t[i]) && (i == 0 || ref.t[i] >= ref.t[i - 1]), "time not finite and ordered");
  }
  return 0;
}
