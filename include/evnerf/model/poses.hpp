// model/poses.hpp — pose refinement: the poses a model renders its training rays from, when the recording's
// are only roughly known. Each pose knot (a slice boundary) carries a rigid correction in its camera's frame,
// and one clock offset shifts every knot along the recording's trajectory:
//   corrected pose i = trajectory(t_i + offset) ∘ correction_i,
// learned with the field by an Adam of their own (per knot: a rotation and a translation step size; the
// offset's in seconds). A correction moves by a twist ε = (φ, ρ) in the camera's frame, pose ∘ Exp(ε)
// (rotation by the rotation vector φ, translation by ρ), and its gradient is the loss's for ε at 0: a ray
// (o, d) of camera-frame direction k moves by do = R ρ, dd = R (φ × k). The first knot's correction is held at
// the identity, which fixes the scene's frame (the gauge). Depends on core/ and geometry/ only.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "../geometry/pose.hpp"
#include "../geometry/trajectory.hpp"

namespace evnerf {

/// What pose refinement learns and how fast (EvNerf::set_pose_refinement; train::Config's refine_poses,
/// pose_lr_rotation, pose_lr_translation, learn_time_offset, time_offset_lr).
struct PoseRefinementSettings {
  bool poses = false;            ///< learn a correction per knot
  bool offset = false;           ///< learn the clock offset between the events and the poses
  double lr_rotation = 5e-4;     ///< Adam's step size for a correction's rotation, radians
  double lr_translation = 2e-4;  ///< Adam's step size for a correction's translation, world units
  double lr_offset = 2e-4;       ///< Adam's step size for the offset, seconds
  /// The step sizes fall exponentially to a hundredth over this many steps, and stay there: a pose
  /// gradient is noisy (a step's few pixels), and what is left of the step size at the end is the
  /// corrections' jitter.
  double decay_steps = 6000;
  /// The levels of a multiresolution position encoding (nn::HashGrid) the pose gradient goes through, the
  /// coarsest first (0: all): the fine levels add sharp, noisy gradients and cost the most.
  int levels = 8;
  /// Steps the field trains on the given poses before they move: a pose gradient through a field that
  /// shows nothing yet is noise.
  long start = 1000;
  /// A pull of each correction toward the given pose: a step's loss holds ½ κ_r |φ|² + ½ κ_t |t|² for the
  /// correction (rotation vector φ, translation t) of every knot it renders from. Events leave some motions
  /// nearly unobserved (along the optical axis, before a scene seen from afar); without the pull the
  /// corrections drift along them with the field, and on exact poses that costs more than it gains.
  double prior_rotation = 10, prior_translation = 10;
  bool active() const { return poses || offset; }
  /// The factor on the step sizes at `step` (0 before `start`).
  double decay(long step) const {
    if (step < start) return 0;
    return std::pow(0.01, std::min(1.0, static_cast<double>(step - start) / decay_steps));
  }
};

/// The state of pose refinement: the corrections (per knot), the offset, their Adam moments (a twist's
/// rotation x y z, then translation x y z), and the poses they give.
struct PoseRefinement {
  PoseRefinementSettings settings;
  std::vector<geometry::Pose> correction;  ///< per knot, in its camera's frame
  std::vector<std::array<double, 6>> m, v;
  double offset = 0, offset_m = 0, offset_v = 0;  ///< seconds: knot i's pose is the trajectory's at t_i + offset
  bool active() const { return settings.active(); }
};

/// The prior's loss for one correction c, ½ κ_r |φ|² + ½ κ_t |t|² (φ the rotation vector of c, t its
/// translation), and its gradient for the twist ε at 0 of c ∘ Exp(ε): (κ_r φ, κ_t Rcᵀ t). The rotation's is
/// exact, not a small-angle approximation: Log(R Exp(δ)) = φ + J_r⁻¹(φ) δ + …, and J_r⁻ᵀ(φ) φ = φ.
inline double pose_prior(const PoseRefinementSettings& s, const geometry::Pose& c, std::array<double, 6>& grad) {
  const Eigen::AngleAxisd aa(c.q.normalized());  // the angle in [0, π]
  const Vec3 phi = aa.axis() * aa.angle();
  const Vec3 gt = c.q.conjugate() * c.t;
  for (int k = 0; k < 3; ++k) {
    grad[k] += s.prior_rotation * phi[k];
    grad[3 + k] += s.prior_translation * gt[k];
  }
  return 0.5 * (s.prior_rotation * phi.squaredNorm() + s.prior_translation * c.t.squaredNorm());
}

/// The twist (φ, ρ) of Exp as pose ∘ Exp(φ, ρ) uses it: rotation by the rotation vector φ, then ρ.
inline geometry::Pose twist_exp(const Vec3& phi, const Vec3& rho) {
  geometry::Pose e;
  const double a = phi.norm();
  e.q = a > 0 ? Quat(Eigen::AngleAxisd(a, phi / a)) : Quat::Identity();
  e.t = rho;
  return e;
}

/// The trajectory's velocity at time t as a twist in its camera's frame (pose(t + dt) ≈ pose(t) ∘ Exp(η dt)),
/// for the interpolation Trajectory::pose_at does (constant within a segment: the rotation's slerp turns at
/// a constant rate about one axis, the translation is linear). Zero outside the trajectory's range (its
/// poses are clamped there) and where it has one pose.
inline std::array<double, 6> trajectory_velocity(const geometry::Trajectory& traj, double t) {
  std::array<double, 6> eta{};
  const auto& ts = traj.times();
  if (ts.size() < 2 || !(t >= ts.front() && t < ts.back())) return eta;
  const std::size_t i = static_cast<std::size_t>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin());  // t in [ts[i-1], ts[i])
  const auto& a = traj.poses()[i - 1];
  const auto& b = traj.poses()[i];
  const double dt = ts[i] - ts[i - 1];
  Quat rel = a.q.conjugate() * b.q;
  if (rel.w() < 0) rel.coeffs() = -rel.coeffs();  // the slerp's shorter arc
  const Eigen::AngleAxisd aa(rel.normalized());
  const Vec3 omega = aa.axis() * (aa.angle() / dt);  // body rate, the same at every s of the segment
  const Vec3 v_world = (b.t - a.t) / dt;
  const Vec3 rho = traj.pose_at(t).q.conjugate() * v_world;
  for (int k = 0; k < 3; ++k) {
    eta[k] = omega[k];
    eta[3 + k] = rho[k];
  }
  return eta;
}

/// A twist in the frame of pose P moved to the frame of P ∘ C: Ad(C⁻¹) (φ, ρ) = (Rcᵀ φ, Rcᵀ (ρ + φ × tc)).
inline std::array<double, 6> twist_through(const geometry::Pose& c, const std::array<double, 6>& eta) {
  const Vec3 phi(eta[0], eta[1], eta[2]), rho(eta[3], eta[4], eta[5]);
  const Vec3 p = c.q.conjugate() * phi, r = c.q.conjugate() * (rho + phi.cross(c.t));
  return {p.x(), p.y(), p.z(), r.x(), r.y(), r.z()};
}

/// The knots' poses under `ref`: the given poses (the trajectory's at the knots' times) with their
/// corrections, or the trajectory's at the shifted times when an offset is learned or held.
inline std::vector<geometry::Pose> refined_poses(const PoseRefinement& ref, const std::vector<geometry::Pose>& given,
                                                 const std::vector<double>& times, const geometry::Trajectory& traj) {
  std::vector<geometry::Pose> out(given.size());
  const bool shifted = ref.offset != 0;
  require(!shifted || !traj.empty(), "pose refinement: a clock offset needs the recording's trajectory");
  for (std::size_t i = 0; i < given.size(); ++i) {
    const geometry::Pose base = shifted ? traj.pose_at(times[i] + ref.offset, geometry::OutOfRange::Clamp) : given[i];
    out[i] = ref.correction.empty() ? base : base * ref.correction[i];
  }
  return out;
}

}  // namespace evnerf
