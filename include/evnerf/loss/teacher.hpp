// loss/teacher.hpp — a teacher's images as a term an objective adds (loss::Plus): where a trained model
// already knows the scene (a field, whose hash grid and network interpolate the interiors no event
// observes), a model that starts from it (Gaussians: train --start-from) is pulled toward the teacher's
// rendered log-luminance at the step's two end poses, with a weight that fades to zero over training, so
// that the events alone have the last word (RadSplat supervises Gaussians with a NeRF's renders). Without a
// teacher (TileView::teacher null) the term adds nothing, to the bit. The penalty (TeacherPull) and the term
// (Teacher). Depends on ad/ and step.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>

#include "../ad/expr.hpp"
#include "step.hpp"

namespace evnerf::loss {

/// The Charbonnier penalty √(d² + δ²) − δ of d = log(ℓ + eps) − log(τ + eps), the rendered ℓ against the
/// teacher's τ: L1-like (a teacher that is wrong somewhere pulls there with a bounded force), smooth at 0.
struct TeacherPull {
  double eps = 1e-3, delta = 0.01, teacher = 0;
  template <class L>
  auto operator()(const L& l) const {
    const auto d = ad::log(l + eps) - std::log(teacher + eps);
    return ad::sqrt(ad::square(d) + delta * delta) - delta;
  }
  /// Value and gradient w.r.t. ℓ.
  std::array<double, 2> evaluate(double l) const {
    const auto vg = ad::value_and_grad(*this, std::array<double, 1>{l});
    return {vg.value, vg.grad[0]};
  }
};

/// The teacher term: weight `PerMille` / 1000 at step 0, falling linearly to 0 at step `Until`; a mean over
/// the step's pixels, channels and the window's two ends. Reads the end rays (2i, 2i + 1); renders none of
/// its own. The default (30, over 6000 steps) lets the teacher lead early and the events refine.
template <int PerMille = 30000, long Until = 6000>
struct Teacher {
  static_assert(PerMille >= 0 && Until > 0, "Teacher: bad weight or schedule");
  static constexpr const char* name = "teacher";
  struct scratch {};
  /// The term's weight at `step`.
  static double weight(long step) { return PerMille / 1000.0 * std::max(0.0, 1.0 - static_cast<double>(step) / Until); }
  void rays(const TileView&, RayList&, scratch&) const {}
  template <class V, class T>
  double score(const TileView& t, const V& v, const T&, scratch&) const {
    const double w = weight(t.step);
    if (!t.teacher || w == 0) return 0;
    const double scale = w / (2.0 * t.batch * t.channels);
    const std::size_t hw = static_cast<std::size_t>(t.width()) * t.height();
    double total = 0;
    for (int i = 0; i < t.P; ++i)
      for (int end = 0; end < 2; ++end) {
        const std::size_t pose = t.first() + (end ? t.draw->len : 0);
        for (int c = 0; c < t.channels; ++c) {
          const TeacherPull f{t.log_eps, 0.01, t.teacher[(pose * hw + t.pixel(i)) * t.channels + c]};
          const auto r = f.evaluate(v.at(2 * i + end, c));
          total += scale * r[0];
          v.add(2 * i + end, c, scale * r[1]);
        }
      }
    return total;
  }
  double rays_per_pixel() const { return 0; }
  bool active() const { return true; }
};

}  // namespace evnerf::loss
