// events/slicing.hpp — cut an event stream into time slices [T_i, T_i+1) and count, per slice and pixel,
// the positive and negative events; noise injection as in Ev-NeRF. Depends on core/ and events/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "event_stream.hpp"

namespace evnerf::events {

/// Per-pixel positive and negative counts of one slice (row-major H×W), plus the pixels with events.
struct SliceCounts {
  int width = 0, height = 0;
  std::vector<std::int16_t> pos, neg;  ///< n⁺ and n⁻ (both non-negative)
  std::vector<std::uint32_t> active;   ///< pixel indices with at least one event, increasing
  std::size_t total = 0;               ///< events counted (Σ n⁺ + n⁻)
  /// The intervals behind the counts (slice_events with `intervals`; empty otherwise): the events of active
  /// pixel a (active[a]) are gap[gap_start[a] .. gap_start[a + 1]), in time order, each the seconds since the
  /// pixel's previous event of either polarity (infinity for its first), negative for an OFF event. A
  /// refractory period reads them (dead_time_weight).
  std::vector<std::uint32_t> gap_start;
  std::vector<float> gap;

  std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
  int signed_count(std::size_t pix) const { return pos[pix] - neg[pix]; }
  bool has_intervals() const { return !gap_start.empty(); }
  /// The signed intervals of pixel `pix`'s events in this slice ([first, last); empty where it has none).
  std::pair<const float*, const float*> intervals(std::uint32_t pix) const {
    const auto it = std::lower_bound(active.begin(), active.end(), pix);
    if (gap_start.empty() || it == active.end() || *it != pix) return {nullptr, nullptr};
    const auto a = static_cast<std::size_t>(it - active.begin());
    return {gap.data() + gap_start[a], gap.data() + gap_start[a + 1]};
  }
};

/// Slices of a stream: boundaries T_0 < … < T_N and counts for each [T_i, T_i+1).
struct SliceSet {
  std::vector<double> boundaries;
  std::vector<SliceCounts> slices;
  std::size_t size() const { return slices.size(); }
};

/// Boundaries every `dt` seconds from the stream's first to its last event (the last slice may be shorter).
inline std::vector<double> uniform_boundaries(double t0, double t1, std::size_t n_slices) {
  require(n_slices > 0 && t1 > t0, "uniform_boundaries: need t1 > t0 and at least one slice");
  std::vector<double> b(n_slices + 1);
  for (std::size_t i = 0; i <= n_slices; ++i) b[i] = t0 + (t1 - t0) * static_cast<double>(i) / n_slices;
  return b;
}

/// How many threshold crossings an event stands for under a refractory period. A DVS pixel that fires is
/// held in reset for the period τ and then memorises the level it sees, so the change during the period is
/// lost: at a locally steady rate of change, an event that came `gap` seconds after the pixel's previous one
/// stands for gap / (gap − τ) thresholds (a non-paralysable dead time: crossings at rate r leave r / (1 + rτ)
/// events). Within kSaturatedPeriods · τ the rate is beyond what the count can tell: the weight stays at its
/// value there, 1 / (1 − 1 / kSaturatedPeriods) = 3, and the event is saturated (its count is a lower bound).
inline constexpr double kSaturatedPeriods = 1.5;
struct DeadTimeWeight {
  double weight = 1, dweight = 0;  ///< the crossings the event stands for, and its derivative w.r.t. τ
  bool saturated = false;
};
inline DeadTimeWeight dead_time_weight(double gap, double tau) {
  if (!(tau > 0)) return {1.0, std::isfinite(gap) && gap > 0 ? 1.0 / gap : 0.0, false};
  if (gap <= kSaturatedPeriods * tau) return {1.0 / (1.0 - 1.0 / kSaturatedPeriods), 0.0, true};
  if (!std::isfinite(gap)) return {1.0, 0.0, false};
  const double r = 1.0 / (gap - tau);
  return {gap * r, gap * r * r, false};
}

/// Fills SliceCounts::gap_start and gap of `set`'s slices from the stream's events.
inline void record_intervals(const EventStream& ev, SliceSet& set) {
  const std::size_t hw = static_cast<std::size_t>(ev.width) * ev.height;
  std::vector<double> last(hw, -std::numeric_limits<double>::infinity());
  std::vector<std::uint32_t> slot(hw, 0);
  const auto& b = set.boundaries;
  std::size_t k = static_cast<std::size_t>(std::lower_bound(ev.t.begin(), ev.t.end(), b.front()) - ev.t.begin());
  for (std::size_t i = 0; i < ev.size() && ev.t[i] < b.front(); ++i) last[static_cast<std::size_t>(ev.y[i]) * ev.width + ev.x[i]] = ev.t[i];
  for (std::size_t i = 0; i < set.size(); ++i) {
    SliceCounts& s = set.slices[i];
    s.gap_start.assign(s.active.size() + 1, 0);
    for (std::size_t a = 0; a < s.active.size(); ++a) {
      const auto p = s.active[a];
      s.gap_start[a + 1] = s.gap_start[a] + static_cast<std::uint32_t>(s.pos[p] + s.neg[p]);
      slot[p] = s.gap_start[a];
    }
    s.gap.assign(s.gap_start.back(), 0.0f);
    for (; k < ev.size() && ev.t[k] < b[i + 1]; ++k) {
      const std::size_t pix = static_cast<std::size_t>(ev.y[k]) * ev.width + ev.x[k];
      const double d = ev.t[k] - last[pix];
      last[pix] = ev.t[k];
      const float g = std::isfinite(d) ? static_cast<float>(d) : std::numeric_limits<float>::infinity();
      s.gap[slot[pix]++] = ev.polarity[k] > 0 ? g : -g;
    }
  }
}

/// Counts events per slice and pixel. Events before T_0 or at/after T_N are ignored; the boundaries must
/// increase strictly. Counts saturate at int16 max with an error rather than wrapping. With `intervals`,
/// each slice also keeps its events' intervals (SliceCounts::gap), which a refractory period reads.
inline SliceSet slice_events(const EventStream& ev, const std::vector<double>& boundaries, bool intervals = false) {
  require(boundaries.size() >= 2, "slice_events: need at least two boundaries");
  for (std::size_t i = 1; i < boundaries.size(); ++i)
    require(boundaries[i] > boundaries[i - 1], "slice_events: boundaries must increase strictly");
  SliceSet set;
  set.boundaries = boundaries;
  const std::size_t n_slices = boundaries.size() - 1, hw = static_cast<std::size_t>(ev.width) * ev.height;
  set.slices.resize(n_slices);
  for (auto& s : set.slices) {
    s.width = ev.width;
    s.height = ev.height;
    s.pos.assign(hw, 0);
    s.neg.assign(hw, 0);
  }
  // Events are sorted by time, so each slice is a contiguous range found by binary search.
  for (std::size_t i = 0; i < n_slices; ++i) {
    auto b = std::lower_bound(ev.t.begin(), ev.t.end(), boundaries[i]) - ev.t.begin();
    auto e = std::lower_bound(ev.t.begin(), ev.t.end(), boundaries[i + 1]) - ev.t.begin();
    SliceCounts& s = set.slices[i];
    for (auto k = b; k < e; ++k) {
      const std::size_t pix = static_cast<std::size_t>(ev.y[k]) * ev.width + ev.x[k];
      auto& c = ev.polarity[k] > 0 ? s.pos[pix] : s.neg[pix];
      if (c == INT16_MAX) throw Error("slice_events: more than 32767 events at one pixel in one slice");
      ++c;
    }
    s.total = static_cast<std::size_t>(e - b);
    for (std::size_t p = 0; p < hw; ++p)
      if (s.pos[p] || s.neg[p]) s.active.push_back(static_cast<std::uint32_t>(p));
  }
  if (intervals) record_intervals(ev, set);
  return set;
}

/// Per-pixel running sums of the counts over slices: pos[i·hw + p] = Σ_{k<i} n⁺_k(p), i = 0..N (likewise
/// neg), so the counts of slices [a, b) at pixel p are two subtractions. Built once per recording; it holds
/// (N + 1)·H·W·2 int32 (about 35 MB for 100 slices of a 240×180 sensor).
struct CountPrefix {
  std::size_t hw = 0, n_slices = 0;
  std::vector<std::int32_t> pos, neg;

  CountPrefix() = default;
  explicit CountPrefix(const SliceSet& s) : hw(s.slices.empty() ? 0 : s.slices.front().pixels()), n_slices(s.size()) {
    pos.assign((n_slices + 1) * hw, 0);
    neg.assign((n_slices + 1) * hw, 0);
    for (std::size_t i = 0; i < n_slices; ++i) {
      const SliceCounts& c = s.slices[i];
      require(c.pixels() == hw, "CountPrefix: slices differ in size");
      const std::size_t o = i * hw, o1 = o + hw;
      for (std::size_t p = 0; p < hw; ++p) {
        pos[o1 + p] = pos[o + p] + c.pos[p];
        neg[o1 + p] = neg[o + p] + c.neg[p];
      }
    }
  }
  bool empty() const { return pos.empty(); }
  /// n⁺ and n⁻ of slices [a, b) at pixel p.
  std::int32_t window_pos(std::size_t a, std::size_t b, std::size_t p) const { return pos[b * hw + p] - pos[a * hw + p]; }
  std::int32_t window_neg(std::size_t a, std::size_t b, std::size_t p) const { return neg[b * hw + p] - neg[a * hw + p]; }
};

/// One injected noise event: pixel, slice within the window it was drawn for, polarity.
struct NoiseEvent {
  std::uint32_t pixel = 0, slice = 0;
  bool positive = false;
};

/// Ev-NeRF's noise injection, drawn: round(ratio × count) events, pixels uniform over `hw` pixels (over
/// `sites`, the pixels that carry events, where given and not empty), polarity ±1 with probability ½, each
/// in a uniformly drawn slice of a window of `window` slices (no draw when the window is one slice). `out`
/// is cleared first.
inline void draw_noise(std::size_t count, double ratio, std::size_t hw, std::size_t window, Rng& rng, std::vector<NoiseEvent>& out,
                       const std::vector<std::uint32_t>* sites = nullptr) {
  const bool some = sites && !sites->empty();
  require(ratio >= 0 && std::isfinite(ratio), "inject_noise: ratio must be finite and non-negative");
  out.clear();
  const auto n = static_cast<std::size_t>(std::llround(ratio * static_cast<double>(count)));
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    NoiseEvent e;
    e.pixel = some ? (*sites)[rng.below(sites->size())] : static_cast<std::uint32_t>(rng.below(hw));
    e.positive = (rng.next_u64() & 1) != 0;
    e.slice = window > 1 ? static_cast<std::uint32_t>(rng.below(window)) : 0u;
    out.push_back(e);
  }
}

/// Adds round(ratio × slice.total) random events (draw_noise; ratio 0.05 in training). Returns the noisy
/// copy; counts saturate at int16 max.
inline SliceCounts inject_noise(const SliceCounts& s, double ratio, Rng& rng) {
  std::vector<NoiseEvent> noise;
  draw_noise(s.total, ratio, s.pixels(), 1, rng, noise);
  SliceCounts out = s;
  for (const auto& e : noise) {
    auto& c = e.positive ? out.pos[e.pixel] : out.neg[e.pixel];
    if (c < INT16_MAX) ++c;
  }
  out.total += noise.size();
  out.gap_start.clear();  // the injected events have no intervals
  out.gap.clear();
  out.active.clear();
  for (std::size_t p = 0; p < s.pixels(); ++p)
    if (out.pos[p] || out.neg[p]) out.active.push_back(static_cast<std::uint32_t>(p));
  return out;
}

}  // namespace evnerf::events
