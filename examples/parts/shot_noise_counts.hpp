// An objective of your own (examples/custom_parts.cpp): windows of up to 32 slices at event-weighted
// pixels, with an interval whose slack grows with the count. A count of N events carries the thresholds'
// pixel-to-pixel mismatch N times, so its error grows like √N; the interval is μ ± (½ + ¼√N) thresholds
// on pixels with events and ±1 threshold without. The bound policy is one type with the members
// loss::BoundPolicy names; the objective is loss::WindowInterval with it.
#pragma once
#include <cmath>

#include <evnerf/loss/objective.hpp>

namespace mylab {

struct ShotNoiseCounts {
  static constexpr const char* name = "shot-noise";
  static evnerf::loss::EventBounds make(int n_pos, int n_neg) {
    const int n = n_pos + n_neg;
    const double k = n > 0 ? 0.5 + 0.25 * std::sqrt(static_cast<double>(n)) : 1.0;
    return {double(n_pos), double(n_neg), k, k};
  }
};
static_assert(evnerf::loss::BoundPolicy<ShotNoiseCounts>);

using ShotNoiseWindows = evnerf::loss::WindowInterval<32, ShotNoiseCounts, evnerf::events::EventPixels<100>>;

}  // namespace mylab
