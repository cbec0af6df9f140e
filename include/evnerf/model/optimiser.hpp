// model/optimiser.hpp — the optimiser step of EvNerf (model/model.hpp), after gradients(): Adam on every
// field parameter and, lazily, on the thresholds of the slices the step touched; thresholds of a projected
// policy kept beyond their floor; a learned refractory period moved by its own Adam; the parameter average
// updated. Included by model/model.hpp. Depends on nn/params.hpp.
#pragma once
#include <algorithm>
#include <cmath>

#include "model.hpp"

namespace evnerf {

template <class FieldT, render::Sampler SamplerT, class ThresholdP, class NoiseP, class ObjectiveP, class Scalar>
void EvNerf<FieldT, SamplerT, ThresholdP, NoiseP, ObjectiveP, Scalar>::apply_update() {
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
  if (refractory_.learned) {  // its own Adam, in seconds, kept within [0, kMax]
    const auto& c = adam_.config();
    const double g = last_refractory_grad_, t = static_cast<double>(adam_.step());
    auto& r = refractory_;
    r.m = c.beta1 * r.m + (1 - c.beta1) * g;
    r.v = c.beta2 * r.v + (1 - c.beta2) * g * g;
    const double mh = r.m / (1 - std::pow(c.beta1, t)), vh = r.v / (1 - std::pow(c.beta2, t));
    r.seconds = std::clamp(r.seconds - RefractoryState::kLr * mh / (std::sqrt(vh) + 1e-12), 0.0, RefractoryState::kMax);
  }
  if (average_.active()) average_.update(params_.values, adam_.step());
}

}  // namespace evnerf
