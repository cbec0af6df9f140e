// render/sampler.hpp — where along a ray the field is evaluated. The `Sampler` concept, and two samplers
// without state: Stratified<N> (one network) and Hierarchical<Nc, Nf> (coarse stratified samples, then Nf
// more drawn from the coarse weights; separate coarse and fine networks, both trained). The sampler with
// state, OccupancySkipping, is in render/occupancy.hpp. Depends on core/ and render/scene.hpp only.
#pragma once
#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "scene.hpp"

namespace evnerf::render {

/// N stratified depths in [near, far]: bin centres when `rng` is null (evaluation), jittered otherwise.
template <class T>
void stratified_depths(int n, T near, T far, Rng* rng, T* t) {
  const T step = (far - near) / static_cast<T>(n);
  for (int k = 0; k < n; ++k) t[k] = near + step * (static_cast<T>(k) + (rng ? static_cast<T>(rng->uniform()) : T(0.5)));
}

/// How a stratified sampler spaces its N bins along a ray, as a policy (the last parameter of Stratified
/// and OccupancySkipping). `UniformDepth`: equal bins in depth (stratified_depths). `LogDepth`: equal bins in
/// log depth, so a bin's length grows in proportion to its depth, as a pixel's footprint does (Instant-NGP
/// spaces its steps the same way with its cone angle). A surface at depth z then gets bins z·ln(far/near)/N
/// long: at N = 128, near 0.3 and far 7 they are shorter than 64 uniform bins up to 4.3 m and longer beyond,
/// where the same error in depth moves a texture by fewer pixels. Needs near > 0.
template <class S>
concept DepthSpacing = requires(int n, float near, float far, Rng* rng, float* t) {
  { S::name } -> std::convertible_to<std::string_view>;
  S::depths(n, near, far, rng, t);
};
struct UniformDepth {
  static constexpr std::string_view name = "";  // sampler names (and so checkpoints) from before the policy
  template <class T>
  static void depths(int n, T near, T far, Rng* rng, T* t) {
    stratified_depths(n, near, far, rng, t);
  }
};
/// LogDepth's and OffsetLogDepth's bins: n equal bins in log(z + c) between near and far; bin k's centre, or
/// a point drawn uniformly in log(z + c) inside it (c = 0 is LogDepth exactly: log(z + 0) is log z).
template <class T>
void log_spaced_depths(int n, double near, double far, double c, Rng* rng, T* t) {
  const double a = std::log(near + c), span = std::log(far + c) - a;
  for (int k = 0; k < n; ++k) {
    const double u = (k + (rng ? rng->uniform() : 0.5)) / n;
    t[k] = static_cast<T>(std::exp(a + u * span) - c);
  }
}

struct LogDepth {
  static constexpr std::string_view name = " log-spaced";
  /// The renderer calls this when it is given a box (outside any parallel region).
  static void check(double near, double far) {
    require(near > 0 && far > near,
            "samples spaced in log depth need 0 < near < far, got near " + short_number(near) + " and far " + short_number(far));
  }
  /// Bin k of n spans [near·r^(k/n), near·r^((k+1)/n)], r = far/near; its centre in log depth, or a point
  /// drawn uniformly in log depth inside it. Needs check(near, far).
  template <class T>
  static void depths(int n, T near, T far, Rng* rng, T* t) {
    log_spaced_depths(n, static_cast<double>(near), static_cast<double>(far), 0.0, rng, t);
  }
};

/// Equal bins in log(z + c), c = CentiMetres/100 world units: LogDepth's growth with depth, levelled off
/// near the camera. A bin at depth z is (z + c)·ln((far + c)/(near + c))/N long, between LogDepth (c = 0)
/// and uniform spacing (c → ∞). At N = 128, c = 1 m, near 0.3 and far 7: 2.8 cm at 1 m, 11.4 cm at 7 m, no
/// longer than 64 uniform bins (10.5 cm) out to 6.4 m, where LogDepth's grow past them from 4.3 m on.
template <int CentiMetres>
struct OffsetLogDepth {
  static_assert(CentiMetres > 0, "OffsetLogDepth: the offset must be positive (render::LogDepth is offset 0)");
  static constexpr double offset = CentiMetres / 100.0;
  static inline const std::string name = " log-spaced offset " + short_number(offset);
  /// The renderer calls this when it is given a box (outside any parallel region).
  static void check(double near, double far) {
    require(near + offset > 0 && far > near, "samples spaced in log(depth + " + short_number(offset) +
                                                 ") need near + offset > 0 and far > near, got near " + short_number(near) + " and far " +
                                                 short_number(far));
  }
  /// Bin k of n spans [exp(a + k·s/n) − c, exp(a + (k + 1)·s/n) − c], a = ln(near + c), s = ln(far + c) − a; its
  /// centre in log(z + c), or a point drawn uniformly in log(z + c) inside it.
  template <class T>
  static void depths(int n, T near, T far, Rng* rng, T* t) {
    log_spaced_depths(n, static_cast<double>(near), static_cast<double>(far), offset, rng, t);
  }
};

/// Added to every bin's weight before drawing fine depths, so that a ray of zero weight still gets a pdf.
inline constexpr double kImportanceWeightFloor = 1e-5;

/// Draws n depths from the piecewise-constant pdf given by `weights` (size m-2) on the bins between the
/// mid-points of the m coarse depths (NeRF's inverse-CDF sampling), then merges them with the coarse
/// depths into `out` (sorted, m + n values). Deterministic midpoints when rng is null.
template <class T>
void importance_depths(int m, const T* coarse_t, const T* weights, int n, Rng* rng, std::vector<T>& out) {
  std::vector<T> mids(m - 1), cdf(m - 1);
  for (int k = 0; k + 1 < m; ++k) mids[k] = T(0.5) * (coarse_t[k] + coarse_t[k + 1]);
  // Bins between consecutive mids carry the interior weights 1..m-2.
  T total = 0;
  cdf[0] = 0;
  for (int k = 1; k + 1 < m; ++k) {
    total += weights[k] + T(kImportanceWeightFloor);
    cdf[k] = total;
  }
  out.assign(coarse_t, coarse_t + m);
  for (int s = 0; s < n; ++s) {
    const T u = (rng ? static_cast<T>(rng->uniform()) : (static_cast<T>(s) + T(0.5)) / static_cast<T>(n)) * total;
    int b = static_cast<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
    b = std::clamp(b, 1, m - 2);
    const T c0 = cdf[b - 1], c1 = cdf[b];
    const T f = c1 > c0 ? (u - c0) / (c1 - c0) : T(0.5);
    out.push_back(mids[b - 1] + f * (mids[b] - mids[b - 1]));
  }
  std::sort(out.begin(), out.end());
}

/// What a sampler may look at between training steps (Sampler::update): the step about to be taken, a
/// seed for it, the scene box, the field's density, and which parts of the box the training cameras see.
struct SamplerUpdate {
  long step = 0;
  std::uint64_t seed = 0;
  SceneBox box;
  /// density(pts, n, out): σ after the field's density activation at n points (3 floats each, in the
  /// normalised box [−1, 1]³). Runs in parallel itself.
  std::function<void(const float*, std::size_t, float*)> density;
  /// seen(world point, radius): whether some training camera sees a ball of this radius between near and
  /// far. Pure: depends only on the recording and the box.
  std::function<bool(const Vec3&, double)> seen;
};

/// A sampler chooses the depths at which a ray is evaluated and may skip some samples. It owns whatever
/// state it keeps (a grid of occupied cells, say), refreshes it in update() before a training step, and
/// writes it into checkpoints with serialize(). Depths are in units of the ray direction (z-depth for
/// our rays). A sampler with `two_networks` also has a fine pass: refine() draws n_fine more depths per
/// ray from the coarse pass's weights, evaluated by a second network.
template <class S>
concept Sampler = std::semiregular<S> &&
    requires(S& s, const S& cs, float* t, Rng* rng, const float* p, const SamplerUpdate& u, std::string_view bytes) {
  requires S::n_coarse >= 2 && S::n_fine >= 0;
  { S::two_networks } -> std::convertible_to<bool>;
  { S::skips_samples } -> std::convertible_to<bool>;
  { S::name() } -> std::convertible_to<std::string>;
  cs.coarse_depths(1, 0.f, 1.f, rng, t);
  { cs.skipping() } -> std::same_as<bool>;
  { cs.evaluates(p) } -> std::same_as<bool>;
  { cs.occupied_fraction() } -> std::convertible_to<double>;
  s.update(u);
  { cs.serialize() } -> std::same_as<std::string>;
  { s.deserialize(bytes) } -> std::same_as<bool>;
} &&(!S::two_networks ||
     requires(const S& cs, const float* t, const float* w, Rng* rng, std::vector<float>& out) { cs.refine(1, t, w, rng, out); });

/// N stratified samples per ray (spaced by the DepthSpacing policy), one network, every sample evaluated.
template <int N, DepthSpacing Spacing = UniformDepth>
struct Stratified {
  static_assert(N >= 2, "Stratified<N>: need at least two samples per ray.");
  static constexpr int n_coarse = N, n_fine = 0;
  static constexpr bool two_networks = false, skips_samples = false;
  using spacing = Spacing;
  static std::string name() { return "stratified " + std::to_string(N) + std::string(Spacing::name); }
  template <class T>
  void coarse_depths(int n, T near, T far, Rng* rng, T* t) const {
    Spacing::depths(n, near, far, rng, t);
  }
  bool skipping() const { return false; }
  template <class T>
  bool evaluates(const T*) const {
    return true;
  }
  double occupied_fraction() const { return 1.0; }
  void update(const SamplerUpdate&) {}
  std::string serialize() const { return {}; }
  bool deserialize(std::string_view b) { return b.empty(); }
};

/// Nc stratified samples through a coarse network, then Nf more from its weights through a fine one.
template <int Nc, int Nf>
struct Hierarchical : Stratified<Nc> {
  static_assert(Nc >= 3 && Nf >= 1, "Hierarchical<Nc, Nf>: need at least three coarse and one fine sample.");
  static constexpr int n_fine = Nf;
  static constexpr bool two_networks = true;
  static std::string name() { return "hierarchical " + std::to_string(Nc) + "+" + std::to_string(Nf); }
  /// The m coarse depths merged with Nf drawn from their weights (jittered by `rng`, or deterministic).
  template <class T>
  void refine(int m, const T* coarse_t, const T* weights, Rng* rng, std::vector<T>& out) const {
    importance_depths<T>(m, coarse_t, weights, Nf, rng, out);
  }
};

}  // namespace evnerf::render
