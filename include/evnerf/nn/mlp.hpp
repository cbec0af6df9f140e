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
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "../core/error.hpp"
#include "../core/rng.hpp"
#include "activation.hpp"
#include "detail/bf16.hpp"
#include "detail/gemm.hpp"

namespace evnerf::nn {

template <class T>
using MatMap = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>;
template <class T>
using CMatMap = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>;

/// Multilayer perceptron: `Depth` hidden layers of `Width` units with `HiddenAct`, then an output layer
/// of `Out` units with `OutAct`. With Skip = s ≥ 0 the encoded input is concatenated again to the output
/// of hidden layer s, so hidden layer s+1 sees Width + In inputs (the NeRF trunk uses Depth 8, Skip 4).
/// Samples are columns of column-major matrices (features × samples). Parameters are one flat array:
/// per layer, W (out × in, column-major) then b (out). `Prec` (Fp32 or Bf16, nn/detail/bf16.hpp) sets how the
/// float matrix products round their operands; double always computes in double.
template <int In, int Width, int Depth, int Out, class HiddenAct = ReLU, class OutAct = Identity, int Skip = -1, class Prec = Fp32>
struct Mlp {
  static_assert(Activation<HiddenAct>, "Mlp: HiddenAct must be an activation type such as ReLU, Softplus, Sigmoid, TruncExp or Identity.");
  static_assert(Activation<OutAct>, "Mlp: OutAct must be an activation type such as ReLU, Softplus, Sigmoid, TruncExp or Identity.");
  static_assert(In >= 1, "Mlp: the input must have at least one feature.");
  static_assert(Out >= 1, "Mlp: the output must have at least one feature.");
  static_assert(Depth >= 0, "Mlp: the number of hidden layers cannot be negative.");
  static_assert(Depth == 0 || Width >= 1, "Mlp: hidden layers need a positive width.");
  static_assert(Skip >= -1, "Mlp: Skip must be -1 (no skip) or a hidden layer index.");
  static_assert(Skip + 1 < Depth || Skip == -1, "Mlp: the skip connection must feed a hidden layer: Skip + 1 must be less than Depth.");
  static_assert(std::is_same_v<Prec, Fp32> || std::is_same_v<Prec, Bf16>, "Mlp: Prec must be nn::Fp32 or nn::Bf16.");

  static constexpr int in_dims = In, out_dims = Out, width = Width, depth = Depth, skip = Skip;
  static constexpr int n_layers = Depth + 1;
  using hidden_activation = HiddenAct;
  using output_activation = OutAct;
  using precision = Prec;
  /// The shape as checkpoints record it (the product precision is not part of it: FP32 and bf16 twins share
  /// their parameters).
  static std::string name() {
    std::string n =
        "mlp " + std::to_string(In) + ">" + std::to_string(Width) + "x" + std::to_string(Depth) + ">" + std::to_string(Out) + " ";
    n.append(HiddenAct::name).append("/").append(OutAct::name);
    if (Skip >= 0) n.append(" skip ").append(std::to_string(Skip));
    return n;
  }

  /// Whether the products of a T network run on bf16 pairs (float, Prec = Bf16, a CPU with AVX-512 BF16).
  template <class T>
  static constexpr bool bf16_products() {
    return std::is_same_v<T, float> && std::is_same_v<Prec, Bf16> && bf16::available();
  }

  static constexpr int layer_in(int l) { return l == 0 ? In : Width + (l == Skip + 1 && Skip >= 0 ? In : 0); }
  static constexpr int layer_out(int l) { return l == Depth ? Out : Width; }
  static constexpr std::size_t weight_offset(int l) {
    std::size_t o = 0;
    for (int i = 0; i < l; ++i) o += static_cast<std::size_t>(layer_in(i)) * layer_out(i) + layer_out(i);
    return o;
  }
  static constexpr std::size_t bias_offset(int l) { return weight_offset(l) + static_cast<std::size_t>(layer_in(l)) * layer_out(l); }
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
    std::vector<T> wt;                           ///< one layer's transposed weights (backward; Fp32 only)
    std::vector<std::uint32_t> pack_a, pack_b;   ///< bf16 pairs of both factors (Bf16 only)
    const T* x = nullptr;                        ///< the tile's input (In × n), owned by the caller

    /// Room for `samples` samples. The first min(n, samples) samples' activations stay (forward_at appends
    /// after them), and buffers never shrink, so a workspace reused for tiles of varying size is not zeroed again.
    void resize(int samples) {
      if (samples <= n && !output.empty()) {
        n = samples;
        return;
      }
      n = samples;
      for (int l = 1; l < n_layers; ++l) at_least(input[l], static_cast<std::size_t>(layer_in(l)) * samples);
      at_least(output, static_cast<std::size_t>(Out) * samples);
      at_least(grad_a, static_cast<std::size_t>(max_width()) * samples);
      at_least(grad_b, static_cast<std::size_t>(max_width()) * samples);
      if constexpr (!bf16_products<T>()) at_least(wt, static_cast<std::size_t>(max_width()) * max_width());
      if constexpr (bf16_products<T>()) {
        // ⌈a/2⌉·b pairs for a, b ≤ max(samples, max_width) with at least one of them ≤ max_width (+ 1: the
        // row of ones that gives the bias gradient).
        const std::size_t w = max_width(), big = std::max<std::size_t>(w, samples);
        const std::size_t size = std::max((w + 1) / 2 * big, (big + 1) / 2 * (w + 1));
        at_least(pack_a, size);
        at_least(pack_b, size);
      }
    }
    template <class V>
    static void at_least(V& v, std::size_t size) {
      if (v.size() < size) v.resize(size);
    }
  };

  /// Whether bias + activation (forward) and the activation's derivative (backward) run inside the
  /// product's epilogue, in registers; otherwise they are a pass over the tile right after the product.
  template <class T, class Act>
  static constexpr bool fused_epilogue() {
    if constexpr (gemm::has_kernel<T>()) return gemm::VectorActivation<Act>::available;
    return false;
  }

  /// Forward pass of n samples: x is In × n (column-major), the result is ws.output (Out × n).
  template <class T>
  static const T* forward(const T* params, const T* x, int n, Workspace<T>& ws) {
    ws.resize(n);
    ws.x = x;
    forward_rows(params, x, 0, n, ws);
    return ws.output.data();
  }

  /// Forward of samples [at, at + n) of x (In × (at + n)) after the `at` samples the workspace holds, which
  /// stay: a tile evaluated in pieces, one after another (a ray batch whose rays stop at different depths).
  /// Afterwards the workspace holds at + n samples, as forward() of all of them at once leaves it, bit for
  /// bit (each sample's products do not depend on the others). Returns ws.output (Out × (at + n)).
  template <class T>
  static const T* forward_at(const T* params, const T* x, int at, int n, Workspace<T>& ws) {
    require(at >= 0 && n >= 0 && ws.n >= at, "Mlp::forward_at: the workspace holds fewer than `at` samples");
    ws.resize(at + n);
    ws.x = x;
    forward_rows(params, x, at, n, ws);
    return ws.output.data();
  }

  /// Layers over samples [at, at + n) of x; the workspace is already sized.
  template <class T>
  static void forward_rows(const T* params, const T* x_all, int at, int n, Workspace<T>& ws) {
    if (n <= 0) return;
    const T* x = x_all + static_cast<std::size_t>(at) * In;
    for (int l = 0; l < n_layers; ++l) {
      const int in = layer_in(l), out = layer_out(l);
      const int dst_rows = l == Depth ? Out : layer_in(l + 1);
      const T* src = l == 0 ? x : ws.input[l].data() + static_cast<std::size_t>(at) * in;
      T* dst = (l == Depth ? ws.output.data() : ws.input[l + 1].data()) + static_cast<std::size_t>(at) * dst_rows;
      const T* b = params + bias_offset(l);
      // Y = act(W·X + b): W is out × in (lda = out), X is in × n, Y goes into the next layer's input rows.
      const gemm::Operands<T> op{out, n, in, params + weight_offset(l), out, src, 1, in, dst, dst_rows};
      auto multiply = [&](const auto&... epi) {
        if constexpr (bf16_products<T>()) {  // W's pairs across its columns, X's down each sample
          const int kp = (in + 1) / 2;
          bf16::pack_across(params + weight_offset(l), out, in, out, ws.pack_a.data(), out);
          bf16::pack_along(src, in, n, in, ws.pack_b.data(), 1, kp);
          bf16::product<false>(bf16::Operands{out, n, kp, ws.pack_a.data(), out, ws.pack_b.data(), 1, kp, dst, dst_rows}, epi...);
        } else {
          gemm::product<false>(op, epi...);
        }
      };
      auto layer = [&](auto act) {
        using Act = decltype(act);
        if constexpr (fused_epilogue<T, Act>()) {
          multiply(gemm::BiasActivation<Act>{b});
        } else {
          multiply();
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
  }

  /// Keeps samples keep[0..m) (increasing) of the last forward: the workspace then holds what forward()
  /// on just those samples leaves, without computing it again. The caller compacts its input x the same
  /// way (the workspace only points to it).
  template <class T>
  static void keep_samples(Workspace<T>& ws, const int* keep, int m) {
    auto compact = [&](std::vector<T>& v, int rows) {
      for (int j = 0; j < m; ++j)  // keep[j] ≥ j: in place, front to back
        std::copy_n(v.begin() + static_cast<std::ptrdiff_t>(keep[j]) * rows, rows, v.begin() + static_cast<std::ptrdiff_t>(j) * rows);
    };
    for (int l = 1; l < n_layers; ++l) compact(ws.input[l], layer_in(l));
    compact(ws.output, Out);
    ws.n = m;
  }

  /// Backward pass for the tile last run through forward(): dy is Out × n (gradient of the loss w.r.t.
  /// the output after OutAct). Adds weight and bias gradients to dparams and, when dx is not null, the
  /// input gradient (In × n) to dx: its first `dx_rows` rows (the rest are left alone), for callers that
  /// need the gradient of only the leading inputs (a colour network's features, not its view encoding).
  template <class T>
  static void backward(const T* params, Workspace<T>& ws, const T* dy, T* dparams, T* dx, int dx_rows = In) {
    const int n = ws.n;
    // dz of the output layer: dy ⊙ OutAct'(y), in grad_a; the previous layer's dz goes to the other buffer.
    T* dz = ws.grad_a.data();
    T* dz_prev = ws.grad_b.data();
    for (std::size_t k = 0; k < static_cast<std::size_t>(Out) * n; ++k) dz[k] = dy[k] * OutAct::df_from_y(ws.output[k]);
    for (int l = Depth; l >= 0; --l) {
      const int in = layer_in(l), out = layer_out(l);
      const T* src = l == 0 ? ws.x : ws.input[l].data();
      // dW += DZ·Xᵀ: DZ is out × n (lda = out); Xᵀ is read in place (element (j, i) = X[i + j·in]).
      if constexpr (bf16_products<T>()) {
        // Both factors paired across samples; X gets a row of ones, so the product's last column (which
        // the parameter layout puts at b) is db = DZ·1.
        const int np = (n + 1) / 2;
        bf16::pack_across(dz, out, n, out, ws.pack_a.data(), out);
        bf16::pack_across(src, in, n, in, ws.pack_b.data(), in + 1);
        for (int p = 0; p < np; ++p) ws.pack_b[static_cast<std::size_t>(p) * (in + 1) + in] = bf16::pair(1.f, 1.f);
        bf16::product<true>(
            bf16::Operands{out, in + 1, np, ws.pack_a.data(), out, ws.pack_b.data(), in + 1, 1, dparams + weight_offset(l), out});
      } else {
        gemm::product<true>(gemm::Operands<T>{out, in, n, dz, out, src, in, 1, dparams + weight_offset(l), out});
        T* db = dparams + bias_offset(l);
        for (int j = 0; j < n; ++j) {
          const T* col = dz + static_cast<std::size_t>(j) * out;
          for (int i = 0; i < out; ++i) db[i] += col[i];
        }
      }
      if (l == 0 && !dx) break;
      // Products with Wᵀ (rows `row0` on, `rows` of them) as A and DZ as B.
      const T* w = params + weight_offset(l);
      T* wt = ws.wt.data();
      const int kp = (out + 1) / 2;
      if constexpr (bf16_products<T>()) {  // W's pairs down each column (Wᵀ's rows), DZ's down each sample
        bf16::pack_along(w, out, in, out, ws.pack_a.data(), in, 1);
        bf16::pack_along(dz, out, n, out, ws.pack_b.data(), 1, kp);
      } else {  // Wᵀ (in × out, column-major) so the product reads its A operand contiguously
        gemm::transpose(w, out, in, out, wt, in);
      }
      auto multiply = [&](auto accumulate, int row0, int rows, T* c, int ldc, const auto&... epi) {
        if constexpr (bf16_products<T>())
          bf16::product<decltype(accumulate)::value>(
              bf16::Operands{rows, n, kp, ws.pack_a.data() + row0, in, ws.pack_b.data(), 1, kp, c, ldc}, epi...);
        else gemm::product<decltype(accumulate)::value>(gemm::Operands<T>{rows, n, out, wt + row0, in, dz, 1, out, c, ldc}, epi...);
      };
      if (l == 0) {
        multiply(std::true_type{}, 0, std::min(in, dx_rows), dx, in);
        break;
      }
      // The input rows fed by the skip connection: their gradient goes straight into dx.
      if (l == Skip + 1 && Skip >= 0 && dx) multiply(std::true_type{}, Width, std::min(In, dx_rows), dx, In);
      // The previous layer's output occupies the top Width rows of this layer's input: its dz is
      // (Wᵀ·DZ) ⊙ act'(y) over those rows.
      const T* y = ws.input[l].data();
      if constexpr (fused_epilogue<T, HiddenAct>()) {
        multiply(std::false_type{}, 0, Width, dz_prev, Width, gemm::ActivationGrad<HiddenAct>{y, in});
      } else {
        multiply(std::false_type{}, 0, Width, dz_prev, Width);
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < Width; ++i)
            dz_prev[static_cast<std::size_t>(j) * Width + i] *= HiddenAct::df_from_y(y[static_cast<std::size_t>(j) * in + i]);
      }
      std::swap(dz, dz_prev);
    }
  }
};

/// An MLP's hidden shape by name: `width` units in each of `hidden_layers` layers, and the layer after which
/// the input is concatenated again (`skip`, −1 for none). For example MlpShape{.width = 256,
/// .hidden_layers = 8, .skip = 4} is the NeRF trunk.
struct MlpShape {
  int width = 64;
  int hidden_layers = 1;
  int skip = -1;
};
/// Mlp with its hidden shape given by name.
template <int In, MlpShape Shape, int Out, class HiddenAct = ReLU, class OutAct = Identity, class Prec = Fp32>
using MlpOf = Mlp<In, Shape.width, Shape.hidden_layers, Out, HiddenAct, OutAct, Shape.skip, Prec>;

}  // namespace evnerf::nn
