// loss/distortion.hpp — the distortion regulariser of Mip-NeRF 360, as a term an objective adds (loss::Plus):
// a penalty on how each rendered ray's weights spread along the ray, which pulls them together into one
// surface and drives out weights that float before or behind it. A term on the samples, not on rendered
// values: it declares `reads_samples`, and the model hands it each pass's sample depths and a buffer for
// dloss/dweight (RenderedValues). The penalty (distortion_loss) and the term (Distortion). Depends on core/
// and loss/step.hpp.
#pragma once
#include <cmath>
#include <string>
#include <type_traits>

#include "../core/error.hpp"
#include "step.hpp"

namespace evnerf::loss {

/// Distortion of one ray's weights: L = Σ_i Σ_j w_i w_j |m_i − m_j| + ⅓ Σ_i w_i² δ_i over the intervals
/// between samples, with midpoints m and lengths δ measured in units of the ray's sampled span
/// (t[S−1] − t[0]), so L does not depend on the scene's scale. Sample k < S−1 owns [t_k, t_{k+1}]; the last
/// sample (the open interval) is a point at t[S−1]. Returns L and writes dL/dw_k to dweight (S values), in
/// O(S) by prefix sums (t ascending).
template <class T>
double distortion_loss(int S, const T* weight, const T* t, T* dweight) {
  if (S <= 0) return 0.0;
  const double span = S > 1 ? double(t[S - 1]) - double(t[0]) : 0.0;
  if (!(span > 0)) {
    for (int k = 0; k < S; ++k) dweight[k] = T(0);
    return 0.0;
  }
  const auto mid = [&](int k) { return k + 1 < S ? 0.5 * (double(t[k]) + double(t[k + 1])) / span : double(t[k]) / span; };
  const auto len = [&](int k) { return k + 1 < S ? (double(t[k + 1]) - double(t[k])) / span : 0.0; };
  double wsum = 0, wm = 0;  // over samples before k: Σ w_j, Σ w_j m_j
  double total_w = 0, total_wm = 0;
  for (int k = 0; k < S; ++k) {
    total_w += double(weight[k]);
    total_wm += double(weight[k]) * mid(k);
  }
  double cross = 0, self = 0;
  for (int k = 0; k < S; ++k) {
    const double w = weight[k], m = mid(k), d = len(k);
    const double after_w = total_w - wsum - w, after_wm = total_wm - wm - w * m;
    const double dist = (m * wsum - wm) + (after_wm - m * after_w);  // Σ_j w_j |m_k − m_j|
    cross += w * dist;
    self += w * w * d / 3.0;
    dweight[k] = static_cast<T>(2.0 * dist + 2.0 * w * d / 3.0);
    wsum += w;
    wm += w * m;
  }
  return cross + self;
}

/// The distortion term's weight, which a program may change: a non-template base, so that it finds the term
/// in any variant (EvNerf::term<DistortionTerm>()).
struct DistortionTerm {
  static constexpr const char* name = "distortion";
  static constexpr bool reads_samples = true;
  double weight = 0;  ///< 0: off (no loss, no gradient: the step is the objective's alone, to the bit)
  void set_weight(double w) {
    require(std::isfinite(w) && w >= 0, "the distortion weight must be finite and non-negative, not " + std::to_string(w));
    weight = w;
  }
  bool active() const { return weight > 0; }
  double rays_per_pixel() const { return 0; }
};

/// The distortion regulariser at weight PerMille/1000: weight × the mean over the step's pixels of the
/// distortion of the objective's two end rays (rays 2i and 2i + 1, averaged), in every pass. It renders no
/// ray of its own.
template <int PerMille>
struct Distortion : DistortionTerm {
  static_assert(PerMille >= 0, "Distortion: the weight must not be negative.");
  Distortion() { weight = PerMille / 1000.0; }
  struct scratch {};
  void rays(const TileView&, RayList&, scratch&) const {}
  template <class V, class T>
  double score(const TileView& t, const V& v, const T&, scratch&) const {
    if (!active()) return 0;
    require(v.weight_grad != nullptr, "loss::Distortion: the model gave the term no samples (RenderedValues::weight_grad)");
    const double scale = weight / (2.0 * t.batch);
    using G = std::remove_pointer_t<decltype(v.weight_grad)>;
    const int S = v.samples;
    double total = 0;
    for (int ray = 0; ray < 2 * t.P; ++ray) {
      const std::size_t o = static_cast<std::size_t>(ray) * S;
      G* g = v.weight_grad + o;
      total += scale * distortion_loss(S, v.comp[ray].weight.data(), v.depth + o, g);
      for (int k = 0; k < S; ++k) g[k] = static_cast<G>(scale * double(g[k]));
    }
    return total;
  }
};

}  // namespace evnerf::loss
