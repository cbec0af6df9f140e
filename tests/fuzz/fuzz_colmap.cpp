// COLMAP's text model: cameras.txt and images.txt. Both parsers read every input.
#include <evnerf/io/colmap.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto in = evfuzz::text(data, size);
  evfuzz::run([&] {
    for (const auto& [id, cam] : evnerf::io::parse_colmap_cameras(in, "cameras.txt"))
      evfuzz::expect(cam.width() > 0 && cam.height() > 0 && cam.fx() > 0 && cam.fy() > 0, "camera not usable");
  });
  evfuzz::run([&] {
    for (const auto& im : evnerf::io::parse_colmap_images(in, "images.txt"))
      evfuzz::expect(std::abs(im.c2w.q.norm() - 1) < 1e-6, "pose rotation is not a unit quaternion");
  });
  return 0;
}
