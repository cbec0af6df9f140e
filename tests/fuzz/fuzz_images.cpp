// IJRR images.txt (`t relative/path.png`): the frame list (the images themselves are the PNG harness's).
#include <evnerf/io/ijrr.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return evfuzz::run([&] {
    const auto f = evnerf::io::parse_frames(evfuzz::text(data, size), "images.txt", "/recording");
    evfuzz::expect(f.t.size() == f.paths.size(), "times and paths differ in number");
    for (std::size_t i = 1; i < f.t.size(); ++i) evfuzz::expect(f.t[i] >= f.t[i - 1], "frame times go back");
  });
}
