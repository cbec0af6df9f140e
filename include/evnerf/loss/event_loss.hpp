// loss/event_loss.hpp — the Ev-NeRF event loss: the rendered log-luminance change between a slice's two
// poses must lie within the interval implied by the pixel's event counts and the slice's thresholds;
// the threshold floor loss; threshold and noise policies. Written once with ad/.
// Depends on ad/ only.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>

#include "../ad/expr.hpp"

namespace evnerf::loss {

/// Bound of the log change for n⁺ positive and n⁻ negative events with thresholds B⁺ > 0 > B⁻:
/// μ = n⁺B⁺ + n⁻B⁻, interval [μ + k⁻·B⁻, μ + k⁺·B⁺] (k± = slack in thresholds; spec §2, default 1).
/// Hinge L1 outside the interval, zero inside. eps keeps log(ℓ + eps) finite (spec: 1e-3).
/// `centre` > 0 adds centre · (change − μ)² (a pull towards the expected change inside the interval, where
/// the hinge alone leaves the change free; 0, the spec's loss, adds nothing at all).
struct EventBounds {
  double n_pos, n_neg, k_neg = 1.0, k_pos = 1.0, eps = 1e-3, centre = 0.0;
  /// Arguments: luminance at T_i, luminance at T_i+1, B⁺, B⁻. The hinge only (spec §2).
  template <class L0, class L1, class BP, class BM>
  auto operator()(const L0& l0, const L1& l1, const BP& bp, const BM& bm) const {
    const auto change = ad::log(l1 + eps) - ad::log(l0 + eps);
    const auto mu = n_pos * bp + n_neg * bm;
    return ad::relu((mu + k_neg * bm) - change) + ad::relu(change - (mu + k_pos * bp));
  }
  /// The hinge plus the centre term.
  template <class L0, class L1, class BP, class BM>
  auto centred(const L0& l0, const L1& l1, const BP& bp, const BM& bm) const {
    const auto change = ad::log(l1 + eps) - ad::log(l0 + eps);
    const auto mu = n_pos * bp + n_neg * bm;
    return ad::relu((mu + k_neg * bm) - change) + ad::relu(change - (mu + k_pos * bp)) + centre * ad::square(change - mu);
  }
  /// Value and gradient w.r.t. (ℓ0, ℓ1, B⁺, B⁻).
  std::array<double, 5> evaluate(double l0, double l1, double bp, double bm) const {
    const std::array<double, 4> x{l0, l1, bp, bm};
    const auto vg = centre == 0.0 ? ad::value_and_grad(*this, x)
                                  : ad::value_and_grad([this](const auto& a, const auto& b, const auto& c, const auto& d) { return centred(a, b, c, d); }, x);
    return {vg.value, vg.grad[0], vg.grad[1], vg.grad[2], vg.grad[3]};
  }
};

/// How a pixel's counts become its interval (spec §2 and §9 #1), as a policy of the model.
/// Split counts with slack K: [μ + K·B⁻, μ + K·B⁺], μ = n⁺B⁺ + n⁻B⁻. K = 1 is the spec's default; K = 2 is
/// the worst case for an unknown reference level at T_i. With K = 1 a pixel with one event also allows no
/// change, so a constant image costs nothing there.
template <int K = 1>
struct SplitCounts {
  static_assert(K >= 0, "SplitCounts: the slack K must not be negative.");
  static constexpr const char* name = "split";
  static constexpr int slack = K;
  static EventBounds make(int n_pos, int n_neg) { return {double(n_pos), double(n_neg), double(K), double(K)}; }
};
/// The signed count n = n⁺ − n⁻ only (the spec's `signed` switch): n > 0 → [nB⁺, (n+1)B⁺], n < 0 →
/// [(|n|+1)B⁻, |n|B⁻], n = 0 → [B⁻, B⁺]. Every pixel with a net event demands a change of at least one
/// threshold, but the interval sits half a threshold above the expected change: contrast comes out high.
struct SignedCount {
  static constexpr const char* name = "signed";
  static EventBounds make(int n_pos, int n_neg) {
    const int n = n_pos - n_neg;
    return {double(n > 0 ? n : 0), double(n < 0 ? -n : 0), n <= 0 ? 1.0 : 0.0, n >= 0 ? 1.0 : 0.0};
  }
};

/// Split counts, centred and narrow where events fired: μ + [½B⁻, ½B⁺] on pixels with events (centred on
/// the expected change μ like k = 1, but excluding no change for a single event), [B⁻, B⁺] on pixels
/// without. Ours, not the paper's: the Fast presets use it (measured against the others in bench/README.md).
struct HalfSlackCounts {
  static constexpr const char* name = "half-slack";
  static EventBounds make(int n_pos, int n_neg) {
    const double k = n_pos + n_neg > 0 ? 0.5 : 1.0;
    return {double(n_pos), double(n_neg), k, k};
  }
};

/// Half-slack counts plus a pull towards the expected change μ at weight PerMille/1000 (EventBounds::centre):
/// the hinge bounds the change, the square picks the centre inside the bound, as the squared losses of
/// EventNeRF and Robust e-NeRF do. Ours; measured in bench/README.md.
template <int PerMille>
struct CentredCounts {
  static_assert(PerMille > 0, "CentredCounts: the weight must be positive (HalfSlackCounts is weight 0).");
  static constexpr const char* name = "half-slack-centred";
  static constexpr int per_mille = PerMille;
  static constexpr double weight = PerMille / 1000.0;
  static EventBounds make(int n_pos, int n_neg) {
    auto b = HalfSlackCounts::make(n_pos, n_neg);
    b.centre = weight;
    return b;
  }
};

/// The floor that stops thresholds collapsing: relu(B0 − B⁺) + relu(B⁻ + B0) (spec §2, B0 = 0.3).
struct ThresholdFloor {
  double b0 = 0.3;
  template <class BP, class BM>
  auto operator()(const BP& bp, const BM& bm) const {
    return ad::relu(b0 - bp) + ad::relu(bm + b0);
  }
};

/// Total variation of the rendered log-luminance between two neighbouring pixels seen from one pose, with
/// the edge-preserving Cauchy (Lorentzian) penalty δ² log(1 + d²/δ²) of d = log(ℓ_a + eps) − log(ℓ_b + eps):
/// about d² for small steps (the grain a hash grid leaves where few events constrain the scene), its pull
/// 2d/(1 + d²/δ²) fading as 2δ²/d on steps well above δ, so edges keep their height. A regulariser of ours
/// (EvNerf::set_tv). An L1-like form (Charbonnier, √(d² + δ²) − δ) pulls every edge down by the same force
/// and lowered the built-in scenes' contrast: measured and not kept (bench/README.md, session 21).
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

/// Which neighbour a step pixel's total-variation term compares it with (EvNerf::set_tv_neighbours). `Any`
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
    case TvNeighbours::Vertical: return "vertical";
    case TvNeighbours::Horizontal: return "horizontal";
    case TvNeighbours::Across: return "across";
    case TvNeighbours::Any: break;
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

/// Per-slice thresholds B_i^± learned jointly with the field, with the floor loss at weight λ = 1000.
struct JointThresholds {
  static constexpr bool learnable = true;
  static constexpr double lambda = 1000.0, init = 0.3;
  static constexpr const char* name = "joint";
};
/// Per-slice thresholds learned jointly, kept at or beyond the floor ±0.3 by projection after every update
/// instead of a penalty (λ unused): the constraint the floor loss approximates, without its gradient of
/// 1000 entering Adam's moments. Ours; measured against JointThresholds in bench/README.md.
struct ProjectedThresholds {
  static constexpr bool learnable = true, projected = true;
  static constexpr double lambda = 0.0, init = 0.3;
  static constexpr const char* name = "joint-projected";
};
/// Per-slice thresholds of which only the ratio B⁺/|B⁻| is learned: after every update each touched pair is
/// projected onto B⁺·|B⁻| = init² (one scale shared by all slices, which a log-affine evaluation cannot see
/// anyway), its ratio kept within [1/max_ratio, max_ratio]. No floor term (λ unused): the fixed scale is
/// what the floor protects.
struct RatioThresholds {
  static constexpr bool learnable = true, shared_scale = true;
  static constexpr double lambda = 0.0, init = 0.3, max_ratio = 4.0;
  static constexpr const char* name = "joint-ratio";
  /// The projection, on one slice's pair.
  template <class T>
  static void project(T& bp, T& bm) {
    double r = bm < 0 ? static_cast<double>(bp) / -static_cast<double>(bm) : max_ratio;
    if (!(r > 0)) r = 1.0 / max_ratio;
    r = std::clamp(r, 1.0 / max_ratio, max_ratio);
    const double q = std::sqrt(r);
    bp = static_cast<T>(init * q);
    bm = static_cast<T>(-init / q);
  }
};
/// Fixed thresholds ±0.3 and λ = 0 (the paper's "without joint training" ablation).
struct FixedThresholds {
  static constexpr bool learnable = false;
  static constexpr double lambda = 0.0, init = 0.3;
  static constexpr const char* name = "fixed";
};

/// Random events worth `Ratio`/1000 of the slice's count, redrawn at every use (paper: 5 %).
template <int PerMille>
struct NoiseInjection {
  static constexpr double ratio = PerMille / 1000.0;
};
using DefaultNoise = NoiseInjection<50>;
using NoNoise = NoiseInjection<0>;

}  // namespace evnerf::loss
