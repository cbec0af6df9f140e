// loss/objective.hpp — what a training step compares. An objective chooses the window of slices whose two
// end poses a step renders, the pixels it renders there (an events/pixels.hpp policy), and scores each
// pixel's rendered log change against the events counted in the window through the per-slice thresholds.
//   SliceInterval<Bound>             the paper's: one slice, its two ends (spec §2).
//   WindowInterval<W, Bound, Pixels> poses 1..W slices apart, drawn uniformly per step: the counts of every
//                                    slice in the window, each with its own learned thresholds.
// A new objective is one type with the members the `Objective` concept names. Depends on ad/ and events/.
#pragma once
#include <concepts>
#include <cstdint>
#include <string>

#include "../core/rng.hpp"
#include "../events/pixels.hpp"
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
/// to gbp[k], gbm[k]. With L = 1 this is spec §2's loss, computed exactly as EventBounds does.
template <BoundPolicy Bound>
PixelLoss window_pixel_loss(double l0, double l1, int L, const int* npos, const int* nneg, const double* bp, const double* bm,
                            double* gbp, double* gbm) {
  if (L == 1) {
    const auto r = Bound::make(npos[0], nneg[0]).evaluate(l0, l1, bp[0], bm[0]);
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
  const auto r = Bound::make(static_cast<int>(std::min<long>(Np, INT32_MAX)), static_cast<int>(std::min<long>(Nm, INT32_MAX)))
                     .evaluate(l0, l1, bpe, bme);
  for (int k = 0; k < L; ++k) {
    gbp[k] += r[3] * (Np > 0 ? npos[k] / static_cast<double>(Np) : 1.0 / L);
    gbm[k] += r[4] * (Nm > 0 ? nneg[k] / static_cast<double>(Nm) : 1.0 / L);
  }
  return {r[0], r[1], r[2]};
}

/// The paper's objective: a step draws one slice and renders its two ends at uniformly drawn pixels.
template <BoundPolicy Bound = SplitCounts<1>>
struct SliceInterval {
  using bound = Bound;
  using pixels = events::UniformPixels;
  static constexpr int max_window = 1;
  static std::string description() { return {}; }  // the checkpoints' loss text before windows existed
};

/// Windows of 1..W consecutive slices, the length uniform per step, then the start uniform among the
/// windows of that length made of trainable slices. Ours (after EventNeRF and Robust e-NeRF, which also
/// compare poses a random interval apart); the paper compares only the two ends of one slice, which leaves
/// low spatial frequencies free. `Pixels` chooses the rendered pixels.
template <int W, BoundPolicy Bound = HalfSlackCounts, class Pixels = events::UniformPixels>
struct WindowInterval {
  static_assert(W >= 1, "WindowInterval<W>: a window spans at least one slice.");
  using bound = Bound;
  using pixels = Pixels;
  static constexpr int max_window = W;
  static std::string description() {
    std::string d = ", window 1..";
    d.append(std::to_string(W)).append(", pixels ").append(Pixels::name);
    if constexpr (requires { Pixels::empty_per_mille; }) d.append(" ").append(std::to_string(Pixels::empty_per_mille));
    return d;
  }
};

/// An objective: a bound policy, a pixel policy, the longest window in slices, and the text checkpoints
/// record. EvNerf's fifth parameter takes one (a bare bound policy means SliceInterval<that bound>).
template <class O>
concept Objective = requires {
  typename O::bound;
  typename O::pixels;
  { O::max_window } -> std::convertible_to<int>;
  { O::description() } -> std::convertible_to<std::string>;
} && BoundPolicy<typename O::bound>;

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

}  // namespace evnerf::loss
