// A regulariser of your own (examples/custom_parts.cpp): a pixel whose window holds no event (noise
// included) should not change brightness between the window's ends. weight × the mean over the step's
// pixels of (log(ℓ1 + ε) − log(ℓ0 + ε))² at those pixels, on the objective's own end rays (rays 2i and
// 2i + 1), so it renders nothing more. One type with the members loss::Regulariser names; a variant adds it
// with loss::Plus, nothing in the library changed.
#pragma once
#include <cmath>

#include <evnerf/loss/objective.hpp>

namespace mylab {

template <int PerMille>
struct QuietPixels {
  static constexpr const char* name = "quiet";
  static constexpr double weight = PerMille / 1000.0;
  struct scratch {};
  void rays(const evnerf::loss::TileView&, evnerf::loss::RayList&, scratch&) const {}
  double rays_per_pixel() const { return 0; }
  bool active() const { return weight > 0; }
  template <class V, class T>
  double score(const evnerf::loss::TileView& t, const V& v, const T&, scratch&) const {
    double total = 0;
    for (int i = 0; i < t.P; ++i) {
      int n = 0;
      for (int k = 0; k < t.len(); ++k) n += t.npos(i)[k] + t.nneg(i)[k];
      if (n > 0) continue;
      const int c = t.channel(i);
      const double l0 = v.at(2 * i, c), l1 = v.at(2 * i + 1, c);
      const double d = std::log(l1 + t.log_eps) - std::log(l0 + t.log_eps), s = weight / t.batch;
      total += s * d * d;
      v.add(2 * i, c, -2 * s * d / (l0 + t.log_eps));
      v.add(2 * i + 1, c, 2 * s * d / (l1 + t.log_eps));
    }
    return total;
  }
};
static_assert(evnerf::loss::Regulariser<QuietPixels<100>>);

}  // namespace mylab
