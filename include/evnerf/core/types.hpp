// core/types.hpp — scalar and small-vector aliases over Eigen used across evnerf.
// Depends on Eigen only.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace evnerf {

inline constexpr const char* version = "0.1.0";

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec3f = Eigen::Vector3f;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

/// A grey or multi-channel float image, row-major, channel-interleaved: value(x, y, c) = data[(y*w + x)*ch + c].
struct Image {
  int width = 0, height = 0, channels = 1;
  std::vector<float> data;
  Image() = default;
  Image(int w, int h, int c = 1, float fill = 0.f) : width(w), height(h), channels(c), data(static_cast<std::size_t>(w) * h * c, fill) {}
  float& at(int x, int y, int c = 0) { return data[(static_cast<std::size_t>(y) * width + x) * channels + c]; }
  float at(int x, int y, int c = 0) const { return data[(static_cast<std::size_t>(y) * width + x) * channels + c]; }
  std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
};

}  // namespace evnerf
