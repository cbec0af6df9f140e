// model/model.hpp — EvNerf<Field, Sampler, Thresholds, Noise, Objective, Scalar>: the Ev-NeRF model as a
// composition of its parts. The renderer (render/renderer.hpp: rays → samples → field → compositing, and
// the sampler's state) turns rays into luminance; the objective (loss/objective.hpp) says which rays a tile
// renders and scores them. This class draws a step's window of slices, its pixels and noise, renders each
// tile's rays, hands the values to the objective, runs the renderer's backward per tile of pixels with
// per-thread gradients reduced in a fixed order, applies Adam, and reads and writes checkpoints
// (io/checkpoint.hpp). The named variants are in model/presets.hpp.
#pragma once
#include <array>
#include <string>
#include <type_traits>
#include <vector>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../core/parallel.hpp"
#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../events/slicing.hpp"
#include "../field/field.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../io/checkpoint.hpp"
#include "../loss/event_loss.hpp"
#include "../loss/objective.hpp"
#include "../nn/params.hpp"
#include "../render/occupancy.hpp"
#include "../render/renderer.hpp"
#include "../render/sampler.hpp"
#include "../render/scene.hpp"

namespace evnerf {

/// Everything a training step reads: slices with their boundary poses and the camera.
struct TrainingData {
  geometry::Camera camera;
  events::SliceSet slices;
  std::vector<geometry::Pose> boundary_poses;  ///< pose at each slice boundary
  std::vector<Vec3f> pixel_dirs;               ///< render::pixel_directions(camera)
  std::vector<bool> slice_enabled;             ///< held-out slices are false (novel-view evaluation)
  events::CountPrefix prefix;                  ///< per-pixel running counts (objectives whose pixels look at the
                                               ///< window's counts need it; train::prepare builds it)
  geometry::BayerPattern bayer;                ///< colour models: the channel of each pixel's events (the
                                               ///< recording's mosaic; RGGB where it names none)
  events::PixelSites sites;                    ///< the pixels that carry events (one colour channel's sites of
                                               ///< a mosaic at the full sensor); all() = every pixel. Steps draw
                                               ///< their pixels and noise among them only.
  int slices_per_interval = 1;                 ///< slices per interval of the recording's own cut (train's
                                               ///< --subslices): a window objective's W counts such intervals,
                                               ///< so its windows span 1..W·this slices, the same time at any cut
};

using render::Rendering;

/// Which shards of a step this process computes (EvNerf::train_step): a step is `count` shards, each its own
/// window and pixels; process `rank` of `ranks` computes shards rank, rank + ranks, … (count a multiple of
/// ranks). The default is the one-shard step of one process.
struct StepShards {
  int count = 1, rank = 0, ranks = 1;
};

struct StepStats {
  double loss = 0, event_loss = 0, threshold_loss = 0;
  double distortion_loss = 0;  ///< the distortion regulariser's term (0 unless set_distortion() was given a weight)
  /// The objective's terms: term_loss[0] is event_loss, term_loss[k] the k-th regulariser's (loss::Plus;
  /// named by the model's term_name(k)).
  static constexpr int kMaxTerms = 4;
  std::array<double, kMaxTerms> term_loss{};
  std::size_t rays = 0;
  std::size_t samples = 0;           ///< field evaluations (fewer than rays × samples per ray when cells are skipped)
  std::size_t backward_samples = 0;  ///< samples run backward (fewer still behind opaque surfaces)
  std::size_t first_slice = 0, window = 1;  ///< the step's window of slices [first, first + window)
  /// event_loss by pass (coarse, fine): a two-network sampler's fine depths are drawn from the coarse
  /// weights and held fixed in the backward (as in NeRF), so the coarse network's gradient is that of the
  /// coarse pass's loss alone.
  std::array<double, 2> pass_event_loss{};
};

/// An Ev-NeRF model: field, sampler, threshold policy (joint or fixed), noise injection, and the objective
/// (loss/objective.hpp: which poses a step compares, at which pixels, with which interval). A bare bound
/// policy (loss::SplitCounts<K>, loss::SignedCount, loss::HalfSlackCounts) as the objective means the
/// paper's one-slice objective with that bound. `Scalar` is the precision of parameters and arithmetic:
/// float for training; double for gradient checks (checkpoints are float models only).
template <class FieldT, render::Sampler SamplerT, class ThresholdP = loss::JointThresholds, class NoiseP = loss::DefaultNoise,
          class ObjectiveP = loss::SplitCounts<1>, class Scalar = float>
class EvNerf {
 public:
  using field_type = FieldT;
  using sampler_type = SamplerT;
  using renderer_type = render::Renderer<FieldT, SamplerT, Scalar>;
  using threshold_policy = ThresholdP;
  using noise_policy = NoiseP;
  using objective_type = typename loss::as_objective<ObjectiveP>::type;
  using pixel_policy = typename objective_type::pixels;
  using scalar = Scalar;
  static constexpr int max_window = objective_type::max_window;
  static constexpr int n_terms = objective_type::n_terms;
  static constexpr int channels = FieldT::channels;
  static constexpr int n_fields = renderer_type::networks;
  static constexpr std::size_t field_params = FieldT::n_params;
  static constexpr int Nc = renderer_type::n_coarse, Nf = renderer_type::n_fine;
  static_assert(channels == 1 || channels == 3, "EvNerf: the field must output 1 (grey) or 3 (RGGB colour) channels.");
  static_assert(std::is_same_v<Scalar, float> || std::is_same_v<Scalar, double>, "EvNerf: Scalar must be float or double.");
  static_assert(n_terms >= 1 && n_terms <= StepStats::kMaxTerms, "EvNerf: an objective has one event term and at most three regularisers.");

  EvNerf() = default;
  /// A fresh model for `n_slices` slices, seeded initialisation.
  EvNerf(std::size_t n_slices, render::SceneBox box, std::uint64_t seed, nn::AdamConfig adam = {})
      : renderer_(box), n_slices_(n_slices), params_(n_fields * field_params + 2 * n_slices),
        adam_(n_fields * field_params + 2 * n_slices, adam) {
    Rng rng(seed);
    for (int f = 0; f < n_fields; ++f) {
      Rng r = rng.split(static_cast<std::uint64_t>(f));
      FieldT::init(params_.values.data() + f * field_params, r);
    }
    for (std::size_t i = 0; i < n_slices; ++i) {
      params_.values[threshold_offset() + 2 * i] = static_cast<Scalar>(ThresholdP::init);
      params_.values[threshold_offset() + 2 * i + 1] = static_cast<Scalar>(-ThresholdP::init);
    }
  }

  std::size_t threshold_offset() const { return n_fields * field_params; }
  std::size_t n_slices() const { return n_slices_; }
  Scalar threshold_pos(std::size_t i) const { return params_.values[threshold_offset() + 2 * i]; }
  Scalar threshold_neg(std::size_t i) const { return params_.values[threshold_offset() + 2 * i + 1]; }
  const render::SceneBox& box() const { return renderer_.box(); }
  const renderer_type& renderer() const { return renderer_; }
  const SamplerT& sampler() const { return renderer_.sampler(); }
  nn::ParameterBuffer<Scalar>& params() { return params_; }
  const nn::ParameterBuffer<Scalar>& params() const { return params_; }
  nn::Adam<Scalar>& optimizer() { return adam_; }
  long step() const { return adam_.step(); }

  /// Keeps a moving average of the parameters (nn::ParameterAverage with `decay`), updated after every
  /// train_step; the model then renders with the average. Averaging never changes training itself. A model
  /// that keeps no average (or one of another size) starts one from its current parameters; one that
  /// does keeps its values and takes the new decay. 0 drops the average: renders use the parameters.
  void set_average(double decay) {
    require(std::isfinite(decay) && decay >= 0 && decay < 1, "the parameter average's decay must be in [0, 1), got " + std::to_string(decay));
    if (decay == 0) {
      average_ = {};
    } else if (!average_.active() || average_.values().size() != params_.size()) {
      average_ = nn::ParameterAverage<Scalar>(decay, params_.values);
    } else {
      average_ = nn::ParameterAverage<Scalar>(decay, std::move(average_.values()));
    }
  }
  /// The parameter average (inactive when the model keeps none).
  const nn::ParameterAverage<Scalar>& average() const { return average_; }
  /// The parameters renders use: the average when the model keeps one, else params().values.
  const std::vector<Scalar>& render_params() const { return average_.active() ? average_.values() : params_.values; }

  /// Lets the sampler refresh its state (an occupancy grid, say) as it would before training step `step`;
  /// train_step() calls this itself. `seen` comes from the training data's cameras: a world ball is seen
  /// when its centre projects (Camera::project) into the image of one of up to 64 boundary poses spread over
  /// the recording, within the ball's projected radius, between near and far.
  void update_sampler(const TrainingData& data, long step, std::uint64_t seed) {
    render::SamplerUpdate u;
    u.step = step;
    u.seed = seed;
    const std::size_t np = data.boundary_poses.size(), every = std::max<std::size_t>(1, np / 64);
    std::vector<const geometry::Pose*> poses;
    for (std::size_t i = 0; i < np; i += every) poses.push_back(&data.boundary_poses[i]);
    if (np > 0) poses.push_back(&data.boundary_poses.back());
    const auto& cam = data.camera;
    const double near = box().near, far = box().far;
    u.seen = [&cam, poses, near, far](const Vec3& world, double radius) {
      for (const auto* pose : poses) {
        const Vec3 q = pose->q.conjugate() * (world - pose->t);
        if (q.z() < near - radius || q.z() > far + radius || q.z() <= 1e-6) continue;
        const double mx = cam.fx() * radius / q.z(), my = cam.fy() * radius / q.z();
        const Vec2 uv = cam.project(q);
        if (uv.x() >= -mx && uv.x() <= cam.width() + mx && uv.y() >= -my && uv.y() <= cam.height() + my) return true;
      }
      return false;
    };
    renderer_.update_sampler(params_.values.data(), std::move(u));
  }

  /// One training step (Ev-NeRF §4): the sampler refreshed (update_sampler), then gradients(), then Adam
  /// applied to the field and to the window's thresholds. Deterministic for a seed and thread count. A
  /// non-finite loss leaves the parameters as they were (the caller stops).
  StepStats train_step(const TrainingData& data, int pixels_per_step, std::uint64_t seed, int pixels_per_tile = 0) {
    return train_step(data, pixels_per_step, seed, pixels_per_tile, StepShards{}, [](std::vector<Scalar>&, std::vector<double>&) {});
  }

  /// A step of `shards.count` shards, each a window and pixels_per_step pixels of its own (gradients() of
  /// that shard), whose gradients and statistics are averaged: one process computing every shard equals
  /// `shards.ranks` processes computing shards rank, rank + ranks, … and summing what they computed.
  /// `exchange(grads, totals)` is that sum across processes (train/group.hpp); it is called once per step
  /// with this process's summed gradients and a vector of statistics followed by one entry per slice
  /// (how many of this process's shards touched it), and must leave in both the sum over all processes.
  /// With one shard in one process this is exactly the single-shard step.
  template <class Exchange>
  StepStats train_step(const TrainingData& data, int pixels_per_step, std::uint64_t seed, int pixels_per_tile, const StepShards& shards,
                       Exchange&& exchange) {
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
      }
      exchange(params_.grads, totals);
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
    return st;
  }

  /// The loss of the step the model would take next and its gradient for every parameter and threshold
  /// (in params().grads), without taking it: a window of slices (one for the paper's objective) and pixels
  /// drawn from (seed, step), noise injected, both end poses rendered, the objective applied per pixel, the
  /// threshold floor on every slice of the window. Calling it twice gives the same result; finite-difference
  /// checks perturb params() between calls.
  /// `shard` > 0 draws another window and other pixels for the same step (train_step's shards); shard 0 is
  /// the step's own draw.
  StepStats gradients(const TrainingData& data, int pixels_per_step, std::uint64_t seed, int pixels_per_tile = 0, int shard = 0) {
    check_data(data);
    const long s = adam_.step();
    Rng rng = Rng(seed).split(static_cast<std::uint64_t>(s));
    if (shard > 0) rng = rng.split(0x5348415244000000ull + static_cast<std::uint64_t>(shard));
    StepWindow& sw = window_;
    loss::draw_step<objective_type>(data.slices, data.slice_enabled, data.prefix, NoiseP::ratio, pixels_per_step, rng, sw, &data.sites,
                               data.slices_per_interval);
    const std::size_t first = sw.first, L = sw.len;
    const int P = static_cast<int>(sw.pixels.size());
    const int tile = pixels_per_tile > 0 ? pixels_per_tile : default_tile_pixels();
    const int n_tiles = (P + tile - 1) / tile;
    const int threads = std::max(1, std::min(thread_count(), n_tiles));
    params_.size_accumulators(threads);  // each thread zeroes its own below
    std::vector<double> loss_ev(threads, 0.0), loss_dist(threads, 0.0);
    std::vector<std::array<double, StepStats::kMaxTerms>> loss_terms(threads);
    std::vector<std::size_t> evaluated(threads, 0), backward(threads, 0), rays(threads, 0);
    std::vector<std::array<double, 2>> pass_loss(threads);
    const std::uint64_t ray_key = rng.next_u64();
    if (work_.size() < static_cast<std::size_t>(threads)) work_.resize(static_cast<std::size_t>(threads));
    parallel_blocks(static_cast<std::size_t>(n_tiles), 1, [&](std::size_t b, std::size_t e, int th) {
      params_.zero_accumulator(th);
      TileWork& w = work_[static_cast<std::size_t>(th)];  // buffers reused from step to step
      w.rw.evaluated = w.rw.backward_samples = 0;
      w.pass_loss = {};
      w.distortion = 0;
      w.terms = {};
      w.rays = 0;
      w.rw.training_termination = ray_termination_;
      w.rw.training_cut = static_cast<scalar>(ray_cut_);
      renderer_type::defer_encoding_grad(w.rw);  // the thread's table gradients in one batch (bit-identical)
      for (std::size_t t = b; t < e; ++t) {
        const int p0 = static_cast<int>(t) * tile, p1 = std::min(P, p0 + tile);
        loss_ev[th] += train_tile(data, sw, p0, p1 - p0, P, ray_key, params_.per_thread[th].data(), w);
      }
      evaluated[th] = w.rw.evaluated;
      pass_loss[th] = w.pass_loss;
      loss_dist[th] = w.distortion;
      loss_terms[th] = w.terms;
      rays[th] = w.rays;
      backward[th] = w.rw.backward_samples;
    });
    // The table gradients each thread held back, applied in parts (a hash grid's levels) shared out by
    // their samples: each thread's accumulator gets the same additions in the same order whichever thread
    // applies them, and the threads, whose tiles differ in samples, finish together.
    constexpr int parts = renderer_type::flush_parts;
    parallel_jobs_by_cost(
        static_cast<std::size_t>(threads) * parts,
        [&](std::size_t j) { return static_cast<double>(renderer_type::deferred_count(work_[j / parts].rw)); },
        [&](std::size_t j) { renderer_type::flush_part(work_[j / parts].rw, static_cast<int>(j % parts)); });
    for (int th = 0; th < threads; ++th) renderer_type::clear_deferred(work_[static_cast<std::size_t>(th)].rw);
    params_.end_accumulate(threads);
    StepStats st;
    st.first_slice = first;
    st.window = L;
    for (double l : loss_ev) st.event_loss += l;
    for (double l : loss_dist) st.distortion_loss += l;
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
        const auto fl = ad::value_and_grad(loss::ThresholdFloor{ThresholdP::init},
                                           std::array<double, 2>{params_.values[to], params_.values[to + 1]});
        st.threshold_loss += ThresholdP::lambda * fl.value;
        params_.grads[to] += static_cast<Scalar>(ThresholdP::lambda * fl.grad[0]);
        params_.grads[to + 1] += static_cast<Scalar>(ThresholdP::lambda * fl.grad[1]);
      } else if constexpr (!ThresholdP::learnable) {
        params_.grads[to] = params_.grads[to + 1] = Scalar(0);
      }
    }
    st.term_loss[0] = st.event_loss;
    st.loss = st.event_loss + st.threshold_loss + st.distortion_loss;
    for (int k = 1; k < n_terms; ++k) st.loss += st.term_loss[k];
    for (std::size_t r : rays) st.rays += r;
    touched_.clear();
    for (std::size_t k = 0; k < 2 * L; ++k) touched_.push_back(threshold_offset() + 2 * first + k);
    return st;
  }

  /// A step's window and what its pixels saw there (loss::draw_step: the per-slice counts, noise included).
  using StepWindow = loss::StepDraw;
  /// What the last gradients() (or train_step()) drew: window, pixels and their counts with the noise.
  const StepWindow& last_draw() const { return window_; }

  /// Renders the full image at `pose` (the fine network where there is one) with render_params(); see
  /// Renderer::render.
  Rendering render(const geometry::Camera& cam, const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose,
                   bool early_termination = true, int rows_per_batch = renderer_type::kRenderRows) const {
    return renderer_.render(render_params().data(), cam, pixel_dirs, pose, early_termination, rows_per_batch);
  }

  // ---- checkpoints -----------------------------------------------------------------------------------
  /// Serialises the model and optimiser state; `extra` carries the caller's metadata (camera, poses…).
  std::string serialize(const std::string& name, const std::string& extra) const {
    static_assert(std::is_same_v<Scalar, float>, "EvNerf::serialize: checkpoints hold float models");
    io::CheckpointHeader h;
    h.name = name;
    h.n_slices = n_slices_;
    h.step = adam_.step();
    const auto& bx = box();
    const double boxv[6] = {bx.center.x(), bx.center.y(), bx.center.z(), bx.scale, bx.near, bx.far};
    std::copy(boxv, boxv + 6, h.box);
    h.density_length = bx.density_length;
    h.loss = loss_description();
    h.architecture = architecture();
    return io::write_checkpoint(h, {params_.values.data(), adam_.m().data(), adam_.v().data(), params_.size(),
                                    average_.active() ? average_.values().data() : nullptr, average_.decay(),
                                    sampler().serialize(), extra});
  }
  /// Restores from serialize()'s bytes (format: io/checkpoint.hpp); errors name the file and what does not
  /// match. The model changes only when the whole file has been read and checked. A file of version 5 or
  /// later must have this model's architecture() and loss_description(); the name it carries is a label.
  /// Older files carry no architecture: their variant name must equal `name` unless that is empty (the
  /// parameter count and, from version 4, the loss are checked).
  std::string deserialize(const std::string& b, const std::string& name, const std::string& file) {
    static_assert(std::is_same_v<Scalar, float>, "EvNerf::deserialize: checkpoints hold float models");
    io::CheckpointReader r(b, file);
    const io::CheckpointHeader h = io::read_checkpoint_header(r);
    if (h.version >= 5) {
      if (h.architecture != architecture())
        r.fail("written by a model of another architecture ('" + h.architecture + "'; this model is '" + architecture() + "')");
    } else if (!name.empty() && h.name != name) {
      r.fail("written by preset '" + h.name + "', loading as '" + name + "'");
    }
    const std::uint64_t n = h.n_params;
    if (h.n_slices > n || n != n_fields * field_params + 2 * h.n_slices)
      r.fail("parameter count does not match this model (" + std::to_string(n) + " in the file, " +
             std::to_string(n_fields * field_params) + " + 2 per slice here)");
    if (n > r.remaining() / 12)  // parameters and Adam's two moments, 4 bytes each: refuse before allocating
      r.fail("truncated: " + std::to_string(n) + " parameters need " + std::to_string(n * 12) + " bytes, " +
             std::to_string(r.remaining()) + " remain");
    std::string note;
    if (h.version >= 4) {
      if (h.loss != loss_description())
        r.fail("trained with the loss '" + h.loss + "', this model's is '" + loss_description() + "'");
    } else {
      note = file + ": checkpoint version " + std::to_string(h.version) +
             " does not record the loss it was trained with; continuing with '" + loss_description() + "'";
    }
    nn::ParameterBuffer<Scalar> params(n);
    nn::Adam<Scalar> adam(n, adam_.config());
    r.get(params.values.data(), n * 4);
    r.get(adam.m().data(), n * 4);
    r.get(adam.v().data(), n * 4);
    adam.set_step(h.step);
    nn::ParameterAverage<Scalar> average;
    if (h.version >= 6) {  // version 6 added the parameter average
      const std::uint64_t m = r.u64();
      double decay = 0;
      r.get(&decay, 8);
      if (m != 0) {
        if (m != n) r.fail("the parameter average has " + std::to_string(m) + " values, the model " + std::to_string(n));
        if (!(decay > 0 && decay < 1)) r.fail("the parameter average's decay is not in (0, 1)");
        std::vector<Scalar> values(n);
        r.get(values.data(), n * 4);
        average = nn::ParameterAverage<Scalar>(decay, std::move(values));
      }
    }
    // The checksum guards against damage, not against a writer that stored a NaN: training never writes one
    // (it stops on a non-finite loss or parameter first), so such a file is refused rather than rendered.
    auto finite = [&](const std::vector<Scalar>& v, const char* what, bool non_negative) {
      for (std::size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]) || (non_negative && v[i] < 0))
          r.fail(std::string(what) + " " + std::to_string(i) + " of " + std::to_string(v.size()) + " is " +
                 (std::isfinite(v[i]) ? "negative" : std::isnan(v[i]) ? "NaN" : "infinite") +
                 " (a checkpoint train writes holds only finite values)");
    };
    finite(params.values, "parameter", false);
    finite(adam.m(), "Adam's first moment of parameter", false);
    finite(adam.v(), "Adam's second moment of parameter", true);
    if (average.active()) finite(average.values(), "the parameter average's value", false);
    SamplerT sampler;
    if (h.version >= 2) {  // version 2 added the sampler's state (the occupancy grid)
      if (!sampler.deserialize(r.str()))
        r.fail("the sampler's state (occupancy grid) does not match this model's sampler (" + SamplerT::name() + ")");
    }
    std::string extra = r.str();
    render::SceneBox bx;
    bx.center = Vec3(h.box[0], h.box[1], h.box[2]);
    bx.scale = h.box[3];
    bx.near = h.box[4];
    bx.far = h.box[5];
    bx.density_length = h.density_length;
    renderer_ = renderer_type(bx, std::move(sampler));
    n_slices_ = h.n_slices;
    params_ = std::move(params);
    adam_ = std::move(adam);
    average_ = std::move(average);
    load_note_ = std::move(note);
    return extra;
  }
  /// The model's architecture as checkpoints record it: the field's (encodings, networks, activation) and
  /// the sampler's. Two variants with the same architecture and loss can load each other's files (the
  /// FP32 and bf16 twins do).
  static std::string architecture() { return FieldT::architecture() + "; sampler " + SamplerT::name(); }
  /// 2 added the occupancy grid, 3 the box's density length, 4 the loss description, 5 the architecture,
  /// 6 the parameter average (io/checkpoint.hpp).
  static constexpr std::uint64_t checkpoint_version = io::kCheckpointVersion;
  /// The loss this model trains with, as checkpoints record it: interval policy, threshold policy, noise.
  /// A checkpoint written under another one is refused (resuming would silently change the objective).
  static std::string loss_description() {
    std::string d = "bounds ";  // appended piece by piece: GCC 12's -Wrestrict misfires on chains of operator+
    d.append(objective_type::bounds());
    d.append(", thresholds ").append(ThresholdP::name).append(", noise ");
    d.append(std::to_string(static_cast<int>(NoiseP::ratio * 1000 + 0.5))).append(" per mille");
    d.append(objective_type::description());
    return d;
  }
  /// Set by deserialize(): empty, or a warning the caller should show (a checkpoint older than version 4
  /// cannot be checked against the loss).
  const std::string& load_note() const { return load_note_; }
  /// The distortion regulariser (render::distortion_loss, Mip-NeRF 360's, against floaters and surfaces
  /// smeared along rays): `weight` × its mean over a step's rays, in every pass, joins the loss. 0 (the
  /// default) leaves the step bit-identical. A training setting like the learning rate: not checkpointed.
  void set_distortion(double weight) {
    require(std::isfinite(weight) && weight >= 0, "the distortion weight must be finite and non-negative");
    distortion_ = weight;
  }
  double distortion() const { return distortion_; }
  /// Training rays stop where their transmittance falls below renderer_type::kMinTransmittance
  /// (Renderer::Workspace::training_termination), for samplers that skip (the occupancy grid). The samples
  /// behind carry no gradient either way; the forward's composite loses less than that fraction of a ray's
  /// luminance, and a step evaluates fewer samples (about 40 % fewer on `planes` late in a Fast run).
  /// Off for a new model, whose step is then bit-identical to one without this setting; train::Config turns
  /// it on with a cut of 1e-2, as it turns on the parameter average. A training setting like the learning
  /// rate: not checkpointed.
  /// `cut` is the transmittance behind which a ray stops (renderer_type::kMinTransmittance unless given):
  /// a larger cut evaluates fewer samples and drops more of each ray's far end from the composite and the
  /// gradient. It must lie in (0, 1).
  void set_ray_termination(bool on, double cut = static_cast<double>(renderer_type::kMinTransmittance)) {
    require(std::isfinite(cut) && cut > 0 && cut < 1, "the ray-termination transmittance must lie in (0, 1), not " + std::to_string(cut));
    ray_termination_ = on;
    ray_cut_ = cut;
  }
  bool ray_termination() const { return ray_termination_; }
  /// The transmittance behind which training rays stop (set_ray_termination).
  double ray_cut() const { return ray_cut_; }
  /// The objective, whose regularisers' settings a run may change (a TV term's weight, say). Not
  /// checkpointed: training settings, like the learning rate.
  objective_type& objective() { return objective_; }
  const objective_type& objective() const { return objective_; }
  /// The first regulariser of the objective that is T or derives from it (loss::Plus::find), or null.
  template <class T>
  T* term() {
    if constexpr (requires { objective_.template find<T>(); }) return objective_.template find<T>();
    else return nullptr;
  }
  template <class T>
  const T* term() const {
    return const_cast<EvNerf*>(this)->template term<T>();
  }
  /// The name of the objective's term k (0: the event term; log.jsonl writes `<name>_loss` for the others).
  static const char* term_name(int k) { return objective_type::term_name(k); }
 private:
  /// train_step's statistics as a vector that processes can sum: loss, event loss, threshold loss, rays,
  /// samples, backward samples and the two passes' event losses.
  static constexpr std::size_t kTotals = 9 + StepStats::kMaxTerms;
  static void add_totals(std::vector<double>& t, const StepStats& s) {
    const double v[9] = {s.loss, s.event_loss, s.threshold_loss, double(s.rays), double(s.samples), double(s.backward_samples),
                         s.pass_event_loss[0], s.pass_event_loss[1], s.distortion_loss};
    for (std::size_t i = 0; i < 9; ++i) t[i] += v[i];
    for (int k = 0; k < StepStats::kMaxTerms; ++k) t[9 + k] += s.term_loss[k];
  }
  StepStats from_totals(const std::vector<double>& t, int count) const {
    StepStats s;
    s.loss = t[0] / count;
    s.event_loss = t[1] / count;
    s.threshold_loss = t[2] / count;
    s.rays = static_cast<std::size_t>(t[3]);
    s.samples = static_cast<std::size_t>(t[4]);
    s.backward_samples = static_cast<std::size_t>(t[5]);
    s.pass_event_loss = {t[6] / count, t[7] / count};
    s.distortion_loss = t[8] / count;
    for (int k = 0; k < StepStats::kMaxTerms; ++k) s.term_loss[k] = t[9 + k] / count;
    s.first_slice = window_.first;
    s.window = window_.len;
    return s;
  }
  void check_data(const TrainingData& data) const {
    if (data.slices.size() != n_slices_)
      throw Error("train_step: the model has " + std::to_string(n_slices_) + " slices' thresholds but the training data has " +
                  std::to_string(data.slices.size()) + " slices (a checkpoint resumed with another slicing?)");
    require(data.boundary_poses.size() == n_slices_ + 1, "train_step: need one boundary pose more than slices");
  }
  static constexpr int default_tile_pixels() {
    // About 1–4 k samples per tile: the activations of the widest layer stay within L2.
    constexpr int per_pixel = 2 * (Nc + (n_fields == 2 ? Nc + Nf : 0));
    return per_pixel >= 1024 ? 4 : std::max(1, 2048 / per_pixel);
  }

  /// A thread's scratch: the renderer's workspace, the tile's rays (as the objective asks for them, then
  /// cast) and their random streams, the window's thresholds, the objective's own scratch.
  struct TileWork {
    typename renderer_type::Workspace rw;
    loss::RayList list;
    std::vector<Vec3> origin, dir;
    std::vector<Rng> rng;
    std::vector<double> bp, bm;
    typename objective_type::scratch scratch;
    std::array<double, 2> pass_loss{};                ///< the thread's event loss by pass, this step
    std::array<double, StepStats::kMaxTerms> terms{};  ///< the thread's regulariser terms, this step
    double distortion = 0;                            ///< the thread's distortion term, this step
    std::size_t rays = 0;                             ///< the thread's rays, this step
  };

  /// One tile of the step (pixels p0 .. p0 + P of the step's draw): the objective's rays, each with its random
  /// stream keyed by the objective (so that the result depends on neither the tiling nor the thread count),
  /// forward through every pass, the objective's score of each pass, backward. Returns the event term's
  /// loss (already a mean over the step's pixels).
  double train_tile(const TrainingData& data, const StepWindow& sw, int p0, int P, int batch, std::uint64_t ray_key, Scalar* grads,
                    TileWork& w) const {
    loss::TileView t;
    t.draw = &sw;
    t.p0 = p0;
    t.P = P;
    t.batch = batch;
    t.channels = channels;
    t.camera = &data.camera;
    t.bayer = &data.bayer;
    t.poses = data.boundary_poses.data();
    t.pixel_dirs = data.pixel_dirs.data();
    t.near = box().near;
    t.far = box().far;
    t.log_eps = FieldT::radiance::log_eps;
    t.ray_key = ray_key;
    w.list.clear();
    objective_.rays(t, w.list, w.scratch);
    const int R = w.list.size();
    w.origin.resize(R);
    w.dir.resize(R);
    w.rng.clear();
    for (int r = 0; r < R; ++r) {
      const std::size_t pose = w.list.pose[r], pixel = w.list.pixel[r];
      const auto a = geometry::Camera::ray_along(data.boundary_poses[pose], data.pixel_dirs[pixel].cast<double>());
      w.origin[r] = a.origin;
      w.dir[r] = a.dir;
      w.rng.push_back(Rng(ray_key).split(w.list.key[r]));
    }
    w.rays += static_cast<std::size_t>(R);
    const int L = static_cast<int>(sw.len);
    const std::size_t to = threshold_offset() + 2 * sw.first;
    w.bp.resize(static_cast<std::size_t>(L));
    w.bm.resize(static_cast<std::size_t>(L));
    for (int k = 0; k < L; ++k) {
      w.bp[k] = params_.values[to + 2 * k];
      w.bm[k] = params_.values[to + 2 * k + 1];
    }
    const loss::WindowThresholds<Scalar> th{L, w.bp.data(), w.bm.data(), ThresholdP::learnable ? grads + to : nullptr};
    const Scalar* params = params_.values.data();
    renderer_.forward_train(params, w.origin.data(), w.dir.data(), w.rng.data(), R, w.rw);
    double loss = 0;
    for (int net = 0; net < n_fields; ++net) {
      const loss::RenderedValues<render::RayComposite<Scalar>, Scalar> v{renderer_type::composites(w.rw, net).data(),
                                                                          w.rw.pass[net].dcolor.data(), channels};
      std::array<double, StepStats::kMaxTerms> l{};
      objective_.score(t, v, th, w.scratch, l.data());
      w.pass_loss[net] += l[0];
      loss += l[0];
      for (int k = 1; k < n_terms; ++k) w.terms[k] += l[k];
    }
    // The distortion regulariser: its weight times the mean over the step's rays, every pass (the expected
    // rays per pixel, the same for every tile).
    if (distortion_ > 0) w.distortion += renderer_type::add_distortion(w.rw, distortion_ / (objective_.rays_per_pixel() * batch));
    renderer_.backward(params, w.rw, grads);
    return loss;
  }

  renderer_type renderer_;
  std::size_t n_slices_ = 0;
  nn::ParameterBuffer<Scalar> params_;
  nn::Adam<Scalar> adam_;
  nn::ParameterAverage<Scalar> average_;  ///< inactive unless set_average(); renders use it when active
  std::vector<TileWork> work_;  ///< gradients()'s per-thread scratch (no state: any content gives the same step)
  StepWindow window_;           ///< the last gradients()'s window (train_step applies Adam to its thresholds)
  std::vector<std::size_t> touched_;  ///< the last step's threshold entries (lazy Adam)
  std::vector<Scalar> shard_sum_;     ///< train_step's sum of the shards before the current one
  std::string load_note_;       ///< what the last deserialize() could not check (see load_note())
  double distortion_ = 0;       ///< the distortion regulariser's weight (set_distortion)
  bool ray_termination_ = false;  ///< training rays stop behind ray_cut_ (set_ray_termination)
  double ray_cut_ = static_cast<double>(renderer_type::kMinTransmittance);
  objective_type objective_;    ///< the objective and its regularisers' settings (objective(), term<T>())
};

}  // namespace evnerf
