// IJRR calib.txt (`fx fy cx cy [k1 k2 p1 p2 [k3]]`) on a 240×180 sensor, and sensor.txt (`width height`).
#include <evnerf/io/dataset.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto in = evfuzz::text(data, size);
  evfuzz::run([&] {
    const auto cam = evnerf::io::parse_calib(in, "calib.txt", 240, 180);
    evfuzz::expect(cam.fx() > 0 && cam.fy() > 0 && std::isfinite(cam.cx()) && std::isfinite(cam.cy()), "camera not usable");
  });
  evfuzz::run([&] {
    const auto [w, h] = evnerf::io::parse_sensor_size(in, "sensor.txt");
    evfuzz::expect(w > 0 && h > 0 && static_cast<long long>(w) * h <= evnerf::io::kMaxSensorPixels, "sensor size not refused");
  });
  return 0;
}
