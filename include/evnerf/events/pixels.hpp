// events/pixels.hpp — which pixels a training step renders, as policies of an objective:
// UniformPixels (the paper's: uniform over the sensor) and EventPixels<EmptyPerMille> (pixels where the
// window saw events, plus a share of pixels where it saw none, as EventNeRF draws them); both draw only
// among a sensor's sites (PixelSites) where the events come from a subset of its pixels.
// Depends on core/ and events/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "slicing.hpp"

namespace evnerf::events {

/// The pixels of a sensor that carry events, where that is a subset: one colour channel's sites of a mosaic
/// trained at the full sensor (green's two sites per 2×2 block). Empty: every pixel.
struct PixelSites {
  std::vector<std::uint32_t> list;  ///< the sites' pixel indices, ascending
  std::vector<std::uint8_t> mask;   ///< per pixel of the sensor, 1 at a site (empty when `list` is)

  PixelSites() = default;
  /// From a per-pixel mask (1 = site); an empty mask means every pixel. A mask without any site is an error.
  explicit PixelSites(std::vector<std::uint8_t> m) : mask(std::move(m)) {
    for (std::size_t p = 0; p < mask.size(); ++p)
      if (mask[p]) list.push_back(static_cast<std::uint32_t>(p));
    require(mask.empty() || !list.empty(), "PixelSites: the mask has no site");
  }
  bool all() const { return list.empty(); }
  /// How many pixels may be drawn on a sensor of hw pixels.
  std::size_t count(std::size_t hw) const { return all() ? hw : list.size(); }
  /// The k-th drawable pixel (k < count(hw)).
  std::uint32_t at(std::size_t k) const { return all() ? static_cast<std::uint32_t>(k) : list[k]; }
};

/// The pixels of one step's window of slices [first, last) (last exclusive) and its counts.
struct PixelWindow {
  std::size_t hw = 0, first = 0, last = 0;
  const CountPrefix* prefix = nullptr;  ///< needed by policies that look at the counts
  const PixelSites* sites = nullptr;    ///< draw only these pixels (null or all(): every pixel)
  std::size_t drawable() const { return sites ? sites->count(hw) : hw; }
  std::uint32_t drawable_at(std::size_t k) const { return sites ? sites->at(k) : static_cast<std::uint32_t>(k); }
};

/// `n` distinct pixels uniformly over the sensor (over its sites where the window names some; rejection of
/// repeats). `taken` is scratch (hw flags, all false on entry and on return).
struct UniformPixels {
  static constexpr const char* name = "uniform";
  static constexpr bool needs_counts = false;
  static void draw(const PixelWindow& w, int n, Rng& rng, std::vector<std::uint32_t>& out, std::vector<std::uint8_t>& taken) {
    out.clear();
    const std::size_t avail = w.drawable();
    const int P = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(n), avail));
    out.reserve(static_cast<std::size_t>(P));
    while (static_cast<int>(out.size()) < P) {
      const auto p = w.drawable_at(rng.below(avail));
      if (!taken[p]) {
        taken[p] = 1;
        out.push_back(p);
      }
    }
    for (auto p : out) taken[p] = 0;
  }
};

/// `n` distinct pixels: a share EmptyPerMille/1000 among the pixels without events in the window (their
/// brightness must stay within one threshold), the rest uniformly among the pixels with at least one
/// event. When one kind runs short, the other fills the batch. Repeats are rejected with a bounded number
/// of tries, then the remaining pixels of the kind are taken in order from a random start, so a step
/// always ends. Where the window names sites, pixels without events are drawn among them only.
template <int EmptyPerMille = 100>
struct EventPixels {
  static_assert(EmptyPerMille >= 0 && EmptyPerMille <= 1000, "EventPixels: the empty share is in per mille (0..1000).");
  static constexpr const char* name = "events";
  static constexpr bool needs_counts = true;
  static constexpr int empty_per_mille = EmptyPerMille;

  static void draw(const PixelWindow& w, int n, Rng& rng, std::vector<std::uint32_t>& out, std::vector<std::uint8_t>& taken) {
    require(w.prefix && !w.prefix->empty(), "EventPixels: the training data has no count prefix (events::CountPrefix)");
    out.clear();
    const std::size_t avail = w.drawable();
    const int P = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(n), avail));
    auto empty = [&](std::uint32_t p) { return w.prefix->window_pos(w.first, w.last, p) + w.prefix->window_neg(w.first, w.last, p) == 0; };
    std::vector<std::uint32_t> active;
    for (std::size_t k = 0; k < avail; ++k)
      if (!empty(w.drawable_at(k))) active.push_back(w.drawable_at(k));
    const std::size_t n_empty_avail = avail - active.size();
    std::size_t want_empty = static_cast<std::size_t>(std::llround(P * (EmptyPerMille / 1000.0)));
    std::size_t want_event = static_cast<std::size_t>(P) - want_empty;
    if (want_event > active.size()) {
      want_empty += want_event - active.size();
      want_event = active.size();
    }
    if (want_empty > n_empty_avail) {
      want_event += want_empty - n_empty_avail;
      want_empty = n_empty_avail;
    }
    out.reserve(static_cast<std::size_t>(P));
    // Pixels with events.
    take(
        want_event, active.size(), [&](std::size_t i) { return active[i]; }, rng, out, taken);
    // Pixels without events: rejection over the sensor (its sites), then a scan.
    std::size_t got = 0;
    for (std::size_t tries = 0; got < want_empty && tries < 64 * want_empty + 64; ++tries) {
      const auto p = w.drawable_at(rng.below(avail));
      if (!taken[p] && empty(p)) {
        taken[p] = 1;
        out.push_back(p);
        ++got;
      }
    }
    if (got < want_empty) {
      const std::size_t start = rng.below(avail);
      for (std::size_t k = 0; k < avail && got < want_empty; ++k) {
        const auto p = w.drawable_at((start + k) % avail);
        if (!taken[p] && empty(p)) {
          taken[p] = 1;
          out.push_back(p);
          ++got;
        }
      }
    }
    for (auto p : out) taken[p] = 0;
  }

 private:
  template <class Get>
  static void take(std::size_t want, std::size_t avail, Get&& get, Rng& rng, std::vector<std::uint32_t>& out,
                   std::vector<std::uint8_t>& taken) {
    std::size_t got = 0;
    for (std::size_t tries = 0; got < want && tries < 64 * want + 64; ++tries) {
      const std::uint32_t p = get(rng.below(avail));
      if (!taken[p]) {
        taken[p] = 1;
        out.push_back(p);
        ++got;
      }
    }
    if (got < want) {
      const std::size_t start = avail ? rng.below(avail) : 0;
      for (std::size_t k = 0; k < avail && got < want; ++k) {
        const std::uint32_t p = get((start + k) % avail);
        if (!taken[p]) {
          taken[p] = 1;
          out.push_back(p);
          ++got;
        }
      }
    }
  }
};

}  // namespace evnerf::events
