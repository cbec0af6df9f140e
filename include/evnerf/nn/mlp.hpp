// nn/mlp.hpp — compile-time multilayer perceptrons over tiles of samples, with a fused forward+backward:
// a tile of samples goes forward through all layers and back through all layers while its activations
// stay in cache; bias, activation and the activation's derivative are applied in the pass right after
// each matrix product, on the tile that product just wrote. Depends on core/ and nn/activation.hpp only.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "../core/rng.hpp"
#include "activation.hpp"
#include "gemm.hpp"

namespace evnerf::nn {

template <class T>
using MatMap = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>;
template <class T>
using CMatMap = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>;

/// Multilayer perceptron: `Depth` hidden layers of `Width` units with `HiddenAct`, then an output layer
/// of `Out` units with `OutAct`. With Skip = s ≥ 0 the encoded input is concatenated again to the output
/// of hidden layer s, so hidden layer s+1 sees Width + In inputs (the NeRF trunk uses Depth 8, Skip 4).
/// Samples are columns of column-major matrices (features × samples). Parameters are one flat array:
/// per layer, W (out × in, column-major) then b (out).
template <int In, int Width, int Depth, int Out, class HiddenAct = ReLU, class OutAct = Identity, int Skip = -1>
struct Mlp {
  static_assert(Activation<HiddenAct>, "Mlp: HiddenAct must be an activation type such as ReLU, Softplus, Sigmoid, TruncExp or Identity.");
  static_assert(Activation<OutAct>, "Mlp: OutAct must be an activation type such as ReLU, Softplus, Sigmoid, TruncExp or Identity.");
  static_assert(In >= 1, "Mlp: the input must have at least one feature.");
  static_assert(Out >= 1, "Mlp: the output must have at least one feature.");
  static_assert(Depth >= 0, "Mlp: the number of hidden layers cannot be negative.");
  static_assert(Depth == 0 || Width >= 1, "Mlp: hidden layers need a positive width.");
  static_assert(Skip >= -1, "Mlp: Skip must be -1 (no skip) or a hidden layer index.");
  static_assert(Skip + 1 < Depth || Skip == -1,
                "Mlp: the skip connection must feed a hidden layer: Skip + 1 must be less than Depth.");

  static constexpr int in_dims = In, out_dims = Out, width = Width, depth = Depth, skip = Skip;
  static constexpr int n_layers = Depth + 1;
  using hidden_activation = HiddenAct;
  using output_activation = OutAct;

  static constexpr int layer_in(int l) {
    return l == 0 ? In : Width + (l == Skip + 1 && Skip >= 0 ? In : 0);
  }
  static constexpr int layer_out(int l) { return l == Depth ? Out : Width; }
  static constexpr std::size_t weight_offset(int l) {
    std::size_t o = 0;
    for (int i = 0; i < l; ++i) o += static_cast<std::size_t>(layer_in(i)) * layer_out(i) + layer_out(i);
    return o;
  }
  static constexpr std::size_t bias_offset(int l) {
    return weight_offset(l) + static_cast<std::size_t>(layer_in(l)) * layer_out(l);
  }
  static constexpr std::size_t n_params = weight_offset(n_layers);
  /// Multiply-adds per sample in the forward pass (the backward costs about twice that).
  static constexpr std::size_t macs_per_sample() {
    std::size_t m = 0;
    for (int l = 0; l < n_layers; ++l) m += static_cast<std::size_t>(layer_in(l)) * layer_out(l);
    return m;
  }
  static constexpr int max_width() {
    int m = In > Out ? In : Out;
    for (int l = 0; l < n_layers; ++l) m = layer_in(l) > m ? layer_in(l) : m;
    return m;
  }

  /// He-uniform weights (scaled for the layer's fan-in), zero biases: suits ReLU trunks.
  template <class T>
  static void init(T* p, Rng& rng) {
    for (int l = 0; l < n_layers; ++l) {
      const double bound = std::sqrt(6.0 / layer_in(l)) * (l == Depth ? 0.5 : 1.0);
      T* w = p + weight_offset(l);
      for (std::size_t i = 0; i < static_cast<std::size_t>(layer_in(l)) * layer_out(l); ++i)
        w[i] = static_cast<T>(rng.uniform(-bound, bound));
      T* b = p + bias_offset(l);
      for (int i = 0; i < layer_out(l); ++i) b[i] = T(0);
    }
  }

  /// Caller-owned memory for one tile: each layer's input and the output, kept for the backward pass.
  template <class T>
  struct Workspace {
    int n = 0;                                   ///< samples in the tile
    std::array<std::vector<T>, n_layers> input;  ///< layer l's input (layer_in(l) × n); [0] unused
    std::vector<T> output;                       ///< Out × n, after OutAct
    std::vector<T> grad_a, grad_b;               ///< ping-pong gradient buffers (max_width × n)
    std::vector<T> wt;                           ///< one layer's transposed weights (backward)
    const T* x = nullptr;                        ///< the tile's input (In × n), owned by the caller

    void resize(int samples) {
      if (samples <= n && !output.empty()) {
        n = samples;
        return;
      }
      n = samples;
      for (int l = 1; l < n_layers; ++l) input[l].resize(static_cast<std::size_t>(layer_in(l)) * samples);
      output.resize(static_cast<std::size_t>(Out) * samples);
      grad_a.resize(static_cast<std::size_t>(max_width()) * samples);
      grad_b.resize(static_cast<std::size_t>(max_width()) * samples);
      wt.resize(static_cast<std::size_t>(max_width()) * max_width());
    }
  };

  /// Whether bias + activation (forward) and the activation's derivative (backward) run inside the
  /// product's epilogue, in registers; otherwise they are a pass over the tile right after the product.
  template <class T, class Act>
  static constexpr bool fused_epilogue() {
#if defined(__AVX512F__)
    if constexpr (gemm::has_kernel<T>()) return gemm::VectorActivation<Act>::available;
#endif
    return false;
  }

  /// Forward pass of n samples: x is In × n (column-major), the result is ws.output (Out × n).
  template <class T>
  static const T* forward(const T* params, const T* x, int n, Workspace<T>& ws) {
    ws.resize(n);
    ws.x = x;
    for (int l = 0; l < n_layers; ++l) {
      const int in = layer_in(l), out = layer_out(l);
      const T* src = l == 0 ? x : ws.input[l].data();
      T* dst = l == Depth ? ws.output.data() : ws.input[l + 1].data();
      const int dst_rows = l == Depth ? Out : layer_in(l + 1);
      const T* b = params + bias_offset(l);
      // Y = act(W·X + b): W is out × in (lda = out), X is in × n, Y goes into the next layer's input rows.
      const gemm::Operands<T> op{out, n, in, params + weight_offset(l), out, src, 1, in, dst, dst_rows};
      auto layer = [&](auto act) {
        using Act = decltype(act);
        if constexpr (fused_epilogue<T, Act>()) {
          gemm::product<false>(op, gemm::BiasActivation<Act>{b});
        } else {
          gemm::product<false>(op);
          for (int j = 0; j < n; ++j) {
            T* col = dst + static_cast<std::size_t>(j) * dst_rows;
            for (int i = 0; i < out; ++i) col[i] = Act::f(col[i] + b[i]);
          }
        }
      };
      if (l == Depth) layer(OutAct{});
      else layer(HiddenAct{});
      if (l == Skip && Skip >= 0) {  // append the input below this layer's output
        for (int j = 0; j < n; ++j) {
          const T* xs = x + static_cast<std::size_t>(j) * In;
          T* col = dst + static_cast<std::size_t>(j) * dst_rows + Width;
          for (int i = 0; i < In; ++i) col[i] = xs[i];
        }
      }
    }
    return ws.output.data();
  }

  /// Backward pass for the tile last run through forward(): dy is Out × n (gradient of the loss w.r.t.
  /// the output after OutAct). Adds weight and bias gradients to dparams and, when dx is not null, the
  /// input gradient (In × n) to dx.
  template <class T>
  static void backward(const T* params, Workspace<T>& ws, const T* dy, T* dparams, T* dx) {
    const int n = ws.n;
    // dz of the output layer: dy ⊙ OutAct'(y), in grad_a; the previous layer's dz goes to the other buffer.
    T* dz = ws.grad_a.data();
    T* dz_prev = ws.grad_b.data();
    for (std::size_t k = 0; k < static_cast<std::size_t>(Out) * n; ++k) dz[k] = dy[k] * OutAct::df_from_y(ws.output[k]);
    for (int l = Depth; l >= 0; --l) {
      const int in = layer_in(l), out = layer_out(l);
      const T* src = l == 0 ? ws.x : ws.input[l].data();
      // dW += DZ·Xᵀ: DZ is out × n (lda = out); Xᵀ is read in place (element (j, i) = X[i + j·in]).
      gemm::product<true>(gemm::Operands<T>{out, in, n, dz, out, src, in, 1, dparams + weight_offset(l), out});
      T* db = dparams + bias_offset(l);
      for (int j = 0; j < n; ++j) {
        const T* col = dz + static_cast<std::size_t>(j) * out;
        for (int i = 0; i < out; ++i) db[i] += col[i];
      }
      if (l == 0 && !dx) break;
      // Wᵀ (in × out, column-major) so the input gradient's product reads its A operand contiguously.
      const T* w = params + weight_offset(l);
      T* wt = ws.wt.data();
      for (int i0 = 0; i0 < in; i0 += 16)
        for (int o = 0; o < out; ++o)
          for (int i = i0; i < std::min(in, i0 + 16); ++i) wt[i + static_cast<std::size_t>(o) * in] = w[o + static_cast<std::size_t>(i) * out];
      if (l == 0) {
        gemm::product<true>(gemm::Operands<T>{in, n, out, wt, in, dz, 1, out, dx, in});
        break;
      }
      // The input rows fed by the skip connection: their gradient goes straight into dx.
      if (l == Skip + 1 && Skip >= 0 && dx)
        gemm::product<true>(gemm::Operands<T>{In, n, out, wt + Width, in, dz, 1, out, dx, In});
      // The previous layer's output occupies the top Width rows of this layer's input: its dz is
      // (Wᵀ·DZ) ⊙ act'(y) over those rows.
      const T* y = ws.input[l].data();
      const gemm::Operands<T> op{Width, n, out, wt, in, dz, 1, out, dz_prev, Width};
      if constexpr (fused_epilogue<T, HiddenAct>()) {
        gemm::product<false>(op, gemm::ActivationGrad<HiddenAct>{y, in});
      } else {
        gemm::product<false>(op);
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < Width; ++i)
            dz_prev[static_cast<std::size_t>(j) * Width + i] *= HiddenAct::df_from_y(y[static_cast<std::size_t>(j) * in + i]);
      }
      std::swap(dz, dz_prev);
    }
  }
};

}  // namespace evnerf::nn
