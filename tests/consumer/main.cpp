// Smallest program against an installed evnerf: builds a camera and one ray.
#include <evnerf/evnerf.hpp>
#include <iostream>

int main() {
  evnerf::geometry::Camera cam(240, 180, 200.0, 200.0, 120.0, 90.0);
  auto ray = cam.ray(evnerf::geometry::Pose::identity(), 120.0, 90.0);
  std::cout << "evnerf " << evnerf::version << " ray dir z = " << ray.dir.z() << "\n";
  return ray.dir.z() > 0 ? 0 : 1;
}
