// splat/rasterizer.hpp — Gaussians to pixels and back: each Gaussian projected into a view (EWA: the
// projection's Jacobian at its centre carries its covariance to the image, widened by a low-pass dilation),
// binned into the tiles its footprint touches, sorted by depth in each, composited front to back at the
// pixels asked for, and the analytic backward of all of it to the Gaussians' parameters (splat/gaussians.hpp)
// and the backdrop. Only tiles that hold an asked pixel are filled, so a training step's cost follows its
// pixels, not the sensor's size. Compositing follows 3DGS: a Gaussian whose α at a pixel is under 1/255 is
// skipped, α is capped at 0.99, and a ray stops before the Gaussian that would take its transmittance under
// 10⁻⁴. A Gaussian's footprint is the ellipse where its α reaches 1/255 (its opacity counted), so a pixel
// outside every footprint the tiles list sees exactly what a visit of every Gaussian sees
// (reference_composite). Deterministic at a given thread count: pixels split into fixed blocks, per-thread
// gradients summed in thread order. Depends on core/, geometry/ and splat/gaussians.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#include "../core/error.hpp"
#include "../core/parallel.hpp"
#include "../core/types.hpp"
#include "../geometry/pose.hpp"
#include "gaussians.hpp"

namespace evnerf::splat {

/// One view: the camera's pose (camera to world, OpenCV axes), its pinhole intrinsics and the image's
/// extent in pixel coordinates. Pixels are continuous coordinates in the undistorted image (a pixel's
/// centre is (x + 0.5, y + 0.5); a distorted sensor's pixels are first undistorted). The extent sets the
/// clamp on the projection's Jacobian (a Gaussian far outside the view is projected as at 1.15 × the
/// view's edge, as 3DGS does), so a view's projection does not depend on which pixels are asked for.
struct View {
  geometry::Pose pose;
  double fx = 1, fy = 1, cx = 0, cy = 0;
  double width = 1, height = 1;  ///< the extent [0, width) × [0, height)
  double near = 0.01;            ///< Gaussians whose centre is nearer (camera z) are not drawn
};

/// Compositing constants (3DGS's): α under kMinAlpha is skipped, α is capped at kMaxAlpha, and a ray stops
/// before its transmittance would fall under kMinTransmittance. kDilation (pixels²) widens every projected
/// covariance, a low-pass filter that keeps a Gaussian at least about a pixel wide.
inline constexpr double kMinAlpha = 1.0 / 255, kMaxAlpha = 0.99, kMinTransmittance = 1e-4, kDilation = 0.3;
inline constexpr int kTile = 16;  ///< tile side in pixels

/// e^x for x ≤ 0, as the compositing evaluates a Gaussian: in float a polynomial after reduction by powers
/// of 2 (Cephes' expf coefficients, within 2 ulp of std::exp; x clamped at −87), written so that a loop over a
/// tile's pixels vectorizes (glibc's vector exp needs -ffast-math); in double std::exp. Every path that
/// composites (tiles, pixels, the reference, the backward) calls this one.
template <class T>
inline T gaussian_exp(T x) {
  if constexpr (std::is_same_v<T, float>) {
    x = x < -87.0f ? -87.0f : x;
    const float n = (x * 1.44269504088896341f + 12582912.0f) - 12582912.0f;  // round to nearest
    const float r = (x - n * 0.693359375f) + n * 2.12194440e-4f;
    float p = 1.9875691500e-4f;
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    p = p * r * r + r + 1.0f;
    const std::int32_t bits = (static_cast<std::int32_t>(n) + 127) << 23;
    float scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return p * scale;
  } else {
    return std::exp(x);
  }
}

/// The Gaussians of a scene projected into one view.
template <class T, int C>
struct Projection {
  std::size_t n = 0;
  std::vector<T> mean2, conic, depth, opacity, colour,
      extent;  ///< 2n image centres, 3n inverse covariances (xx, xy, yy), n depths, n opacities, C·n colours, 2n footprint half-sizes
  std::vector<unsigned char> visible;
};

/// The gradient of a loss for the projected Gaussians (rasterizer backward's output, projection backward's input).
template <class T, int C>
struct ProjectionGrad {
  std::vector<T> mean2, conic, opacity, colour;  ///< 2n, 3n, n, C·n
  void reset(std::size_t n) {
    mean2.assign(2 * n, T(0));
    conic.assign(3 * n, T(0));
    opacity.assign(n, T(0));
    colour.assign(C * n, T(0));
  }
};

namespace detail {

/// What projection and its backward both compute for one Gaussian in one view.
template <class T>
struct Projected3 {
  T qn[4], qnorm, r[9], s[3], m[9], cov3[9];  // unit quaternion, |q|, rotation, scales, M = R·S, Σ = M·Mᵀ
  T pc[3], u, v;                              // camera-frame centre; x/z and y/z, clamped
  bool u_free, v_free;                        // u, v not clamped
  T j[6], tm[6], cov2[3], det;                // Jacobian (2×3), J·W (2×3), image covariance (xx, xy, yy), its determinant
};

template <class T>
inline void world_to_camera(const geometry::Pose& pose, T w[9], T t[3]) {
  const Mat3 rcw = pose.q.conjugate().toRotationMatrix();
  const Vec3 tcw = -(rcw * pose.t);
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) w[3 * a + b] = static_cast<T>(rcw(a, b));
    t[a] = static_cast<T>(tcw[a]);
  }
}

/// The clamp limits of x/z and y/z: the view's extent widened by 15 % on each side.
template <class T>
inline std::array<T, 4> jacobian_limits(const View& v) {
  const double x0 = -v.cx / v.fx, x1 = (v.width - v.cx) / v.fx, y0 = -v.cy / v.fy, y1 = (v.height - v.cy) / v.fy;
  const double mx = 0.15 * (x1 - x0), my = 0.15 * (y1 - y0);
  return {static_cast<T>(x0 - mx), static_cast<T>(x1 + mx), static_cast<T>(y0 - my), static_cast<T>(y1 + my)};
}

/// Projects one Gaussian's shape; false when its centre lies nearer than the view's near plane or its image
/// covariance is degenerate.
template <class L, class T>
inline bool project_shape(const T* g, const View& view, const T w[9], const T tw[3], const std::array<T, 4>& lim, Projected3<T>& p) {
  const T* mu = g + L::mean;
  for (int a = 0; a < 3; ++a) p.pc[a] = w[3 * a] * mu[0] + w[3 * a + 1] * mu[1] + w[3 * a + 2] * mu[2] + tw[a];
  const T z = p.pc[2];
  if (!(z > static_cast<T>(view.near))) return false;
  const T* q = g + L::rotation;
  p.qnorm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(p.qnorm > T(0))) return false;
  for (int a = 0; a < 4; ++a) p.qn[a] = q[a] / p.qnorm;
  quat_to_matrix(p.qn, p.r);
  for (int a = 0; a < 3; ++a) p.s[a] = std::exp(g[L::log_scale + a]);
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) p.m[3 * a + b] = p.r[3 * a + b] * p.s[b];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      p.cov3[3 * a + b] = p.m[3 * a] * p.m[3 * b] + p.m[3 * a + 1] * p.m[3 * b + 1] + p.m[3 * a + 2] * p.m[3 * b + 2];
  const T fx = static_cast<T>(view.fx), fy = static_cast<T>(view.fy);
  const T xz = p.pc[0] / z, yz = p.pc[1] / z;
  p.u = std::clamp(xz, lim[0], lim[1]);
  p.v = std::clamp(yz, lim[2], lim[3]);
  p.u_free = p.u == xz;
  p.v_free = p.v == yz;
  p.j[0] = fx / z, p.j[1] = 0, p.j[2] = -fx * p.u / z;
  p.j[3] = 0, p.j[4] = fy / z, p.j[5] = -fy * p.v / z;
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 3; ++b) p.tm[3 * a + b] = p.j[3 * a] * w[b] + p.j[3 * a + 1] * w[3 + b] + p.j[3 * a + 2] * w[6 + b];
  T tc[6];  // Tm · Σ
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 3; ++b) tc[3 * a + b] = p.tm[3 * a] * p.cov3[b] + p.tm[3 * a + 1] * p.cov3[3 + b] + p.tm[3 * a + 2] * p.cov3[6 + b];
  const T dil = static_cast<T>(kDilation);
  p.cov2[0] = tc[0] * p.tm[0] + tc[1] * p.tm[1] + tc[2] * p.tm[2] + dil;
  p.cov2[1] = tc[0] * p.tm[3] + tc[1] * p.tm[4] + tc[2] * p.tm[5];
  p.cov2[2] = tc[3] * p.tm[3] + tc[4] * p.tm[4] + tc[5] * p.tm[5] + dil;
  p.det = p.cov2[0] * p.cov2[2] - p.cov2[1] * p.cov2[1];
  return p.det > T(0) && std::isfinite(p.det);
}

/// The view direction (unit, camera centre to the Gaussian) and the distance it was normalised by.
template <class L, class T>
inline T view_direction(const T* g, const View& view, T d[3]) {
  const T* mu = g + L::mean;
  for (int a = 0; a < 3; ++a) d[a] = mu[a] - static_cast<T>(view.pose.t[a]);
  const T len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const T inv = len > T(0) ? T(1) / len : T(0);
  for (int a = 0; a < 3; ++a) d[a] *= inv;
  return len;
}

}  // namespace detail

/// Projects the `n` Gaussians of `params` (n · L::size values) into `view`. The colour of channel c is
/// Act::f of its spherical harmonics at the view direction. A Gaussian is visible when its centre is
/// beyond the near plane, its image covariance is proper and its opacity reaches 1/255.
template <class L, class Act, class T>
void project(const T* params, std::size_t n, const View& view, Projection<T, L::channels>& out) {
  constexpr int C = L::channels;
  out.n = n;
  out.mean2.assign(2 * n, T(0));
  out.conic.assign(3 * n, T(0));
  out.depth.assign(n, T(0));
  out.opacity.assign(n, T(0));
  out.colour.assign(C * n, T(0));
  out.extent.assign(2 * n, T(0));
  out.visible.assign(n, 0);
  T w[9], tw[3];
  detail::world_to_camera(view.pose, w, tw);
  const auto lim = detail::jacobian_limits<T>(view);
  parallel_for(n, 4096, [&](std::size_t i) {
    const T* g = params + i * L::size;
    detail::Projected3<T> p;
    if (!detail::project_shape<L>(g, view, w, tw, lim, p)) return;
    const T o = T(1) / (T(1) + std::exp(-g[L::opacity]));
    if (!(o >= static_cast<T>(kMinAlpha))) return;
    const T z = p.pc[2];
    out.mean2[2 * i] = static_cast<T>(view.fx) * p.pc[0] / z + static_cast<T>(view.cx);
    out.mean2[2 * i + 1] = static_cast<T>(view.fy) * p.pc[1] / z + static_cast<T>(view.cy);
    out.conic[3 * i] = p.cov2[2] / p.det;
    out.conic[3 * i + 1] = -p.cov2[1] / p.det;
    out.conic[3 * i + 2] = p.cov2[0] / p.det;
    out.depth[i] = z;
    out.opacity[i] = o;
    // The footprint: the ellipse dᵀ Σ⁻¹ d = 2 ln(255 o), where α falls to 1/255; its bounding box, padded
    // so that rounding never drops a pixel that the exact test keeps.
    const T r2 = T(2) * std::log(o / static_cast<T>(kMinAlpha));
    out.extent[2 * i] = std::sqrt(std::max(T(0), r2 * p.cov2[0])) * T(1.001) + T(1e-3);
    out.extent[2 * i + 1] = std::sqrt(std::max(T(0), r2 * p.cov2[2])) * T(1.001) + T(1e-3);
    T d[3], basis[L::sh];
    detail::view_direction<L>(g, view, d);
    sh_basis<L::degree>(d, basis);
    for (int c = 0; c < C; ++c) {
      T value = 0;
      for (int k = 0; k < L::sh; ++k) value += g[L::colour + c * L::sh + k] * basis[k];
      out.colour[C * i + c] = Act::f(value);
    }
    out.visible[i] = 1;
  });
}

/// Adds to `dparams` (n · L::size values) the gradient of the loss whose gradient for the projection is
/// `grad`: through the colours' activation and spherical harmonics (and their direction), the opacity's
/// sigmoid, the conic's inverse, the EWA projection, and the covariance's scales and rotation.
///
/// With `dpose` not null, also adds the gradient for the view's pose: for the twist ε = (φ, ρ) at 0 of
/// pose ∘ Exp(ε) (rotation vector φ, then translation ρ, in the camera's frame; model/poses.hpp's convention).
/// The world-to-camera map (W, w) becomes (Eᵀ W, Eᵀ (w − ρ)) with E = Exp(φ), so a camera-frame centre moves
/// by pc × φ − ρ and W by −[φ]ₓ W; the camera's centre, which the colours' view direction starts from, by R ρ.
/// Per-Gaussian terms are summed in index order (the same bits at any thread count).
template <class L, class Act, class T>
void project_backward(const T* params, std::size_t n, const View& view, const Projection<T, L::channels>& proj,
                      const ProjectionGrad<T, L::channels>& grad, T* dparams, std::array<double, 6>* dpose = nullptr) {
  constexpr int C = L::channels;
  T w[9], tw[3];
  detail::world_to_camera(view.pose, w, tw);
  const auto lim = detail::jacobian_limits<T>(view);
  const T fx = static_cast<T>(view.fx), fy = static_cast<T>(view.fy);
  std::vector<std::array<T, 6>> pose_part(dpose ? n : 0);
  parallel_for(n, 4096, [&](std::size_t i) {
    if (!proj.visible[i]) return;
    const T* g = params + i * L::size;
    T* dg = dparams + i * L::size;
    detail::Projected3<T> p;
    detail::project_shape<L>(g, view, w, tw, lim, p);
    T dmu[3] = {0, 0, 0};
    // Colour: Act, then the harmonics' coefficients and direction.
    {
      T d[3], basis[L::sh], wsum[L::sh] = {};
      const T len = detail::view_direction<L>(g, view, d);
      sh_basis<L::degree>(d, basis);
      for (int c = 0; c < C; ++c) {
        const T dv = grad.colour[C * i + c] * Act::df_from_y(proj.colour[C * i + c]);
        for (int k = 0; k < L::sh; ++k) {
          dg[L::colour + c * L::sh + k] += dv * basis[k];
          wsum[k] += dv * g[L::colour + c * L::sh + k];
        }
      }
      if constexpr (L::degree >= 1) {
        T dd[3];
        sh_basis_dir_grad<L::degree>(wsum, dd);
        const T dot = dd[0] * d[0] + dd[1] * d[1] + dd[2] * d[2];
        if (len > T(0))
          for (int a = 0; a < 3; ++a) dmu[a] += (dd[a] - d[a] * dot) / len;
        // The camera's centre moves the direction as −μ does: ρ's share is −W dμ.
        if (dpose)
          for (int a = 0; a < 3; ++a) pose_part[i][3 + a] -= w[3 * a] * dmu[0] + w[3 * a + 1] * dmu[1] + w[3 * a + 2] * dmu[2];
      }
    }
    const T o = proj.opacity[i];
    dg[L::opacity] += grad.opacity[i] * o * (T(1) - o);
    // Conic (xx, xy, yy with xy counted once, as the compositing uses it twice) to the image covariance:
    // dΣ₂ = −K G K with G the symmetric gradient for K's entries.
    const T k0 = proj.conic[3 * i], k1 = proj.conic[3 * i + 1], k2 = proj.conic[3 * i + 2];
    const T g0 = grad.conic[3 * i], g1 = grad.conic[3 * i + 1] / 2, g2 = grad.conic[3 * i + 2];
    const T kg00 = k0 * g0 + k1 * g1, kg01 = k0 * g1 + k1 * g2, kg10 = k1 * g0 + k2 * g1, kg11 = k1 * g1 + k2 * g2;
    const T s00 = -(kg00 * k0 + kg01 * k1), s01 = -(kg00 * k1 + kg01 * k2), s11 = -(kg10 * k1 + kg11 * k2);
    const T gs[4] = {s00, s01, s01, s11};
    // Σ₂ = Tm Σ Tmᵀ: dTm = 2 Gs Tm Σ, dΣ = Tmᵀ Gs Tm.
    T tc[6], dtm[6], dcov[9];
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 3; ++b)
        tc[3 * a + b] = p.tm[3 * a] * p.cov3[b] + p.tm[3 * a + 1] * p.cov3[3 + b] + p.tm[3 * a + 2] * p.cov3[6 + b];
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 3; ++b) dtm[3 * a + b] = 2 * (gs[2 * a] * tc[b] + gs[2 * a + 1] * tc[3 + b]);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        T sum = 0;
        for (int c = 0; c < 2; ++c)
          for (int e = 0; e < 2; ++e) sum += p.tm[3 * c + a] * gs[2 * c + e] * p.tm[3 * e + b];
        dcov[3 * a + b] = sum;
      }
    // Tm = J W: dJ = dTm Wᵀ; J's entries to the camera-frame centre.
    T dj[6];
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 3; ++b) dj[3 * a + b] = dtm[3 * a] * w[3 * b] + dtm[3 * a + 1] * w[3 * b + 1] + dtm[3 * a + 2] * w[3 * b + 2];
    const T z = p.pc[2], x = p.pc[0], y = p.pc[1];
    T dpc[3] = {0, 0, 0};
    dpc[2] += dj[0] * (-fx / (z * z)) + dj[2] * (fx * p.u / (z * z)) + dj[4] * (-fy / (z * z)) + dj[5] * (fy * p.v / (z * z));
    const T du = dj[2] * (-fx / z), dv = dj[5] * (-fy / z);
    if (p.u_free) dpc[0] += du / z, dpc[2] -= du * x / (z * z);
    if (p.v_free) dpc[1] += dv / z, dpc[2] -= dv * y / (z * z);
    // The image centre.
    const T dm0 = grad.mean2[2 * i], dm1 = grad.mean2[2 * i + 1];
    dpc[0] += dm0 * fx / z;
    dpc[1] += dm1 * fy / z;
    dpc[2] -= (dm0 * fx * x + dm1 * fy * y) / (z * z);
    for (int a = 0; a < 3; ++a) dmu[a] += w[a] * dpc[0] + w[3 + a] * dpc[1] + w[6 + a] * dpc[2];
    for (int a = 0; a < 3; ++a) dg[L::mean + a] += dmu[a];
    if (dpose) {
      auto& q = pose_part[i];
      // The centre: dpc · (pc × φ − ρ) = φ · (dpc × pc) − dpc · ρ.
      q[0] += dpc[1] * p.pc[2] - dpc[2] * p.pc[1];
      q[1] += dpc[2] * p.pc[0] - dpc[0] * p.pc[2];
      q[2] += dpc[0] * p.pc[1] - dpc[1] * p.pc[0];
      for (int a = 0; a < 3; ++a) q[3 + a] -= dpc[a];
      // W in Tm = J W: dW = Jᵀ dTm; ⟨dW, −[φ]ₓ W⟩ = −φ · (M₁₂ − M₂₁, M₂₀ − M₀₂, M₀₁ − M₁₀) with M = W dWᵀ.
      T dw[9], mm[9];
      for (int k = 0; k < 3; ++k)
        for (int b = 0; b < 3; ++b) dw[3 * k + b] = p.j[k] * dtm[b] + p.j[3 + k] * dtm[3 + b];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) mm[3 * r + c] = w[3 * r] * dw[3 * c] + w[3 * r + 1] * dw[3 * c + 1] + w[3 * r + 2] * dw[3 * c + 2];
      q[0] -= mm[5] - mm[7];
      q[1] -= mm[6] - mm[2];
      q[2] -= mm[1] - mm[3];
    }
    // Σ = M Mᵀ, M = R S: dM = 2 dΣ M (dΣ symmetric); the scales and the rotation.
    T dm[9], dr[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        dm[3 * a + b] =
            (dcov[3 * a] + dcov[a]) * p.m[b] + (dcov[3 * a + 1] + dcov[3 + a]) * p.m[3 + b] + (dcov[3 * a + 2] + dcov[6 + a]) * p.m[6 + b];
    for (int b = 0; b < 3; ++b) {
      T ds = 0;
      for (int a = 0; a < 3; ++a) {
        ds += p.r[3 * a + b] * dm[3 * a + b];
        dr[3 * a + b] = dm[3 * a + b] * p.s[b];
      }
      dg[L::log_scale + b] += ds * p.s[b];
    }
    T dqn[4];
    quat_to_matrix_backward(p.qn, dr, dqn);
    const T dot = dqn[0] * p.qn[0] + dqn[1] * p.qn[1] + dqn[2] * p.qn[2] + dqn[3] * p.qn[3];
    for (int a = 0; a < 4; ++a) dg[L::rotation + a] += (dqn[a] - p.qn[a] * dot) / p.qnorm;
  });
  if (dpose)
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < 6; ++k) (*dpose)[k] += static_cast<double>(pose_part[i][k]);
}

/// The pixels of one view rendered from a projection: the tiles that hold them filled with the Gaussians
/// whose footprint touches them, in depth order, then composited; with `keep` (training) what each pixel
/// composited is kept for backward.
template <class T, int C>
class Rasterizer {
 public:
  /// Renders the P pixels `px` (2P continuous coordinates) over the backdrop `bg` (C values): colour (C·P),
  /// expected depth (P; the composited depths, the backdrop counting 0) and opacity (P, 1 − the
  /// transmittance left).
  void forward(const Projection<T, C>& proj, const View& view, const T* px, std::size_t P, const T* bg, T* colour, T* depth, T* alpha,
               bool keep) {
    bin(proj, view, px, P);
    P_ = P;
    keep_ = keep;
    const int threads = std::max(1, thread_count());
    if (!keep) {
      forward_tiles(proj, px, P, bg, colour, depth, alpha);
      return;
    }
    records_.assign(static_cast<std::size_t>(threads), {});
    first_.assign(P + 1, 0);
    owner_.assign(P, 0);
    final_t_.assign(P, T(1));
    evals_.assign(static_cast<std::size_t>(threads), 0);
    parallel_blocks(P, 64, [&](std::size_t b, std::size_t e, int th) {
      auto& rec = records_[static_cast<std::size_t>(th)];
      std::size_t evals = 0;
      for (std::size_t p = b; p < e; ++p) {
        const std::size_t tile = pixel_tile_[p];
        const T ux = px[2 * p], uy = px[2 * p + 1];
        T tr = 1, col[C] = {}, dep = 0;
        if (keep) first_[p] = rec.size(), owner_[p] = th;
        std::size_t k = tile_begin_[tile];
        for (; k < tile_begin_[tile + 1]; ++k) {
          const std::uint32_t gi = list_[k];
          const T dx = ux - proj.mean2[2 * gi], dy = uy - proj.mean2[2 * gi + 1];
          const T power = T(-0.5) * (proj.conic[3 * gi] * dx * dx + proj.conic[3 * gi + 2] * dy * dy) - proj.conic[3 * gi + 1] * dx * dy;
          if (power > T(0)) continue;
          const T a = std::min(static_cast<T>(kMaxAlpha), proj.opacity[gi] * gaussian_exp(power));
          if (a < static_cast<T>(kMinAlpha)) continue;
          const T next = tr * (T(1) - a);
          if (next < static_cast<T>(kMinTransmittance)) break;
          const T wgt = a * tr;
          for (int c = 0; c < C; ++c) col[c] += proj.colour[C * gi + c] * wgt;
          dep += proj.depth[gi] * wgt;
          if (keep) rec.push_back({gi, a, tr});
          tr = next;
        }
        evals += std::min(k + 1, tile_begin_[tile + 1]) - tile_begin_[tile];  // the one that stopped the ray was tested too
        if (keep) last_[p] = rec.size();
        for (int c = 0; c < C; ++c) colour[C * p + c] = col[c] + tr * bg[c];
        if (depth) depth[p] = dep;
        if (alpha) alpha[p] = T(1) - tr;
        final_t_[p] = tr;
      }
      evals_[static_cast<std::size_t>(th)] = evals;
    });
  }

  /// The gradient of the loss for the projection and the backdrop (`dbg`, C values, added to), given its
  /// gradient `dcolour` (C·P) for the colours the last forward (with `keep`) rendered.
  void backward(const Projection<T, C>& proj, const T* px, const T* dcolour, const T* bg, ProjectionGrad<T, C>& grad, T* dbg) {
    require(keep_, "splat::Rasterizer::backward: the forward did not keep what it composited");
    const std::size_t n = proj.n;
    // parallel_blocks' split of the forward's pixels: `used` blocks, one a thread.
    const std::size_t used = std::clamp<std::size_t>(P_ / 64, 1, static_cast<std::size_t>(std::max(1, thread_count())));
    if (part_.size() < used) part_.resize(used);
    std::vector<std::array<T, C>> dbg_part(used);
    parallel_blocks(P_, 64, [&](std::size_t b, std::size_t e, int th) {
      auto& g = part_[static_cast<std::size_t>(th)];
      g.reset(n);
      auto& db = dbg_part[static_cast<std::size_t>(th)];
      db.fill(T(0));
      for (std::size_t p = b; p < e; ++p) {
        const auto& rec = records_[static_cast<std::size_t>(owner_[p])];
        const T* dc = dcolour + C * p;
        T acc[C];
        for (int c = 0; c < C; ++c) acc[c] = bg[c], db[c] += final_t_[p] * dc[c];
        const T ux = px[2 * p], uy = px[2 * p + 1];
        for (std::size_t k = last_[p]; k-- > first_[p];) {
          const auto& r = rec[k];
          const std::uint32_t gi = r.index;
          const T a = r.alpha, tb = r.transmittance;
          T da = 0;
          for (int c = 0; c < C; ++c) {
            const T ci = proj.colour[C * gi + c];
            da += tb * (ci - acc[c]) * dc[c];
            g.colour[C * gi + c] += a * tb * dc[c];
            acc[c] = a * ci + (T(1) - a) * acc[c];
          }
          const T dx = ux - proj.mean2[2 * gi], dy = uy - proj.mean2[2 * gi + 1];
          const T k0 = proj.conic[3 * gi], k1 = proj.conic[3 * gi + 1], k2 = proj.conic[3 * gi + 2];
          const T gauss = gaussian_exp(T(-0.5) * (k0 * dx * dx + k2 * dy * dy) - k1 * dx * dy);
          if (proj.opacity[gi] * gauss > static_cast<T>(kMaxAlpha)) continue;  // α held at its cap
          g.opacity[gi] += da * gauss;
          const T dp = da * a;
          g.mean2[2 * gi] += dp * (k0 * dx + k1 * dy);
          g.mean2[2 * gi + 1] += dp * (k1 * dx + k2 * dy);
          g.conic[3 * gi] += dp * T(-0.5) * dx * dx;
          g.conic[3 * gi + 1] -= dp * dx * dy;
          g.conic[3 * gi + 2] += dp * T(-0.5) * dy * dy;
        }
      }
    });
    // The threads' parts summed in thread order.
    grad.reset(n);
    for (std::size_t t = 0; t < used; ++t) {
      const auto& g = part_[t];
      parallel_for(n, 1 << 14, [&](std::size_t i) {
        grad.mean2[2 * i] += g.mean2[2 * i], grad.mean2[2 * i + 1] += g.mean2[2 * i + 1];
        for (int k = 0; k < 3; ++k) grad.conic[3 * i + k] += g.conic[3 * i + k];
        grad.opacity[i] += g.opacity[i];
        for (int c = 0; c < C; ++c) grad.colour[C * i + c] += g.colour[C * i + c];
      });
      if (dbg)
        for (int c = 0; c < C; ++c) dbg[c] += dbg_part[t][c];
    }
  }

  /// Pairs (Gaussian, tile) the last forward composited from: what binning cost.
  std::size_t pairs() const { return list_.size(); }
  /// Pairs (Gaussian, pixel) the last forward evaluated: what compositing cost (without `keep`, every
  /// pixel of a tile until all of them stopped).
  std::size_t evaluated() const {
    std::size_t s = 0;
    for (auto e : evals_) s += e;
    return s;
  }

 private:
  struct Record {
    std::uint32_t index;
    T alpha, transmittance;
  };

  /// Rendering without keeping: a tile's pixels side by side, each Gaussian of its list tested at all of
  /// them in one loop the compiler vectorizes (a pixel that has stopped takes no more), until every pixel
  /// of the tile has stopped. The same operations per pixel as the pixel loop (the compiler may fuse
  /// their multiply-adds differently), in the same order.
  void forward_tiles(const Projection<T, C>& proj, const T* px, std::size_t P, const T* bg, T* colour, T* depth, T* alpha) {
    // The pixels of each tile, in the order asked.
    const std::size_t tiles = tile_begin_.size() - 1;
    std::vector<std::size_t> start(tiles + 1, 0), order(P);
    for (std::size_t p = 0; p < P; ++p) ++start[pixel_tile_[p] + 1];
    for (std::size_t t = 0; t < tiles; ++t) start[t + 1] += start[t];
    {
      auto fill = start;
      for (std::size_t p = 0; p < P; ++p) order[fill[pixel_tile_[p]]++] = p;
    }
    final_t_.assign(P, T(1));
    std::vector<std::size_t> work;
    for (std::size_t t = 0; t < tiles; ++t)
      if (start[t + 1] > start[t]) work.push_back(t);
    const int threads = std::max(1, thread_count());
    std::vector<std::size_t> evals(static_cast<std::size_t>(threads), 0);
    struct Lanes {
      std::vector<T> ux, uy, tr, dep, col, live;  // live: 1 while the pixel's ray goes on, 0 once it stopped
    };
    std::vector<Lanes> lanes(static_cast<std::size_t>(threads));
    parallel_blocks(work.size(), 1, [&](std::size_t b, std::size_t e, int th) {
      Lanes& l = lanes[static_cast<std::size_t>(th)];
      std::size_t tested = 0;
      for (std::size_t w = b; w < e; ++w) {
        const std::size_t t = work[w], np = start[t + 1] - start[t];
        l.ux.resize(np), l.uy.resize(np), l.tr.assign(np, T(1)), l.dep.assign(np, T(0)), l.col.assign(C * np, T(0)),
            l.live.assign(np, T(1));
        for (std::size_t j = 0; j < np; ++j) l.ux[j] = px[2 * order[start[t] + j]], l.uy[j] = px[2 * order[start[t] + j] + 1];
        T* __restrict ux = l.ux.data();
        T* __restrict uy = l.uy.data();
        T* __restrict tr = l.tr.data();
        T* __restrict dep = l.dep.data();
        T* __restrict col = l.col.data();
        T* __restrict live = l.live.data();
        std::size_t alive = np;
        for (std::size_t k = tile_begin_[t]; k < tile_begin_[t + 1] && alive > 0; ++k) {
          const std::uint32_t gi = list_[k];
          const T mx = proj.mean2[2 * gi], my = proj.mean2[2 * gi + 1];
          const T k0 = proj.conic[3 * gi], k1 = proj.conic[3 * gi + 1], k2 = proj.conic[3 * gi + 2];
          const T o = proj.opacity[gi], z = proj.depth[gi];
          T ci[C];
          for (int c = 0; c < C; ++c) ci[c] = proj.colour[C * gi + c];
          tested += np;
#pragma omp simd
          for (std::size_t j = 0; j < np; ++j) {
            const T dx = ux[j] - mx, dy = uy[j] - my;
            const T power = T(-0.5) * (k0 * dx * dx + k2 * dy * dy) - k1 * dx * dy;
            const T g = o * gaussian_exp(power);
            const T a = g < static_cast<T>(kMaxAlpha) ? g : static_cast<T>(kMaxAlpha);
            const T next = tr[j] * (T(1) - a);
            // The pixel loop's branches as 0/1 factors, so that the loop has no control flow.
            const T hit = live[j] * (power <= T(0) ? T(1) : T(0)) * (a >= static_cast<T>(kMinAlpha) ? T(1) : T(0));
            const T stop = hit * (next < static_cast<T>(kMinTransmittance) ? T(1) : T(0));
            const T take = hit - stop;
            const T wgt = take * (a * tr[j]);
            for (int c = 0; c < C; ++c) col[C * j + c] += ci[c] * wgt;
            dep[j] += z * wgt;
            tr[j] = take > T(0) ? next : tr[j];
            live[j] -= stop;
          }
          if (((k - tile_begin_[t]) & 15) == 15) {
            alive = 0;
            for (std::size_t j = 0; j < np; ++j) alive += live[j] > T(0);
          }
        }
        for (std::size_t j = 0; j < np; ++j) {
          const std::size_t p = order[start[t] + j];
          for (int c = 0; c < C; ++c) colour[C * p + c] = col[C * j + c] + tr[j] * bg[c];
          if (depth) depth[p] = dep[j];
          if (alpha) alpha[p] = T(1) - tr[j];
          final_t_[p] = tr[j];
        }
      }
      evals[static_cast<std::size_t>(th)] = tested;
    });
    evals_ = evals;
  }

  /// The tile grid over the view's extent and the pixels' bounding box; each asked pixel's tile; for each
  /// tile that holds one, the visible Gaussians whose footprint box touches it, sorted by (depth, index).
  void bin(const Projection<T, C>& proj, const View& view, const T* px, std::size_t P) {
    require(proj.n < std::numeric_limits<std::uint32_t>::max(), "splat::Rasterizer: too many Gaussians");
    double x0 = 0, y0 = 0, x1 = view.width, y1 = view.height;
    for (std::size_t p = 0; p < P; ++p) {
      require(std::isfinite(px[2 * p]) && std::isfinite(px[2 * p + 1]), "splat::Rasterizer: a pixel coordinate is not finite");
      x0 = std::min<double>(x0, px[2 * p]), x1 = std::max<double>(x1, px[2 * p] + 1);
      y0 = std::min<double>(y0, px[2 * p + 1]), y1 = std::max<double>(y1, px[2 * p + 1] + 1);
    }
    ox_ = std::floor(x0), oy_ = std::floor(y0);
    tx_ = static_cast<long>(std::ceil((x1 - ox_) / kTile)), ty_ = static_cast<long>(std::ceil((y1 - oy_) / kTile));
    const std::size_t tiles = static_cast<std::size_t>(tx_ * ty_);
    active_.assign(tiles, 0);
    pixel_tile_.resize(P);
    for (std::size_t p = 0; p < P; ++p) {
      const long cx = std::clamp(static_cast<long>(std::floor((px[2 * p] - ox_) / kTile)), 0L, tx_ - 1);
      const long cy = std::clamp(static_cast<long>(std::floor((px[2 * p + 1] - oy_) / kTile)), 0L, ty_ - 1);
      pixel_tile_[p] = static_cast<std::size_t>(cy * tx_ + cx);
      active_[pixel_tile_[p]] = 1;
    }
    // Count, then place (a counting sort by tile), then sort each tile by depth.
    tile_begin_.assign(tiles + 1, 0);
    auto range = [&](std::size_t i, long& a0, long& a1, long& b0, long& b1) {
      const double mx = proj.mean2[2 * i], my = proj.mean2[2 * i + 1], ex = proj.extent[2 * i], ey = proj.extent[2 * i + 1];
      a0 = std::max(0L, static_cast<long>(std::floor((mx - ex - ox_) / kTile)));
      a1 = std::min(tx_ - 1, static_cast<long>(std::floor((mx + ex - ox_) / kTile)));
      b0 = std::max(0L, static_cast<long>(std::floor((my - ey - oy_) / kTile)));
      b1 = std::min(ty_ - 1, static_cast<long>(std::floor((my + ey - oy_) / kTile)));
    };
    for (std::size_t i = 0; i < proj.n; ++i) {
      if (!proj.visible[i]) continue;
      long a0, a1, b0, b1;
      range(i, a0, a1, b0, b1);
      for (long b = b0; b <= b1; ++b)
        for (long a = a0; a <= a1; ++a) {
          const std::size_t t = static_cast<std::size_t>(b * tx_ + a);
          if (active_[t]) ++tile_begin_[t + 1];
        }
    }
    for (std::size_t t = 0; t < tiles; ++t) tile_begin_[t + 1] += tile_begin_[t];
    list_.resize(tile_begin_[tiles]);
    fill_ = tile_begin_;
    for (std::size_t i = 0; i < proj.n; ++i) {
      if (!proj.visible[i]) continue;
      long a0, a1, b0, b1;
      range(i, a0, a1, b0, b1);
      for (long b = b0; b <= b1; ++b)
        for (long a = a0; a <= a1; ++a) {
          const std::size_t t = static_cast<std::size_t>(b * tx_ + a);
          if (active_[t]) list_[fill_[t]++] = static_cast<std::uint32_t>(i);
        }
    }
    parallel_for(tiles, 4, [&](std::size_t t) {
      if (tile_begin_[t + 1] - tile_begin_[t] < 2) return;
      std::sort(
          list_.begin() + static_cast<std::ptrdiff_t>(tile_begin_[t]), list_.begin() + static_cast<std::ptrdiff_t>(tile_begin_[t + 1]),
          [&](std::uint32_t a, std::uint32_t b) { return proj.depth[a] < proj.depth[b] || (proj.depth[a] == proj.depth[b] && a < b); });
    });
    last_.assign(P, 0);
  }

  double ox_ = 0, oy_ = 0;
  long tx_ = 0, ty_ = 0;
  std::vector<unsigned char> active_;
  std::vector<std::size_t> pixel_tile_, tile_begin_, fill_, first_, last_;
  std::vector<std::uint32_t> list_;
  std::vector<int> owner_;
  std::vector<std::vector<Record>> records_;
  std::vector<T> final_t_;
  std::vector<std::size_t> evals_;
  std::vector<ProjectionGrad<T, C>> part_;
  std::size_t P_ = 0;
  bool keep_ = false;
};

/// The plain reference of Rasterizer::forward: every visible Gaussian visited at every pixel, in (depth,
/// index) order, without tiles or footprints.
template <class T, int C>
void reference_composite(const Projection<T, C>& proj, const T* px, std::size_t P, const T* bg, T* colour, T* depth, T* alpha) {
  std::vector<std::uint32_t> order;
  for (std::size_t i = 0; i < proj.n; ++i)
    if (proj.visible[i]) order.push_back(static_cast<std::uint32_t>(i));
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return proj.depth[a] < proj.depth[b] || (proj.depth[a] == proj.depth[b] && a < b); });
  for (std::size_t p = 0; p < P; ++p) {
    T tr = 1, col[C] = {}, dep = 0;
    for (const std::uint32_t gi : order) {
      const T dx = px[2 * p] - proj.mean2[2 * gi], dy = px[2 * p + 1] - proj.mean2[2 * gi + 1];
      const T power = T(-0.5) * (proj.conic[3 * gi] * dx * dx + proj.conic[3 * gi + 2] * dy * dy) - proj.conic[3 * gi + 1] * dx * dy;
      if (power > T(0)) continue;
      const T a = std::min(static_cast<T>(kMaxAlpha), proj.opacity[gi] * gaussian_exp(power));
      if (a < static_cast<T>(kMinAlpha)) continue;
      const T next = tr * (T(1) - a);
      if (next < static_cast<T>(kMinTransmittance)) break;
      const T wgt = a * tr;
      for (int c = 0; c < C; ++c) col[c] += proj.colour[C * gi + c] * wgt;
      dep += proj.depth[gi] * wgt;
      tr = next;
    }
    for (int c = 0; c < C; ++c) colour[C * p + c] = col[c] + tr * bg[c];
    depth[p] = dep;
    alpha[p] = T(1) - tr;
  }
}

}  // namespace evnerf::splat
