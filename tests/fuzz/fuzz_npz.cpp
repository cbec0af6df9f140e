// .npz archives (io::read_npz: zip members stored or deflated by stb's inflater, zip64, CRC-32) and the
// .npy members in them (io::parse_npy_numeric as double and int64, io::parse_npy_string), as EventNeRF
// scenes and Robust e-NeRF sequences are read. The input is written
// to a file in /dev/shm (the reader opens paths).
#include <unistd.h>

#include <cstdio>
#include <string>

#include <evnerf/io/eventnerf.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "archive.npz");
  if (path.empty()) return 0;
  evfuzz::run([&] {
    const auto members = evnerf::io::read_npz(path);
    for (const auto& member : members) {
      const std::string& name = member.first;
      const std::string& bytes = member.second;
      evfuzz::run([&] {
        const auto a = evnerf::io::parse_npy_numeric(bytes, path + " (" + name + ")");
        std::size_t n = 1;
        for (auto d : a.shape) n *= d;
        evfuzz::expect(n == a.data.size(), "an array whose size differs from its shape");
      });
      evfuzz::run([&] { (void)evnerf::io::parse_npy_numeric<std::int64_t>(bytes, path); });
      evfuzz::run([&] {
        for (char c : evnerf::io::parse_npy_string(bytes, path)) evfuzz::expect(c > 0, "a string character outside ASCII");
      });
    }
  });
  return 0;
}
