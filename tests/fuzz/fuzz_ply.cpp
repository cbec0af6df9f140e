// PLY files of one vertex element and at most one face element (io::read_ply, what `evnerf export` writes):
// a header of float and uchar properties, then the binary body. What it reads must hold together: as many
// floats as vertices times names, three colour bytes a vertex where the header declares them, triangles
// that name vertices the file has. The input is written to a file
// in /dev/shm (the reader opens paths).
#include <evnerf/io/ply.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "points.ply");
  if (path.empty()) return 0;
  evfuzz::run([&] {
    const auto v = evnerf::io::read_ply(path);
    evfuzz::expect(v.floats.size() == v.size() * v.names.size(), "floats that do not fill the vertices");
    evfuzz::expect(v.rgb.size() == (v.colour ? 3 * v.size() : 0), "colour bytes that do not match the vertices");
    for (const auto& f : v.faces) evfuzz::expect(f[0] < v.size() && f[1] < v.size() && f[2] < v.size(), "a triangle beyond the vertices");
  });
  return 0;
}
