// loss/objective.hpp — what a training step compares. An objective chooses the window of slices whose two
// end poses a step renders, the pixels it renders there (an events/pixels.hpp policy), and scores each
// pixel's rendered log change against the events counted in the window through the per-slice thresholds.
//   SliceInterval<Bound>             the paper's: one slice, its two ends (spec §2).
//   WindowInterval<W, Bound, Pixels, Poses>
//                                    poses 1..W frame intervals apart (slices where each interval is one),
//                                    drawn uniformly per step: the counts of every slice in the window,
//                                    each with its own learned thresholds; with Poses = 3 also one inner
//                                    boundary per pixel, each pair of the three poses a term.
// A new objective is one type with the members the `Objective` concept names. draw_step() draws a step of
// any objective: its window, its noise, its pixels and their counts. Depends on ad/ and events/.
#pragma once
#include <concepts>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/rng.hpp"
#include "../core/error.hpp"
#include "../events/pixels.hpp"
#include "../events/slicing.hpp"
#include "event_loss.hpp"

namespace evnerf::loss {

/// How a pixel's counts become its interval: SplitCounts<K>, SignedCount, HalfSlackCounts, or your own.
template <class B>
concept BoundPolicy = requires(int a, int b) {
  { B::make(a, b) } -> std::same_as<EventBounds>;
  { B::name } -> std::convertible_to<const char*>;
};

/// One pixel's loss and its gradient w.r.t. the luminance rendered at the window's two ends.
struct PixelLoss {
  double value = 0, dl0 = 0, dl1 = 0;
};

/// Scores one pixel over a window of L slices: per-slice counts npos[k], nneg[k] and thresholds bp[k] > 0 >
/// bm[k]. The interval is the bound policy's for the window's total counts N± with the count-weighted
/// thresholds B±_eff = Σ_k n±_k B±_k / N± (the plain mean where N± = 0), so its centre is exactly
/// Σ_k n⁺_k B⁺_k + Σ_k n⁻_k B⁻_k and its slack is in units of the thresholds that fired. Adds dloss/dB±_k
/// to gbp[k], gbm[k]. With L = 1 this is spec §2's loss, computed exactly as EventBounds does. `log_eps` is
/// the ε of log(ℓ + ε) (the field's radiance policy's; the spec's 1e-3 by default).
template <BoundPolicy Bound>
PixelLoss window_pixel_loss(double l0, double l1, int L, const int* npos, const int* nneg, const double* bp, const double* bm,
                            double* gbp, double* gbm, double log_eps = EventBounds{}.eps) {
  auto bounds = [log_eps](int np, int nm) {
    auto b = Bound::make(np, nm);
    b.eps = log_eps;
    return b;
  };
  if (L == 1) {
    const auto r = bounds(npos[0], nneg[0]).evaluate(l0, l1, bp[0], bm[0]);
    gbp[0] += r[3];
    gbm[0] += r[4];
    return {r[0], r[1], r[2]};
  }
  long Np = 0, Nm = 0;
  double sp = 0, sm = 0, mp = 0, mm = 0;
  for (int k = 0; k < L; ++k) {
    Np += npos[k];
    Nm += nneg[k];
    sp += npos[k] * bp[k];
    sm += nneg[k] * bm[k];
    mp += bp[k];
    mm += bm[k];
  }
  const double bpe = Np > 0 ? sp / static_cast<double>(Np) : mp / L, bme = Nm > 0 ? sm / static_cast<double>(Nm) : mm / L;
  const auto r = bounds(static_cast<int>(std::min<long>(Np, INT32_MAX)), static_cast<int>(std::min<long>(Nm, INT32_MAX)))
                     .evaluate(l0, l1, bpe, bme);
  for (int k = 0; k < L; ++k) {
    gbp[k] += r[3] * (Np > 0 ? npos[k] / static_cast<double>(Np) : 1.0 / L);
    gbm[k] += r[4] * (Nm > 0 ? nneg[k] / static_cast<double>(Nm) : 1.0 / L);
  }
  return {r[0], r[1], r[2]};
}

/// One pixel's loss at three poses of its window and its gradient w.r.t. the luminance rendered at each.
struct ThreePoseLoss {
  double value = 0, dl0 = 0, dlm = 0, dl1 = 0;
};

/// Scores one pixel rendered at three boundaries of its window of L slices: the start (ℓ0), the inner
/// boundary m with 0 < m < L (ℓm) and the end (ℓ1). The sum of window_pixel_loss over the three pairs:
/// (ℓ0, ℓ1) over slices [0, L), (ℓ0, ℓm) over [0, m) and (ℓm, ℓ1) over [m, L), each with its own slices'
/// counts and thresholds. Adds dloss/dB±_k to gbp[k], gbm[k].
template <BoundPolicy Bound>
ThreePoseLoss three_pose_pixel_loss(double l0, double lm, double l1, int m, int L, const int* npos, const int* nneg, const double* bp,
                                    const double* bm, double* gbp, double* gbm, double log_eps = EventBounds{}.eps) {
  require(m > 0 && m < L, "three_pose_pixel_loss: the inner boundary must lie strictly inside the window");
  const auto w = window_pixel_loss<Bound>(l0, l1, L, npos, nneg, bp, bm, gbp, gbm, log_eps);
  const auto a = window_pixel_loss<Bound>(l0, lm, m, npos, nneg, bp, bm, gbp, gbm, log_eps);
  const auto b = window_pixel_loss<Bound>(lm, l1, L - m, npos + m, nneg + m, bp + m, bm + m, gbp + m, gbm + m, log_eps);
  return {w.value + a.value + b.value, w.dl0 + a.dl0, a.dl1 + b.dl0, w.dl1 + b.dl1};
}

/// The paper's objective: a step draws one slice and renders its two ends at uniformly drawn pixels.
template <BoundPolicy Bound = SplitCounts<1>>
struct SliceInterval {
  using bound = Bound;
  using pixels = events::UniformPixels;
  static constexpr int max_window = 1;
  static std::string description() { return {}; }  // the checkpoints' loss text before windows existed
};

/// Windows of 1..W intervals of the recording's own cut (1..W·K consecutive slices where train's --subslices
/// cuts each interval into K), the length uniform per step, then the start uniform among the windows of that
/// length made of trainable slices. Ours (after EventNeRF and Robust e-NeRF, which also
/// compare poses a random interval apart); the paper compares only the two ends of one slice, which leaves
/// low spatial frequencies free. `Pixels` chooses the rendered pixels.
/// `Poses` is how many boundaries of the window a pixel is rendered at: 2, the window's two ends; or 3, the
/// ends and one slice boundary strictly inside the window, drawn per pixel (uniform; a one-slice window has
/// none, and its pixels are rendered at the ends only). With three poses each of the three pairs is a term
/// (the whole window and its two parts, each with its own slices' counts and thresholds): three terms from
/// three rays where two poses give one from two. Ours.
template <int W, BoundPolicy Bound = HalfSlackCounts, class Pixels = events::UniformPixels, int Poses = 2>
struct WindowInterval {
  static_assert(W >= 1, "WindowInterval<W>: a window spans at least one slice.");
  static_assert(Poses == 2 || Poses == 3, "WindowInterval: a pixel is rendered at 2 or 3 poses of its window.");
  using bound = Bound;
  using pixels = Pixels;
  static constexpr int max_window = W;
  static constexpr int poses = Poses;
  static std::string description() {
    std::string d = ", window 1..";
    d.append(std::to_string(W)).append(", pixels ").append(Pixels::name);
    if constexpr (requires { Pixels::empty_per_mille; }) d.append(" ").append(std::to_string(Pixels::empty_per_mille));
    if constexpr (Poses != 2) d.append(", ").append(std::to_string(Poses)).append(" poses");
    return d;
  }
};

/// How many poses of its window objective O renders a pixel at: O::poses where O names it, else 2 (the
/// window's two ends, as SliceInterval and every objective written before the member existed).
template <class O>
constexpr int poses_of() {
  if constexpr (requires { O::poses; }) return O::poses;
  else return 2;
}

/// An objective: a bound policy, a pixel policy, the longest window in slices, and the text checkpoints
/// record. EvNerf's fifth parameter takes one (a bare bound policy means SliceInterval<that bound>).
template <class O>
concept Objective = requires {
  typename O::bound;
  typename O::pixels;
  { O::max_window } -> std::convertible_to<int>;
  { O::description() } -> std::convertible_to<std::string>;
} && BoundPolicy<typename O::bound>;

/// Objective O with the total-variation regulariser (loss::LogTv, EvNerf::set_tv) on by default at weight
/// PerMille/1000, comparing each pixel with the neighbour `Neighbours` picks (EvNerf::set_tv_neighbours),
/// for a share SharePerMille/1000 of the step's pixels (EvNerf::set_tv_share). Training settings like the
/// learning rate: the checkpoints' loss text is O's, and EvNerf's setters (train --tv, --tv-neighbours,
/// --tv-share) override them.
template <Objective O, int PerMille, TvNeighbours Neighbours = TvNeighbours::Any, int SharePerMille = 1000>
struct WithTv : O {
  static_assert(PerMille >= 0, "WithTv: the weight must not be negative.");
  static_assert(SharePerMille > 0 && SharePerMille <= 1000, "WithTv: the share must lie in (0, 1000] per mille.");
  static constexpr double tv_weight = PerMille / 1000.0;
  static constexpr TvNeighbours tv_neighbours = Neighbours;
  static constexpr double tv_share = SharePerMille / 1000.0;
};

template <class P>
struct as_objective {
  static_assert(Objective<P>, "EvNerf: the fifth parameter must be an objective (loss::SliceInterval, loss::WindowInterval, ...) "
                              "or a bound policy (loss::SplitCounts<K>, loss::SignedCount, loss::HalfSlackCounts).");
  using type = P;
};
template <BoundPolicy P>
struct as_objective<P> {
  using type = SliceInterval<P>;
};

/// What a training step draws: its window of slices [first, first + len), its pixels, and for every pixel
/// and slice of the window the counts with the injected noise; the rest is scratch kept between steps.
struct StepDraw {
  std::size_t first = 0, len = 1;
  std::vector<std::uint32_t> pixels;
  std::vector<int> npos, nneg;  ///< P × len: pixel i's counts in slice first + k at i · len + k
  /// Objectives of three poses: pixel i's inner boundary, first + mid[i], with 0 < mid[i] < len (0 where
  /// the window is one slice long and has none). Empty for objectives of two poses.
  std::vector<std::uint32_t> mid;
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
/// and the noise to the pixels that carry events. Deterministic for a given rng.
template <Objective O>
void draw_step(const events::SliceSet& slices, const std::vector<bool>& enabled, const events::CountPrefix& prefix,
               double noise_ratio, int pixels_per_step, Rng& rng, StepDraw& d, const events::PixelSites* sites = nullptr,
               int per_interval = 1) {
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
  for (int i = 0; i < P; ++i)
    for (std::size_t k = 0; k < L; ++k) {
      const auto& c = slices.slices[first + k];
      d.npos[static_cast<std::size_t>(i) * L + k] = c.pos[d.pixels[i]];
      d.nneg[static_cast<std::size_t>(i) * L + k] = c.neg[d.pixels[i]];
    }
  if (!d.noise.empty()) {
    if (d.slot.size() != hw) d.slot.assign(hw, -1);
    for (int i = 0; i < P; ++i) d.slot[d.pixels[i]] = i;
    for (const auto& e : d.noise) {
      const int i = d.slot[e.pixel];
      if (i < 0) continue;
      int& c = (e.positive ? d.npos : d.nneg)[static_cast<std::size_t>(i) * L + e.slice];
      if (c < INT16_MAX) ++c;
    }
    for (int i = 0; i < P; ++i) d.slot[d.pixels[i]] = -1;
  }
  // Drawn last, so that an objective of two poses draws exactly as before the inner boundary existed.
  d.mid.clear();
  if constexpr (poses_of<O>() == 3) {
    d.mid.resize(static_cast<std::size_t>(P), 0);
    if (L >= 2)
      for (int i = 0; i < P; ++i) d.mid[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(1 + rng.below(L - 1));
  }
}

}  // namespace evnerf::loss
