// splat/gaussians.hpp — a scene of anisotropic 3D Gaussians as flat parameters: what one Gaussian holds, in
// which order, and how its parameters become what the rasterizer composites (a world-space covariance, an
// opacity, a colour seen from a direction). One Gaussian is a block of Layout::size values:
//   mean (x, y, z) · log-scale (3) · rotation quaternion (w, x, y, z; normalised where used) ·
//   opacity logit · colour: channels × (degree + 1)² spherical-harmonic coefficients, channel-major.
// Flat blocks keep a scene in one parameter vector, so that the project's Adam, checkpoints and shards treat
// Gaussians like network weights. Depends on core/ only.
#pragma once
#include <cmath>
#include <cstddef>
#include <vector>

#include "../core/types.hpp"

namespace evnerf::splat {

/// The parameter block of one Gaussian with `C` colour channels and spherical harmonics up to `Degree`
/// (0: one coefficient a channel, the same colour from every side; 1: four, a linear change with direction).
template <int C, int Degree>
struct Layout {
  static_assert(C >= 1, "a Gaussian has at least one colour channel");
  static_assert(Degree == 0 || Degree == 1, "spherical harmonics of degree 0 or 1");
  static constexpr int channels = C, degree = Degree;
  static constexpr int sh = (Degree + 1) * (Degree + 1);  ///< coefficients a channel
  static constexpr int mean = 0, log_scale = 3, rotation = 6, opacity = 10, colour = 11;
  static constexpr int size = colour + C * sh;
};

/// Real spherical harmonics of degree ≤ 1 at the unit direction d (the constant 1/(2√π), then the linear
/// band in the y, z, x order of the usual real basis, with 3DGS's sign convention).
template <int Degree, class T>
inline void sh_basis(const T d[3], T out[]) {
  constexpr T c0 = T(0.28209479177387814), c1 = T(0.4886025119029199);
  out[0] = c0;
  if constexpr (Degree >= 1) {
    out[1] = -c1 * d[1];
    out[2] = c1 * d[2];
    out[3] = -c1 * d[0];
  }
}

/// The gradient of Σ_k w_k · basis_k(d) for the direction d, given w (the coefficients' weights).
template <int Degree, class T>
inline void sh_basis_dir_grad(const T w[], T dd[3]) {
  constexpr T c1 = T(0.4886025119029199);
  dd[0] = dd[1] = dd[2] = 0;
  if constexpr (Degree >= 1) {
    dd[0] = -c1 * w[3];
    dd[1] = -c1 * w[1];
    dd[2] = c1 * w[2];
  }
}

/// Where a scene of Gaussians starts when a teacher already knows the scene (a field trained on the same
/// recording: evaluation::gaussian_seeds): one isotropic Gaussian per point, with its luminance
/// (`channels` values a point, point-major) and width (the spacing of its neighbours), all at `opacity`;
/// and what the teacher learned of the recording beside the scene: its backdrop's luminance per channel
/// (empty: none learned) and its thresholds per slice (B⁺ and B⁻ interleaved; empty: the model's own).
struct Seeds {
  int channels = 1;
  std::vector<Vec3> position;
  std::vector<float> luminance;
  std::vector<double> width;
  double opacity = 0.5;
  std::vector<double> backdrop;
  std::vector<double> thresholds;
  std::size_t size() const { return position.size(); }
};

/// The rotation matrix of the unit quaternion (w, x, y, z), row-major.
template <class T>
inline void quat_to_matrix(const T q[4], T r[9]) {
  const T w = q[0], x = q[1], y = q[2], z = q[3];
  r[0] = 1 - 2 * (y * y + z * z), r[1] = 2 * (x * y - w * z), r[2] = 2 * (x * z + w * y);
  r[3] = 2 * (x * y + w * z), r[4] = 1 - 2 * (x * x + z * z), r[5] = 2 * (y * z - w * x);
  r[6] = 2 * (x * z - w * y), r[7] = 2 * (y * z + w * x), r[8] = 1 - 2 * (x * x + y * y);
}

/// dL/dq for the unit quaternion q, given dL/dR (row-major) of R = quat_to_matrix(q).
template <class T>
inline void quat_to_matrix_backward(const T q[4], const T g[9], T dq[4]) {
  const T w = q[0], x = q[1], y = q[2], z = q[3];
  dq[0] = 2 * (-z * g[1] + y * g[2] + z * g[3] - x * g[5] - y * g[6] + x * g[7]);
  dq[1] = 2 * (y * g[1] + z * g[2] + y * g[3] - 2 * x * g[4] - w * g[5] + z * g[6] + w * g[7] - 2 * x * g[8]);
  dq[2] = 2 * (-2 * y * g[0] + x * g[1] + w * g[2] + x * g[3] + z * g[5] - w * g[6] + z * g[7] - 2 * y * g[8]);
  dq[3] = 2 * (-2 * z * g[0] - w * g[1] + x * g[2] + w * g[3] - 2 * z * g[4] + y * g[5] + x * g[6] + y * g[7]);
}

}  // namespace evnerf::splat
