// model/checkpoint.hpp — Model (model/model.hpp) as a checkpoint and back: the format is io/checkpoint.hpp;
// here the model's part of it (box and backdrop, parameters, Adam's moments, the parameter average, the
// representation's state (an occupancy grid), pose refinement's) and the checks a load makes (architecture, loss, counts, finite values) before the model
// changes.
// Included by model/model.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "../io/checkpoint.hpp"
#include "model.hpp"

namespace evnerf {

/// The model and its optimiser state as a checkpoint (io/checkpoint.hpp) named `name`, with `run`'s record
/// of what it was trained on.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
std::string Model<Rep, ThresholdP, NoiseP, ObjectiveP>::serialize(const std::string& name, const io::CheckpointRun& run) const {
  static_assert(std::is_same_v<Scalar, float>, "Model::serialize: checkpoints hold float models");
  io::CheckpointHeader h;
  h.name = name;
  h.n_slices = n_slices_;
  h.step = adam_.step();
  const auto& bx = box();
  const double boxv[6] = {bx.center.x(), bx.center.y(), bx.center.z(), bx.scale, bx.near, bx.far};
  std::copy(boxv, boxv + 6, h.box);
  h.density_length = bx.density_length;
  h.background = bx.background.value_or(std::numeric_limits<double>::quiet_NaN());
  h.background_learned = bx.background_learned;
  h.refractory = refractory_.seconds;
  h.refractory_m = refractory_.m;
  h.refractory_v = refractory_.v;
  h.refractory_learned = refractory_.learned;
  h.loss = loss_description();
  h.architecture = architecture();
  io::CheckpointPoses poses;
  if (poses_.active()) {
    poses.poses = poses_.settings.poses;
    poses.offset = poses_.settings.offset;
    poses.time_offset = poses_.offset;
    poses.offset_m = poses_.offset_m;
    poses.offset_v = poses_.offset_v;
    poses.correction = poses_.correction;
    poses.m = poses_.m;
    poses.v = poses_.v;
    poses.refined = refined_;
  }
  return io::write_checkpoint(
      h,
      {params_.values.data(), adam_.m().data(), adam_.v().data(), params_.size(), average_.active() ? average_.values().data() : nullptr,
       average_.decay(), renderer_.state(), std::move(poses)},
      run);
}

/// Restores from serialize()'s bytes; errors name the file and what does not match. The file must have
/// this model's architecture() and loss_description() (its variant name is a label); the model changes
/// only when the whole file has been read and checked. Returns the file's record of the run.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
io::CheckpointRun Model<Rep, ThresholdP, NoiseP, ObjectiveP>::deserialize(const std::string& b, const std::string& file) {
  static_assert(std::is_same_v<Scalar, float>, "Model::deserialize: checkpoints hold float models");
  io::CheckpointReader r(b, file);
  const io::CheckpointHeader h = io::read_checkpoint_header(r);
  if (h.architecture != architecture())
    r.fail("written by a model of another architecture ('" + h.architecture + "'; this model is '" + architecture() + "')");
  const std::uint64_t n = h.n_params;
  if (h.n_slices > n || n != renderer_type::n_params + 2 * h.n_slices)
    r.fail("parameter count does not match this model (" + std::to_string(n) + " in the file, " + std::to_string(renderer_type::n_params) +
           " + 2 per slice here)");
  if (n > r.remaining() / 12)  // parameters and Adam's two moments, 4 bytes each: refuse before allocating
    r.fail("truncated: " + std::to_string(n) + " parameters need " + std::to_string(n * 12) + " bytes, " + std::to_string(r.remaining()) +
           " remain");
  if (h.loss != loss_description()) r.fail("trained with the loss '" + h.loss + "', this model's is '" + loss_description() + "'");
  nn::ParameterBuffer<Scalar> params(n);
  nn::Adam<Scalar> adam(n, adam_.config());
  r.get(params.values.data(), n * 4);
  r.get(adam.m().data(), n * 4);
  r.get(adam.v().data(), n * 4);
  adam.set_step(h.step);
  nn::ParameterAverage<Scalar> average;
  const std::uint64_t m = r.u64();
  const double decay = r.f64();
  if (m != 0) {
    if (m != n) r.fail("the parameter average has " + std::to_string(m) + " values, the model " + std::to_string(n));
    if (!(decay > 0 && decay < 1)) r.fail("the parameter average's decay is not in (0, 1)");
    std::vector<Scalar> values(n);
    r.get(values.data(), n * 4);
    average = nn::ParameterAverage<Scalar>(decay, std::move(values));
  }
  // The checksum guards against damage, not against a writer that stored a NaN: training never writes one
  // (it stops on a non-finite loss or parameter first), so such a file is refused rather than rendered.
  auto finite = [&](const std::vector<Scalar>& v, const char* what, bool non_negative) {
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]) || (non_negative && v[i] < 0))
        r.fail(std::string(what) + " " + std::to_string(i) + " of " + std::to_string(v.size()) + " is " +
               (std::isfinite(v[i]) ? "negative"
                : std::isnan(v[i])  ? "NaN"
                                    : "infinite") +
               " (a checkpoint train writes holds only finite values)");
  };
  finite(params.values, "parameter", false);
  finite(adam.m(), "Adam's first moment of parameter", false);
  finite(adam.v(), "Adam's second moment of parameter", true);
  if (average.active()) finite(average.values(), "the parameter average's value", false);
  Rep rep;
  if (!rep.restore(r.str())) r.fail("the representation's state does not match this model's: " + Rep::state_name());
  const io::CheckpointPoses poses = io::read_checkpoint_poses(r, h.n_slices);
  io::CheckpointRun run = io::read_checkpoint_run(r);
  if (!run.times.empty() && run.times.size() != h.n_slices + 1)
    r.fail("the run records " + std::to_string(run.times.size()) + " slice boundaries for " + std::to_string(h.n_slices) + " slices");
  render::SceneBox bx;
  bx.center = Vec3(h.box[0], h.box[1], h.box[2]);
  bx.scale = h.box[3];
  bx.near = h.box[4];
  bx.far = h.box[5];
  bx.density_length = h.density_length;
  if (!std::isnan(h.background)) bx.background = h.background;
  bx.background_learned = h.background_learned;
  rep.box() = bx;
  renderer_ = std::move(rep);
  n_slices_ = h.n_slices;
  refractory_ = {};  // its bound (max) is not kept: the trainer reads it off the recording again
  refractory_.seconds = h.refractory < 0 ? -1.0 : std::min(h.refractory, RefractoryState::kMax);
  refractory_.m = h.refractory_m;
  refractory_.v = h.refractory_v;
  refractory_.learned = h.refractory_learned && h.refractory >= 0;
  poses_ = {};
  poses_.settings.poses = poses.poses;
  poses_.settings.offset = poses.offset;
  poses_.offset = poses.time_offset;
  poses_.offset_m = poses.offset_m;
  poses_.offset_v = poses.offset_v;
  poses_.correction = poses.correction;
  poses_.m = poses.m;
  poses_.v = poses.v;
  refined_ = poses.refined;
  pose_grad_.clear();
  params_ = std::move(params);
  adam_ = std::move(adam);
  average_ = std::move(average);
  return run;
}

}  // namespace evnerf
