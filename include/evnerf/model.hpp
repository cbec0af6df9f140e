// model.hpp — EvNerf<Field, Sampler, Thresholds, Noise>: the Ev-NeRF model as a type, its fused
// training step (per tile of pixels: encode → MLP forward → compositing → event loss → backward → MLP
// backward, with per-thread gradients reduced in a fixed order), rendering, checkpoints. The named variants
// are in presets.hpp. Depends on everything below it.
#pragma once
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/parallel.hpp"
#include "core/rng.hpp"
#include "core/types.hpp"
#include "events/slicing.hpp"
#include "field/field.hpp"
#include "geometry/bayer.hpp"
#include "geometry/camera.hpp"
#include "geometry/pose.hpp"
#include "io/checkpoint.hpp"
#include "loss/event_loss.hpp"
#include "loss/objective.hpp"
#include "nn/activation.hpp"
#include "nn/encoding.hpp"
#include "nn/mlp.hpp"
#include "nn/params.hpp"
#include "render/compositing.hpp"
#include "render/occupancy.hpp"
#include "render/sampler.hpp"
#include "render/scene.hpp"

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
};

/// One rendered image: luminance (C channels), depth along the optical axis, opacity.
struct Rendering {
  Image luminance, depth, opacity;
};

struct StepStats {
  double loss = 0, event_loss = 0, threshold_loss = 0;
  std::size_t rays = 0;
  std::size_t samples = 0;           ///< field evaluations (fewer than rays × samples per ray when cells are skipped)
  std::size_t backward_samples = 0;  ///< samples run backward (fewer still behind opaque surfaces)
  std::size_t first_slice = 0, window = 1;  ///< the step's window of slices [first, first + window)
};

/// An Ev-NeRF model: field, sampler, threshold policy (joint or fixed), noise injection, and the objective
/// (loss/objective.hpp: which poses a step compares, at which pixels, with which interval). A bare bound
/// policy (loss::SplitCounts<K>, loss::SignedCount, loss::HalfSlackCounts) as the objective means the
/// paper's one-slice objective with that bound.
template <class FieldT, class SamplerT, class ThresholdP = loss::JointThresholds, class NoiseP = loss::DefaultNoise,
          class ObjectiveP = loss::SplitCounts<1>>
class EvNerf {
 public:
  using field_type = FieldT;
  using sampler_type = SamplerT;
  using threshold_policy = ThresholdP;
  using noise_policy = NoiseP;
  using objective = typename loss::as_objective<ObjectiveP>::type;
  using bound_policy = typename objective::bound;
  using pixel_policy = typename objective::pixels;
  static constexpr int max_window = objective::max_window;
  static constexpr int channels = FieldT::channels;
  static constexpr int n_fields = SamplerT::two_networks ? 2 : 1;
  static constexpr std::size_t field_params = FieldT::n_params;
  static constexpr int Nc = SamplerT::n_coarse, Nf = SamplerT::n_fine;
  static constexpr bool has_occupancy = render::has_occupancy<SamplerT>();
  static_assert(channels == 1 || channels == 3, "EvNerf: the field must output 1 (grey) or 3 (RGGB colour) channels.");

  EvNerf() = default;
  /// A fresh model for `n_slices` slices, seeded initialisation.
  EvNerf(std::size_t n_slices, render::SceneBox box, std::uint64_t seed, nn::AdamConfig adam = {})
      : box_(box), n_slices_(n_slices), params_(n_fields * field_params + 2 * n_slices),
        adam_(n_fields * field_params + 2 * n_slices, adam) {
    if constexpr (has_occupancy) grid_ = render::OccupancyGrid(SamplerT::grid_res);
    Rng rng(seed);
    for (int f = 0; f < n_fields; ++f) {
      Rng r = rng.split(static_cast<std::uint64_t>(f));
      FieldT::init(params_.values.data() + f * field_params, r);
    }
    for (std::size_t i = 0; i < n_slices; ++i) {
      params_.values[threshold_offset() + 2 * i] = static_cast<float>(ThresholdP::init);
      params_.values[threshold_offset() + 2 * i + 1] = static_cast<float>(-ThresholdP::init);
    }
  }

  std::size_t threshold_offset() const { return n_fields * field_params; }
  std::size_t n_slices() const { return n_slices_; }
  float threshold_pos(std::size_t i) const { return params_.values[threshold_offset() + 2 * i]; }
  float threshold_neg(std::size_t i) const { return params_.values[threshold_offset() + 2 * i + 1]; }
  const render::SceneBox& box() const { return box_; }
  nn::ParameterBuffer<float>& params() { return params_; }
  const nn::ParameterBuffer<float>& params() const { return params_; }
  nn::Adam<float>& optimizer() { return adam_; }
  long step() const { return adam_.step(); }
  const render::OccupancyGrid& occupancy() const { return grid_; }

  /// Refreshes the occupancy grid from the current density (samplers with a grid only). A cell is
  /// occupied when its density can give a sample an alpha of 1 % at the stratified spacing.
  void update_occupancy(const TrainingData& data, std::uint64_t seed) {
    static_assert(has_occupancy, "update_occupancy: this model's sampler has no occupancy grid");
    if (!grid_.has_visibility()) grid_.set_visible(visible_cells(data));
    const float threshold = static_cast<float>(0.01 * Nc * box_.density_length / (box_.far - box_.near));
    const float* params = params_.values.data();
    grid_.update(
        [&](const float* pts, std::size_t n, float* out) {
          parallel_blocks(n, 8192, [&](std::size_t b, std::size_t e, int) {
            typename FieldT::template Workspace<float> ws;
            for (std::size_t c = b; c < e; c += 4096) {
              const int m = static_cast<int>(std::min<std::size_t>(4096, e - c));
              FieldT::density(params, pts + 3 * c, m, ws, out + c);
              for (int j = 0; j < m; ++j) out[c + j] = FieldT::density_activation::f(out[c + j]);  // σ as α sees it
            }
          });
        },
        Rng(seed), threshold);
  }

  /// One training step (Ev-NeRF §4): a window of slices (one slice for the paper's objective) and pixels
  /// drawn from (seed, step), noise injected, both end poses rendered, loss and gradients computed, Adam
  /// applied. Deterministic for a seed and thread count.
  StepStats train_step(const TrainingData& data, int pixels_per_step, std::uint64_t seed, int pixels_per_tile = 0) {
    if (data.slices.size() != n_slices_)
      throw Error("train_step: the model has " + std::to_string(n_slices_) + " slices' thresholds but the training data has " +
                  std::to_string(data.slices.size()) + " slices (a checkpoint resumed with another slicing?)");
    require(data.boundary_poses.size() == n_slices_ + 1, "train_step: need one boundary pose more than slices");
    const long s = adam_.step();
    Rng rng = Rng(seed).split(static_cast<std::uint64_t>(s));
    if constexpr (has_occupancy)
      if (s >= SamplerT::warmup_steps && (s - SamplerT::warmup_steps) % SamplerT::update_interval == 0)
        update_occupancy(data, rng.split(0xCCu).next_u64());
    StepWindow& sw = window_;
    draw_window(data, rng, sw);
    const std::size_t first = sw.first, L = sw.len;
    const std::size_t hw = data.slices.slices[first].pixels();
    // Noise events (Ev-NeRF's injection, redrawn at every step): ratio × the window's count, each in a
    // random slice of the window. Drawn before the pixels, so a one-slice step draws as inject_noise does.
    sw.noise.clear();
    if constexpr (NoiseP::ratio > 0) {
      std::size_t total = 0;
      for (std::size_t k = 0; k < L; ++k) total += data.slices.slices[first + k].total;
      events::draw_noise(total, NoiseP::ratio, hw, L, rng, sw.noise);
    }
    // Pixels, by the objective's pixel policy.
    if (taken_.size() != hw) taken_.assign(hw, 0);
    pixel_policy::draw(events::PixelWindow{hw, first, first + L, &data.prefix}, pixels_per_step, rng, sw.pixels, taken_);
    const int P = static_cast<int>(sw.pixels.size());
    require(P > 0, "train_step: no pixel to train on");
    // Per pixel and slice of the window: n⁺, n⁻ with the noise added (saturating like inject_noise).
    sw.npos.resize(static_cast<std::size_t>(P) * L);
    sw.nneg.resize(static_cast<std::size_t>(P) * L);
    for (int i = 0; i < P; ++i)
      for (std::size_t k = 0; k < L; ++k) {
        const auto& c = data.slices.slices[first + k];
        sw.npos[static_cast<std::size_t>(i) * L + k] = c.pos[sw.pixels[i]];
        sw.nneg[static_cast<std::size_t>(i) * L + k] = c.neg[sw.pixels[i]];
      }
    if (!sw.noise.empty()) {
      if (slot_.size() != hw) slot_.assign(hw, -1);
      for (int i = 0; i < P; ++i) slot_[sw.pixels[i]] = i;
      for (const auto& e : sw.noise) {
        const int i = slot_[e.pixel];
        if (i < 0) continue;
        int& c = (e.positive ? sw.npos : sw.nneg)[static_cast<std::size_t>(i) * L + e.slice];
        if (c < INT16_MAX) ++c;
      }
      for (int i = 0; i < P; ++i) slot_[sw.pixels[i]] = -1;
    }
    const int tile = pixels_per_tile > 0 ? pixels_per_tile : default_tile_pixels();
    const int n_tiles = (P + tile - 1) / tile;
    const int threads = std::max(1, std::min(thread_count(), n_tiles));
    params_.begin_accumulate(threads);
    std::vector<double> loss_ev(threads, 0.0);
    std::vector<std::size_t> evaluated(threads, 0), backward(threads, 0);
    const geometry::Pose& pose0 = data.boundary_poses[first];
    const geometry::Pose& pose1 = data.boundary_poses[first + L];
    const std::uint64_t ray_key = rng.next_u64();
    if (work_.size() < static_cast<std::size_t>(threads)) work_.resize(static_cast<std::size_t>(threads));
    parallel_blocks(static_cast<std::size_t>(n_tiles), 1, [&](std::size_t b, std::size_t e, int th) {
      TileWork& w = work_[static_cast<std::size_t>(th)];  // buffers reused from step to step
      w.evaluated = w.backward_samples = 0;
      w.ws.defer_encoding_grad = true;  // the thread's table gradients in one batch (bit-identical)
      for (std::size_t t = b; t < e; ++t) {
        const int p0 = static_cast<int>(t) * tile, p1 = std::min(P, p0 + tile);
        loss_ev[th] += train_tile(data, sw, p0, pose0, pose1, p1 - p0, P, ray_key, params_.per_thread[th].data(), w);
      }
      FieldT::flush_encoding_grad(w.ws);
      evaluated[th] = w.evaluated;
      backward[th] = w.backward_samples;
    });
    params_.end_accumulate(threads);
    StepStats st;
    st.first_slice = first;
    st.window = L;
    for (double l : loss_ev) st.event_loss += l;
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
        params_.grads[to] += static_cast<float>(ThresholdP::lambda * fl.grad[0]);
        params_.grads[to + 1] += static_cast<float>(ThresholdP::lambda * fl.grad[1]);
      } else if constexpr (!ThresholdP::learnable) {
        params_.grads[to] = params_.grads[to + 1] = 0.f;
      }
    }
    st.loss = st.event_loss + st.threshold_loss;
    st.rays = static_cast<std::size_t>(2 * P);
    if (!std::isfinite(st.loss)) return st;  // the caller stops; parameters stay as they were
    // The field's parameters all move; of the thresholds only the window's slices' (lazy Adam).
    sw.touched.clear();
    for (std::size_t k = 0; k < 2 * L; ++k) sw.touched.push_back(threshold_offset() + 2 * first + k);
    adam_.update(params_.values, params_.grads, threshold_offset(), sw.touched);
    if constexpr (requires { ThresholdP::projected; })
      for (std::size_t k = 0; k < L; ++k) {
        float& bp = params_.values[threshold_offset() + 2 * (first + k)];
        float& bm = params_.values[threshold_offset() + 2 * (first + k) + 1];
        bp = std::max(bp, static_cast<float>(ThresholdP::init));
        bm = std::min(bm, static_cast<float>(-ThresholdP::init));
      }
    return st;
  }

  /// Renders the full image at `pose` (the fine network where there is one). Parallel over rows.
  /// With `early_termination` (the default) a ray stops being evaluated once its transmittance falls below
  /// kEvalTransmittance (checked every kEvalChunk samples): what lies behind changes a pixel by less than that.
  Rendering render(const geometry::Camera& cam, const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose,
                   bool early_termination = true) const {
    Rendering out{Image(cam.width(), cam.height(), channels), Image(cam.width(), cam.height(), 1),
                  Image(cam.width(), cam.height(), 1)};
    const int H = cam.height(), W = cam.width();
    parallel_blocks(static_cast<std::size_t>(H), 4, [&](std::size_t b, std::size_t e, int) {
      TileWork w;
      w.early_termination = early_termination;
      std::vector<std::uint32_t> pix(W);
      for (std::size_t y = b; y < e; ++y) {
        for (int x = 0; x < W; ++x) pix[x] = static_cast<std::uint32_t>(y * W + x);
        eval_rays(pixel_dirs, pose, pix.data(), W, w);
        for (int x = 0; x < W; ++x) {
          const auto& r = n_fields == 2 ? w.fine[x] : w.coarse[x];
          for (int c = 0; c < channels; ++c) out.luminance.at(x, int(y), c) = r.color[c];
          out.depth.at(x, int(y)) = r.depth;
          out.opacity.at(x, int(y)) = r.opacity;
        }
      }
    });
    return out;
  }

  /// Cells of the occupancy grid inside the view of some slice-boundary camera between near and far
  /// (pinhole projection of the cell centre, with a margin of the cell's radius; up to 64 poses spread
  /// over the recording). Depends only on the data and the box, so a resumed run gets the same mask.
  std::vector<std::uint8_t> visible_cells(const TrainingData& data) const {
    std::vector<std::uint8_t> vis(grid_.cells(), 0);
    const auto& cam = data.camera;
    const std::size_t np = data.boundary_poses.size(), step = std::max<std::size_t>(1, np / 64);
    std::vector<const geometry::Pose*> poses;
    for (std::size_t i = 0; i < np; i += step) poses.push_back(&data.boundary_poses[i]);
    if (np > 0) poses.push_back(&data.boundary_poses.back());
    const double radius = std::sqrt(3.0) * box_.scale / grid_.resolution();
    parallel_for(grid_.cells(), 4096, [&](std::size_t c) {
      float p[3];
      grid_.cell_centre(c, p);
      const Vec3 world = box_.center + box_.scale * Vec3(p[0], p[1], p[2]);
      for (const auto* pose : poses) {
        const Vec3 q = pose->q.conjugate() * (world - pose->t);
        if (q.z() < box_.near - radius || q.z() > box_.far + radius || q.z() <= 1e-6) continue;
        const double mx = cam.fx() * radius / q.z(), my = cam.fy() * radius / q.z();
        const double u = cam.fx() * q.x() / q.z() + cam.cx(), v = cam.fy() * q.y() / q.z() + cam.cy();
        if (u >= -mx && u <= cam.width() + mx && v >= -my && v <= cam.height() + my) {
          vis[c] = 1;
          break;
        }
      }
    });
    return vis;
  }

  // ---- checkpoints -----------------------------------------------------------------------------------
  /// Serialises the model and optimiser state; `extra` carries the caller's metadata (camera, poses…).
  std::string serialize(const std::string& name, const std::string& extra) const {
    std::string b;
    auto put = [&](const void* p, std::size_t n) { b.append(static_cast<const char*>(p), n); };
    auto put_u64 = [&](std::uint64_t v) { put(&v, 8); };
    auto put_str = [&](const std::string& s) {
      put_u64(s.size());
      put(s.data(), s.size());
    };
    put("EVNERFCK", 8);
    put_u64(checkpoint_version);
    put_str(name);
    put_u64(params_.size());
    put_u64(n_slices_);
    const std::int64_t step = adam_.step();
    put(&step, 8);
    const double boxv[6] = {box_.center.x(), box_.center.y(), box_.center.z(), box_.scale, box_.near, box_.far};
    put(boxv, sizeof boxv);
    put(&box_.density_length, 8);
    put_str(loss_description());
    put(params_.values.data(), params_.size() * 4);
    put(adam_.m().data(), params_.size() * 4);
    put(adam_.v().data(), params_.size() * 4);
    put_str(has_occupancy ? grid_.serialize() : std::string());
    put_str(extra);
    put_u64(fnv1a64(b));
    return b;
  }
  /// Restores from serialize()'s bytes (format: io/checkpoint.hpp); errors name the file and what does not
  /// match. The model changes only when the whole file has been read and checked. An empty `name` accepts
  /// any variant name (the parameter count and the loss are still checked).
  std::string deserialize(const std::string& b, const std::string& name, const std::string& file) {
    io::CheckpointReader r(b, file);
    const io::CheckpointHeader h = io::read_checkpoint_header(r);
    if (!name.empty() && h.name != name) r.fail("written by preset '" + h.name + "', loading as '" + name + "'");
    const std::uint64_t n = h.n_params;
    if (h.n_slices > n || n != n_fields * field_params + 2 * h.n_slices)
      r.fail("parameter count does not match this model (" + std::to_string(n) + " in the file, " +
             std::to_string(n_fields * field_params) + " + 2 per slice here)");
    std::string note;
    if (h.version >= 4) {
      if (h.loss != loss_description())
        r.fail("trained with the loss '" + h.loss + "', this model's is '" + loss_description() + "'");
    } else {
      note = file + ": checkpoint version " + std::to_string(h.version) +
             " does not record the loss it was trained with; continuing with '" + loss_description() + "'";
    }
    nn::ParameterBuffer<float> params(n);
    nn::Adam<float> adam(n, adam_.config());
    r.get(params.values.data(), n * 4);
    r.get(adam.m().data(), n * 4);
    r.get(adam.v().data(), n * 4);
    adam.set_step(h.step);
    render::OccupancyGrid grid;
    if constexpr (has_occupancy) grid = render::OccupancyGrid(SamplerT::grid_res);
    if (h.version >= 2) {  // version 2 added the occupancy grid
      const std::string g = r.str();
      if constexpr (has_occupancy) {
        if (!grid.deserialize(g)) r.fail("occupancy grid does not match this model");
      } else if (!g.empty()) {
        r.fail("has an occupancy grid this model does not use");
      }
    }
    std::string extra = r.str();
    box_.center = Vec3(h.box[0], h.box[1], h.box[2]);
    box_.scale = h.box[3];
    box_.near = h.box[4];
    box_.far = h.box[5];
    box_.density_length = h.density_length;
    n_slices_ = h.n_slices;
    params_ = std::move(params);
    adam_ = std::move(adam);
    grid_ = std::move(grid);
    load_note_ = std::move(note);
    return extra;
  }
  /// 2 added the occupancy grid, 3 the box's density length, 4 the loss description (io/checkpoint.hpp).
  static constexpr std::uint64_t checkpoint_version = io::kCheckpointVersion;
  /// The loss this model trains with, as checkpoints record it: interval policy, threshold policy, noise.
  /// A checkpoint written under another one is refused (resuming would silently change the objective).
  static std::string loss_description() {
    std::string d = "bounds ";  // appended piece by piece: GCC 12's -Wrestrict misfires on chains of operator+
    d.append(bound_policy::name);
    if constexpr (requires { bound_policy::slack; }) d.append(" ").append(std::to_string(bound_policy::slack));
    d.append(", thresholds ").append(ThresholdP::name).append(", noise ");
    d.append(std::to_string(static_cast<int>(NoiseP::ratio * 1000 + 0.5))).append(" per mille");
    d.append(objective::description());  // empty for the paper's one-slice objective (older files compare equal)
    return d;
  }
  /// Set by deserialize(): empty, or a warning the caller should show (a checkpoint older than version 4
  /// cannot be checked against the loss).
  const std::string& load_note() const { return load_note_; }
  /// Backward early termination (occupancy samplers): samples behind this transmittance get no gradient.
  static constexpr float kMinTransmittance = 1e-4f;
  /// Forward early termination of evaluation rays (render()): a ray stops behind this transmittance,
  /// checked every kEvalChunk samples.
  static constexpr float kEvalTransmittance = 1e-4f;
  static constexpr int kEvalChunk = 8;
  /// Raw density given to samples that were not evaluated (skipped cells, terminated rays): α = 0.
  static constexpr float kSkippedDensity = -1e4f;

 private:
  static constexpr int default_tile_pixels() {
    // About 1–4 k samples per tile: the activations of the widest layer stay within L2.
    constexpr int per_pixel = 2 * (Nc + (n_fields == 2 ? Nc + Nf : 0));
    return per_pixel >= 1024 ? 4 : std::max(1, 2048 / per_pixel);
  }

  /// A step's window and what its pixels saw there (the per-slice counts, noise included).
  struct StepWindow {
    std::size_t first = 0, len = 1;
    std::vector<std::uint32_t> pixels;
    std::vector<int> npos, nneg;  ///< P × len
    std::vector<events::NoiseEvent> noise;
    std::vector<std::size_t> starts, touched;
  };

  /// The step's window. One slice (max_window = 1): uniform among the trainable slices, as the paper.
  /// Otherwise the length uniform in 1..max_window, then the start uniform among the windows of that length
  /// whose slices are all trainable (shorter when none is).
  void draw_window(const TrainingData& data, Rng& rng, StepWindow& sw) const {
    const std::size_t N = data.slices.size();
    auto enabled = [&](std::size_t i) { return data.slice_enabled.empty() || data.slice_enabled[i]; };
    sw.starts.clear();
    if constexpr (max_window == 1) {
      for (std::size_t i = 0; i < N; ++i)
        if (enabled(i)) sw.starts.push_back(i);
      require(!sw.starts.empty(), "train_step: no slice to train on");
      sw.first = sw.starts[rng.below(sw.starts.size())];
      sw.len = 1;
    } else {
      // run[i]: trainable slices in a row from i.
      std::vector<std::size_t> run(N + 1, 0);
      for (std::size_t i = N; i-- > 0;) run[i] = enabled(i) ? run[i + 1] + 1 : 0;
      std::size_t L = 1 + rng.below(static_cast<std::uint64_t>(max_window));
      for (; L >= 1; --L) {
        for (std::size_t i = 0; i + L <= N; ++i)
          if (run[i] >= L) sw.starts.push_back(i);
        if (!sw.starts.empty()) break;
      }
      require(!sw.starts.empty(), "train_step: no slice to train on");
      sw.first = sw.starts[rng.below(sw.starts.size())];
      sw.len = L;
    }
  }

  struct TileWork {
    typename FieldT::template Workspace<float> ws;
    std::vector<float> pts, dirs, t, noise, dsigma, draw;
    std::vector<render::RayComposite<float>> coarse, fine;
    std::vector<std::vector<float>> fine_t;
    std::vector<float> dcolor;
    std::vector<double> bp, bm, gbp, gbm;  // the window's thresholds and one pixel's threshold gradients
    // Occupancy skipping: indices of the evaluated samples, their packed inputs and gradients, and the
    // scattered outputs (skipped samples: density −1e4, luminance 0).
    std::vector<int> active;
    std::vector<int> keep;
    std::size_t evaluated = 0;         ///< field evaluations so far
    bool early_termination = false;    ///< evaluation rays: stop a ray behind transmittance kEvalTransmittance
    std::vector<float> ray_trans;      ///< evaluation rays: transmittance so far
    std::size_t backward_samples = 0;  ///< samples run backward so far
    std::vector<float> cpts, cdirs, sig_full, raw_full, cdsigma, cdraw;
  };

  /// Builds points and directions for R rays with S depths each (depths in w.t, R×S) into w.pts/w.dirs.
  void make_samples(const Vec3* origin, const Vec3* dir, int R, int S, const std::vector<float>& t, TileWork& w) const {
    w.pts.resize(3 * static_cast<std::size_t>(R) * S);
    w.dirs.resize(3 * static_cast<std::size_t>(R) * S);
    const double inv = 1.0 / box_.scale;
    for (int r = 0; r < R; ++r) {
      const Vec3 u = dir[r].normalized();
      for (int k = 0; k < S; ++k) {
        const std::size_t i = static_cast<std::size_t>(r) * S + k;
        const Vec3 p = (origin[r] + static_cast<double>(t[i]) * dir[r] - box_.center) * inv;
        for (int d = 0; d < 3; ++d) {
          w.pts[3 * i + d] = static_cast<float>(p[d]);
          w.dirs[3 * i + d] = static_cast<float>(u[d]);
        }
      }
    }
  }

  /// Packs the points and directions of the samples listed in w.active into w.cpts / w.cdirs.
  static void gather_active(TileWork& w) {
    const std::size_t m = w.active.size();
    w.cpts.resize(3 * m);
    w.cdirs.resize(3 * m);
    for (std::size_t j = 0; j < m; ++j)
      for (int d = 0; d < 3; ++d) {
        w.cpts[3 * j + d] = w.pts[3 * static_cast<std::size_t>(w.active[j]) + d];
        w.cdirs[3 * j + d] = w.dirs[3 * static_cast<std::size_t>(w.active[j]) + d];
      }
  }

  /// Evaluation forward with early termination: fills w.sig_full (raw density, −1e4 where not evaluated) and
  /// w.raw_full (R×S×C) chunk by chunk along the rays.
  void forward_rays_terminating(const float* params, const Vec3* dir, int R, int S, const std::vector<float>& t,
                                TileWork& w) const {
    const std::size_t n = static_cast<std::size_t>(R) * S;
    w.sig_full.assign(n, kSkippedDensity);
    w.raw_full.assign(n * channels, 0.f);
    w.ray_trans.assign(static_cast<std::size_t>(R), 1.f);
    const int stride = FieldT::density_net::out_dims;
    for (int k0 = 0; k0 < S; k0 += kEvalChunk) {
      const int k1 = std::min(S, k0 + kEvalChunk);
      w.active.clear();
      for (int r = 0; r < R; ++r) {
        if (w.ray_trans[r] <= kEvalTransmittance) continue;
        for (int k = k0; k < k1; ++k) {
          const int i = r * S + k;
          bool keep = true;
          if constexpr (has_occupancy) keep = !grid_.active() || grid_.occupied(&w.pts[3 * static_cast<std::size_t>(i)]);
          if (keep) w.active.push_back(i);
        }
      }
      const int m = static_cast<int>(w.active.size());
      if (m > 0) {
        gather_active(w);
        const float *sg = nullptr, *rw = nullptr;
        FieldT::forward(params, w.cpts.data(), w.cdirs.data(), m, w.ws, &sg, &rw);
        w.evaluated += static_cast<std::size_t>(m);
        for (int j = 0; j < m; ++j) {
          const std::size_t i = static_cast<std::size_t>(w.active[j]);
          w.sig_full[i] = sg[static_cast<std::size_t>(j) * stride];
          for (int c = 0; c < channels; ++c) w.raw_full[i * channels + c] = rw[static_cast<std::size_t>(j) * channels + c];
        }
      }
      // Transmittance after this chunk (as composite_forward computes it).
      bool alive = false;
      for (int r = 0; r < R; ++r) {
        if (w.ray_trans[r] <= kEvalTransmittance) continue;
        const double dn = dir[r].norm() / box_.density_length;
        for (int k = k0; k < k1; ++k) {
          const std::size_t i = static_cast<std::size_t>(r) * S + k;
          const double delta = k + 1 < S ? double(t[i + 1] - t[i]) * dn : 1e10;
          const double alpha = 1.0 - std::exp(-(FieldT::density_activation::f(w.sig_full[i]) * delta));
          w.ray_trans[r] *= static_cast<float>(1.0 - alpha + 1e-10);
        }
        alive = alive || w.ray_trans[r] > kEvalTransmittance;
      }
      if (!alive) break;
    }
  }

  /// Forward of one network over R rays × S samples, compositing each ray into comp[r]. Training rays
  /// (noise given) evaluate every sample the sampler keeps; evaluation rays with w.early_termination go
  /// kEvalChunk samples at a time and stop where the transmittance has fallen below kEvalTransmittance.
  void forward_rays(int net, const Vec3* dir, int R, int S, const std::vector<float>& t, const float* noise,
                    TileWork& w, std::vector<render::RayComposite<float>>& comp) const {
    const float* params = params_.values.data() + net * field_params;
    const float *sigma = nullptr, *raw = nullptr;
    int stride = FieldT::density_net::out_dims;
    if (!noise && w.early_termination) {
      forward_rays_terminating(params, dir, R, S, t, w);
      sigma = w.sig_full.data();
      raw = w.raw_full.data();
      stride = 1;
    }
    if constexpr (has_occupancy) {
      if (!sigma && grid_.active()) {
        const int n = R * S;
        w.active.clear();
        for (int i = 0; i < n; ++i)
          if (grid_.occupied(&w.pts[3 * static_cast<std::size_t>(i)])) w.active.push_back(i);
        const int m = static_cast<int>(w.active.size());
        gather_active(w);
        w.sig_full.assign(static_cast<std::size_t>(n), kSkippedDensity);
        w.raw_full.assign(static_cast<std::size_t>(n) * channels, 0.f);
        w.evaluated += static_cast<std::size_t>(m);
        if (m > 0) {
          FieldT::forward(params, w.cpts.data(), w.cdirs.data(), m, w.ws, &sigma, &raw);
          for (int j = 0; j < m; ++j) {
            const std::size_t i = static_cast<std::size_t>(w.active[j]);
            w.sig_full[i] = sigma[static_cast<std::size_t>(j) * stride];
            for (int c = 0; c < channels; ++c) w.raw_full[i * channels + c] = raw[static_cast<std::size_t>(j) * channels + c];
          }
        }
        sigma = w.sig_full.data();
        raw = w.raw_full.data();
        stride = 1;
      }
    }
    if (!sigma) {
      FieldT::forward(params, w.pts.data(), w.dirs.data(), R * S, w.ws, &sigma, &raw);
      w.evaluated += static_cast<std::size_t>(R) * S;
    }
    comp.resize(R);
    for (int r = 0; r < R; ++r) {
      const std::size_t o = static_cast<std::size_t>(r) * S;
      render::composite_forward<float, typename FieldT::density_activation>(
          S, channels, sigma + o * stride, stride, raw + o * channels, t.data() + o,
          static_cast<float>(dir[r].norm() / box_.density_length), noise ? noise + o : nullptr, comp[r]);
    }
  }

  /// Loss over the tile's pixel pairs (pixels p0 .. p0+P of the step) for one network's composites; fills
  /// w.dcolor (2P×C) and adds the threshold gradients of the window's slices. Returns the loss contribution
  /// (already divided by the batch size).
  double pair_loss(const StepWindow& sw, int p0, int P, int batch, const std::vector<render::RayComposite<float>>& comp,
                   float* grads, TileWork& w, int width) const {
    const int L = static_cast<int>(sw.len);
    const std::size_t to = threshold_offset() + 2 * sw.first;
    w.bp.resize(static_cast<std::size_t>(L));
    w.bm.resize(static_cast<std::size_t>(L));
    w.gbp.resize(static_cast<std::size_t>(L));
    w.gbm.resize(static_cast<std::size_t>(L));
    for (int k = 0; k < L; ++k) {
      w.bp[k] = params_.values[to + 2 * k];
      w.bm[k] = params_.values[to + 2 * k + 1];
    }
    w.dcolor.assign(static_cast<std::size_t>(2 * P) * channels, 0.f);
    double total = 0;
    for (int i = 0; i < P; ++i) {
      const std::uint32_t pix = sw.pixels[p0 + i];
      const int c = channels == 1 ? 0 : geometry::rggb_channel(static_cast<int>(pix % width), static_cast<int>(pix / width));
      std::fill(w.gbp.begin(), w.gbp.end(), 0.0);
      std::fill(w.gbm.begin(), w.gbm.end(), 0.0);
      const std::size_t o = static_cast<std::size_t>(p0 + i) * L;
      const auto r = loss::window_pixel_loss<bound_policy>(comp[2 * i].color[c], comp[2 * i + 1].color[c], L, &sw.npos[o],
                                                           &sw.nneg[o], w.bp.data(), w.bm.data(), w.gbp.data(), w.gbm.data());
      total += r.value / batch;
      w.dcolor[static_cast<std::size_t>(2 * i) * channels + c] = static_cast<float>(r.dl0 / batch);
      w.dcolor[static_cast<std::size_t>(2 * i + 1) * channels + c] = static_cast<float>(r.dl1 / batch);
      if constexpr (ThresholdP::learnable)
        for (int k = 0; k < L; ++k) {
          grads[to + 2 * k] += static_cast<float>(w.gbp[k] / batch);
          grads[to + 2 * k + 1] += static_cast<float>(w.gbm[k] / batch);
        }
    }
    return total;
  }

  void backward_rays(int net, int R, int S, const std::vector<render::RayComposite<float>>& comp, float* grads,
                     TileWork& w) const {
    w.dsigma.resize(static_cast<std::size_t>(R) * S);
    w.draw.resize(static_cast<std::size_t>(R) * S * channels);
    for (int r = 0; r < R; ++r) {
      const std::size_t o = static_cast<std::size_t>(r) * S;
      render::composite_backward<float>(S, channels, comp[r], w.dcolor.data() + static_cast<std::size_t>(r) * channels,
                                        w.dsigma.data() + o, 1, w.draw.data() + o * channels);
    }
    const float* params = params_.values.data() + net * field_params;
    if constexpr (has_occupancy) {
      if (grid_.active()) {  // only the evaluated samples carry gradient
        // Early termination for the backward pass: a sample behind transmittance < 1e-4 has weight and
        // gradients below 1e-4 of the ray's, so it is dropped: the forward's workspace is compacted to
        // the kept samples (Field::keep_only) and only they go backward.
        std::vector<int>& keep = w.keep;
        keep.clear();
        for (int j = 0; j < static_cast<int>(w.active.size()); ++j) {
          const int i = w.active[j];
          if (comp[i / S].trans[i % S] > kMinTransmittance) keep.push_back(j);
        }
        const int m = static_cast<int>(keep.size());
        w.backward_samples += static_cast<std::size_t>(m);
        if (m == 0) return;
        w.cdsigma.resize(static_cast<std::size_t>(m));
        w.cdraw.resize(static_cast<std::size_t>(m) * channels);
        for (int j = 0; j < m; ++j) {
          const std::size_t i = static_cast<std::size_t>(w.active[keep[j]]);
          w.cdsigma[j] = w.dsigma[i];
          for (int c = 0; c < channels; ++c) w.cdraw[static_cast<std::size_t>(j) * channels + c] = w.draw[i * channels + c];
        }
        if (m < static_cast<int>(w.active.size())) {
          const float *sg = nullptr, *rw = nullptr;
          FieldT::keep_only(w.ws, keep.data(), m, &sg, &rw);
        }
        FieldT::backward(params, w.ws, w.cdsigma.data(), w.cdraw.data(), grads + net * field_params);
        return;
      }
    }
    w.backward_samples += static_cast<std::size_t>(R) * S;
    FieldT::backward(params, w.ws, w.dsigma.data(), w.draw.data(), grads + net * field_params);
  }

  /// Fine depths of R rays (R × (Nc+Nf)): coarse depths merged with Nf drawn from the coarse weights;
  /// `rngs` (one per ray) jitters the draws in training, null gives deterministic evaluation depths.
  std::vector<float> fine_depths(int R, Rng* rngs, const TileWork& w) const {
    constexpr int S = Nc + Nf;
    std::vector<float> tf(static_cast<std::size_t>(R) * S), one;
    for (int r = 0; r < R; ++r) {
      render::importance_depths<float>(Nc, &w.t[static_cast<std::size_t>(r) * Nc], w.coarse[r].weight.data(), Nf,
                                       rngs ? &rngs[r] : nullptr, one);
      std::copy(one.begin(), one.end(), tf.begin() + static_cast<std::ptrdiff_t>(r) * S);
    }
    return tf;
  }

  double train_tile(const TrainingData& data, const StepWindow& sw, int p0, const geometry::Pose& pose0,
                    const geometry::Pose& pose1, int P, int batch, std::uint64_t ray_key, float* grads, TileWork& w) const {
    const int R = 2 * P;
    const std::uint32_t* pix = sw.pixels.data() + p0;
    std::vector<Vec3> origin(R), dir(R);
    for (int i = 0; i < P; ++i) {
      const Vec3 d = data.pixel_dirs[pix[i]].cast<double>();
      origin[2 * i] = pose0.t;
      dir[2 * i] = pose0.q * d;
      origin[2 * i + 1] = pose1.t;
      dir[2 * i + 1] = pose1.q * d;
    }
    // Per-ray random streams keyed by the pixel: independent of tiling and thread count.
    w.t.resize(static_cast<std::size_t>(R) * Nc);
    w.noise.resize(static_cast<std::size_t>(R) * Nc);
    std::vector<Rng> ray_rng;
    ray_rng.reserve(R);
    for (int r = 0; r < R; ++r) {
      ray_rng.push_back(Rng(ray_key).split(static_cast<std::uint64_t>(pix[r / 2]) * 2 + static_cast<std::uint64_t>(r & 1)));
      render::stratified_depths<float>(Nc, float(box_.near), float(box_.far), &ray_rng[r], &w.t[static_cast<std::size_t>(r) * Nc]);
      for (int k = 0; k < Nc; ++k) w.noise[static_cast<std::size_t>(r) * Nc + k] = static_cast<float>(ray_rng[r].normal());
    }
    const int width = data.camera.width();
    make_samples(origin.data(), dir.data(), R, Nc, w.t, w);
    forward_rays(0, dir.data(), R, Nc, w.t, w.noise.data(), w, w.coarse);
    double loss = pair_loss(sw, p0, P, batch, w.coarse, grads, w, width);
    backward_rays(0, R, Nc, w.coarse, grads, w);
    if constexpr (n_fields == 2) {
      constexpr int S = Nc + Nf;
      const std::vector<float> tf = fine_depths(R, ray_rng.data(), w);
      std::vector<float> nf(static_cast<std::size_t>(R) * S);
      for (int r = 0; r < R; ++r)
        for (int k = 0; k < S; ++k) nf[static_cast<std::size_t>(r) * S + k] = static_cast<float>(ray_rng[r].normal());
      make_samples(origin.data(), dir.data(), R, S, tf, w);
      forward_rays(1, dir.data(), R, S, tf, nf.data(), w, w.fine);
      loss += pair_loss(sw, p0, P, batch, w.fine, grads, w, width);
      backward_rays(1, R, S, w.fine, grads, w);
    }
    return loss;
  }

  /// Evaluation rays (no jitter, no density noise) for pixels of one pose; results in w.coarse / w.fine.
  void eval_rays(const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose, const std::uint32_t* pix, int R,
                 TileWork& w) const {
    std::vector<Vec3> origin(R, pose.t), dir(R);
    for (int r = 0; r < R; ++r) dir[r] = pose.q * pixel_dirs[pix[r]].cast<double>();
    w.t.resize(static_cast<std::size_t>(R) * Nc);
    for (int r = 0; r < R; ++r)
      render::stratified_depths<float>(Nc, float(box_.near), float(box_.far), nullptr, &w.t[static_cast<std::size_t>(r) * Nc]);
    make_samples(origin.data(), dir.data(), R, Nc, w.t, w);
    forward_rays(0, dir.data(), R, Nc, w.t, nullptr, w, w.coarse);
    if constexpr (n_fields == 2) {
      constexpr int S = Nc + Nf;
      const std::vector<float> tf = fine_depths(R, nullptr, w);
      make_samples(origin.data(), dir.data(), R, S, tf, w);
      forward_rays(1, dir.data(), R, S, tf, nullptr, w, w.fine);
    }
  }

  render::SceneBox box_;
  render::OccupancyGrid grid_;
  std::size_t n_slices_ = 0;
  nn::ParameterBuffer<float> params_;
  nn::Adam<float> adam_;
  std::vector<TileWork> work_;  ///< train_step's per-thread scratch (no state: any content gives the same step)
  StepWindow window_;           ///< train_step's window scratch (likewise)
  std::vector<std::uint8_t> taken_;
  std::vector<int> slot_;
  std::string load_note_;       ///< what the last deserialize() could not check (see load_note())
};

}  // namespace evnerf
