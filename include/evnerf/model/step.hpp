// model/step.hpp — a training step of Model (model/model.hpp): the representation's preparation (a
// sampler's refresh), the step's draw of a window of slices, pixels and noise (loss::draw_step), the tiles
// of pixels rendered by the representation and handed to the objective in parallel, per-thread gradients
// reduced in a fixed order, the threshold floor, and the shards of a data-parallel step summed across
// processes (train/group.hpp's exchange). Included by model/model.hpp. Depends on ad/ (the threshold floor),
// loss/ and core/.
#pragma once
#include "model.hpp"

namespace evnerf {

/// update_sampler: the representation prepared for step `step` (a ray-marcher's sampler refreshed from the
/// poses the training rays start at).
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
void Model<Rep, ThresholdP, NoiseP, ObjectiveP>::update_sampler(const TrainingData& data, long step, std::uint64_t seed) {
  if constexpr (requires { renderer_.prepare_step(params_.values.data(), data, training_poses(data), step, seed); })
    renderer_.prepare_step(params_.values.data(), data, training_poses(data), step, seed);
}

/// train_step over shards: this process's shards, their gradients summed in shard order, exchanged with the
/// other processes, averaged; then the optimiser step.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
template <class Exchange>
StepStats Model<Rep, ThresholdP, NoiseP, ObjectiveP>::train_step(const TrainingData& data, int pixels_per_step, std::uint64_t seed,
                                                                 int pixels_per_tile, const StepShards& shards, Exchange&& exchange) {
  check_data(data);
  require(shards.count >= 1 && shards.ranks >= 1 && shards.count % shards.ranks == 0 && shards.rank >= 0 && shards.rank < shards.ranks,
          "train_step: the shards per step (" + std::to_string(shards.count) + ") must be a positive multiple of the processes (" +
              std::to_string(shards.ranks) + ")");
  const long s = adam_.step();
  update_sampler(data, s, Rng(seed).split(static_cast<std::uint64_t>(s)).split(0xCCu).next_u64());
  StepStats st;
  if (shards.count == 1) {
    st = gradients(data, pixels_per_step, seed, pixels_per_tile);
  } else {
    // This process's shards, their gradients summed in shard order, their statistics and touched slices.
    std::vector<double> totals(kTotals + n_slices_, 0.0);
    const std::size_t pose_at = totals.size();  // then pose refinement's gradients (knots × 6, offset)
    if (poses_.active()) totals.resize(pose_at + 6 * (n_slices_ + 1) + 1, 0.0);
    bool first = true;
    for (int k = shards.rank; k < shards.count; k += shards.ranks) {
      if (!first) {  // keep the sum so far; gradients() overwrites grads
        shard_sum_.resize(params_.grads.size());
        shard_sum_.swap(params_.grads);
      }
      const StepStats one = gradients(data, pixels_per_step, seed, pixels_per_tile, k);
      if (!first) {
        Scalar* g = params_.grads.data();
        const Scalar* a = shard_sum_.data();
        parallel_blocks(params_.grads.size(), 1 << 16, [&](std::size_t b, std::size_t e, int) {
          for (std::size_t i = b; i < e; ++i) g[i] = a[i] + g[i];
        });
      }
      first = false;
      add_totals(totals, one);
      for (std::size_t j = 0; j < one.window; ++j) totals[kTotals + one.first_slice + j] += 1;
      if (poses_.active()) {
        for (std::size_t i = 0; i < pose_grad_.size(); ++i)
          for (int k = 0; k < 6; ++k) totals[pose_at + 6 * i + k] += pose_grad_[i][k];
        totals.back() += offset_grad_;
      }
    }
    exchange(params_.grads, totals);
    if (poses_.active()) {
      for (std::size_t i = 0; i < pose_grad_.size(); ++i)
        for (int k = 0; k < 6; ++k) pose_grad_[i][k] = totals[pose_at + 6 * i + k] / shards.count;
      offset_grad_ = totals.back() / shards.count;
      totals.resize(pose_at);
    }
    st = from_totals(totals, shards.count);
    touched_.clear();
    for (std::size_t j = 0; j < n_slices_; ++j)
      if (totals[kTotals + j] > 0) {
        touched_.push_back(threshold_offset() + 2 * j);
        touched_.push_back(threshold_offset() + 2 * j + 1);
      }
    if (!std::isfinite(st.loss)) return st;
    const Scalar inv = static_cast<Scalar>(1.0 / shards.count);
    for (auto& g : params_.grads) g *= inv;
  }
  if (!std::isfinite(st.loss)) return st;
  last_refractory_grad_ = st.refractory_grad;
  apply_update(data);
  // The representation's upkeep after the step (a Gaussian scene's densification and pruning), from what
  // every process holds alike: the parameters and the exchanged gradient.
  if constexpr (requires { renderer_.after_step(params_.values, params_.grads, adam_, average_, data, s, seed); })
    renderer_.after_step(params_.values, params_.grads, adam_, average_, data, s, seed);
  return st;
}

/// gradients: the step's draw (window, pixels, noise), its tiles rendered and scored in parallel with
/// per-thread gradients reduced in a fixed order, the deferred table gradients flushed, the threshold floor.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
StepStats Model<Rep, ThresholdP, NoiseP, ObjectiveP>::gradients(const TrainingData& data, int pixels_per_step, std::uint64_t seed,
                                                                int pixels_per_tile, int shard) {
  check_data(data);
  const long s = adam_.step();
  Rng rng = Rng(seed).split(static_cast<std::uint64_t>(s));
  if (shard > 0) rng = rng.split(0x5348415244000000ull + static_cast<std::uint64_t>(shard));
  StepWindow& sw = window_;
  loss::draw_step<objective_type>(data.slices, data.slice_enabled, data.prefix, NoiseP::ratio, pixels_per_step, rng, sw, &data.sites,
                                  data.slices_per_interval, refractory_.seconds);
  const std::size_t first = sw.first, L = sw.len;
  const int P = static_cast<int>(sw.pixels.size());
  const int tile = pixels_per_tile > 0 ? pixels_per_tile : Rep::default_tile_pixels(P);
  const int n_tiles = (P + tile - 1) / tile;
  const int threads = std::max(1, std::min(thread_count(), n_tiles));
  params_.size_accumulators(threads);  // each thread zeroes its own below
  std::vector<double> loss_ev(threads, 0.0), grad_tau(threads, 0.0);
  std::vector<std::array<double, StepStats::kMaxTerms>> loss_terms(threads);
  std::vector<std::size_t> evaluated(threads, 0), backward(threads, 0), rays(threads, 0);
  std::vector<std::array<double, 2>> pass_loss(threads);
  const std::uint64_t ray_key = rng.next_u64();
  if (work_.size() < static_cast<std::size_t>(threads)) work_.resize(static_cast<std::size_t>(threads));
  parallel_blocks(static_cast<std::size_t>(n_tiles), 1, [&](std::size_t b, std::size_t e, int th) {
    params_.zero_accumulator(th);
    TileWork& w = work_[static_cast<std::size_t>(th)];  // buffers reused from step to step
    w.pass_loss = {};
    w.refractory_grad = 0;
    w.terms = {};
    w.rays = 0;
    if (poses_.active()) w.pose_grad.assign(n_slices_ + 1, {});
    Rep::begin_step(w.rw, TrainSettings{ray_termination_, ray_cut_});
    for (std::size_t t = b; t < e; ++t) {
      const int p0 = static_cast<int>(t) * tile, p1 = std::min(P, p0 + tile);
      loss_ev[th] += train_tile(data, sw, p0, p1 - p0, P, ray_key, params_.per_thread[th].data(), w);
    }
    evaluated[th] = Rep::evaluated(w.rw);
    pass_loss[th] = w.pass_loss;
    grad_tau[th] = w.refractory_grad;
    loss_terms[th] = w.terms;
    rays[th] = w.rays;
    backward[th] = Rep::backward_samples(w.rw);
  });
  // The table gradients each thread held back, applied in parts (a hash grid's levels) shared out by
  // their samples: each thread's accumulator gets the same additions in the same order whichever thread
  // applies them, and the threads, whose tiles differ in samples, finish together.
  constexpr int parts = Rep::flush_parts;
  if constexpr (parts > 0)
    parallel_jobs_by_cost(
        static_cast<std::size_t>(threads) * parts, [&](std::size_t j) { return Rep::flush_cost(work_[j / parts].rw); },
        [&](std::size_t j) { Rep::flush(work_[j / parts].rw, static_cast<int>(j % parts)); });
  for (int th = 0; th < threads; ++th) Rep::end_step(work_[static_cast<std::size_t>(th)].rw);
  params_.end_accumulate(threads);
  double prior = 0;
  if (poses_.active()) {  // the threads' pose gradients in thread order; the first knot held (the gauge)
    pose_grad_.assign(n_slices_ + 1, {});
    for (int th = 0; th < threads; ++th)
      for (std::size_t i = 0; i < pose_grad_.size(); ++i)
        for (int k = 0; k < 6; ++k) pose_grad_[i][k] += work_[static_cast<std::size_t>(th)].pose_grad[i][k];
    offset_grad_ = poses_.settings.offset ? offset_gradient_of(data) : 0.0;
    pose_grad_[0] = {};
    if (!poses_.settings.poses)
      for (auto& g : pose_grad_) g = {};
    else  // the pull toward the given poses, on the knots the step rendered from (those with a gradient)
      for (std::size_t i = 1; i < pose_grad_.size(); ++i)
        if (pose_grad_[i] != std::array<double, 6>{}) prior += pose_prior(poses_.settings, poses_.correction[i], pose_grad_[i]);
  }
  StepStats st;
  st.pose_prior_loss = prior;
  st.first_slice = first;
  st.window = L;
  for (double l : loss_ev) st.event_loss += l;
  for (double g : grad_tau) st.refractory_grad += g;
  for (const auto& l : loss_terms)
    for (int k = 1; k < n_terms; ++k) st.term_loss[k] += l[k];
  for (const auto& l : pass_loss)
    for (int net = 0; net < 2; ++net) st.pass_event_loss[net] += l[net];
  for (std::size_t e : evaluated) st.samples += e;
  for (std::size_t e : backward) st.backward_samples += e;
  // Threshold floor on every slice of the window (λ = 1000 for joint training, floor at the policy's
  // initial value; fixed thresholds get no gradient at all).
  for (std::size_t k = 0; k < L; ++k) {
    const std::size_t to = threshold_offset() + 2 * (first + k);
    if constexpr (ThresholdP::learnable && ThresholdP::lambda > 0) {
      const auto fl =
          ad::value_and_grad(loss::ThresholdFloor{ThresholdP::init}, std::array<double, 2>{params_.values[to], params_.values[to + 1]});
      st.threshold_loss += ThresholdP::lambda * fl.value;
      params_.grads[to] += static_cast<Scalar>(ThresholdP::lambda * fl.grad[0]);
      params_.grads[to + 1] += static_cast<Scalar>(ThresholdP::lambda * fl.grad[1]);
    } else if constexpr (!ThresholdP::learnable) {
      params_.grads[to] = params_.grads[to + 1] = Scalar(0);
    }
  }
  st.term_loss[0] = st.event_loss;
  st.loss = st.event_loss + st.threshold_loss + st.pose_prior_loss;
  for (int k = 1; k < n_terms; ++k) st.loss += st.term_loss[k];
  for (std::size_t r : rays) st.rays += r;
  touched_.clear();
  for (std::size_t k = 0; k < 2 * L; ++k) touched_.push_back(threshold_offset() + 2 * first + k);
  return st;
}

/// train_tile: one tile's rays as the objective lists them, rendered by the representation (a ray each
/// with its random stream keyed by the objective), the objective's score of each pass (with the samples
/// where a term reads them), backward.
template <Representation Rep, class ThresholdP, class NoiseP, class ObjectiveP>
double Model<Rep, ThresholdP, NoiseP, ObjectiveP>::train_tile(const TrainingData& data, const StepWindow& sw, int p0, int P, int batch,
                                                              std::uint64_t ray_key, Scalar* grads, TileWork& w) const {
  loss::TileView t;
  t.draw = &sw;
  t.p0 = p0;
  t.P = P;
  t.batch = batch;
  t.channels = channels;
  t.camera = &data.camera;
  t.bayer = &data.bayer;
  const auto& poses = training_poses(data);
  t.poses = poses.data();
  t.pixel_dirs = data.pixel_dirs.data();
  t.near = box().near;
  t.far = box().far;
  t.log_eps = Rep::log_eps;
  t.ray_key = ray_key;
  t.step = adam_.step();
  t.teacher = data.teacher.empty() ? nullptr : data.teacher.data();
  w.list.clear();
  objective_.rays(t, w.list, w.scratch);
  w.rays += static_cast<std::size_t>(w.list.size());
  const int L = static_cast<int>(sw.len);
  const std::size_t to = threshold_offset() + 2 * sw.first;
  w.bp.resize(static_cast<std::size_t>(L));
  w.bm.resize(static_cast<std::size_t>(L));
  for (int k = 0; k < L; ++k) {
    w.bp[k] = params_.values[to + 2 * k];
    w.bm[k] = params_.values[to + 2 * k + 1];
  }
  const loss::WindowThresholds<Scalar> th{L, w.bp.data(), w.bm.data(), ThresholdP::learnable ? grads + to : nullptr,
                                          refractory_.learned ? &w.refractory_grad : nullptr};
  const Scalar* params = params_.values.data();
  TileRays in;
  in.camera = &data.camera;
  in.poses = poses.data();
  in.pixel_dirs = data.pixel_dirs.data();
  in.rays = &w.list;
  in.ray_key = ray_key;
  in.pose_grad = poses_.active();
  in.pose_levels = poses_.settings.levels;
  renderer_.forward(params, in, w.rw);
  double loss = 0;
  for (int pass = 0; pass < Rep::passes; ++pass) {
    const auto v = Rep::values(w.rw, pass, loss::needs_samples(objective_));
    std::array<double, StepStats::kMaxTerms> l{};
    objective_.score(t, v, th, w.scratch, l.data());
    w.pass_loss[pass] += l[0];
    loss += l[0];
    for (int k = 1; k < n_terms; ++k) w.terms[k] += l[k];
  }
  renderer_.backward(params, in, w.rw, grads, poses_.active() ? w.pose_grad.data() : nullptr);
  return loss;
}

}  // namespace evnerf
