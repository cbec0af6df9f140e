// eval/baselines.hpp — classic event-only reconstructions to compare against: direct integration of
// events and the high-pass filter of Scheerlinck et al. (ACCV 2018), each giving an image at any time.
// Depends on core/ and events/ only.
#pragma once
#include <numbers>
#include <cmath>
#include <vector>

#include "../core/types.hpp"
#include "../events/event_stream.hpp"

namespace evnerf::eval {

/// Log intensity per pixel as the running sum of polarity × contrast from the stream's start; images at
/// the requested (increasing) times, as exp(log intensity), i.e. relative brightness.
inline std::vector<Image> direct_integration(const events::EventStream& ev, const std::vector<double>& times, double contrast = 0.2) {
  std::vector<double> logi(static_cast<std::size_t>(ev.width) * ev.height, 0.0);
  std::vector<Image> out;
  std::size_t k = 0;
  for (double t : times) {
    for (; k < ev.size() && ev.t[k] < t; ++k) logi[static_cast<std::size_t>(ev.y[k]) * ev.width + ev.x[k]] += ev.polarity[k] * contrast;
    Image img(ev.width, ev.height, 1);
    for (std::size_t i = 0; i < logi.size(); ++i) img.data[i] = static_cast<float>(std::exp(logi[i]));
    out.push_back(std::move(img));
  }
  return out;
}

/// High-pass filter: per pixel L ← exp(−α·Δt)·L + polarity × contrast at every event, decayed to each
/// requested time; α (rad/s) is the cut-off. Returns exp(L).
inline std::vector<Image> high_pass_filter(const events::EventStream& ev, const std::vector<double>& times, double contrast = 0.2,
                                           double alpha = 2.0 * std::numbers::pi) {
  const std::size_t n = static_cast<std::size_t>(ev.width) * ev.height;
  std::vector<double> logi(n, 0.0), last(n, ev.empty() ? 0.0 : ev.t.front());
  std::vector<Image> out;
  std::size_t k = 0;
  for (double t : times) {
    for (; k < ev.size() && ev.t[k] < t; ++k) {
      const std::size_t p = static_cast<std::size_t>(ev.y[k]) * ev.width + ev.x[k];
      logi[p] = std::exp(-alpha * (ev.t[k] - last[p])) * logi[p] + ev.polarity[k] * contrast;
      last[p] = ev.t[k];
    }
    Image img(ev.width, ev.height, 1);
    for (std::size_t p = 0; p < n; ++p) img.data[p] = static_cast<float>(std::exp(std::exp(-alpha * std::max(0.0, t - last[p])) * logi[p]));
    out.push_back(std::move(img));
  }
  return out;
}

}  // namespace evnerf::eval
