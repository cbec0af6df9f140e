// geometry/pose.hpp — rigid camera-to-world transforms (OpenCV camera axes: x right, y down, z forward).
// Depends on core/ only.
#pragma once
#include "../core/types.hpp"

namespace evnerf::geometry {

/// Camera-to-world rigid transform: p_world = R * p_cam + t.
struct Pose {
  Quat q = Quat::Identity();
  Vec3 t = Vec3::Zero();

  static Pose identity() { return {}; }
  static Pose from_matrix(const Eigen::Matrix4d& m) {
    Pose p;
    p.q = Quat(m.topLeftCorner<3, 3>()).normalized();
    p.t = m.topRightCorner<3, 1>();
    return p;
  }
  Mat3 rotation() const { return q.toRotationMatrix(); }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = rotation();
    m.topRightCorner<3, 1>() = t;
    return m;
  }
  Pose inverse() const {
    Pose p;
    p.q = q.conjugate();
    p.t = -(p.q * t);
    return p;
  }
  Pose operator*(const Pose& o) const {
    Pose p;
    p.q = (q * o.q).normalized();
    p.t = q * o.t + t;
    return p;
  }
  Vec3 apply(const Vec3& x) const { return q * x + t; }

  /// Interpolates between a (s=0) and b (s=1): linear translation, quaternion slerp.
  static Pose interpolate(const Pose& a, const Pose& b, double s) {
    Pose p;
    p.q = a.q.slerp(s, b.q).normalized();
    p.t = (1 - s) * a.t + s * b.t;
    return p;
  }
  /// Builds a camera looking from `eye` at `target`; `up` is the world's up direction.
  static Pose look_at(const Vec3& eye, const Vec3& target, const Vec3& up) {
    Vec3 z = (target - eye).normalized();
    Vec3 x = z.cross(up).normalized();  // OpenCV: x right
    if (!x.allFinite() || x.norm() < 1e-9) x = z.unitOrthogonal();
    Vec3 y = z.cross(x);  // y down
    Mat3 r;
    r << x, y, z;
    Pose p;
    p.q = Quat(r).normalized();
    p.t = eye;
    return p;
  }
};

/// Converts an OpenGL/Blender camera-to-world (x right, y up, z backward) to our OpenCV convention.
inline Pose from_opengl(const Eigen::Matrix4d& c2w_gl) {
  Eigen::Matrix4d flip = Eigen::Matrix4d::Identity();
  flip(1, 1) = -1;
  flip(2, 2) = -1;
  return Pose::from_matrix(c2w_gl * flip);
}
inline Eigen::Matrix4d to_opengl(const Pose& p) {
  Eigen::Matrix4d flip = Eigen::Matrix4d::Identity();
  flip(1, 1) = -1;
  flip(2, 2) = -1;
  return p.matrix() * flip;
}

}  // namespace evnerf::geometry
