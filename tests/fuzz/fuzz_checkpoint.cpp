// The checkpoint loader (EvNerf::deserialize: the header, the model, the run, through io/checkpoint.hpp).
// A checkpoint ends in a checksum that random bytes almost never match, so the first input byte picks the
// mode: odd, the harness appends the right checksum to the rest (the fuzzer explores the parser behind
// it); even, the rest is read as it is (the checksum and magic checks themselves).
#include <cmath>

#include <evnerf/io/checkpoint.hpp>

#include "fuzz.hpp"
#include "fuzz_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] & 1) {
    const std::uint64_t sum = evnerf::fnv1a64(bytes);
    bytes.append(reinterpret_cast<const char*>(&sum), 8);
  }
  static evfuzz::FuzzModel model(3, evnerf::render::SceneBox{}, 1);
  return evfuzz::run([&] {
    const auto run = model.deserialize(bytes, "model.ckpt");
    evfuzz::expect(run.times.size() == run.poses.size(), "a run with other counts of times and poses");
    evfuzz::expect(run.times.empty() || (run.times.size() == model.n_slices() + 1 && run.camera.width() > 0 && run.camera.height() > 0),
                   "a run whose boundaries do not match the slices, or without a sensor");
    for (const auto& pose : run.poses) evfuzz::expect(std::abs(pose.q.norm() - 1) < 1e-9, "a boundary pose that is not a rotation");
    evfuzz::expect(model.params().size() == evfuzz::FuzzModel::renderer_type::n_params + 2 * model.n_slices(),
                   "parameter count does not match the slices");
    const auto& avg = model.average();
    evfuzz::expect(!avg.active() || (avg.values().size() == model.params().size() && avg.decay() >= 0 && avg.decay() < 1),
                   "a parameter average of another size, or a decay outside [0, 1)");
  });
}
