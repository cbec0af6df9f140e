// loss/step.hpp — what a training step hands an objective. A step draws its window of slices, its pixels and
// their noisy counts (StepDraw, draw_step); the model cuts the pixels into tiles, and for each tile asks the
// objective which rays to render (RayList), renders them, and gives the objective the rendered values
// (RenderedValues) and the window's thresholds (WindowThresholds); the objective returns its loss and writes
// the gradient with respect to both. TileView is everything an objective may read about the tile.
// Depends on core/, events/ and geometry/.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../events/pixels.hpp"
#include "../events/slicing.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"

namespace evnerf::loss {

/// What a training step draws: its window of slices [first, first + len), its pixels, and for every pixel
/// and slice of the window the counts with the injected noise; the rest is scratch kept between steps.
struct StepDraw {
  std::size_t first = 0, len = 1;
  std::vector<std::uint32_t> pixels;
  std::vector<int> npos, nneg;  ///< P × len: pixel i's counts in slice first + k at i · len + k
  /// Under a refractory period (draw_step's `refractory` ≥ 0; all empty otherwise), P × len as npos: the
  /// crossings the counts stand for (events::dead_time_weight summed, an injected event counting one), their
  /// derivatives w.r.t. the period, and the saturated bits (1: n⁺ is a lower bound, 2: n⁻ is).
  std::vector<double> wpos, wneg, dwpos, dwneg;
  std::vector<std::uint8_t> limited;
  std::vector<events::NoiseEvent> noise;
  std::vector<std::size_t> starts;
  std::vector<std::uint8_t> taken;
  std::vector<int> slot;
};

/// Draws a step of objective O from `rng`: the window (one slice when O::max_window = 1: uniform among
/// the trainable slices, as the paper; otherwise the length uniform in 1..max_window × `per_interval`, then
/// the start uniform among the windows of that length whose slices are all trainable, shorter when there is
/// none; `per_interval` is the slices per interval of the recording's own cut, TrainingData's
/// slices_per_interval, so finer cuts move the windows' ends, not their span in time),
/// then Ev-NeRF's noise (noise_ratio × the window's count, each event in a random slice of the window,
/// redrawn at every step; drawn before the pixels, so a one-slice step draws as inject_noise does), then
/// the pixels by O's pixel policy, then their counts with the noise added (saturating like inject_noise).
/// `enabled` marks trainable slices (empty: all); `sites`, where not null and not all(), restricts the pixels
/// and the noise to the pixels that carry events. `refractory` ≥ 0 (seconds; the slices must keep their
/// intervals) weighs each event by the crossings it stands for (StepDraw::wpos); negative: plain counts.
/// Deterministic for a given rng.
template <class O>
void draw_step(const events::SliceSet& slices, const std::vector<bool>& enabled, const events::CountPrefix& prefix, double noise_ratio,
               int pixels_per_step, Rng& rng, StepDraw& d, const events::PixelSites* sites = nullptr, int per_interval = 1,
               double refractory = -1) {
  require(per_interval >= 1, "train_step: slices per interval must be at least 1, got " + std::to_string(per_interval));
  const std::size_t N = slices.size();
  auto trainable = [&](std::size_t i) { return enabled.empty() || enabled[i]; };
  d.starts.clear();
  if constexpr (O::max_window == 1) {
    for (std::size_t i = 0; i < N; ++i)
      if (trainable(i)) d.starts.push_back(i);
    require(!d.starts.empty(), "train_step: no slice to train on");
    d.first = d.starts[rng.below(d.starts.size())];
    d.len = 1;
  } else {
    std::vector<std::size_t> run(N + 1, 0);  // run[i]: trainable slices in a row from i
    for (std::size_t i = N; i-- > 0;) run[i] = trainable(i) ? run[i + 1] + 1 : 0;
    std::size_t L = 1 + rng.below(static_cast<std::uint64_t>(O::max_window) * static_cast<std::uint64_t>(per_interval));
    for (; L >= 1; --L) {
      for (std::size_t i = 0; i + L <= N; ++i)
        if (run[i] >= L) d.starts.push_back(i);
      if (!d.starts.empty()) break;
    }
    require(!d.starts.empty(), "train_step: no slice to train on");
    d.first = d.starts[rng.below(d.starts.size())];
    d.len = L;
  }
  const std::size_t first = d.first, L = d.len;
  const std::size_t hw = slices.slices[first].pixels();
  d.noise.clear();
  if (noise_ratio > 0) {
    std::size_t total = 0;
    for (std::size_t k = 0; k < L; ++k) total += slices.slices[first + k].total;
    events::draw_noise(total, noise_ratio, hw, L, rng, d.noise, sites ? &sites->list : nullptr);
  }
  if (d.taken.size() != hw) d.taken.assign(hw, 0);
  if (sites && !sites->all()) require(sites->mask.size() == hw, "train_step: the pixel sites do not match the sensor");
  O::pixels::draw(events::PixelWindow{hw, first, first + L, &prefix, sites && !sites->all() ? sites : nullptr}, pixels_per_step, rng,
                  d.pixels, d.taken);
  const int P = static_cast<int>(d.pixels.size());
  require(P > 0, "train_step: no pixel to train on");
  d.npos.resize(static_cast<std::size_t>(P) * L);
  d.nneg.resize(static_cast<std::size_t>(P) * L);
  const bool weighed = refractory >= 0;
  require(!weighed || slices.slices[first].has_intervals(), "train_step: a refractory period needs the slices' event intervals");
  const std::size_t PL = weighed ? static_cast<std::size_t>(P) * L : 0;
  d.wpos.assign(PL, 0.0);
  d.wneg.assign(PL, 0.0);
  d.dwpos.assign(PL, 0.0);
  d.dwneg.assign(PL, 0.0);
  d.limited.assign(PL, 0);
  for (int i = 0; i < P; ++i)
    for (std::size_t k = 0; k < L; ++k) {
      const auto& c = slices.slices[first + k];
      const std::size_t o = static_cast<std::size_t>(i) * L + k;
      d.npos[o] = c.pos[d.pixels[i]];
      d.nneg[o] = c.neg[d.pixels[i]];
      if (!weighed) continue;
      const auto [g0, g1] = c.intervals(d.pixels[i]);
      for (const float* g = g0; g != g1; ++g) {
        const bool on = *g > 0;
        const auto w = events::dead_time_weight(std::abs(static_cast<double>(*g)), refractory);
        (on ? d.wpos : d.wneg)[o] += w.weight;
        (on ? d.dwpos : d.dwneg)[o] += w.dweight;
        if (w.saturated) d.limited[o] |= on ? 1 : 2;
      }
    }
  if (!d.noise.empty()) {
    if (d.slot.size() != hw) d.slot.assign(hw, -1);
    for (int i = 0; i < P; ++i) d.slot[d.pixels[i]] = i;
    for (const auto& e : d.noise) {
      const int i = d.slot[e.pixel];
      if (i < 0) continue;
      const std::size_t o = static_cast<std::size_t>(i) * L + e.slice;
      int& c = (e.positive ? d.npos : d.nneg)[o];
      if (c < INT16_MAX) {
        ++c;
        if (weighed) (e.positive ? d.wpos : d.wneg)[o] += 1;
      }
    }
    for (int i = 0; i < P; ++i) d.slot[d.pixels[i]] = -1;
  }
}

/// One pixel's counts over a window under a refractory period: per slice, the crossings its ON and OFF events
/// stand for, their derivatives w.r.t. the period, and the saturated bits (all null: plain counts).
struct DeadTimeCounts {
  const double *wpos = nullptr, *wneg = nullptr, *dwpos = nullptr, *dwneg = nullptr;
  const std::uint8_t* limited = nullptr;
  explicit operator bool() const { return wpos != nullptr; }
};

/// Everything an objective may read about one tile of a step: the step's draw, the tile's pixels
/// (draw.pixels[p0 .. p0 + P)), the step's pixel count (every loss is a mean over it), the sensor, the
/// boundary poses and pixel directions rays are cast from, the scene's depth range, the ε of the field's
/// log(ℓ + ε), the step's ray key (a ray's random stream is Rng(ray_key).split(its key)), the step, and a
/// teacher's images where the model has one (loss::Teacher).
struct TileView {
  const StepDraw* draw = nullptr;
  int p0 = 0, P = 0, batch = 1;
  int channels = 1;  ///< the field's: 1 grey, 3 colour behind a Bayer mosaic
  const geometry::Camera* camera = nullptr;
  const geometry::BayerPattern* bayer = nullptr;
  const geometry::Pose* poses = nullptr;  ///< boundary poses: slice k lies between poses[k] and poses[k + 1]
  const Vec3f* pixel_dirs = nullptr;      ///< render::pixel_directions of the camera
  double near = 0, far = 0, log_eps = 1e-3;
  std::uint64_t ray_key = 0;
  long step = 0;                   ///< the training step (a term's schedule)
  const float* teacher = nullptr;  ///< TrainingData::teacher (a teacher's images at the boundary poses), or null

  int width() const { return camera->width(); }
  int height() const { return camera->height(); }
  std::size_t first() const { return draw->first; }
  int len() const { return static_cast<int>(draw->len); }
  /// Tile pixel i's index on the sensor (y · width + x).
  std::uint32_t pixel(int i) const { return draw->pixels[static_cast<std::size_t>(p0 + i)]; }
  /// Tile pixel i's counts in the window's slices (len() of each).
  const int* npos(int i) const { return &draw->npos[static_cast<std::size_t>(p0 + i) * draw->len]; }
  const int* nneg(int i) const { return &draw->nneg[static_cast<std::size_t>(p0 + i) * draw->len]; }
  /// Tile pixel i's saturated bits in the window's slices (StepDraw::limited), or null without a refractory period.
  const std::uint8_t* limited(int i) const {
    return draw->limited.empty() ? nullptr : &draw->limited[static_cast<std::size_t>(p0 + i) * draw->len];
  }
  /// Tile pixel i's counts as the crossings they stand for under the refractory period (StepDraw::wpos …),
  /// or all null without one.
  DeadTimeCounts dead_time(int i) const {
    if (draw->wpos.empty()) return {};
    const std::size_t o = static_cast<std::size_t>(p0 + i) * draw->len;
    return {&draw->wpos[o], &draw->wneg[o], &draw->dwpos[o], &draw->dwneg[o], &draw->limited[o]};
  }
  /// The channel tile pixel i's events see: 0 for a grey field, else its colour in the mosaic.
  int channel(int i) const {
    if (channels == 1) return 0;
    const std::uint32_t p = pixel(i), w = static_cast<std::uint32_t>(width());
    return bayer->at(static_cast<int>(p % w), static_cast<int>(p / w));
  }
  /// The window's two end poses.
  const geometry::Pose& start_pose() const { return poses[draw->first]; }
  const geometry::Pose& end_pose() const { return poses[draw->first + draw->len]; }
};

/// The rays a tile renders, in order: each the ray through a sensor pixel from a boundary pose, with the key
/// of its random stream. Objectives append theirs; keys must differ between rays of a tile.
struct RayList {
  std::vector<std::size_t> pose;
  std::vector<std::uint32_t> pixel;
  std::vector<std::uint64_t> key;
  /// Appends a ray; returns its index.
  int add(std::size_t pose_index, std::uint32_t pixel_index, std::uint64_t stream_key) {
    pose.push_back(pose_index);
    pixel.push_back(pixel_index);
    key.push_back(stream_key);
    return static_cast<int>(pose.size()) - 1;
  }
  int size() const { return static_cast<int>(pose.size()); }
  void clear() {
    pose.clear();
    pixel.clear();
    key.clear();
  }
};

/// The rays every objective starts with: tile pixel i at the window's start pose is ray 2i, at its end pose
/// ray 2i + 1 (keys 2 · pixel and 2 · pixel + 1). Regularisers may read them (TotalVariation does).
inline void add_end_rays(const TileView& t, RayList& rays) {
  for (int i = 0; i < t.P; ++i) {
    const std::uint32_t p = t.pixel(i);
    rays.add(t.draw->first, p, std::uint64_t{p} * 2);
    rays.add(t.draw->first + t.draw->len, p, std::uint64_t{p} * 2 + 1);
  }
}

/// One pass's rendered luminance of a tile's rays (`Composite`: anything with color[c], as
/// render::Composite) and the gradient buffer the objective adds dloss/dvalue to (zeroed by the forward).
/// For a term on the samples themselves (one that declares `reads_samples`, as loss::Distortion), and only
/// while such a term is on: the samples per ray, their depths along each ray (rays × samples, as the
/// composites' weights) and the buffer the term adds dloss/dweight to (zeroed); otherwise 0 and null.
template <class Composite, class Scalar>
struct RenderedValues {
  const Composite* comp;
  Scalar* grad;
  int channels;
  int samples = 0;
  const Scalar* depth = nullptr;
  Scalar* weight_grad = nullptr;
  double at(int ray, int c) const { return static_cast<double>(comp[ray].color[c]); }
  void add(int ray, int c, double g) const { grad[static_cast<std::size_t>(ray) * channels + c] += static_cast<Scalar>(g); }
};

/// The thresholds of the step's window, B⁺_k > 0 > B⁻_k for its slices k = 0 .. len − 1, and where their
/// gradient goes (none for fixed thresholds).
template <class Scalar>
struct WindowThresholds {
  int len = 1;
  const double* pos = nullptr;
  const double* neg = nullptr;
  Scalar* grad = nullptr;             ///< B⁺_k's at 2k, B⁻_k's at 2k + 1; null: fixed thresholds
  double* refractory_grad = nullptr;  ///< where dloss/dτ goes (a learned refractory period; null: none)
  void add(int k, double dpos, double dneg) const {
    if (!grad) return;
    grad[2 * k] += static_cast<Scalar>(dpos);
    grad[2 * k + 1] += static_cast<Scalar>(dneg);
  }
};

}  // namespace evnerf::loss
