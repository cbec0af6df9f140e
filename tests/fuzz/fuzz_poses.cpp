// Pose files: IJRR groundtruth.txt and TUM trajectories share one layout and one parser
// (`t px py pz qx qy qz qw`); the seed corpus holds both kinds. The trajectory is then interpolated.
#include <evnerf/io/ijrr.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return evfuzz::run([&] {
    const auto tr = evnerf::io::parse_poses(evfuzz::text(data, size), "groundtruth.txt");
    evfuzz::expect(tr.size() > 0, "an empty trajectory was accepted");
    for (std::size_t i = 1; i < tr.size(); ++i) evfuzz::expect(tr.times()[i] > tr.times()[i - 1], "pose times not increasing");
    const double mid = 0.5 * (tr.times().front() + tr.times().back());
    const auto p = tr.pose_at(mid);
    evfuzz::expect(std::abs(p.q.norm() - 1) < 1e-6, "an interpolated rotation is not a unit quaternion");
  });
}
