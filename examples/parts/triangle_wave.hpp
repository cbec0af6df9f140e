// An encoding of your own (examples/custom_parts.cpp): x and N triangle waves per axis,
// tri(2^k x) with tri(u) = |2(u − round(u))| (period 1, values in [0, 1]): a piecewise-linear cousin of
// NeRF's sines, cheap and exactly differentiable almost everywhere. One type with the members the
// nn::Encoding concept names; no parameters.
#pragma once
#include <cmath>
#include <string>

#include <evnerf/nn/encoding.hpp>

namespace mylab {

template <int N>
struct TriangleWave {
  static_assert(N >= 1 && N <= 20, "TriangleWave<N>: between 1 and 20 octaves.");
  static constexpr int in_dims = 3, out_dims = 3 * (1 + N);
  static constexpr std::size_t n_params = 0;
  static std::string name() { return "triangle wave " + std::to_string(N); }
  template <class T>
  static void init(T*, evnerf::Rng&) {}
  template <class T>
  static void forward(const T*, const T* x, T* y) {
    for (int d = 0; d < 3; ++d) y[d] = x[d];
    for (int k = 0; k < N; ++k)
      for (int d = 0; d < 3; ++d) {
        const T u = static_cast<T>(1 << k) * x[d];
        y[3 + 3 * k + d] = std::abs(T(2) * (u - std::round(u)));
      }
  }
  /// Adds dL/dx to dx (the encoding has no parameters).
  template <class T>
  static void backward(const T*, const T* x, const T* dy, T*, T* dx) {
    if (!dx) return;
    for (int d = 0; d < 3; ++d) dx[d] += dy[d];
    for (int k = 0; k < N; ++k)
      for (int d = 0; d < 3; ++d) {
        const T s = static_cast<T>(1 << k), u = s * x[d], r = u - std::round(u);
        dx[d] += dy[3 + 3 * k + d] * (r >= 0 ? T(2) : T(-2)) * s;
      }
  }
};
static_assert(evnerf::nn::Encoding<TriangleWave<4>>);

}  // namespace mylab
