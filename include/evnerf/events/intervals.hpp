// events/intervals.hpp — the intervals between consecutive events of one pixel (either polarity) and their
// low quantiles. A pixel that fires is blind for the sensor's refractory period τ, and its next event needs
// the brightness to cross a threshold again after that: every interval is at least τ, so a low quantile of
// the intervals bounds τ from above. A quantile, not the minimum: timestamp jitter, background activity and
// hot pixels put a few intervals below τ. On an ideal sensor the bound is the time a fast edge takes to
// re-cross a threshold (tens of microseconds in the simulator's recordings), not 0. Depends on
// events/event_stream.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "event_stream.hpp"

namespace evnerf::events {

/// The quantiles that inspect reports; the middle one bounds the refractory period.
inline constexpr std::array<double, 3> kIntervalQuantiles = {0.001, 0.005, 0.01};
/// The quantile taken as the refractory period's upper bound: on simulated sensors of 0.1–2 ms it lies
/// above the period, within twice it from 1 ms on where the motion is fast (tests/test_sim.cpp); on the 12
/// IJRR windows of ../shared/data (a DAVIS240C) it reads 1.5–2.2 ms.
inline constexpr double kRefractoryBoundQuantile = 0.005;
static_assert(kIntervalQuantiles[1] == kRefractoryBoundQuantile, "IntervalStatistics::refractory_bound reads quantile[1]");

/// What intervals a stream's pixels keep between their consecutive events.
struct IntervalStatistics {
  std::size_t intervals = 0;                                 ///< consecutive pairs of one pixel's events
  double minimum = 0;                                        ///< the shortest, seconds (0 when there are none)
  std::array<double, kIntervalQuantiles.size()> quantile{};  ///< seconds, at kIntervalQuantiles
  /// The refractory period's upper bound: the kRefractoryBoundQuantile quantile (0 when no pixel fired twice).
  double refractory_bound() const { return quantile[1]; }
};

/// The intervals between each pixel's consecutive events (either polarity), in the order their second
/// events come. The stream's times must be in order (EventStream::validate); a pixel outside the sensor is
/// skipped, and so is pixel y · width + x where `left_out` (empty, or one byte a pixel) is not 0 (hot pixels,
/// whose own firing is no measure of the sensor's dead time).
inline std::vector<double> pixel_intervals(const EventStream& e, const std::vector<std::uint8_t>& left_out = {}) {
  const std::size_t W = static_cast<std::size_t>(std::max(0, e.width)), H = static_cast<std::size_t>(std::max(0, e.height));
  const bool masked = left_out.size() == W * H && W * H > 0;
  std::vector<double> last(W * H, std::numeric_limits<double>::quiet_NaN());
  std::vector<double> out;
  out.reserve(e.size());
  for (std::size_t i = 0; i < e.size(); ++i) {
    if (e.x[i] >= W || e.y[i] >= H) continue;
    const std::size_t p = static_cast<std::size_t>(e.y[i]) * W + e.x[i];
    if (masked && left_out[p]) continue;
    double& l = last[p];
    if (l == l) out.push_back(e.t[i] - l);  // not NaN: the pixel fired before
    l = e.t[i];
  }
  return out;
}

/// The q-quantile of `v` (0 ≤ q ≤ 1) by the nearest rank below, reordering v; 0 for an empty v.
inline double quantile_in_place(std::vector<double>& v, double q) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// The stream's per-pixel interval statistics (pixel_intervals, its minimum and kIntervalQuantiles), the
/// pixels of `left_out` left out.
inline IntervalStatistics interval_statistics(const EventStream& e, const std::vector<std::uint8_t>& left_out = {}) {
  std::vector<double> d = pixel_intervals(e, left_out);
  IntervalStatistics s;
  s.intervals = d.size();
  if (d.empty()) return s;
  s.minimum = *std::min_element(d.begin(), d.end());
  for (std::size_t k = 0; k < kIntervalQuantiles.size(); ++k) s.quantile[k] = quantile_in_place(d, kIntervalQuantiles[k]);
  return s;
}

}  // namespace evnerf::events
