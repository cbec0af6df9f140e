// loss/total_variation.hpp — the total-variation regulariser on rendered log-luminance, as a term an objective
// adds (loss::Plus): each of a share of the step's pixels gets one more ray, its neighbour seen from the
// window's first pose, and the Cauchy penalty of their log difference joins the loss. The penalty (LogTv),
// the choice of neighbour (TvNeighbours) and the term (TotalVariation). Depends on ad/, core/rng.hpp and
// geometry/ (through step.hpp).
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "../ad/expr.hpp"
#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "step.hpp"

namespace evnerf::loss {

/// Total variation of the rendered log-luminance between two neighbouring pixels seen from one pose, with
/// the edge-preserving Cauchy (Lorentzian) penalty δ² log(1 + d²/δ²) of d = log(ℓ_a + eps) − log(ℓ_b + eps):
/// about d² for small steps (the grain a hash grid leaves where few events constrain the scene), its pull
/// 2d/(1 + d²/δ²) fading as 2δ²/d on steps well above δ, so edges keep their height (an L1-like
/// Charbonnier penalty pulls every edge down by the same force and lowers contrast: docs/experiments.md).
struct LogTv {
  double eps = 1e-3, delta = 0.1;
  template <class LA, class LB>
  auto operator()(const LA& la, const LB& lb) const {
    const auto d = ad::log(la + eps) - ad::log(lb + eps);
    return ad::log(1.0 + ad::square(d) * (1.0 / (delta * delta))) * (delta * delta);
  }
  /// Value and gradient w.r.t. (ℓ_a, ℓ_b).
  std::array<double, 3> evaluate(double la, double lb) const {
    const auto vg = ad::value_and_grad(*this, std::array<double, 2>{la, lb});
    return {vg.value, vg.grad[0], vg.grad[1]};
  }
};

/// Which neighbour a step pixel's total-variation term compares it with (TotalVariation's `Neighbours`). `Any`
/// (the default): the pixel to the right or the one below, drawn per pixel and step. `Vertical`: always the
/// one below, `Horizontal`: always the one to the right (above, left at the last row, column). A camera that
/// moves along its x axis (a slider, an orbit about the vertical) never shows the events how bright one image
/// row is against the next: the events fix each row up to a constant. Vertical neighbours tie the rows
/// together where nothing else does, and leave the detail along the rows, which the events do see, to the
/// events; Horizontal does the same for a motion along y. `Across` generalises both to any motion: the
/// neighbour across the axis along which the pixel's scene point moves between the window's two poses
/// (geometry::image_motion_axis), the nearest of the four pixel axes (right, below-right, below,
/// below-left) to its perpendicular; Vertical's neighbour under a motion along x, Horizontal's along y, and
/// Any's draw where the poses show no motion.
enum class TvNeighbours { Any, Vertical, Horizontal, Across };
inline const char* tv_neighbours_name(TvNeighbours n) {
  switch (n) {
    case TvNeighbours::Vertical:
      return "vertical";
    case TvNeighbours::Horizontal:
      return "horizontal";
    case TvNeighbours::Across:
      return "across";
    case TvNeighbours::Any:
      break;
  }
  return "any";
}
/// Pixel (x, y)'s neighbour one step (dx, dy) away on a width × height sensor, or one step back where that
/// leaves the sensor; the pixel itself where both do (no neighbour, no cost).
inline std::pair<int, int> tv_step(int x, int y, int width, int height, int dx, int dy) {
  const auto inside = [&](int u, int v) { return u >= 0 && v >= 0 && u < width && v < height; };
  if (inside(x + dx, y + dy)) return {x + dx, y + dy};
  if (inside(x - dx, y - dy)) return {x - dx, y - dy};
  return {x, y};
}
/// Across's step for the image-motion axis (ax, ay) (either sign): of right (1, 0), below-right (1, 1),
/// below (0, 1) and below-left (−1, 1), the one nearest in angle to the axis's perpendicular; right or below
/// by the draw's lowest bit (as Any) for the zero axis.
inline std::pair<int, int> across_step(double ax, double ay, std::uint64_t draw) {
  if (ax == 0 && ay == 0) return (draw & 1) ? std::pair{1, 0} : std::pair{0, 1};
  const long k = std::lround((std::atan2(ay, ax) + std::numbers::pi / 2) / (std::numbers::pi / 4));
  static constexpr std::pair<int, int> steps[4] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1}};
  return steps[((k % 4) + 4) % 4];
}
/// The neighbour of pixel (x, y) that the term compares it with, on a width × height sensor; `draw` is the
/// step's random bits for this pixel (its lowest bit picks right or below under Any, and under Across
/// without motion), (ax, ay) the pixel's image-motion axis (read under Across only).
inline std::pair<int, int> tv_neighbour(int x, int y, int width, int height, std::uint64_t draw, TvNeighbours n, double ax = 0,
                                        double ay = 0) {
  if (n == TvNeighbours::Across) {
    const auto [dx, dy] = across_step(ax, ay, draw);
    return tv_step(x, y, width, height, dx, dy);
  }
  const bool right = n == TvNeighbours::Horizontal || (n == TvNeighbours::Any && (draw & 1));
  return right ? tv_step(x, y, width, height, 1, 0) : tv_step(x, y, width, height, 0, 1);
}

/// The total-variation term's settings, which a run may change (train --tv): a non-template base, so that
/// a program finds the term in any variant (EvNerf::term<TvTerm>()).
struct TvTerm {
  static constexpr const char* name = "tv";
  double weight = 0;  ///< 0: off (no rays, no loss: the step is the objective's alone, to the bit)
  TvNeighbours neighbours = TvNeighbours::Any;
  double share = 1;  ///< the share of step pixels that get a neighbour ray, in (0, 1]
  void set_weight(double w) {
    require(std::isfinite(w) && w >= 0, "the total-variation weight must be finite and non-negative, not " + std::to_string(w));
    weight = w;
  }
  void set_share(double s) {
    require(std::isfinite(s) && s > 0 && s <= 1, "the total-variation share must lie in (0, 1], not " + std::to_string(s));
    share = s;
  }
  bool active() const { return weight > 0; }
  double rays_per_pixel() const { return share; }
};

/// The total-variation regulariser at weight PerMille/1000, each pixel compared with the neighbour
/// `Neighbours` picks, for a share SharePerMille/1000 of the step's pixels. Each pixel is drawn in with that
/// probability, keyed by (step, pixel), so neither the tiling nor the thread count changes the draw; the
/// weight is divided by the share, so the term's expected value and gradient are those of the whole term at
/// a fraction of its rays. Its loss is weight × the mean over the step's pixels and channels of
/// LogTv(ℓ_pixel, ℓ_neighbour), both seen from the window's first pose, in every pass.
template <int PerMille, TvNeighbours Neighbours = TvNeighbours::Any, int SharePerMille = 1000>
struct TotalVariation : TvTerm {
  static_assert(PerMille >= 0, "TotalVariation: the weight must not be negative.");
  static_assert(SharePerMille > 0 && SharePerMille <= 1000, "TotalVariation: the share must lie in (0, 1000] per mille.");
  TotalVariation() {
    weight = PerMille / 1000.0;
    neighbours = Neighbours;
    share = SharePerMille / 1000.0;
  }
  struct scratch {
    int first_ray = 0;             ///< the term's first ray in the tile's list
    std::vector<int> tile_pixels;  ///< the tile pixels drawn in, in the order of their rays
  };
  void rays(const TileView& t, RayList& rays, scratch& s) const {
    s.first_ray = rays.size();
    s.tile_pixels.clear();
    if (!active()) return;
    const int width = t.width(), height = t.height();
    for (int i = 0; i < t.P; ++i) {
      const std::uint32_t p = t.pixel(i);
      const std::uint64_t h = mix64(t.ray_key ^ mix64(0x7456000000000000ull + p));
      if (share < 1 && unit_double(mix64(h ^ 0x5348415245000000ull)) >= share) continue;
      s.tile_pixels.push_back(i);
      const int x = static_cast<int>(p % static_cast<std::uint32_t>(width)), y = static_cast<int>(p / static_cast<std::uint32_t>(width));
      Vec2 axis = Vec2::Zero();
      if (neighbours == TvNeighbours::Across)
        axis = geometry::image_motion_axis(*t.camera, t.start_pose(), t.end_pose(), t.pixel_dirs[p].cast<double>(), t.near, t.far);
      const auto [nx, ny] = tv_neighbour(x, y, width, height, h, neighbours, axis.x(), axis.y());
      const std::uint32_t q = static_cast<std::uint32_t>(ny) * static_cast<std::uint32_t>(width) + static_cast<std::uint32_t>(nx);
      rays.add(t.first(), q, (std::uint64_t{1} << 40) + q);  // keyed apart from the end rays
    }
  }
  template <class V, class T>
  double score(const TileView& t, const V& v, const T&, scratch& s) const {
    if (!active()) return 0;
    const double scale = weight / (double(t.batch) * t.channels * share);
    const LogTv f{t.log_eps};
    double total = 0;
    for (std::size_t j = 0; j < s.tile_pixels.size(); ++j)
      for (int c = 0; c < t.channels; ++c) {
        const int i = s.tile_pixels[j];
        const int n = s.first_ray + static_cast<int>(j);
        const auto r = f.evaluate(v.at(2 * i, c), v.at(n, c));
        total += scale * r[0];
        v.add(2 * i, c, scale * r[1]);
        v.add(n, c, scale * r[2]);
      }
    return total;
  }
};

}  // namespace evnerf::loss
