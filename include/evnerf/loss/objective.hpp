// loss/objective.hpp — what a training step compares. An objective is one type: how a step draws its window
// of slices and its pixels (max_window, an events/pixels.hpp policy), which rays a tile renders (rays), and
// how the rendered values score (score: the loss, its gradient with respect to every rendered value and to
// the window's thresholds; loss/step.hpp). The model calls it and holds no objective-specific code.
//   SliceInterval<Bound>             the paper's: one slice, its two ends, each pixel's change inside the
//                                    interval its counts imply (spec §2).
//   WindowInterval<W, Bound, Pixels> poses 1..W frame intervals apart, drawn uniformly per step: the counts
//                                    of every slice in the window, each with its own learned thresholds.
//   Plus<O, R...>                    objective O with regularisers R... (loss/total_variation.hpp's,
//                                    loss/distortion.hpp's, or your own: a type with the members
//                                    `Regulariser` names), each rendering the rays it needs after O's.
// A new objective or regulariser is one type in your own header (examples/parts/). Depends on ad/, events/
// and geometry/ (through step.hpp).
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <cstdint>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "event_loss.hpp"
#include "step.hpp"

namespace evnerf::loss {

/// How a pixel's counts become its interval: SplitCounts<K>, SignedCount, HalfSlackCounts, or your own.
template <class B>
concept BoundPolicy = requires(int a, int b) {
  { B::make(a, b) } -> std::same_as<EventBounds>;
  { B::name } -> std::convertible_to<const char*>;
};

/// A bound policy's name as checkpoints record it: its name, and its slack where it has one.
template <BoundPolicy B>
std::string bound_text() {
  std::string d = B::name;
  if constexpr (requires { B::slack; }) d.append(" ").append(std::to_string(B::slack));
  return d;
}

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
/// Under a refractory period (`dt` not null: TileView::dead_time) the counts in the centre and the weights
/// are the crossings the events stand for (the slack's size still follows the event counts), a window with
/// a saturated n⁺ has no upper end and one with a saturated n⁻ no lower end (the pixel may have changed
/// more than it could fire), and dloss/dτ is added to `gtau` where not null.
template <BoundPolicy Bound>
PixelLoss window_pixel_loss(double l0, double l1, int L, const int* npos, const int* nneg, const double* bp, const double* bm, double* gbp,
                            double* gbm, double log_eps = EventBounds{}.eps, const DeadTimeCounts& dt = {}, double* gtau = nullptr) {
  unsigned open = 0;
  if (dt)
    for (int k = 0; k < L; ++k) open |= dt.limited[k];
  // The bounds for n⁺, n⁻ events standing for wp, wm crossings.
  auto bounds = [log_eps, open](int np, int nm, double wp, double wm) {
    auto b = Bound::make(np, nm);
    b.eps = log_eps;
    b.n_pos *= wp / std::max(np, 1);
    b.n_neg *= wm / std::max(nm, 1);
    b.open_pos = b.open_pos || (open & 1u);
    b.open_neg = b.open_neg || (open & 2u);
    return b;
  };
  // dloss/dμ of bounds `b` at the rendered change: +1 below the lower end, −1 above the upper end.
  auto dmu = [&](const EventBounds& b, double bpe, double bme) {
    const double change = std::log(l1 + log_eps) - std::log(l0 + log_eps), mu = b.n_pos * bpe + b.n_neg * bme;
    if (!b.open_neg && mu + b.k_neg * bme - change > 0) return 1.0;
    if (!b.open_pos && change - (mu + b.k_pos * bpe) > 0) return -1.0;
    return 0.0;
  };
  if (L == 1) {
    const double wp = dt ? dt.wpos[0] : npos[0], wm = dt ? dt.wneg[0] : nneg[0];
    const auto b = bounds(npos[0], nneg[0], wp, wm);
    const auto r = b.evaluate(l0, l1, bp[0], bm[0]);
    gbp[0] += r[3];
    gbm[0] += r[4];
    if (dt && gtau) *gtau += dmu(b, bp[0], bm[0]) * (bp[0] * dt.dwpos[0] + bm[0] * dt.dwneg[0]);
    return {r[0], r[1], r[2]};
  }
  long Np = 0, Nm = 0;
  double Wp = 0, Wm = 0, sp = 0, sm = 0, mp = 0, mm = 0;
  for (int k = 0; k < L; ++k) {
    const double wp = dt ? dt.wpos[k] : npos[k], wm = dt ? dt.wneg[k] : nneg[k];
    Np += npos[k];
    Nm += nneg[k];
    Wp += wp;
    Wm += wm;
    sp += wp * bp[k];
    sm += wm * bm[k];
    mp += bp[k];
    mm += bm[k];
  }
  const double bpe = Wp > 0 ? sp / Wp : mp / L, bme = Wm > 0 ? sm / Wm : mm / L;
  const auto b = bounds(static_cast<int>(std::min<long>(Np, INT32_MAX)), static_cast<int>(std::min<long>(Nm, INT32_MAX)), Wp, Wm);
  const auto r = b.evaluate(l0, l1, bpe, bme);
  for (int k = 0; k < L; ++k) {
    const double wp = dt ? dt.wpos[k] : npos[k], wm = dt ? dt.wneg[k] : nneg[k];
    gbp[k] += r[3] * (Wp > 0 ? wp / Wp : 1.0 / L);
    gbm[k] += r[4] * (Wm > 0 ? wm / Wm : 1.0 / L);
  }
  if (dt && gtau) {
    // The loss depends on each slice's crossings through μ = Σ w⁺_k B⁺_k + Σ w⁻_k B⁻_k and through the slack's
    // thresholds B±_eff = Σ w±_k B±_k / W±, whose own dloss/dB±_eff with μ held is r[3] − dloss/dμ · W⁺.
    const double g = dmu(b, bpe, bme), sp_slack = r[3] - g * b.n_pos, sm_slack = r[4] - g * b.n_neg;
    double d = 0;
    for (int k = 0; k < L; ++k) {
      const double dp = g * bp[k] + (Wp > 0 ? sp_slack * (bp[k] - bpe) / Wp : 0.0);
      const double dm = g * bm[k] + (Wm > 0 ? sm_slack * (bm[k] - bme) / Wm : 0.0);
      d += dp * dt.dwpos[k] + dm * dt.dwneg[k];
    }
    *gtau += d;
  }
  return {r[0], r[1], r[2]};
}

/// A rendered composite with up to three channels: what the concepts below probe objectives with.
struct ProbeComposite {
  float color[3];
};

/// An objective: how a step draws (`pixels`, `max_window`), the rays of a tile (`rays`: the ends first, as
/// add_end_rays lays them out), their score (`score` adds each term's loss to losses[term] and the gradients
/// to the values and thresholds), the expected rays per pixel of a step (`rays_per_pixel`), its terms'
/// names (the first its event term; log.jsonl writes `<name>_loss` for the others), and the text
/// checkpoints record (`bounds`, `description`). `scratch` is a thread's state between rays and score.
/// EvNerf's fifth parameter takes one (a bare bound policy means SliceInterval<that bound>).
template <class O>
concept Objective = std::default_initializable<O> &&
    requires(const O& o, const TileView& t, RayList& rays, typename O::scratch& s, const RenderedValues<ProbeComposite, float>& v,
             const WindowThresholds<float>& th, double* losses) {
  typename O::pixels;
  { O::max_window } -> std::convertible_to<int>;
  { O::n_terms } -> std::convertible_to<int>;
  { O::term_name(0) } -> std::convertible_to<const char*>;
  { O::bounds() } -> std::convertible_to<std::string>;
  { O::description() } -> std::convertible_to<std::string>;
  o.rays(t, rays, s);
  o.score(t, v, th, s, losses);
  { o.rays_per_pixel() } -> std::convertible_to<double>;
  { o.active(0) } -> std::convertible_to<bool>;
};

/// A regulariser: a term added to an objective by Plus. `rays` appends the rays it needs (it may read the
/// objective's end rays, 2i and 2i + 1 for tile pixel i), `score` returns its loss over the tile (a mean over
/// the step's pixels) and adds its gradients; `active` false means it renders and adds nothing (the step is
/// then the objective's alone, to the bit); `rays_per_pixel` its expected rays per step pixel.
template <class R>
concept Regulariser = std::default_initializable<R> &&
    requires(const R& r, const TileView& t, RayList& rays, typename R::scratch& s, const RenderedValues<ProbeComposite, float>& v,
             const WindowThresholds<float>& th) {
  { R::name } -> std::convertible_to<const char*>;
  r.rays(t, rays, s);
  { r.score(t, v, th, s) } -> std::convertible_to<double>;
  { r.rays_per_pixel() } -> std::convertible_to<double>;
  { r.active() } -> std::convertible_to<bool>;
};

/// Whether objective O would, as it is now, read the samples of a pass (a regulariser on them that is on:
/// loss::Distortion); the model then hands them over (RenderedValues' depth and weight_grad).
template <class O>
bool needs_samples(const O& o) {
  if constexpr (requires { o.needs_samples(); }) return o.needs_samples();
  else return false;
}

/// The part every objective that renders a pixel at its window's two ends shares: the draw (`Pixels`, windows
/// of up to W intervals) and the rays (add_end_rays). Derive from it and add `score` and the names.
template <int W, class Pixels = events::UniformPixels>
struct EndsObjective {
  static_assert(W >= 1, "EndsObjective<W>: a window spans at least one slice.");
  using pixels = Pixels;
  static constexpr int max_window = W;
  static constexpr int n_terms = 1;
  static const char* term_name(int) { return "event"; }
  template <class Scratch>
  void rays(const TileView& t, RayList& rays, Scratch&) const {
    add_end_rays(t, rays);
  }
  double rays_per_pixel() const { return 2; }
  bool active(int) const { return true; }
};

/// Ev-NeRF's event term over a window's two ends: each pixel's rendered log change against the interval
/// its counts imply (window_pixel_loss), a mean over the step's pixels.
template <BoundPolicy Bound>
struct IntervalScore {
  struct scratch {
    std::vector<double> gbp, gbm;
  };
  template <class V, class T>
  static double score(const TileView& t, const V& v, const T& th, scratch& s) {
    const int L = t.len();
    s.gbp.resize(static_cast<std::size_t>(L));
    s.gbm.resize(static_cast<std::size_t>(L));
    double total = 0;
    for (int i = 0; i < t.P; ++i) {
      const int c = t.channel(i);
      std::fill(s.gbp.begin(), s.gbp.end(), 0.0);
      std::fill(s.gbm.begin(), s.gbm.end(), 0.0);
      double gtau = 0;
      const auto r = window_pixel_loss<Bound>(v.at(2 * i, c), v.at(2 * i + 1, c), L, t.npos(i), t.nneg(i), th.pos, th.neg, s.gbp.data(),
                                              s.gbm.data(), t.log_eps, t.dead_time(i), th.refractory_grad ? &gtau : nullptr);
      if (th.refractory_grad) *th.refractory_grad += gtau / t.batch;
      total += r.value / t.batch;
      v.add(2 * i, c, r.dl0 / t.batch);
      v.add(2 * i + 1, c, r.dl1 / t.batch);
      for (int k = 0; k < L; ++k) th.add(k, s.gbp[k] / t.batch, s.gbm[k] / t.batch);
    }
    return total;
  }
};

/// The paper's objective: a step draws one slice and renders its two ends at uniformly drawn pixels.
template <BoundPolicy Bound = SplitCounts<1>>
struct SliceInterval : EndsObjective<1> {
  using bound = Bound;
  using scratch = typename IntervalScore<Bound>::scratch;
  static std::string bounds() { return bound_text<Bound>(); }
  static std::string description() { return {}; }
  template <class V, class T>
  void score(const TileView& t, const V& v, const T& th, scratch& s, double* losses) const {
    losses[0] += IntervalScore<Bound>::score(t, v, th, s);
  }
};

/// Windows of 1..W intervals of the recording's own cut (1..W·K consecutive slices where train's --subslices
/// cuts each interval into K), the length uniform per step, then the start uniform among the windows of that
/// length made of trainable slices. Ours (after EventNeRF and Robust e-NeRF, which also compare poses a
/// random interval apart); the paper compares only the two ends of one slice, which leaves low spatial
/// frequencies free. `Pixels` chooses the rendered pixels.
template <int W, BoundPolicy Bound = HalfSlackCounts, class Pixels = events::UniformPixels>
struct WindowInterval : EndsObjective<W, Pixels> {
  using bound = Bound;
  using scratch = typename IntervalScore<Bound>::scratch;
  static std::string bounds() { return bound_text<Bound>(); }
  static std::string description() {
    std::string d = ", window 1..";
    d.append(std::to_string(W)).append(", pixels ").append(Pixels::name);
    if constexpr (requires { Pixels::empty_per_mille; }) d.append(" ").append(std::to_string(Pixels::empty_per_mille));
    return d;
  }
  template <class V, class T>
  void score(const TileView& t, const V& v, const T& th, scratch& s, double* losses) const {
    losses[0] += IntervalScore<Bound>::score(t, v, th, s);
  }
};

/// Objective O with the regularisers R... added: O's rays, then each regulariser's; the loss is O's event
/// term plus each regulariser's term. The checkpoints' loss text is O's: a regulariser's weight is a training
/// setting (a fast checkpoint resumes as fast-no-tv, and the other way).
template <Objective O, Regulariser... R>
struct Plus : O {
  static_assert(O::n_terms == 1, "loss::Plus: the first part is an objective of one term; add every regulariser in one Plus.");
  static constexpr int n_terms = 1 + static_cast<int>(sizeof...(R));
  std::tuple<R...> regularisers;
  struct scratch {
    typename O::scratch objective;
    std::tuple<typename R::scratch...> terms;
  };
  static const char* term_name(int k) {
    if (k == 0) return O::term_name(0);
    const char* names[] = {R::name...};
    return names[k - 1];
  }
  void rays(const TileView& t, RayList& rays, scratch& s) const {
    O::rays(t, rays, s.objective);
    each([&](const auto& r, auto& rs, int) { r.rays(t, rays, rs); }, s);
  }
  template <class V, class T>
  void score(const TileView& t, const V& v, const T& th, scratch& s, double* losses) const {
    O::score(t, v, th, s.objective, losses);
    each([&](const auto& r, auto& rs, int k) { losses[1 + k] += r.score(t, v, th, rs); }, s);
  }
  /// Whether a regulariser that reads the samples (declares `reads_samples`) is on.
  bool needs_samples() const {
    bool on = false;
    std::apply([&](const auto&... r) { ((on = on || (reads_samples_of(r) && r.active())), ...); }, regularisers);
    return on;
  }
  double rays_per_pixel() const {
    double n = O::rays_per_pixel();
    std::apply([&](const auto&... r) { ((n += r.active() ? r.rays_per_pixel() : 0.0), ...); }, regularisers);
    return n;
  }
  bool active(int k) const {
    if (k == 0) return true;
    bool on = false;
    int i = 1;
    std::apply([&](const auto&... r) { ((on = i++ == k ? r.active() : on), ...); }, regularisers);
    return on;
  }
  /// The first regulariser that is T or derives from it, or null.
  template <class T>
  T* find() {
    T* p = nullptr;
    std::apply([&](auto&... r) { ((p = p ? p : as<T>(r)), ...); }, regularisers);
    return p;
  }
  template <class T>
  const T* find() const {
    return const_cast<Plus*>(this)->template find<T>();
  }

 private:
  template <class X>
  static constexpr bool reads_samples_of(const X&) {
    if constexpr (requires { X::reads_samples; }) return X::reads_samples;
    else return false;
  }
  template <class T, class X>
  static T* as(X& x) {
    if constexpr (std::is_base_of_v<T, X>) return &x;
    else return nullptr;
  }
  template <class F>
  void each(F&& f, scratch& s) const {
    [&]<std::size_t... I>(std::index_sequence<I...>) { (f(std::get<I>(regularisers), std::get<I>(s.terms), static_cast<int>(I)), ...); }
    (std::index_sequence_for<R...>{});
  }
};

template <class P>
struct as_objective {
  static_assert(Objective<P>,
                "EvNerf: the fifth parameter must be an objective (loss::SliceInterval, loss::WindowInterval, loss::Plus, "
                "your own) or a bound policy (loss::SplitCounts<K>, loss::SignedCount, loss::HalfSlackCounts).");
  using type = P;
};
template <BoundPolicy P>
struct as_objective<P> {
  using type = SliceInterval<P>;
};

}  // namespace evnerf::loss
