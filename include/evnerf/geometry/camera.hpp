// geometry/camera.hpp — pinhole camera with radial-tangential (OpenCV "plumb bob") distortion; rays in
// world space. Depends on core/ and geometry/pose.hpp only.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>

#include "../core/error.hpp"
#include "pose.hpp"

namespace evnerf::geometry {

struct Ray {
  Vec3 origin;
  Vec3 dir;  ///< world-space direction with unit z in camera coordinates (so depth = t along the ray)
};

class Camera {
 public:
  Camera() = default;
  /// k = {k1, k2, p1, p2, k3} as in IJRR's calib.txt.
  Camera(int width, int height, double fx, double fy, double cx, double cy, std::array<double, 5> k = {0, 0, 0, 0, 0})
      : width_(width), height_(height), fx_(fx), fy_(fy), cx_(cx), cy_(cy), k_(k) {
    require(width > 0 && height > 0, "camera: sensor size must be positive");
    require(fx > 0 && fy > 0 && std::isfinite(cx) && std::isfinite(cy), "camera: bad intrinsics");
    for (double v : k) require_finite(v, "camera distortion coefficient");
  }
  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  const std::array<double, 5>& distortion() const { return k_; }
  bool distorted() const { return k_[0] != 0 || k_[1] != 0 || k_[2] != 0 || k_[3] != 0 || k_[4] != 0; }
  Camera resized(int w, int h) const {
    const double sx = double(w) / width_, sy = double(h) / height_;
    return Camera(w, h, fx_ * sx, fy_ * sy, cx_ * sx, cy_ * sy, k_);
  }

  /// Normalised coordinates (x/z, y/z) → distorted normalised coordinates.
  Vec2 distort_normalized(const Vec2& n) const {
    const double x = n.x(), y = n.y(), r2 = x * x + y * y;
    const double radial = 1 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[4]));
    const double p1 = k_[2], p2 = k_[3];
    return {x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y};
  }
  /// Distorted pixel → undistorted normalised coordinates (Newton iterations on the 2×2 Jacobian).
  Vec2 undistort_to_normalized(double u, double v) const {
    const Vec2 target((u - cx_) / fx_, (v - cy_) / fy_);
    if (!distorted()) return target;
    Vec2 n = target;
    for (int it = 0; it < 20; ++it) {
      const Vec2 f = distort_normalized(n) - target;
      if (f.squaredNorm() < 1e-24) break;
      const double h = 1e-7;
      Eigen::Matrix2d j;
      j.col(0) = (distort_normalized(n + Vec2(h, 0)) - distort_normalized(n - Vec2(h, 0))) / (2 * h);
      j.col(1) = (distort_normalized(n + Vec2(0, h)) - distort_normalized(n - Vec2(0, h))) / (2 * h);
      n -= j.partialPivLu().solve(f);
    }
    return n;
  }
  /// Undistorted normalised coordinates → distorted pixel.
  Vec2 project_normalized(const Vec2& n) const {
    const Vec2 d = distort_normalized(n);
    return {fx_ * d.x() + cx_, fy_ * d.y() + cy_};
  }
  /// Camera-frame point → distorted pixel (z must be positive).
  Vec2 project(const Vec3& p_cam) const { return project_normalized({p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z()}); }
  /// Pixel (u, v) (continuous, pixel centres at integer + 0.5 when called with x+0.5) → undistorted pixel.
  Vec2 undistort_pixel(double u, double v) const {
    const Vec2 n = undistort_to_normalized(u, v);
    return {fx_ * n.x() + cx_, fy_ * n.y() + cy_};
  }
  /// World-space ray through continuous pixel coordinate (u, v). Pass x + 0.5 for a pixel centre.
  Ray ray(const Pose& c2w, double u, double v) const {
    const Vec2 n = undistort_to_normalized(u, v);
    return ray_along(c2w, Vec3(n.x(), n.y(), 1.0));
  }
  /// World-space ray along a camera-frame direction with unit z: what ray() gives for the pixel that
  /// direction passes through (renderers cache the directions, render::pixel_directions, and call this).
  static Ray ray_along(const Pose& c2w, const Vec3& dir_cam) { return {c2w.t, c2w.q * dir_cam}; }

 private:
  int width_ = 0, height_ = 0;
  double fx_ = 1, fy_ = 1, cx_ = 0, cy_ = 0;
  std::array<double, 5> k_{};
};

/// The axis along which a scene point on the ray of camera-frame direction `dir` (unit z, as
/// render::pixel_directions gives) moves in the image from pose `from` to pose `to`, over the depths the
/// scene may hold: the major eigenvector of Σ_k f̂_k f̂_kᵀ, f̂_k the unit image displacement of the point at
/// depth z_k, `depths` depths spaced evenly in log between `near` and `far`. An axis, not a direction (a
/// point before the fixation distance and one behind it move in opposite senses along the same line), so
/// the unit vector's sign carries no meaning. Displacements under `min_px` pixels, and points behind or in
/// the plane of the second camera, do not vote; zero when none does (no motion).
inline Vec2 image_motion_axis(const Camera& cam, const Pose& from, const Pose& to, const Vec3& dir, double near, double far, int depths = 4,
                              double min_px = 1e-2) {
  near = std::max(near, 1e-6);
  far = std::max(far, near);
  const Pose rel = to.inverse() * from;  // camera `from` → camera `to`
  double a = 0, b = 0, c = 0;
  for (int k = 0; k < depths; ++k) {
    const double z = depths > 1 ? near * std::pow(far / near, double(k) / (depths - 1)) : std::sqrt(near * far);
    const Vec3 p0 = dir * z;
    const Vec3 p1 = rel.apply(p0);
    if (!(p1.z() > 1e-9 * z)) continue;
    const Vec2 f = cam.project(p1) - cam.project(p0);
    const double n = f.norm();
    if (!(n >= min_px)) continue;
    a += f.x() * f.x() / (n * n);
    b += f.x() * f.y() / (n * n);
    c += f.y() * f.y() / (n * n);
  }
  if (a + c == 0) return Vec2::Zero();
  const double theta = 0.5 * std::atan2(2 * b, a - c);
  return {std::cos(theta), std::sin(theta)};
}

}  // namespace evnerf::geometry
