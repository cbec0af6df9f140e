// A sampler of your own (examples/custom_parts.cpp): N samples per ray stratified in inverse depth
// (disparity) between near and far, so that near surfaces get fine spacing and the far end coarse.
// One type with the members the render::Sampler concept names; no state, one network.
#pragma once
#include <evnerf/render/sampler.hpp>

namespace mylab {

template <int N>
struct InverseDepth {
  static_assert(N >= 2, "InverseDepth<N>: need at least two samples per ray.");
  static constexpr int n_coarse = N, n_fine = 0;
  static constexpr bool two_networks = false, skips_samples = false;
  static std::string name() { return "inverse depth " + std::to_string(N); }
  /// Bin k of N in disparity: centres (no rng) or jittered; returned in increasing depth.
  template <class T>
  void coarse_depths(int n, T near, T far, evnerf::Rng* rng, T* t) const {
    const T d0 = T(1) / near, d1 = T(1) / far;  // disparity falls from d0 to d1
    for (int k = 0; k < n; ++k) {
      const T u = (static_cast<T>(k) + (rng ? static_cast<T>(rng->uniform()) : T(0.5))) / static_cast<T>(n);
      t[k] = T(1) / (d0 + u * (d1 - d0));
    }
  }
  bool skipping() const { return false; }
  template <class T>
  bool evaluates(const T*) const {
    return true;
  }
  double occupied_fraction() const { return 1.0; }
  void update(const evnerf::render::SamplerUpdate&) {}
  std::string serialize() const { return {}; }
  bool deserialize(std::string_view b) { return b.empty(); }
};

}  // namespace mylab
