// render/scene.hpp — what the renderer needs from a recording: the camera's per-pixel ray directions,
// the scene box that normalises world points to [−1, 1]³, and near/far. Depends on geometry/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "../core/types.hpp"
#include "../geometry/camera.hpp"

namespace evnerf::render {

/// Maps world points to the network's [−1, 1]³: p_n = (p − center) / scale. `density_length` is the
/// world length over which density is measured: 1 (per world unit, the default) or `scale` (per unit of
/// the normalised box, which makes the untrained field's opacity and the N(0, 1) density noise
/// independent of the recording's units). `background`, when set, is the luminance (the same in every
/// channel) a ray sees where it leaves the samples unstopped: a backdrop of known brightness behind an
/// object, as EventNeRF's object scenes assume (render::composite_forward). `background_learned` puts a
/// backdrop of unknown brightness there instead, one luminance per channel learned with the field (the
/// renderer's backdrop parameters; Robust e-NeRF learns one for the same reason: the sequence's log offset
/// is unknown, so no fixed brightness fits it). With neither, the last sample stops every ray (NeRF's open
/// interval) and the field itself must paint what lies behind.
struct SceneBox {
  Vec3 center = Vec3::Zero();
  double scale = 1.0, near = 0.1, far = 5.0;
  double density_length = 1.0;
  std::optional<double> background;
  bool background_learned = false;  ///< a learned backdrop (ignored when `background` is known)

  /// The box that holds every point at depth ≤ far seen from any of the camera centres.
  static SceneBox from_cameras(const std::vector<Vec3>& centres, double near, double far) {
    SceneBox b;
    b.near = near;
    b.far = far;
    Vec3 lo = centres.front(), hi = centres.front();
    for (auto& c : centres) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
    b.center = 0.5 * (lo + hi);
    // A ray with unit camera-z has length ≤ far·|d|; |d| ≤ ~1.5 for common fields of view.
    b.scale = 0.5 * (hi - lo).maxCoeff() + far * 1.5;
    return b;
  }
};

/// One rendered image: luminance (C channels), depth along the optical axis, opacity.
struct Rendering {
  Image luminance, depth, opacity;
};

/// Undistorted camera-frame directions (x, y, 1) of every pixel centre, row-major: Camera::ray's direction
/// at the identity pose, cached (geometry::Camera::ray_along turns one into a world ray).
inline std::vector<Vec3f> pixel_directions(const geometry::Camera& cam) {
  std::vector<Vec3f> d(static_cast<std::size_t>(cam.width()) * cam.height());
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x)
      d[static_cast<std::size_t>(y) * cam.width() + x] = cam.ray(geometry::Pose{}, x + 0.5, y + 0.5).dir.cast<float>();
  return d;
}

}  // namespace evnerf::render

namespace evnerf {
using render::Rendering;
}  // namespace evnerf
