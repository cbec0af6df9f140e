// view/request.hpp — a frame request of the viewer's page read from its query (pose, scale, show), every
// value checked: what view/server.hpp reads from the network before anything renders. Depends on core/ and
// geometry/.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "../geometry/pose.hpp"

namespace evnerf::view {

/// One frame the page asks for: the camera's pose (camera to world: x right, y down, z forward), the factor
/// the sensor's width and height are divided by, and whether depth is shown rather than intensity.
struct FrameRequest {
  geometry::Pose pose;
  int scale = 1;
  bool depth = false;
};

/// The largest factor a frame's resolution is divided by.
inline constexpr int kMaxScale = 16;

/// A frame request from a query's parameters (`param(name)`: the value, or none where absent):
/// `pose` twelve numbers separated by commas, the camera-to-world matrix's three rows [R | t]; `scale`
/// 1..kMaxScale (default 1); `show` intensity or depth (default intensity). A rotation that is not one
/// (rows not orthonormal within 1e-3, or a reflection) or a number that is not finite is refused, naming it.
inline FrameRequest parse_frame_request(const std::function<std::optional<std::string>(const std::string&)>& param) {
  FrameRequest r;
  const auto pose = param("pose");
  if (!pose) throw Error("frame: no pose (twelve numbers: the camera-to-world matrix's rows)");
  std::vector<double> v;
  std::size_t at = 0;
  while (at <= pose->size() && v.size() < 13) {
    const std::size_t end = std::min(pose->find(',', at), pose->size());
    const std::string item = pose->substr(at, end - at);
    char* stop = nullptr;
    const double x = std::strtod(item.c_str(), &stop);
    if (item.empty() || stop != item.c_str() + item.size() || !std::isfinite(x))
      throw Error("frame: pose value " + std::to_string(v.size() + 1) + " '" + item.substr(0, 40) + "' is not a finite number");
    v.push_back(x);
    at = end + 1;
  }
  if (v.size() != 12) throw Error("frame: a pose is twelve numbers (the camera-to-world matrix's rows), got " + std::to_string(v.size()));
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = v[static_cast<std::size_t>(4 * i + j)];
  if ((R * R.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-3 || R.determinant() < 0)
    throw Error("frame: the pose's rotation is not a rotation (its rows are not orthonormal, or it reflects)");
  r.pose.q = Quat(R).normalized();
  r.pose.t = Vec3(v[3], v[7], v[11]);
  if (const auto s = param("scale")) {
    char* stop = nullptr;
    const long k = std::strtol(s->c_str(), &stop, 10);
    if (s->empty() || stop != s->c_str() + s->size() || k < 1 || k > kMaxScale)
      throw Error("frame: scale '" + s->substr(0, 40) + "' is not a whole number in 1.." + std::to_string(kMaxScale));
    r.scale = static_cast<int>(k);
  }
  if (const auto s = param("show")) {
    if (*s != "intensity" && *s != "depth") throw Error("frame: show '" + s->substr(0, 40) + "' is not intensity or depth");
    r.depth = *s == "depth";
  }
  return r;
}

/// The twelve numbers of a pose as parse_frame_request reads them.
inline std::vector<double> pose_numbers(const geometry::Pose& p) {
  const Mat3 R = p.rotation();
  return {R(0, 0), R(0, 1), R(0, 2), p.t.x(), R(1, 0), R(1, 1), R(1, 2), p.t.y(), R(2, 0), R(2, 1), R(2, 2), p.t.z()};
}

}  // namespace evnerf::view
