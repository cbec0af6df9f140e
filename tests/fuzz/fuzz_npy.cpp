// .npy arrays (the simulator's depth and linear truth, the event cache): float, uint16 and int8 readers.
#include <evnerf/io/npy.hpp>

#include "fuzz.hpp"

template <class T>
void read(std::string_view in) {
  evfuzz::run([&] {
    const auto a = evnerf::io::parse_npy<T>(in, "a.npy");
    std::size_t n = 1;
    for (auto d : a.shape) n *= d;
    evfuzz::expect(n == a.data.size(), "element count differs from the shape");
  });
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto in = evfuzz::text(data, size);
  read<float>(in);
  read<double>(in);
  read<std::uint16_t>(in);
  read<std::int8_t>(in);
  return 0;
}
