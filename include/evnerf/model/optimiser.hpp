// model/optimiser.hpp — the optimiser step of Model (model/model.hpp), after gradients(): Adam on every
// field parameter and, lazily, on the thresholds of the slices the step touched; thresholds of a projected
// policy kept beyond their floor; a learned refractory period moved by its own Adam; the parameter average
// updated; pose refinement's corrections and offset moved by their Adam. Included by model/model.hpp. Depends on nn/params.hpp.
#pragma once
#include <algorithm>
#include <cmath>

#include "model.hpp"

namespace evnerf {

template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
void Model<Rep, ThresholdP, NoiseP, ObjectiveP>::apply_update(const TrainingData& data) {
  // The field's parameters all move; of the thresholds only the step's windows' slices' (lazy Adam).
  adam_.update(params_.values, params_.grads, threshold_offset(), touched_);
  for (std::size_t t = 0; t + 1 < touched_.size(); t += 2) {
    Scalar& bp = params_.values[touched_[t]];
    Scalar& bm = params_.values[touched_[t + 1]];
    if constexpr (requires { ThresholdP::projected; }) {
      bp = std::max(bp, static_cast<Scalar>(ThresholdP::init));
      bm = std::min(bm, static_cast<Scalar>(-ThresholdP::init));
    }
  }
  if (refractory_.learned) {  // its own Adam, in seconds, kept within [0, max]
    const auto& c = adam_.config();
    const double g = last_refractory_grad_, t = static_cast<double>(adam_.step());
    auto& r = refractory_;
    r.m = c.beta1 * r.m + (1 - c.beta1) * g;
    r.v = c.beta2 * r.v + (1 - c.beta2) * g * g;
    const double mh = r.m / (1 - std::pow(c.beta1, t)), vh = r.v / (1 - std::pow(c.beta2, t));
    r.seconds = std::clamp(r.seconds - RefractoryState::kLr * mh / (std::sqrt(vh) + 1e-12), 0.0, r.max);
  }
  if (poses_.active()) update_poses(data);
  if (average_.active()) average_.update(params_.values, adam_.step());
}

}  // namespace evnerf

namespace evnerf {

/// Pose refinement's Adam (the field's betas, its own step sizes): a knot's correction moves when the step
/// gave it a gradient (lazily, like the thresholds), by the twist −step ∘ its correction; the first knot
/// stays (the gauge). The offset moves every step it is learned.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
void Model<Rep, ThresholdP, NoiseP, ObjectiveP>::update_poses(const TrainingData& data) {
  const auto& c = adam_.config();
  const double t = static_cast<double>(adam_.step());
  const double c1 = 1 - std::pow(c.beta1, t), c2 = 1 - std::pow(c.beta2, t);
  auto& s = poses_.settings;
  const double f = s.decay(adam_.step() - 1);  // the step just taken
  if (f == 0) return;                          // the moments start with the poses' first move
  if (s.poses)
    for (std::size_t i = 1; i < pose_grad_.size(); ++i) {
      const auto& g = pose_grad_[i];
      if (g == std::array<double, 6>{}) continue;
      Vec3 phi, rho;
      for (int k = 0; k < 6; ++k) {
        double& m = poses_.m[i][k];
        double& v = poses_.v[i][k];
        m = c.beta1 * m + (1 - c.beta1) * g[k];
        v = c.beta2 * v + (1 - c.beta2) * g[k] * g[k];
        const double step = (m / c1) / (std::sqrt(v / c2) + 1e-12);
        if (k < 3) phi[k] = -f * s.lr_rotation * step;
        else rho[k - 3] = -f * s.lr_translation * step;
      }
      poses_.correction[i] = poses_.correction[i] * twist_exp(phi, rho);
    }
  if (s.offset) {
    const double g = offset_grad_;
    poses_.offset_m = c.beta1 * poses_.offset_m + (1 - c.beta1) * g;
    poses_.offset_v = c.beta2 * poses_.offset_v + (1 - c.beta2) * g * g;
    poses_.offset -= f * s.lr_offset * (poses_.offset_m / c1) / (std::sqrt(poses_.offset_v / c2) + 1e-12);
  }
  refresh_poses(data);
}

}  // namespace evnerf
