// An objective of your own (examples/custom_parts.cpp): EventNeRF's event loss (Rudnev et al., CVPR 2023)
// with learned thresholds. Each step pixel is rendered at its window's two ends; the rendered change of
// f(ℓ) = log(ℓ^γ + ε) (γ = 2.2 turns an sRGB-like output linear, ε = 0.1 as EventNeRF's synthetic configs)
// is regressed onto the events' change μ = Σ_k n⁺_k B⁺_k + Σ_k n⁻_k B⁻_k, squared and normalised by the
// window's mean threshold C̄ = Σ_k (B⁺_k − B⁻_k) / 2L, as Robust e-NeRF normalises its squared loss, so its
// scale does not depend on the contrast:  loss = mean over the step's pixels of ((Δf − μ) / C̄)².
// Pixels: 90 % where the window has events, 10 % anywhere (EventNeRF's negative sampling). One type with the
// members loss::Objective names, nothing in the library changed.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>

#include <evnerf/loss/objective.hpp>

namespace mylab {

template <int W = 24, int GammaTenths = 22, int EpsPerMille = 100>
struct EventNerfMse : evnerf::loss::EndsObjective<W, evnerf::events::EventPixels<100>> {
  static constexpr double gamma = GammaTenths / 10.0, eps = EpsPerMille / 1000.0;
  struct scratch {};
  static std::string bounds() {
    return "eventnerf-mse gamma " + std::to_string(GammaTenths) + "/10 eps " + std::to_string(EpsPerMille) + "/1000";
  }
  static std::string description() { return ", window 1.." + std::to_string(W) + ", pixels events 100"; }
  /// f(ℓ) and f'(ℓ).
  static double f(double l) { return std::log(std::pow(std::max(l, 0.0), gamma) + eps); }
  static double df(double l) {
    const double x = std::max(l, 0.0);
    return x > 0 ? gamma * std::pow(x, gamma - 1) / (std::pow(x, gamma) + eps) : 0.0;
  }
  template <class V, class T>
  void score(const evnerf::loss::TileView& t, const V& v, const T& th, scratch&, double* losses) const {
    const int L = t.len();
    double cbar = 0;
    for (int k = 0; k < L; ++k) cbar += (th.pos[k] - th.neg[k]) / (2.0 * L);
    double total = 0;
    for (int i = 0; i < t.P; ++i) {
      const int c = t.channel(i);
      const double l0 = v.at(2 * i, c), l1 = v.at(2 * i + 1, c);
      const int *np = t.npos(i), *nn = t.nneg(i);
      double mu = 0;
      for (int k = 0; k < L; ++k) mu += np[k] * th.pos[k] + nn[k] * th.neg[k];
      const double r = f(l1) - f(l0) - mu, q = r / cbar;
      total += q * q / t.batch;
      const double dr = 2 * q / cbar / t.batch;  // dloss/dr
      v.add(2 * i, c, -dr * df(l0));
      v.add(2 * i + 1, c, dr * df(l1));
      const double dc = -2 * q * q / cbar / t.batch;  // dloss/dC̄
      for (int k = 0; k < L; ++k) th.add(k, -dr * np[k] + dc / (2.0 * L), -dr * nn[k] - dc / (2.0 * L));
    }
    losses[0] += total;
  }
};
static_assert(evnerf::loss::Objective<EventNerfMse<>>);

}  // namespace mylab
