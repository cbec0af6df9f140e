// loss/event_loss.hpp — the Ev-NeRF event loss: the rendered log-luminance change between a slice's two
// poses must lie within the interval implied by the pixel's event counts and the slice's thresholds;
// the bound policies, the threshold floor loss, threshold and noise policies. Written once with ad/.
// Depends on ad/ only.
#pragma once
#include <array>

#include "../ad/expr.hpp"

namespace evnerf::loss {

/// Bound of the log change for n⁺ positive and n⁻ negative events with thresholds B⁺ > 0 > B⁻:
/// μ = n⁺B⁺ + n⁻B⁻, interval [μ + k⁻·B⁻, μ + k⁺·B⁺] (k± = slack in thresholds; spec §2, default 1).
/// Hinge L1 outside the interval, zero inside. eps keeps log(ℓ + eps) finite (spec: 1e-3). An open end
/// (open_pos: the ON count is only a lower bound, so the change may rise above the interval; open_neg the
/// same below) adds nothing.
struct EventBounds {
  double n_pos, n_neg, k_neg = 1.0, k_pos = 1.0, eps = 1e-3;
  bool open_neg = false, open_pos = false;
  /// Arguments: luminance at T_i, luminance at T_i+1, B⁺, B⁻ (spec §2).
  template <class L0, class L1, class BP, class BM>
  auto operator()(const L0& l0, const L1& l1, const BP& bp, const BM& bm) const {
    const auto change = ad::log(l1 + eps) - ad::log(l0 + eps);
    const auto mu = n_pos * bp + n_neg * bm;
    return (open_neg ? 0.0 : 1.0) * ad::relu((mu + k_neg * bm) - change) + (open_pos ? 0.0 : 1.0) * ad::relu(change - (mu + k_pos * bp));
  }
  /// Value and gradient w.r.t. (ℓ0, ℓ1, B⁺, B⁻).
  std::array<double, 5> evaluate(double l0, double l1, double bp, double bm) const {
    const std::array<double, 4> x{l0, l1, bp, bm};
    const auto vg = ad::value_and_grad(*this, x);
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
/// without. Ours, not the paper's: the Fast presets use it (measured against the others: docs/results.md).
struct HalfSlackCounts {
  static constexpr const char* name = "half-slack";
  static EventBounds make(int n_pos, int n_neg) {
    const double k = n_pos + n_neg > 0 ? 0.5 : 1.0;
    return {double(n_pos), double(n_neg), k, k};
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

/// Per-slice thresholds B_i^± learned jointly with the field, with the floor loss at weight λ = 1000.
struct JointThresholds {
  static constexpr bool learnable = true;
  static constexpr double lambda = 1000.0, init = 0.3;
  static constexpr const char* name = "joint";
};
/// Per-slice thresholds learned jointly, kept at or beyond the floor ±0.3 by projection after every update
/// instead of a penalty (λ unused): the constraint the floor loss approximates, without its gradient of
/// 1000 entering Adam's moments. Ours; measured against JointThresholds (docs/results.md).
struct ProjectedThresholds {
  static constexpr bool learnable = true, projected = true;
  static constexpr double lambda = 0.0, init = 0.3;
  static constexpr const char* name = "joint-projected";
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
