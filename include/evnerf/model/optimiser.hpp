// model/optimiser.hpp — the optimiser step of EvNerf (model/model.hpp), after gradients(): Adam on every
// field parameter and, lazily, on the thresholds of the slices the step touched; thresholds of a projected
// policy kept beyond their floor; the parameter average updated. Included by model/model.hpp. Depends on
// nn/params.hpp.
#pragma once
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
  if (average_.active()) average_.update(params_.values, adam_.step());
}

}  // namespace evnerf
