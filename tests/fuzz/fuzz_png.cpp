// Image decoding (frames, textures): stb_image from memory, as stored or converted to 1 or 3 channels
// (chosen by the input's length, so every input is decoded once).
#include <evnerf/io/image_io.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto in = evfuzz::text(data, size);
  const int ch = size % 3 == 0 ? 0 : size % 3 == 1 ? 1 : 3;
  return evfuzz::run([&] {
    const auto img = evnerf::io::decode_png(in, "frame.png", ch);
    evfuzz::expect(img.width > 0 && img.height > 0 && static_cast<long long>(img.width) * img.height <= evnerf::io::kMaxImagePixels,
                   "image size not refused");
    evfuzz::expect(img.data.size() == std::size_t(img.width) * img.height * img.channels, "pixel count");
  });
}
