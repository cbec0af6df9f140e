// nn/activation.hpp — activations as types. Each is written once with ad/ (so its derivative is generated)
// and also gives the derivative from its output, which is what the fused MLP keeps in cache.
// Depends on ad/ only.
#pragma once
#include <cmath>

#include "../ad/expr.hpp"

namespace evnerf::nn {

struct ReLU {
  static constexpr const char* name = "relu";
  template <class X>
  static constexpr auto apply(const X& x) {
    return ad::relu(x);
  }
  template <class T>
  static constexpr T f(T x) {
    return x > T(0) ? x : T(0);
  }
  template <class T>
  static constexpr T df_from_y(T y) {
    return y > T(0) ? T(1) : T(0);
  }
};

struct Identity {
  static constexpr const char* name = "identity";
  template <class X>
  static constexpr auto apply(const X& x) {
    return x;
  }
  template <class T>
  static constexpr T f(T x) {
    return x;
  }
  template <class T>
  static constexpr T df_from_y(T) {
    return T(1);
  }
};

struct Sigmoid {
  static constexpr const char* name = "sigmoid";
  template <class X>
  static constexpr auto apply(const X& x) {
    return ad::sigmoid(x);
  }
  template <class T>
  static T f(T x) {
    return T(1) / (T(1) + std::exp(-x));
  }
  template <class T>
  static constexpr T df_from_y(T y) {
    return y * (T(1) - y);
  }
};

struct Softplus {
  static constexpr const char* name = "softplus";
  template <class X>
  static constexpr auto apply(const X& x) {
    return ad::softplus(x);
  }
  template <class T>
  static T f(T x) {
    return ad::op::Softplus::f(x);
  }
  template <class T>
  static T df_from_y(T y) {
    return T(1) - std::exp(-y);
  }  // σ(x) = 1 − e^{−softplus(x)}
};

/// exp(min(x, 15)): density activation of Instant-NGP-style fields; truncated so it cannot overflow.
/// The derivative is the output below the cut and 0 above it.
struct TruncExp {
  static constexpr const char* name = "trunc_exp";
  static constexpr double cut = 15.0;
  template <class X>
  static constexpr auto apply(const X& x) {
    return ad::exp(ad::min(x, cut));
  }
  template <class T>
  static T f(T x) {
    return std::exp(x < T(cut) ? x : T(cut));
  }
  template <class T>
  static T df_from_y(T y) {
    return y < static_cast<T>(std::exp(cut)) * T(0.999999) ? y : T(0);
  }
};

template <class A>
concept Activation = requires(float x) {
  A::name;
  {A::f(x)};
  {A::df_from_y(x)};
};

}  // namespace evnerf::nn
