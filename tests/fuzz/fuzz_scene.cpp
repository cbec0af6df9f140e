// The simulator's scene description (built-in scenes, `evnerf simulate random`'s scene.txt). Textures that
// name image files are looked up in an empty folder.
#include <evnerf/sim/scene.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return evfuzz::run([&] {
    const auto spec = evnerf::sim::parse_scene(evfuzz::text(data, size), "scene.txt", "/nonexistent-fuzz-folder");
    evfuzz::expect(spec.path.duration > 0 && std::isfinite(spec.path.duration), "path duration not positive");
  });
}
