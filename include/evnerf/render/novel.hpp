// render/novel.hpp — a novel camera path for rendering views no camera recorded: from the first to the
// last recorded pose, swung sideways (±0.06 rad about the camera's y axis) and lifted (up to 0.05 world
// units along its y axis). Depends on geometry/.
#pragma once
#include <cmath>
#include <numbers>

#include "../geometry/pose.hpp"

namespace evnerf::render {

/// View k of n (k = 0 … n−1) along the novel path between `first` and `last`.
inline geometry::Pose novel_pose(const geometry::Pose& first, const geometry::Pose& last, int k, int n) {
  const double s = n > 1 ? double(k) / (n - 1) : 0.5;
  geometry::Pose p = geometry::Pose::interpolate(first, last, s);
  const double ang = 0.06 * std::sin(2 * std::numbers::pi * s);
  p.q = (p.q * Quat(Eigen::AngleAxisd(ang, Vec3::UnitY()))).normalized();
  p.t += p.q * Vec3(0, 0.05 * std::sin(std::numbers::pi * s), 0);
  return p;
}

}  // namespace evnerf::render
