// nn/encoding.hpp — input encodings as types: the Encoding concept, Identity, Frequency<N> (NeRF positional
// encoding), SphericalHarmonics<Degree> (directions); HashGrid<...> (multiresolution hash encoding,
// trainable) is nn/hash_grid.hpp, included at the end. Every encoding maps in_dims inputs to out_dims features
// per sample and has a backward to its input (and to its parameters where it has any). Depends on core/ and ad/ only.
#pragma once
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <concepts>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "../ad/expr.hpp"
#include "../core/rng.hpp"

namespace evnerf::nn {

/// An encoding maps `in_dims` inputs of a sample to `out_dims` features (name() says which, for checkpoints'
/// architecture), may have `n_params` trainable
/// parameters (initialised by init), and has a backward that adds the gradient for its parameters and for
/// its input. Batch paths (forward_batch, backward_batch) are optional; field::Field uses them when
/// present. An encoding that wants its points in [0, 1]³ rather than [−1, 1]³ declares
/// `static constexpr bool unit_cube_input = true`. A network that follows an encoding takes its width from out_dims (field::FieldOf).
template <class E>
concept Encoding = requires(const double* p, const double* x, double* y, double* dp, double* dx, Rng& rng) {
  requires E::in_dims >= 1 && E::out_dims >= 1;
  { E::n_params } -> std::convertible_to<std::size_t>;
  { E::name() } -> std::convertible_to<std::string>;
  E::init(dp, rng);
  E::forward(p, x, y);
  E::backward(p, x, y, dp, dx);
};

/// Passes D inputs through.
template <int D = 3>
struct IdentityEncoding {
  static constexpr int in_dims = D, out_dims = D;
  static std::string name() { return "identity " + std::to_string(D); }
  static constexpr std::size_t n_params = 0;
  template <class T>
  static void init(T*, Rng&) {}
  template <class T>
  static void forward(const T*, const T* x, T* y) {
    std::copy(x, x + D, y);
  }
  template <class T>
  static void backward(const T*, const T*, const T* dy, T*, T* dx) {
    if (dx)
      for (int i = 0; i < D; ++i) dx[i] += dy[i];
  }
};

/// NeRF positional encoding γ(x) = [x, sin(2^k x), cos(2^k x)], k = 0..N-1 (no π factor; nerf-pytorch's
/// convention), feature order [x | sin block | cos block], each block frequency-major. out = D(1 + 2N).
template <int N, int D = 3>
struct Frequency {
  static_assert(N >= 0 && N <= 24, "Frequency<N>: N must be between 0 and 24 frequencies.");
  static constexpr int in_dims = D, out_dims = D * (1 + 2 * N);
  static std::string name() { return "frequency " + std::to_string(N) + " of " + std::to_string(D); }
  static constexpr std::size_t n_params = 0;
  template <class T>
  static void init(T*, Rng&) {}
  template <class T>
  static void forward(const T*, const T* x, T* y) {
    for (int d = 0; d < D; ++d) y[d] = x[d];
    for (int k = 0; k < N; ++k) {
      const T s = static_cast<T>(1 << k);
      for (int d = 0; d < D; ++d) {
        y[D + k * D + d] = std::sin(s * x[d]);
        y[D + N * D + k * D + d] = std::cos(s * x[d]);
      }
    }
  }
  template <class T>
  static void backward(const T*, const T* x, const T* dy, T*, T* dx) {
    if (!dx) return;
    for (int d = 0; d < D; ++d) {
      T g = dy[d];
      for (int k = 0; k < N; ++k) {
        const T s = static_cast<T>(1 << k);
        g += s * (std::cos(s * x[d]) * dy[D + k * D + d] - std::sin(s * x[d]) * dy[D + N * D + k * D + d]);
      }
      dx[d] += g;
    }
  }
};

/// Real spherical harmonics of a unit direction up to `Degree` bands (Degree² outputs, Degree 1..4).
/// The basis is written once on generic values, so the input gradient comes from ad/.
template <int Degree>
struct SphericalHarmonics {
  static_assert(Degree >= 1 && Degree <= 4, "SphericalHarmonics<Degree>: Degree must be between 1 and 4.");
  static constexpr int in_dims = 3, out_dims = Degree * Degree;
  /// Leading outputs that do not depend on the input (band 0): a network weight on one acts as a bias.
  static constexpr int constant_outputs = 1;
  static std::string name() { return "spherical harmonics " + std::to_string(Degree); }
  static constexpr std::size_t n_params = 0;
  template <class T>
  static void init(T*, Rng&) {}

  /// The basis on any value type (plain scalars or ad expressions); calls out(i, value) per coefficient.
  template <class X, class Y, class Z, class Out>
  static void basis(const X& x, const Y& y, const Z& z, Out&& out) {
    // Normalisation constants of the real SH basis, bands 0..3.
    out(0, ad::value_of(x) * 0 + 0.28209479177387814);
    if constexpr (Degree > 1) {
      out(1, -0.48860251190291987 * y);
      out(2, 0.48860251190291987 * z);
      out(3, -0.48860251190291987 * x);
    }
    if constexpr (Degree > 2) {
      out(4, 1.0925484305920792 * (x * y));
      out(5, -1.0925484305920792 * (y * z));
      out(6, 0.31539156525252005 * (3.0 * (z * z) - 1.0));
      out(7, -1.0925484305920792 * (x * z));
      out(8, 0.54627421529603959 * (x * x - y * y));
    }
    if constexpr (Degree > 3) {
      out(9, -0.59004358992664352 * (y * (3.0 * (x * x) - y * y)));
      out(10, 2.8906114426405538 * (x * (y * z)));
      out(11, -0.45704579946446572 * (y * (5.0 * (z * z) - 1.0)));
      out(12, 0.3731763325901154 * (z * (5.0 * (z * z) - 3.0)));
      out(13, -0.45704579946446572 * (x * (5.0 * (z * z) - 1.0)));
      out(14, 1.4453057213202769 * (z * (x * x - y * y)));
      out(15, -0.59004358992664352 * (x * (x * x - 3.0 * (y * y))));
    }
  }
  template <class T>
  static void forward(const T*, const T* d, T* y) {
    basis(d[0], d[1], d[2], [&](int i, auto v) { y[i] = static_cast<T>(ad::value_of(v)); });
  }
  template <class T>
  static void backward(const T*, const T* d, const T* dy, T*, T* dx) {
    if (!dx) return;
    const ad::Arg<T, 0> x{{}, d[0]};
    const ad::Arg<T, 1> yy{{}, d[1]};
    const ad::Arg<T, 2> z{{}, d[2]};
    std::array<T, 3> g{};
    basis(x, yy, z, [&](int i, const auto& e) {
      if constexpr (ad::Expr<std::remove_cvref_t<decltype(e)>>) e.backprop(dy[i], g);
    });
    for (int k = 0; k < 3; ++k) dx[k] += g[k];
  }
};

}  // namespace evnerf::nn

#include "hash_grid.hpp"
