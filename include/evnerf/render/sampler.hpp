// render/sampler.hpp — where along a ray the field is evaluated: Stratified<N> (one network) and
// Hierarchical<Nc, Nf> (coarse stratified samples, then Nf more drawn from the coarse weights; separate
// coarse and fine networks, both trained). Depends on core/ only.
#pragma once
#include <algorithm>
#include <vector>

#include "../core/rng.hpp"

namespace evnerf::render {

template <int N>
struct Stratified {
  static_assert(N >= 2, "Stratified<N>: need at least two samples per ray.");
  static constexpr int n_coarse = N, n_fine = 0;
  static constexpr bool two_networks = false;
};

template <int Nc, int Nf>
struct Hierarchical {
  static_assert(Nc >= 2 && Nf >= 1, "Hierarchical<Nc, Nf>: need at least two coarse and one fine sample.");
  static constexpr int n_coarse = Nc, n_fine = Nf;
  static constexpr bool two_networks = true;
};

/// N stratified depths in [near, far]: bin centres when `rng` is null (evaluation), jittered otherwise.
template <class T>
void stratified_depths(int n, T near, T far, Rng* rng, T* t) {
  const T step = (far - near) / static_cast<T>(n);
  for (int k = 0; k < n; ++k) t[k] = near + step * (static_cast<T>(k) + (rng ? static_cast<T>(rng->uniform()) : T(0.5)));
}

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
    total += weights[k] + T(1e-5);
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

}  // namespace evnerf::render
