// nn/params.hpp — a model's parameters and gradients in one flat buffer (so optimisers, checkpoints and
// gradient checks see one array), per-thread gradient accumulators reduced in a fixed order, Adam, and a
// moving average of the parameters. Depends on core/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "../core/error.hpp"
#include "../core/parallel.hpp"

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace evnerf::nn {

namespace detail {
/// Adam's update of entries [b, e): with β's complements c₁ = 1 − β₁ and c₂ = 1 − β₂ (rounded to T),
///   m ← fma(β₁, m, c₁·g),  v ← fma(β₂, v, (c₂·g)·g),  θ ← θ − (a·m) / (√v + ε).
/// Where the target has FMA the two moment updates are fused multiply-adds (what GCC makes of the plain
/// expressions there), written out so the result does not depend on the compiler's contraction; without
/// FMA they are the plain expressions. For float with AVX2 + FMA eight entries go at a time (vsqrtps and
/// vdivps round as the scalar instructions do, so every entry gets the same bits). The plain loop is not
/// vectorised by the compiler: std::sqrt may set errno.
template <class T>
inline void adam_one(T* p, const T* g, T* m, T* v, std::size_t i, T a, T b1, T b2, T eps) {
  const T gi = g[i];
#if defined(__FMA__)
  m[i] = std::fma(b1, m[i], (T(1) - b1) * gi);
  v[i] = std::fma(b2, v[i], (T(1) - b2) * gi * gi);
#else
  m[i] = b1 * m[i] + (T(1) - b1) * gi;
  v[i] = b2 * v[i] + (T(1) - b2) * gi * gi;
#endif
  p[i] = p[i] - a * m[i] / (std::sqrt(v[i]) + eps);
}

template <class T>
inline void adam_range(T* p, const T* g, T* m, T* v, std::size_t b, std::size_t e, T a, T b1, T b2, T eps) {
  std::size_t i = b;
#if defined(__AVX2__) && defined(__FMA__)
  if constexpr (std::is_same_v<T, float>) {
    const __m256 vb1 = _mm256_set1_ps(b1), vc1 = _mm256_set1_ps(1.f - b1), vb2 = _mm256_set1_ps(b2), vc2 = _mm256_set1_ps(1.f - b2),
                 va = _mm256_set1_ps(a), veps = _mm256_set1_ps(eps);
    for (; i + 8 <= e; i += 8) {
      const __m256 gi = _mm256_loadu_ps(g + i);
      const __m256 mi = _mm256_fmadd_ps(vb1, _mm256_loadu_ps(m + i), _mm256_mul_ps(vc1, gi));
      const __m256 vi = _mm256_fmadd_ps(vb2, _mm256_loadu_ps(v + i), _mm256_mul_ps(_mm256_mul_ps(vc2, gi), gi));
      _mm256_storeu_ps(m + i, mi);
      _mm256_storeu_ps(v + i, vi);
      const __m256 step = _mm256_div_ps(_mm256_mul_ps(va, mi), _mm256_add_ps(_mm256_sqrt_ps(vi), veps));
      _mm256_storeu_ps(p + i, _mm256_sub_ps(_mm256_loadu_ps(p + i), step));
    }
  }
#endif
  for (; i < e; ++i) adam_one(p, g, m, v, i, a, b1, b2, eps);
}
}  // namespace detail

/// Parameters, their gradients, and one gradient accumulator per thread.
template <class T = float>
struct ParameterBuffer {
  std::vector<T> values, grads;
  std::vector<std::vector<T>> per_thread;

  explicit ParameterBuffer(std::size_t n = 0) : values(n, T(0)), grads(n, T(0)) {}
  std::size_t size() const { return values.size(); }
  void zero_grads() { std::fill(grads.begin(), grads.end(), T(0)); }

  /// Zeroed accumulators for `threads` threads.
  void begin_accumulate(int threads) {
    size_accumulators(threads);
    for (int t = 0; t < threads; ++t) zero_accumulator(t);
  }
  /// Accumulators for `threads` threads, not zeroed: each thread zeroes its own (zero_accumulator) where it
  /// starts to work, so the zeroing runs in parallel and the memory is first touched by its thread.
  void size_accumulators(int threads) {
    per_thread.resize(static_cast<std::size_t>(threads));
    for (auto& g : per_thread) g.resize(values.size());
  }
  void zero_accumulator(int t) {
    auto& g = per_thread[static_cast<std::size_t>(t)];
    std::fill(g.begin(), g.end(), T(0));
  }
  /// grads = Σ_thread accumulators, summed in thread order from zero, (0 + g₀) + g₁ + …, as adding each to
  /// zeroed gradients in turn would (deterministic for a given thread count). `used` limits the sum to the
  /// accumulators that were handed out.
  void end_accumulate(int used) {
    const std::size_t n = values.size();
    grads.resize(n);
    parallel_blocks(n, 1 << 16, [&](std::size_t b, std::size_t e, int) {
      T* out = grads.data();
      if (used <= 0) {
        std::fill(out + b, out + e, T(0));
        return;
      }
      const T* g0 = per_thread[0].data();
      for (std::size_t i = b; i < e; ++i) out[i] = T(0) + g0[i];
      for (int t = 1; t < used; ++t) {
        const T* g = per_thread[static_cast<std::size_t>(t)].data();
        for (std::size_t i = b; i < e; ++i) out[i] += g[i];
      }
    });
  }
};

/// Adam (Kingma & Ba) with an exponential learning-rate decay lr(s) = lr · decay^(s / decay_steps).
/// Defaults are the tool's (train::Config takes them): Ev-NeRF's β (0.9, 0.999), ε 1e-7 and decay 0.1 over
/// 250 000 steps, with lr 5e-3, which the hash-grid presets want (the paper's model wants 5e-4).
struct AdamConfig {
  double lr = 5e-3, beta1 = 0.9, beta2 = 0.999, eps = 1e-7;
  double decay = 0.1, decay_steps = 250000;
};

template <class T = float>
class Adam {
 public:
  Adam() = default;
  Adam(std::size_t n, AdamConfig cfg = {}) : cfg_(cfg), m_(n, T(0)), v_(n, T(0)) {}
  double learning_rate() const { return cfg_.lr * std::pow(cfg_.decay, static_cast<double>(step_) / cfg_.decay_steps); }
  long step() const { return step_; }
  const AdamConfig& config() const { return cfg_; }
  void set_config(const AdamConfig& c) { cfg_ = c; }

  /// One update of `values` from `grads` (bias-corrected moments).
  void update(std::vector<T>& values, const std::vector<T>& grads) { update(values, grads, values.size(), {}); }
  /// Like update(), but of the entries from `dense_end` on only those listed in `sparse` move, and only
  /// their moments decay (lazy Adam for parameters a step does not touch: a per-slice threshold that was not
  /// drawn keeps its value and state instead of coasting on its old momentum).
  void update(std::vector<T>& values, const std::vector<T>& grads, std::size_t dense_end, const std::vector<std::size_t>& sparse) {
    require(values.size() == m_.size() && grads.size() == m_.size() && dense_end <= m_.size(), "Adam: parameter count changed");
    ++step_;
    const double lr = cfg_.lr * std::pow(cfg_.decay, static_cast<double>(step_ - 1) / cfg_.decay_steps);
    const double bc1 = 1 - std::pow(cfg_.beta1, static_cast<double>(step_));
    const double bc2 = 1 - std::pow(cfg_.beta2, static_cast<double>(step_));
    const T a = static_cast<T>(lr * std::sqrt(bc2) / bc1), b1 = static_cast<T>(cfg_.beta1), b2 = static_cast<T>(cfg_.beta2),
            eps = static_cast<T>(cfg_.eps * std::sqrt(bc2));
    T *p = values.data(), *m = m_.data(), *v = v_.data();
    const T* g = grads.data();
    parallel_blocks(dense_end, 1 << 16, [&](std::size_t b, std::size_t e, int) { detail::adam_range(p, g, m, v, b, e, a, b1, b2, eps); });
    for (std::size_t i : sparse) {
      require(i >= dense_end && i < m_.size(), "Adam: sparse index out of range");
      detail::adam_one(p, g, m, v, i, a, b1, b2, eps);
    }
  }
  // State access for checkpoints.
  std::vector<T>& m() { return m_; }
  std::vector<T>& v() { return v_; }
  const std::vector<T>& m() const { return m_; }
  const std::vector<T>& v() const { return v_; }
  void set_step(long s) { step_ = s; }

 private:
  AdamConfig cfg_;
  std::vector<T> m_, v_;
  long step_ = 0;
};

/// An exponential moving average of the parameters (Polyak averaging), the weights a model renders with.
/// After training step n the average moves towards the parameters by w(n) = 1 − min(decay, (1 + n)/(10 + n))
/// (TensorFlow's ExponentialMovingAverage with its step-count warm-up): early in a run it follows the
/// parameters closely, and from step (10·decay − 1)/(1 − decay) on (4490 for decay 0.998) it averages over
/// about 1/(1 − decay) steps. It never feeds back into training. Element-wise, so deterministic for any
/// thread count.
template <class T = float>
class ParameterAverage {
 public:
  ParameterAverage() = default;
  /// An average of `decay` in (0, 1) starting at `start` (the parameters it is first set from).
  ParameterAverage(double decay, std::vector<T> start) : decay_(decay), values_(std::move(start)) {
    require(decay > 0 && decay < 1, "ParameterAverage: the decay must be in (0, 1), got " + std::to_string(decay));
  }
  double decay() const { return decay_; }
  bool active() const { return !values_.empty(); }
  /// The weight the parameters of step n get.
  static double weight(double decay, long n) {
    return 1.0 - std::min(decay, (1.0 + static_cast<double>(n)) / (10.0 + static_cast<double>(n)));
  }
  /// Moves the average towards `params` as after step n.
  void update(const std::vector<T>& params, long n) {
    require(params.size() == values_.size(), "ParameterAverage: parameter count changed");
    const T w = static_cast<T>(weight(decay_, n));
    T* a = values_.data();
    const T* p = params.data();
    parallel_blocks(values_.size(), 1 << 16, [&](std::size_t b, std::size_t e, int) {
      for (std::size_t i = b; i < e; ++i) a[i] += w * (p[i] - a[i]);
    });
  }
  const std::vector<T>& values() const { return values_; }
  std::vector<T>& values() { return values_; }

 private:
  double decay_ = 0;
  std::vector<T> values_;
};

}  // namespace evnerf::nn
