// model/model.hpp — Model<Representation, Thresholds, Noise, Objective>: an event-trained model as a
// composition of its parts. The representation (model/representation.hpp) turns (pose, pixel) pairs into
// luminance and takes their gradients back: a neural field through a ray-marcher (model/ray_marching.hpp;
// EvNerf<Field, Sampler, …> is that model) or a scene of Gaussians through a rasterizer
// (model/splatting.hpp). The objective (loss/objective.hpp) says which pairs a tile renders and scores
// them; the thresholds, one pair per slice, sit after the representation's parameters. Both families train
// by the same step, optimiser, checkpoints, shards and pose refinement. This
// header declares the class and holds its state; its work is in the headers it includes at its end:
// model/step.hpp (a training step: the draw, the tiles, the shards), model/optimiser.hpp (Adam, the
// threshold projection, the parameter average) and model/checkpoint.hpp (the model as a checkpoint, format
// io/checkpoint.hpp). The per-run settings are train/settings.hpp; the named variants model/presets.hpp.
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
#include "../events/training_data.hpp"
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
#include "../splat/gaussians.hpp"
#include "poses.hpp"
#include "ray_marching.hpp"
#include "representation.hpp"

namespace evnerf {

/// Which shards of a step this process computes (Model::train_step): a step is `count` shards, each its own
/// window and pixels; process `rank` of `ranks` computes shards rank, rank + ranks, … (count a multiple of
/// ranks). The default is the one-shard step of one process.
struct StepShards {
  int count = 1, rank = 0, ranks = 1;
};

/// What a training step reports (Model::train_step): the means over its shards of the losses and of
/// dloss/dτ, the sums of its counts, and its window.
struct StepStats {
  double loss = 0, event_loss = 0, threshold_loss = 0;
  /// The objective's terms: term_loss[0] is event_loss, term_loss[k] the k-th regulariser's (loss::Plus;
  /// named by the model's term_name(k)).
  static constexpr int kMaxTerms = 4;
  std::array<double, kMaxTerms> term_loss{};
  std::size_t rays = 0;
  std::size_t samples = 0;                  ///< field evaluations (fewer than rays × samples per ray when cells are skipped)
  std::size_t backward_samples = 0;         ///< samples run backward (fewer still behind opaque surfaces)
  std::size_t first_slice = 0, window = 1;  ///< the step's window of slices [first, first + window)
  /// event_loss by pass (coarse, fine): a two-network sampler's fine depths are drawn from the coarse
  /// weights and held fixed in the backward (as in NeRF), so the coarse network's gradient is that of the
  /// coarse pass's loss alone.
  std::array<double, 2> pass_event_loss{};
  double refractory_grad = 0;  ///< dloss/dτ of a learned refractory period (0 when none is learned)
  double pose_prior_loss = 0;  ///< pose refinement's pull toward the given poses (in loss; model/poses.hpp's pose_prior)

  /// Visits every field a step's shards add up, each once and in one fixed order: every loss, count and
  /// gradient above but the window. A new statistic goes here, and shards and processes sum it.
  template <class S, class F>
  static constexpr void summed_fields(S& s, F&& f) {
    f(s.loss), f(s.event_loss), f(s.threshold_loss), f(s.refractory_grad), f(s.pose_prior_loss);
    f(s.rays), f(s.samples), f(s.backward_samples);
    for (auto& v : s.pass_event_loss) f(v);
    for (auto& v : s.term_loss) f(v);
  }
};

/// The refractory period a model reads its counts with (Model::set_refractory): `seconds` < 0 reads the
/// counts as they are; otherwise each event stands for the crossings events::dead_time_weight gives. A
/// learned period moves with the field, by its own Adam (lr kLr seconds, the field's betas, no decay) within
/// [0, max]; m and v are that Adam's moments. `max` is kMax unless the data bound the period (train sets it to
/// the recording's bound, events::IntervalStatistics::refractory_bound, which is also where it starts);
/// checkpoints do not keep it: a resumed run reads it off the recording again.
struct RefractoryState {
  static constexpr double kLr = 2e-6, kMax = 5e-3;
  double seconds = -1, m = 0, v = 0;
  double max = kMax;
  bool learned = false;
  bool active() const { return seconds >= 0; }
};

/// The field's and sampler's types and sizes of a ray-marching representation, under the names a model
/// has always given them (none for other representations).
template <class Rep>
struct RepresentationTypes {};
template <class Rep>
requires requires { typename Rep::field_type; }
struct RepresentationTypes<Rep> {
  using field_type = typename Rep::field_type;
  using sampler_type = typename Rep::sampler_type;
  static constexpr int n_fields = Rep::networks;
  static constexpr std::size_t field_params = Rep::field_params;
  static constexpr int Nc = Rep::n_coarse, Nf = Rep::n_fine;
};

/// An event-trained model: representation (model/representation.hpp), threshold policy (joint or fixed),
/// noise injection, and the objective (loss/objective.hpp: which poses a step compares, at which pixels,
/// with which interval). A bare bound policy (loss::SplitCounts<K>, loss::SignedCount,
/// loss::HalfSlackCounts) as the objective means the paper's one-slice objective with that bound. The
/// representation's scalar is the precision of parameters and arithmetic: float for training; double for
/// gradient checks (checkpoints are float models only).
template <Representation Rep, class ThresholdP = loss::JointThresholds, class NoiseP = loss::DefaultNoise,
          class ObjectiveP = loss::SplitCounts<1>>
class Model : public RepresentationTypes<Rep> {
 public:
  using Scalar = typename Rep::scalar;
  using representation_type = Rep;
  using renderer_type = Rep;
  using threshold_policy = ThresholdP;
  using noise_policy = NoiseP;
  using objective_type = typename loss::as_objective<ObjectiveP>::type;
  using pixel_policy = typename objective_type::pixels;
  using scalar = Scalar;
  static constexpr int max_window = objective_type::max_window;
  static constexpr int n_terms = objective_type::n_terms;
  static constexpr int channels = Rep::channels;
  static_assert(channels == 1 || channels == 3, "Model: the representation must render 1 (grey) or 3 (RGGB colour) channels.");
  static_assert(std::is_same_v<Scalar, float> || std::is_same_v<Scalar, double>, "Model: the scalar must be float or double.");
  static_assert(n_terms >= 1 && n_terms <= StepStats::kMaxTerms, "Model: an objective has one event term and at most three regularisers.");

  Model() = default;
  /// A fresh model for `n_slices` slices, seeded initialisation (the representation's own where it needs
  /// no data: a field's networks; a Gaussian scene's points spread over the box).
  Model(std::size_t n_slices, render::SceneBox box, std::uint64_t seed, nn::AdamConfig adam = {})
      : Model(nullptr, n_slices, box, seed, adam) {}
  /// A fresh model for `data`, seeded initialisation; a representation may place itself by the data (a
  /// Gaussian scene's points in the cameras' frusta). A field's networks start as without data.
  Model(const TrainingData& data, render::SceneBox box, std::uint64_t seed, nn::AdamConfig adam = {})
      : Model(&data, data.slices.size(), box, seed, adam) {}

 private:
  Model(const TrainingData* data, std::size_t n_slices, render::SceneBox box, std::uint64_t seed, nn::AdamConfig adam)
      : renderer_(box), n_slices_(n_slices), params_(renderer_type::n_params + 2 * n_slices),
        adam_(renderer_type::n_params + 2 * n_slices, adam) {
    Rng rng(seed);
    renderer_.init(params_.values.data(), rng, data);
    for (std::size_t i = 0; i < n_slices; ++i) {
      params_.values[threshold_offset() + 2 * i] = static_cast<Scalar>(ThresholdP::init);
      params_.values[threshold_offset() + 2 * i + 1] = static_cast<Scalar>(-ThresholdP::init);
    }
  }

 public:
  /// Where the thresholds lie in params(): behind the representation's (a field's networks and the
  /// backdrop's raw values; a scene's Gaussians and the backdrop's).
  std::size_t threshold_offset() const { return renderer_type::n_params; }
  /// Where the backdrop's raw values lie in params() (render::Renderer::backdrop_offset; used when the box's
  /// backdrop is learned).
  static constexpr std::size_t backdrop_offset() { return renderer_type::backdrop_offset; }
  std::size_t n_slices() const { return n_slices_; }
  Scalar threshold_pos(std::size_t i) const { return params_.values[threshold_offset() + 2 * i]; }
  Scalar threshold_neg(std::size_t i) const { return params_.values[threshold_offset() + 2 * i + 1]; }
  const render::SceneBox& box() const { return renderer_.box(); }
  const renderer_type& renderer() const { return renderer_; }
  /// The sampler of a ray-marching representation.
  const auto& sampler() const requires requires(const Rep& r) { r.sampler(); }
  { return renderer_.sampler(); }
  nn::ParameterBuffer<Scalar>& params() { return params_; }
  const nn::ParameterBuffer<Scalar>& params() const { return params_; }
  nn::Adam<Scalar>& optimizer() { return adam_; }
  const nn::Adam<Scalar>& optimizer() const { return adam_; }
  long step() const { return adam_.step(); }

  /// A representation that can start from a teacher's seeds (Gaussians: Splatting::start_from) starts
  /// there instead of its own init; the thresholds take the teacher's where it learned them on as many
  /// slices. Only for a model that has not stepped yet (its Adam moments and average are still empty).
  void start_from(const splat::Seeds& seeds) requires requires(const Rep& r, Scalar* p, const splat::Seeds& s) { r.start_from(p, s); }
  {
    require(step() == 0, "a model starts from seeds only before its first step");
    renderer_.start_from(params_.values.data(), seeds);
    if (seeds.thresholds.size() == 2 * n_slices_)
      for (std::size_t i = 0; i < 2 * n_slices_; ++i) params_.values[threshold_offset() + i] = static_cast<Scalar>(seeds.thresholds[i]);
    if (average_.active()) average_ = nn::ParameterAverage<Scalar>(average_.decay(), params_.values);
  }

  /// Keeps a moving average of the parameters (nn::ParameterAverage with `decay`), updated after every
  /// train_step; the model then renders with the average. Averaging never changes training itself. A model
  /// that keeps no average (or one of another size) starts one from its current parameters; one that
  /// does keeps its values and takes the new decay. 0 drops the average: renders use the parameters.
  void set_average(double decay) {
    require(std::isfinite(decay) && decay >= 0 && decay < 1,
            "the parameter average's decay must be in [0, 1), got " + std::to_string(decay));
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
  void update_sampler(const TrainingData& data, long step, std::uint64_t seed);

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
                       Exchange&& exchange);

  /// The loss of the step the model would take next and its gradient for every parameter and threshold
  /// (in params().grads), without taking it: a window of slices (one for the paper's objective) and pixels
  /// drawn from (seed, step), noise injected, both end poses rendered, the objective applied per pixel, the
  /// threshold floor on every slice of the window. Calling it twice gives the same result; finite-difference
  /// checks perturb params() between calls.
  /// `shard` > 0 draws another window and other pixels for the same step (train_step's shards); shard 0 is
  /// the step's own draw.
  StepStats gradients(const TrainingData& data, int pixels_per_step, std::uint64_t seed, int pixels_per_tile = 0, int shard = 0);

  /// A step's window and what its pixels saw there (loss::draw_step: the per-slice counts, noise included).
  using StepWindow = loss::StepDraw;
  /// What the last gradients() (or train_step()) drew: window, pixels and their counts with the noise.
  const StepWindow& last_draw() const { return window_; }

  /// Renders the full image at `pose` (a field's fine network where there is one) with render_params(); see
  /// the representation's render (render::Renderer::render, splat::render_image).
  Rendering render(const geometry::Camera& cam, const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose,
                   bool early_termination = true, int rows_per_batch = renderer_type::kRenderRows) const {
    return renderer_.render(render_params().data(), cam, pixel_dirs, pose, early_termination, rows_per_batch);
  }

  // ---- checkpoints (model/checkpoint.hpp) ------------------------------------------------------------
  /// The model and its optimiser state as a checkpoint named `name`, with `run`'s record of its training.
  std::string serialize(const std::string& name, const io::CheckpointRun& run) const;
  /// Restores from serialize()'s bytes (errors name `file`); returns the file's record of the run.
  io::CheckpointRun deserialize(const std::string& bytes, const std::string& file);
  /// The model's architecture as checkpoints record it: the representation's (a field's encodings,
  /// networks, activation and sampler; a Gaussian scene's layout, capacity and activation). Two variants
  /// with the same architecture and loss can load each other's files (the FP32 and bf16 twins do).
  static std::string architecture() { return Rep::architecture(); }
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
  /// The refractory period the counts are read with: `seconds` ≥ 0 weighs each event by the threshold
  /// crossings it stands for (events::dead_time_weight; the slices must keep their intervals), learned with
  /// the field when `learn`; negative reads the counts as they are (the default: a new model's step is then
  /// bit-identical to one without this setting). Checkpoints keep it with its optimiser state. A learned
  /// period stays within [0, max] (set_refractory_bound).
  void set_refractory(double seconds, bool learn, double max = RefractoryState::kMax) {
    require(std::isfinite(seconds) && seconds <= RefractoryState::kMax,
            "the refractory period must be at most " + std::to_string(RefractoryState::kMax) + " s, not " + std::to_string(seconds));
    refractory_ = {};
    refractory_.seconds = seconds < 0 ? -1.0 : seconds;
    refractory_.learned = learn && seconds >= 0;
    set_refractory_bound(max);
  }
  /// The largest period learning may reach, within [0, RefractoryState::kMax] (a recording's bound: the
  /// period is learned downward from it).
  void set_refractory_bound(double max) {
    require(std::isfinite(max) && max >= 0,
            "the refractory period's bound must be a finite number of seconds ≥ 0, not " + std::to_string(max));
    refractory_.max = std::min(max, RefractoryState::kMax);
  }
  const RefractoryState& refractory() const { return refractory_; }
  /// Pose refinement (model/poses.hpp): a correction per pose knot (slice boundary) and a clock offset,
  /// learned with the field by their own Adam as `s` says, starting from the identity and no offset. Off
  /// (the default) the rays start at data's boundary poses and a step is bit-identical to one without this
  /// setting. Checkpoints keep the corrections, the offset and their moments.
  void set_pose_refinement(const TrainingData& data, const PoseRefinementSettings& s) {
    check_data(data);
    require(!s.offset || data.trajectory.size() >= 2, "pose refinement: learning the clock offset needs the recording's trajectory");
    require(std::isfinite(s.lr_rotation) && s.lr_rotation >= 0 && std::isfinite(s.lr_translation) && s.lr_translation >= 0 &&
                std::isfinite(s.lr_offset) && s.lr_offset >= 0 && s.decay_steps > 0 && s.levels >= 0 && s.start >= 0 &&
                std::isfinite(s.prior_rotation) && s.prior_rotation >= 0 && std::isfinite(s.prior_translation) && s.prior_translation >= 0,
            "pose refinement: the learning rates and the pull's weights must be finite and not negative, the decay's steps positive, the "
            "levels not negative");
    poses_ = {};
    poses_.settings = s;
    if (s.active()) {
      poses_.correction.assign(n_slices_ + 1, geometry::Pose{});
      poses_.m.assign(n_slices_ + 1, {});
      poses_.v.assign(n_slices_ + 1, {});
    }
    refresh_poses(data);
  }
  const PoseRefinement& pose_refinement() const { return poses_; }
  /// The step sizes, their decay and the levels of pose refinement from `s` (what it learns stays as the model has it: a resumed run
  /// goes on as its checkpoint did); the poses follow the data (a resumed run's trajectory).
  void set_pose_rates(const TrainingData& data, const PoseRefinementSettings& s) {
    poses_.settings.lr_rotation = s.lr_rotation;
    poses_.settings.lr_translation = s.lr_translation;
    poses_.settings.lr_offset = s.lr_offset;
    poses_.settings.decay_steps = s.decay_steps;
    poses_.settings.levels = s.levels;
    poses_.settings.start = s.start;
    poses_.settings.prior_rotation = s.prior_rotation;
    poses_.settings.prior_translation = s.prior_translation;
    if (poses_.active()) {
      check_data(data);
      refresh_poses(data);
    }
  }
  /// Sets a correction or the offset (a test's perturbation; a resumed run's state); the poses follow.
  void set_pose_correction(const TrainingData& data, std::size_t knot, const geometry::Pose& c) {
    require(poses_.active() && knot < poses_.correction.size(), "set_pose_correction: no such knot, or pose refinement is off");
    poses_.correction[knot] = c;
    refresh_poses(data);
  }
  void set_time_offset(const TrainingData& data, double seconds) {
    require(poses_.active() && std::isfinite(seconds), "set_time_offset: pose refinement is off, or the offset is not finite");
    poses_.offset = seconds;
    refresh_poses(data);
  }
  /// The poses the training rays start from: the refined ones, or data's boundary poses.
  const std::vector<geometry::Pose>& training_poses(const TrainingData& data) const {
    return poses_.active() ? refined_ : data.boundary_poses;
  }
  /// The refined poses of the knots (empty when pose refinement is off).
  const std::vector<geometry::Pose>& refined_poses() const { return refined_; }
  /// The last gradients()'s dloss/dε of every knot's correction (a twist: rotation x y z, translation x y z,
  /// in its camera's frame; the first knot's is 0, the gauge) and dloss/d(offset), when pose refinement is on.
  const std::vector<std::array<double, 6>>& pose_gradient() const { return pose_grad_; }
  double offset_gradient() const { return offset_grad_; }
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
    return const_cast<Model*>(this)->template term<T>();
  }
  /// The name of the objective's term k (0: the event term; log.jsonl writes `<name>_loss` for the others).
  static const char* term_name(int k) { return objective_type::term_name(k); }

 private:
  /// train_step's statistics as a vector that shards add up and processes sum (StepStats::summed_fields'
  /// order), then the slices' counts.
  static constexpr std::size_t kTotals = [] {
    StepStats s;
    std::size_t n = 0;
    StepStats::summed_fields(s, [&](auto&) { ++n; });
    return n;
  }();
  static void add_totals(std::vector<double>& t, const StepStats& s) {
    std::size_t i = 0;
    StepStats::summed_fields(s, [&](const auto& v) { t[i++] += static_cast<double>(v); });
  }
  StepStats from_totals(const std::vector<double>& t, int count) const {
    StepStats s;
    std::size_t i = 0;
    StepStats::summed_fields(s, [&](auto& v) {
      if constexpr (std::is_integral_v<std::remove_reference_t<decltype(v)>>) v = static_cast<std::remove_reference_t<decltype(v)>>(t[i++]);
      else v = t[i++] / count;
    });
    s.first_slice = window_.first;
    s.window = window_.len;
    return s;
  }
  void check_data(const TrainingData& data) const {
    if (data.slices.size() != n_slices_)
      throw Error("train_step: the model has " + std::to_string(n_slices_) + " slices' thresholds but the training data has " +
                  std::to_string(data.slices.size()) + " slices (a checkpoint resumed with another slicing?)");
    require(data.boundary_poses.size() == n_slices_ + 1, "train_step: need one boundary pose more than slices");
    require(data.teacher.empty() || data.teacher.size() == data.boundary_poses.size() * static_cast<std::size_t>(data.camera.width()) *
                                                               data.camera.height() * channels,
            "train_step: the teacher's images must cover every boundary pose's pixels in the model's " + std::to_string(channels) +
                " channel(s)");
  }
  /// A thread's scratch: the representation's, the tile's rays (as the objective asks for them), the
  /// window's thresholds, the objective's own scratch.
  struct TileWork {
    typename Rep::TileWork rw;
    loss::RayList list;
    std::vector<double> bp, bm;
    typename objective_type::scratch scratch;
    std::array<double, 2> pass_loss{};                 ///< the thread's event loss by pass, this step
    std::array<double, StepStats::kMaxTerms> terms{};  ///< the thread's regulariser terms, this step
    double refractory_grad = 0;                        ///< the thread's dloss/dτ, this step
    std::size_t rays = 0;                              ///< the thread's rays, this step
    std::vector<std::array<double, 6>> pose_grad;      ///< the thread's dloss/dε per knot (pose refinement)
  };
  /// The refined poses from the corrections and the offset (or none, refinement off).
  void refresh_poses(const TrainingData& data) {
    refined_.clear();
    if (poses_.active()) refined_ = evnerf::refined_poses(poses_, data.boundary_poses, data.slices.boundaries, data.trajectory);
  }
  /// dloss/d(offset) from the knots' twist gradients: each knot moves along the trajectory's velocity at its
  /// shifted time, seen in its corrected camera's frame.
  double offset_gradient_of(const TrainingData& data) const {
    double g = 0;
    for (std::size_t i = 0; i < pose_grad_.size(); ++i) {
      const auto eta = twist_through(poses_.correction[i], trajectory_velocity(data.trajectory, data.slices.boundaries[i] + poses_.offset));
      for (int k = 0; k < 6; ++k) g += pose_grad_[i][k] * eta[k];
    }
    return g;
  }

  /// One tile of the step (pixels p0 .. p0 + P of the step's draw): the objective's rays, each with its random
  /// stream keyed by the objective (so that the result depends on neither the tiling nor the thread count),
  /// forward through every pass, the objective's score of each pass, backward. Returns the event term's
  /// loss (already a mean over the step's pixels).
  double train_tile(const TrainingData& data, const StepWindow& sw, int p0, int P, int batch, std::uint64_t ray_key, Scalar* grads,
                    TileWork& w) const;
  /// The optimiser step after gradients(): Adam on the field and on the thresholds the step touched (lazy),
  /// the projection of projected thresholds, the parameter average (model/optimiser.hpp).
  void apply_update(const TrainingData& data);
  /// Pose refinement's optimiser step (model/optimiser.hpp), within apply_update.
  void update_poses(const TrainingData& data);

  renderer_type renderer_;
  std::size_t n_slices_ = 0;
  nn::ParameterBuffer<Scalar> params_;
  nn::Adam<Scalar> adam_;
  nn::ParameterAverage<Scalar> average_;  ///< inactive unless set_average(); renders use it when active
  std::vector<TileWork> work_;            ///< gradients()'s per-thread scratch (no state: any content gives the same step)
  StepWindow window_;                     ///< the last gradients()'s window (train_step applies Adam to its thresholds)
  std::vector<std::size_t> touched_;      ///< the last step's threshold entries (lazy Adam)
  std::vector<Scalar> shard_sum_;         ///< train_step's sum of the shards before the current one
  bool ray_termination_ = false;          ///< training rays stop behind ray_cut_ (set_ray_termination)
  double ray_cut_ = static_cast<double>(renderer_type::kMinTransmittance);
  objective_type objective_;                      ///< the objective and its regularisers' settings (objective(), term<T>())
  RefractoryState refractory_;                    ///< the period the counts are read with (set_refractory)
  double last_refractory_grad_ = 0;               ///< the step's dloss/dτ, for apply_update
  PoseRefinement poses_;                          ///< pose refinement's state (set_pose_refinement; inactive by default)
  std::vector<geometry::Pose> refined_;           ///< the knots' refined poses (empty when inactive)
  std::vector<std::array<double, 6>> pose_grad_;  ///< the last gradients()'s dloss/dε per knot
  double offset_grad_ = 0;                        ///< and dloss/d(offset)
};

/// The Ev-NeRF model: the neural field `FieldT` rendered by ray marching with `SamplerT`
/// (model/ray_marching.hpp), in precision `Scalar`, with the threshold policy, noise and objective.
template <class FieldT, render::Sampler SamplerT, class ThresholdP = loss::JointThresholds, class NoiseP = loss::DefaultNoise,
          class ObjectiveP = loss::SplitCounts<1>, class Scalar = float>
using EvNerf = Model<RayMarching<FieldT, SamplerT, Scalar>, ThresholdP, NoiseP, ObjectiveP>;

}  // namespace evnerf

#include "checkpoint.hpp"
#include "optimiser.hpp"
#include "step.hpp"
