// geometry/trajectory.hpp — timestamped camera-to-world poses with interpolation and an explicit policy
// for times outside the covered range. Depends on core/ and geometry/pose.hpp only.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "pose.hpp"

namespace evnerf::geometry {

/// What pose_at does for a time outside [front, back].
enum class OutOfRange { Error, Clamp };

class Trajectory {
 public:
  Trajectory() = default;
  /// Times in seconds, strictly increasing, one pose each.
  Trajectory(std::vector<double> t, std::vector<Pose> poses, std::string source = "trajectory")
      : t_(std::move(t)), poses_(std::move(poses)), source_(std::move(source)) {
    require(t_.size() == poses_.size(), source_ + ": times and poses differ in count");
    for (std::size_t i = 1; i < t_.size(); ++i)
      if (!(t_[i] > t_[i - 1])) throw Error(source_ + ": pose times must increase strictly (pose " + std::to_string(i) + ")");
  }
  std::size_t size() const { return t_.size(); }
  bool empty() const { return t_.empty(); }
  double front() const { return t_.front(); }
  double back() const { return t_.back(); }
  const std::vector<double>& times() const { return t_; }
  const std::vector<Pose>& poses() const { return poses_; }
  bool covers(double t) const { return !empty() && t >= t_.front() && t <= t_.back(); }

  /// Pose at time t (seconds): linear translation, slerp rotation between the neighbouring samples.
  Pose pose_at(double t, OutOfRange policy = OutOfRange::Error) const {
    if (empty()) throw Error(source_ + ": no poses");
    if (!covers(t)) {
      if (policy == OutOfRange::Error)
        throw Error(source_ + ": time " + short_number(t) + " s is outside the poses' range [" + short_number(t_.front()) + ", " +
                    short_number(t_.back()) + "] s");
      return t < t_.front() ? poses_.front() : poses_.back();
    }
    auto it = std::upper_bound(t_.begin(), t_.end(), t);
    if (it == t_.end()) return poses_.back();
    const std::size_t i = static_cast<std::size_t>(it - t_.begin());
    if (i == 0) return poses_.front();
    const double s = (t - t_[i - 1]) / (t_[i] - t_[i - 1]);
    return Pose::interpolate(poses_[i - 1], poses_[i], s);
  }

 private:
  std::vector<double> t_;
  std::vector<Pose> poses_;
  std::string source_;
};

/// Pose errors of `poses` against `truth` (same knots): the mean and largest translation error (world units)
/// and rotation error (degrees).
struct PoseError {
  double translation_mean = 0, translation_max = 0, rotation_mean_deg = 0, rotation_max_deg = 0;
};
inline PoseError pose_error(const std::vector<Pose>& poses, const std::vector<Pose>& truth) {
  require(poses.size() == truth.size() && !poses.empty(), "pose_error: the poses and the true poses differ in count");
  PoseError e;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const double dt = (poses[i].t - truth[i].t).norm();
    const double dr = Eigen::AngleAxisd((truth[i].q.conjugate() * poses[i].q).normalized()).angle() * 180.0 / 3.14159265358979323846;
    const double r = std::min(dr, 360.0 - dr);
    e.translation_mean += dt / poses.size();
    e.rotation_mean_deg += r / poses.size();
    e.translation_max = std::max(e.translation_max, dt);
    e.rotation_max_deg = std::max(e.rotation_max_deg, r);
  }
  return e;
}

}  // namespace evnerf::geometry
