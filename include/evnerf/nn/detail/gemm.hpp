// nn/detail/gemm.hpp — the matrix products of the fused MLP: C (+)= A·B on one tile of samples, with A and B
// read in place through strides, so a layer's weights, their transpose or a tile's gradients go straight into
// the kernel (the AVX2 kernel copies a row panel of A side by side first where many column blocks read it).
// On AVX-512 an explicit register-blocked kernel runs; elsewhere (and for double, which the gradient checks
// use) Eigen does the work. Also the transpose in register blocks (16×16, or 8×8 on AVX2) that gives the
// backward pass Wᵀ. Depends on Eigen and nn/activation.hpp only.
//
// Why not Eigen everywhere: for these shapes (M, K ≤ ~320, N = one tile) Eigen packs both operands on every
// call and reaches about 58 % of the FP32 FMA peak on one core of this project's machine; the kernel below
// reaches 95–100 % on the same shapes (bench/run.sh measures both).
//
// On AVX2 + FMA without AVX-512 (AMD Zen 2/3, Intel before Skylake-SP) an 8-lane kernel runs instead. Both
// kernels compute every element of C the same way: its old value (or zero), then one fused multiply-add per
// k in order, then the epilogue. So a float network gives the same bits on either CPU (tested against a
// scalar std::fma chain), where Eigen's blocked order would give other roundings.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <type_traits>
#include <vector>

#include "../activation.hpp"
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif
#if !defined(__AVX512F__) && defined(__AVX2__) && defined(__FMA__)
#define EVNERF_GEMM_AVX2 1  ///< the 8-lane kernel below serves float products
#endif

namespace evnerf::nn::gemm {

/// Operand views: element (i, k) of A is a[i + k·lda] (columns contiguous); element (k, j) of B is
/// b[k·bk + j·bn] (any strides, so B or Bᵀ of a column-major matrix); C is column-major with ldc.
template <class T>
struct Operands {
  int m, n, k;
  const T* a;
  std::ptrdiff_t lda;
  const T* b;
  std::ptrdiff_t bk, bn;
  T* c;
  std::ptrdiff_t ldc;
};

/// The plain path: Eigen maps over the same strided views. Used for double, for non-AVX-512 builds, and
/// as the reference the kernel is tested against.
template <bool Accumulate, class T>
void eigen_product(const Operands<T>& o) {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  Eigen::Map<const Mat, 0, Eigen::OuterStride<>> A(o.a, o.m, o.k, Eigen::OuterStride<>(o.lda));
  Eigen::Map<Mat, 0, Eigen::OuterStride<>> C(o.c, o.m, o.n, Eigen::OuterStride<>(o.ldc));
  auto apply = [&](const auto& B) {
    if constexpr (Accumulate) C.noalias() += A * B;
    else C.noalias() = A * B;
  };
  if (o.bk == 1) {  // B column-major
    apply(Eigen::Map<const Mat, 0, Eigen::OuterStride<>>(o.b, o.k, o.n, Eigen::OuterStride<>(o.bn)));
  } else {  // B row-major (a transposed column-major matrix) with unit stride along j
    apply(Eigen::Map<const Mat, 0, Eigen::OuterStride<>>(o.b, o.n, o.k, Eigen::OuterStride<>(o.bk)).transpose());
  }
}

/// No epilogue: C gets the product as it is.
struct NoEpilogue {
  static constexpr bool active = false;
  static float scalar(float v, int, int) { return v; }
};

/// An epilogue's gradient one lane at a time, as the vector forms mask it: g where the activation's slope
/// at output y is not zero, else +0 (whatever g is). The forward's scalar form is the activation's own f.
template <class Act>
float masked_grad(float g, float y) {
  return Act::template df_from_y<float>(y) != 0.f ? g : 0.f;
}

/// The epilogues (defined for the kernels' builds below; elsewhere they stay declared for discarded branches).
template <class Act>
struct BiasActivation;
template <class Act>
struct ActivationGrad;

/// Vector forms of the activations the epilogues can apply in registers (the others, and all of them
/// where no kernel is built, run as a scalar pass after the product, in nn/mlp.hpp).
template <class Act>
struct VectorActivation {
  static constexpr bool available = false;
};

#if defined(__AVX512F__)
template <>
struct VectorActivation<ReLU> {
  static constexpr bool available = true;
  // maskz form: GCC 12 warns about _mm512_max_ps (it passes _mm512_undefined_ps() inside its header)
  static __m512 f(__m512 x) { return _mm512_maskz_max_ps(0xFFFF, x, _mm512_setzero_ps()); }
  static __m512 grad(__m512 g, __m512 y) { return _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(y, _mm512_setzero_ps(), _CMP_GT_OQ), g); }
};
template <>
struct VectorActivation<Identity> {
  static constexpr bool available = true;
  static __m512 f(__m512 x) { return x; }
  static __m512 grad(__m512 g, __m512) { return g; }
};

/// Forward epilogue: C = act(A·B + bias), bias indexed by row.
template <class Act>
struct BiasActivation {
  static constexpr bool active = true;
  const float* bias;
  __m512 operator()(__m512 v, int row, int, __mmask16 m) const {
    return VectorActivation<Act>::f(_mm512_add_ps(v, _mm512_maskz_loadu_ps(m, bias + row)));
  }
  float scalar(float v, int row, int) const { return Act::template f<float>(v + bias[row]); }
};
/// Backward epilogue: C = (A·B) ⊙ act'(y), with act' computed from the activation's output y (ld ldy).
template <class Act>
struct ActivationGrad {
  static constexpr bool active = true;
  const float* y;
  std::ptrdiff_t ldy;
  __m512 operator()(__m512 v, int row, int col, __mmask16 m) const {
    return VectorActivation<Act>::grad(v, _mm512_maskz_loadu_ps(m, y + row + col * ldy));
  }
  float scalar(float v, int row, int col) const { return masked_grad<Act>(v, y[row + col * ldy]); }
};

namespace detail {

/// A block's accumulators: C's values (Accumulate) or zeros; masked rows read as zero.
template <int V, int NR, bool Accumulate, bool Full>
inline void load_block(__m512 (&acc)[V][NR], const float* c, std::ptrdiff_t ldc, const __mmask16 (&mask)[2]) {
  for (int j = 0; j < NR; ++j)
    for (int v = 0; v < V; ++v) {
      if constexpr (Accumulate)
        acc[v][j] = Full ? _mm512_loadu_ps(c + j * ldc + 16 * v) : _mm512_maskz_loadu_ps(mask[v], c + j * ldc + 16 * v);
      else acc[v][j] = _mm512_setzero_ps();
    }
}
/// Stores a block through the epilogue; masked rows are left untouched.
template <int V, int NR, bool Full, class Epi>
inline void store_block(const __m512 (&acc)[V][NR], float* c, std::ptrdiff_t ldc, const __mmask16 (&mask)[2], const Epi& epi, int i0,
                        int j0) {
  for (int j = 0; j < NR; ++j)
    for (int v = 0; v < V; ++v) {
      __m512 r = acc[v][j];
      if constexpr (Epi::active) r = epi(r, i0 + 16 * v, j0 + j, mask[v]);
      if constexpr (Full) _mm512_storeu_ps(c + j * ldc + 16 * v, r);
      else _mm512_mask_storeu_ps(c + j * ldc + 16 * v, mask[v], r);
    }
}

/// One (16·V) × NR block of C: V 16-lane rows of accumulators per column, A's V vectors loaded once per k
/// and each B element broadcast once: V·NR FMAs per k against V vector loads and NR broadcasts. `i0` and
/// `j0` are the block's position in C, for the epilogue.
template <int V, int NR, bool Accumulate, bool Full, class Epi>
inline void block(int K, const float* __restrict a, std::ptrdiff_t lda, const float* __restrict b, std::ptrdiff_t bk, std::ptrdiff_t bn,
                  float* __restrict c, std::ptrdiff_t ldc, const __mmask16 (&mask)[2], const Epi& epi, int i0, int j0) {
  __m512 acc[V][NR];
  load_block<V, NR, Accumulate, Full>(acc, c, ldc, mask);
  for (int k = 0; k < K; ++k) {
    const float* ak = a + k * lda;
    __m512 av[V];
    for (int v = 0; v < V; ++v) av[v] = Full ? _mm512_loadu_ps(ak + 16 * v) : _mm512_maskz_loadu_ps(mask[v], ak + 16 * v);
    const float* bp = b + k * bk;
#pragma GCC unroll 12
    for (int j = 0; j < NR; ++j) {
      const __m512 bj = _mm512_set1_ps(bp[j * bn]);
      for (int v = 0; v < V; ++v) acc[v][j] = _mm512_fmadd_ps(av[v], bj, acc[v][j]);
    }
  }
  store_block<V, NR, Full>(acc, c, ldc, mask, epi, i0, j0);
}

/// The blocking shared by the FP32 and the BF16 kernels. Rows: 32-row panels (V = 2 vectors), then the
/// remainder as one full or masked panel; calls panel(V, Full, i0, mask) with V and Full as constants.
template <class Panel>
inline void row_panels(int m, Panel&& panel) {
  using V1 = std::integral_constant<int, 1>;
  using V2 = std::integral_constant<int, 2>;
  const __mmask16 full[2] = {0xFFFF, 0xFFFF};
  int i = 0;
  for (; i + 32 <= m; i += 32) panel(V2{}, std::true_type{}, i, full);
  const int r = m - i;
  if (r == 16) {
    panel(V1{}, std::true_type{}, i, full);
  } else if (r > 16) {
    const __mmask16 mask[2] = {0xFFFF, static_cast<__mmask16>((1u << (r - 16)) - 1)};
    panel(V2{}, std::false_type{}, i, mask);
  } else if (r > 0) {
    const __mmask16 mask[2] = {static_cast<__mmask16>((1u << r) - 1), 0};
    panel(V1{}, std::false_type{}, i, mask);
  }
}
/// Columns: blocks of 12, then 4, then 1; calls block(NR, j) with NR as a constant.
template <class Block>
inline void column_blocks(int n, Block&& block) {
  int j = 0;
  auto run = [&](auto nr) {
    for (; j + decltype(nr)::value <= n; j += decltype(nr)::value) block(nr, j);
  };
  run(std::integral_constant<int, 12>{});
  run(std::integral_constant<int, 4>{});
  run(std::integral_constant<int, 1>{});
}

}  // namespace detail
#endif

#if defined(EVNERF_GEMM_AVX2)
// The 8-lane kernel: the AVX-512 kernel's arithmetic on 8-float vectors, with lane masks (__m256i, all ones
// in the lanes kept) in place of mask registers. 16 registers: 16-row panels of 2 × 6 accumulators; one-row
// products (a network's single output) run along the row instead (one_row); long accumulating products in
// chunks of k.
template <>
struct VectorActivation<ReLU> {
  static constexpr bool available = true;
  static __m256 f(__m256 x) { return _mm256_max_ps(x, _mm256_setzero_ps()); }  // as vmaxps on 16 lanes: NaN → 0
  static __m256 grad(__m256 g, __m256 y) { return _mm256_and_ps(g, _mm256_cmp_ps(y, _mm256_setzero_ps(), _CMP_GT_OQ)); }
};
template <>
struct VectorActivation<Identity> {
  static constexpr bool available = true;
  static __m256 f(__m256 x) { return x; }
  static __m256 grad(__m256 g, __m256) { return g; }
};

/// Forward epilogue: C = act(A·B + bias), bias indexed by row.
template <class Act>
struct BiasActivation {
  static constexpr bool active = true;
  const float* bias;
  __m256 operator()(__m256 v, int row, int, __m256i m) const {
    return VectorActivation<Act>::f(_mm256_add_ps(v, _mm256_maskload_ps(bias + row, m)));
  }
  float scalar(float v, int row, int) const { return Act::template f<float>(v + bias[row]); }
  /// The same on 8 columns col.. of one row (one_row()).
  __m256 along_row(__m256 v, int row, int, __m256i) const {
    return VectorActivation<Act>::f(_mm256_add_ps(v, _mm256_broadcast_ss(bias + row)));
  }
};
/// Backward epilogue: C = (A·B) ⊙ act'(y), with act' computed from the activation's output y (ld ldy).
template <class Act>
struct ActivationGrad {
  static constexpr bool active = true;
  const float* y;
  std::ptrdiff_t ldy;
  __m256 operator()(__m256 v, int row, int col, __m256i m) const {
    return VectorActivation<Act>::grad(v, _mm256_maskload_ps(y + row + col * ldy, m));
  }
  float scalar(float v, int row, int col) const { return masked_grad<Act>(v, y[row + col * ldy]); }
  /// The same on 8 columns col.. of one row (one_row()); lanes past C's last column read y as zero.
  __m256 along_row(__m256 v, int row, int col, __m256i m) const {
    const __m256i at = _mm256_mullo_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(static_cast<int>(ldy)));
    return VectorActivation<Act>::grad(v,
                                       _mm256_mask_i32gather_ps(_mm256_setzero_ps(), y + row + col * ldy, at, _mm256_castsi256_ps(m), 4));
  }
};

namespace detail {

/// The chunk of k an accumulating product takes at a time (a 16-row panel's chunk of A is 4 KB; 64 measured
/// best of 64–512 on an AVX2 CPU for the weight gradients of 64-wide layers over 1024 samples).
inline constexpr int k_chunk8 = 64;

/// The 8·V rows i0.. of A's columns 0..K-1 copied side by side into a per-thread buffer (masked rows as
/// zeros), so that block8 reads them with a leading dimension of 8·V. Valid until the thread's next call.
template <int V>
inline const float* pack_panel8(const float* a, std::ptrdiff_t lda, int K, const __m256i (&mask)[2]) {
  thread_local std::vector<float, Eigen::aligned_allocator<float>> buf;
  const std::size_t need = static_cast<std::size_t>(8 * V) * static_cast<std::size_t>(K);
  if (buf.size() < need) buf.resize(need);
  float* out = buf.data();
  for (int k = 0; k < K; ++k)
    for (int v = 0; v < V; ++v) _mm256_storeu_ps(out + (8 * V) * k + 8 * v, _mm256_maskload_ps(a + k * lda + 8 * v, mask[v]));
  return out;
}

/// Lanes 0..r-1 of a mask (r in 0..8).
inline __m256i lanes_below(int r) { return _mm256_cmpgt_epi32(_mm256_set1_epi32(r), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)); }

/// One (8·V) × NR block of C, as the AVX-512 block(): accumulators from C (or zero), one FMA per k in order,
/// the epilogue, a (masked) store. Masked rows are neither read nor written. A masked panel of two vectors
/// has its first 8 rows whole (row_panels8), so only its second vector is loaded and stored through the mask:
/// with both masks held in registers, the 12 accumulators, A's two vectors and B's broadcast are 17 ymm
/// registers, and GCC keeps one accumulator on the stack, stored and loaded again on every k.
template <int V, int NR, bool Accumulate, bool Full, class Epi>
inline void block8(int K, const float* __restrict a, std::ptrdiff_t lda, const float* __restrict b, std::ptrdiff_t bk, std::ptrdiff_t bn,
                   float* __restrict c, std::ptrdiff_t ldc, const __m256i (&mask)[2], const Epi& epi, int i0, int j0) {
  // Every loop over the accumulators is unrolled, so that each is a register: a loop GCC leaves rolled
  // indexes the array, which then lives on the stack and is stored to on every k.
  auto whole = [](int v) { return Full || (V == 2 && v == 0); };
  __m256 acc[V][NR];
#pragma GCC unroll 8
  for (int j = 0; j < NR; ++j)
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) {
      if constexpr (Accumulate)
        acc[v][j] = whole(v) ? _mm256_loadu_ps(c + j * ldc + 8 * v) : _mm256_maskload_ps(c + j * ldc + 8 * v, mask[v]);
      else acc[v][j] = _mm256_setzero_ps();
    }
  for (int k = 0; k < K; ++k) {
    const float* ak = a + k * lda;
    __m256 av[V];
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) av[v] = whole(v) ? _mm256_loadu_ps(ak + 8 * v) : _mm256_maskload_ps(ak + 8 * v, mask[v]);
    const float* bp = b + k * bk;
#pragma GCC unroll 8
    for (int j = 0; j < NR; ++j) {
      const __m256 bj = _mm256_broadcast_ss(bp + j * bn);
#pragma GCC unroll 2
      for (int v = 0; v < V; ++v) acc[v][j] = _mm256_fmadd_ps(av[v], bj, acc[v][j]);
    }
  }
#pragma GCC unroll 8
  for (int j = 0; j < NR; ++j)
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) {
      __m256 r = acc[v][j];
      if constexpr (Epi::active) r = epi(r, i0 + 8 * v, j0 + j, mask[v]);
      if (whole(v)) _mm256_storeu_ps(c + j * ldc + 8 * v, r);
      else _mm256_maskstore_ps(c + j * ldc + 8 * v, mask[v], r);
    }
}

/// Transposes an 8×8 block held as 8 row vectors, in registers.
inline void transpose8(__m256 (&r)[8]) {
  __m256 t[8], u[8];
  for (int q = 0; q < 4; ++q) {
    t[2 * q] = _mm256_unpacklo_ps(r[2 * q], r[2 * q + 1]);
    t[2 * q + 1] = _mm256_unpackhi_ps(r[2 * q], r[2 * q + 1]);
  }
  for (int g = 0; g < 2; ++g) {
    u[4 * g + 0] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], 0x44);
    u[4 * g + 1] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], 0xEE);
    u[4 * g + 2] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], 0x44);
    u[4 * g + 3] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], 0xEE);
  }
  for (int q = 0; q < 4; ++q) {
    r[q] = _mm256_permute2f128_ps(u[q], u[4 + q], 0x20);
    r[q + 4] = _mm256_permute2f128_ps(u[q], u[4 + q], 0x31);
  }
}

/// A one-row product (m = 1: a network's single output, or its weight gradient) with the lanes along the
/// row: 8 columns of C per vector, four vectors at a time (four chains hide the FMA's and the gather's
/// latency), B's elements of a k loaded together (bn = 1) or gathered, A's element broadcast. Each element
/// is the same chain of FMAs as in block8 (a·b and b·a round alike).
template <int J, bool Accumulate, class Epi>
inline void one_row_block(int j0, __m256i tail, int K, const float* __restrict a, std::ptrdiff_t lda, const float* __restrict b,
                          std::ptrdiff_t bk, std::ptrdiff_t bn, float* __restrict c, std::ptrdiff_t ldc, const Epi& epi) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i cstep = _mm256_mullo_epi32(lane, _mm256_set1_epi32(static_cast<int>(ldc)));
  const __m256i bstep = _mm256_mullo_epi32(lane, _mm256_set1_epi32(static_cast<int>(bn)));
  const __m256i all = lanes_below(8);
  __m256i m[J];
  __m256 acc[J];
  for (int v = 0; v < J; ++v) {
    m[v] = v == J - 1 ? tail : all;
    acc[v] = _mm256_setzero_ps();
    if constexpr (Accumulate) acc[v] = _mm256_mask_i32gather_ps(acc[v], c + (j0 + 8 * v) * ldc, cstep, _mm256_castsi256_ps(m[v]), 4);
  }
  const float* bj = b + j0 * bn;
  const bool full = _mm256_movemask_ps(_mm256_castsi256_ps(tail)) == 0xFF;
  const bool loads = bn == 1 && full;
  int k = 0;
  if (bk == 1 && !loads && full)  // each column's k contiguous: 8 columns × 8 k loaded, then transposed
    for (; k + 8 <= K; k += 8) {
      for (int v = 0; v < J; ++v) {
        __m256 r[8];
        for (int q = 0; q < 8; ++q) r[q] = _mm256_loadu_ps(bj + (8 * v + q) * bn + k);
        transpose8(r);  // r[kk] = B(k + kk, the 8 columns)
        for (int kk = 0; kk < 8; ++kk) acc[v] = _mm256_fmadd_ps(_mm256_broadcast_ss(a + (k + kk) * lda), r[kk], acc[v]);
      }
    }
  for (; k < K; ++k) {
    const __m256 ak = _mm256_broadcast_ss(a + k * lda);
    const float* bk0 = bj + k * bk;
    for (int v = 0; v < J; ++v) {
      const __m256 bv = loads ? _mm256_loadu_ps(bk0 + 8 * v)
                              : _mm256_mask_i32gather_ps(_mm256_setzero_ps(), bk0 + 8 * v * bn, bstep, _mm256_castsi256_ps(m[v]), 4);
      acc[v] = _mm256_fmadd_ps(ak, bv, acc[v]);
    }
  }
  alignas(32) float out[8];
  for (int v = 0; v < J; ++v) {
    if constexpr (Epi::active) acc[v] = epi.along_row(acc[v], 0, j0 + 8 * v, m[v]);
    _mm256_store_ps(out, acc[v]);
    const int w = __builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(m[v]))));
    for (int q = 0; q < w; ++q) c[(j0 + 8 * v + q) * ldc] = out[q];
  }
}
template <bool Accumulate, class Epi>
inline void one_row(int n, int K, const float* a, std::ptrdiff_t lda, const float* b, std::ptrdiff_t bk, std::ptrdiff_t bn, float* c,
                    std::ptrdiff_t ldc, const Epi& epi) {
  const __m256i all = lanes_below(8);
  int j = 0;
  for (; j + 32 <= n; j += 32) one_row_block<4, Accumulate>(j, all, K, a, lda, b, bk, bn, c, ldc, epi);
  for (; j + 8 <= n; j += 8) one_row_block<1, Accumulate>(j, all, K, a, lda, b, bk, bn, c, ldc, epi);
  if (j < n) one_row_block<1, Accumulate>(j, lanes_below(n - j), K, a, lda, b, bk, bn, c, ldc, epi);
}

/// Rows: 16-row panels (V = 2), then the remainder as one full or masked panel; calls panel(V, Full, i0,
/// mask) with V and Full as constants.
template <class Panel>
inline void row_panels8(int m, Panel&& panel) {
  using V1 = std::integral_constant<int, 1>;
  using V2 = std::integral_constant<int, 2>;
  const __m256i all = lanes_below(8), none = lanes_below(0);
  const __m256i full[2] = {all, all};
  int i = 0;
  for (; i + 16 <= m; i += 16) panel(V2{}, std::true_type{}, i, full);
  const int r = m - i;
  if (r == 8) {
    panel(V1{}, std::true_type{}, i, full);
  } else if (r > 8) {
    const __m256i mask[2] = {all, lanes_below(r - 8)};
    panel(V2{}, std::false_type{}, i, mask);
  } else if (r > 0) {
    const __m256i mask[2] = {lanes_below(r), none};
    panel(V1{}, std::false_type{}, i, mask);
  }
}
/// Columns: blocks of 6, with the last 4–11 columns as two blocks of 4–6 (so no block has fewer than 4
/// columns, 8 independent FMA chains, where n ≥ 4: narrower blocks wait on the FMA latency); calls
/// block(NR, j) with NR as a constant. The blocking never changes an element's chain of FMAs.
template <class Block>
inline void column_blocks8(int n, Block&& block) {
  auto run = [&](int j, int nr) {
    switch (nr) {
      case 6:
        block(std::integral_constant<int, 6>{}, j);
        break;
      case 5:
        block(std::integral_constant<int, 5>{}, j);
        break;
      case 4:
        block(std::integral_constant<int, 4>{}, j);
        break;
      case 3:
        block(std::integral_constant<int, 3>{}, j);
        break;
      case 2:
        block(std::integral_constant<int, 2>{}, j);
        break;
      default:
        block(std::integral_constant<int, 1>{}, j);
        break;
    }
  };
  int j = 0;
  for (; n - j >= 12; j += 6) run(j, 6);
  const int r = n - j;  // 0..11
  if (r > 6) {
    run(j, r - r / 2);
    run(j + r - r / 2, r / 2);
  } else if (r > 0) {
    run(j, r);
  }
}

}  // namespace detail
#endif

#if defined(__AVX512F__)
namespace detail {
/// Transposes a 16×16 block held as 16 row vectors, in registers (4 rounds of 16 shuffles).
inline void transpose16(__m512 (&r)[16]) {
  __m512 t[16];
  for (int k = 0; k < 8; ++k) {  // per 128-bit lane: pairs of rows interleaved
    t[2 * k] = _mm512_unpacklo_ps(r[2 * k], r[2 * k + 1]);
    t[2 * k + 1] = _mm512_unpackhi_ps(r[2 * k], r[2 * k + 1]);
  }
  for (int g = 0; g < 4; ++g) {  // per lane: column 4L + c of rows 4g..4g+3, c = 0..3
    const __m512d a = _mm512_castps_pd(t[4 * g]), b = _mm512_castps_pd(t[4 * g + 1]);
    const __m512d c = _mm512_castps_pd(t[4 * g + 2]), d = _mm512_castps_pd(t[4 * g + 3]);
    r[4 * g + 0] = _mm512_castpd_ps(_mm512_unpacklo_pd(a, c));
    r[4 * g + 1] = _mm512_castpd_ps(_mm512_unpackhi_pd(a, c));
    r[4 * g + 2] = _mm512_castpd_ps(_mm512_unpacklo_pd(b, d));
    r[4 * g + 3] = _mm512_castpd_ps(_mm512_unpackhi_pd(b, d));
  }
  for (int c = 0; c < 4; ++c) {  // gather the four row groups' lanes: columns c, c + 4, c + 8, c + 12
    const __m512 v0 = _mm512_shuffle_f32x4(r[c], r[4 + c], 0x88), v1 = _mm512_shuffle_f32x4(r[c], r[4 + c], 0xDD);
    const __m512 w0 = _mm512_shuffle_f32x4(r[8 + c], r[12 + c], 0x88), w1 = _mm512_shuffle_f32x4(r[8 + c], r[12 + c], 0xDD);
    t[c] = _mm512_shuffle_f32x4(v0, w0, 0x88);
    t[c + 8] = _mm512_shuffle_f32x4(v0, w0, 0xDD);
    t[c + 4] = _mm512_shuffle_f32x4(v1, w1, 0x88);
    t[c + 12] = _mm512_shuffle_f32x4(v1, w1, 0xDD);
  }
  for (int k = 0; k < 16; ++k) r[k] = t[k];
}
}  // namespace detail
#endif

/// dst = srcᵀ: src is rows × cols, column-major with leading dimension ld (element (i, j) at
/// src[i + j·ld]); dst is cols × rows, column-major with leading dimension ldd. For float in blocks held in
/// registers, with masked edges: 16×16 on AVX-512, 8×8 on AVX2 (element by element, a 256-wide layer's
/// weights are 64 k single-float stores 1 KB apart, each to another cache line); elsewhere element by element.
template <class T>
void transpose(const T* src, int rows, int cols, std::ptrdiff_t ld, T* dst, std::ptrdiff_t ldd) {
#if defined(__AVX512F__)
  if constexpr (std::is_same_v<T, float>) {
    for (int j0 = 0; j0 < cols; j0 += 16) {
      const int nj = cols - j0 < 16 ? cols - j0 : 16;
      const __mmask16 jmask = static_cast<__mmask16>((1u << nj) - 1);
      for (int i0 = 0; i0 < rows; i0 += 16) {
        const int ni = rows - i0 < 16 ? rows - i0 : 16;
        const __mmask16 imask = static_cast<__mmask16>((1u << ni) - 1);
        __m512 r[16];  // r[c] = src column j0 + c, rows i0..i0+15
        for (int c = 0; c < 16; ++c) r[c] = c < nj ? _mm512_maskz_loadu_ps(imask, src + i0 + (j0 + c) * ld) : _mm512_setzero_ps();
        detail::transpose16(r);  // r[k] = src row i0 + k, columns j0..j0+15
        for (int k = 0; k < ni; ++k) _mm512_mask_storeu_ps(dst + j0 + (i0 + k) * ldd, jmask, r[k]);
      }
    }
    return;
  }
#elif defined(EVNERF_GEMM_AVX2)
  if constexpr (std::is_same_v<T, float>) {
    for (int j0 = 0; j0 < cols; j0 += 8) {
      const int nj = cols - j0 < 8 ? cols - j0 : 8;
      const __m256i jmask = detail::lanes_below(nj);
      for (int i0 = 0; i0 < rows; i0 += 8) {
        const int ni = rows - i0 < 8 ? rows - i0 : 8;
        const bool full = ni == 8 && nj == 8;
        const __m256i imask = detail::lanes_below(ni);
        __m256 r[8];  // r[c] = src column j0 + c, rows i0..i0+7
        for (int c = 0; c < 8; ++c) {
          const float* col = src + i0 + static_cast<std::ptrdiff_t>(j0 + c) * ld;
          r[c] = full ? _mm256_loadu_ps(col) : c < nj ? _mm256_maskload_ps(col, imask) : _mm256_setzero_ps();
        }
        detail::transpose8(r);  // r[k] = src row i0 + k, columns j0..j0+7
        for (int k = 0; k < ni; ++k) {
          float* row = dst + j0 + static_cast<std::ptrdiff_t>(i0 + k) * ldd;
          if (full) _mm256_storeu_ps(row, r[k]);
          else _mm256_maskstore_ps(row, jmask, r[k]);
        }
      }
    }
    return;
  }
#endif
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) dst[j + i * ldd] = src[i + j * ld];
}

/// Whether product() runs a kernel (and so can apply epilogues) for element type T, else Eigen.
template <class T>
constexpr bool has_kernel() {
#if defined(__AVX512F__) || defined(EVNERF_GEMM_AVX2)
  return std::is_same_v<T, float>;
#else
  return false;
#endif
}

/// Where an element of C breaks the kernels' promise: row i, column j, its bits and the chain's.
struct ChainMismatch {
  int i, j;
  float got, want;
};

/// The first element of C (column by column) whose bits differ from what a kernel promises: its old value
/// (`before`, leading dimension ldb; Accumulate only) or zero, one std::fma per k in order, then the
/// epilogue's scalar form. Two NaNs count as equal. For the tests and EVNERF_CHECK_KERNELS builds.
template <bool Accumulate, class Epi = NoEpilogue>
std::optional<ChainMismatch> first_chain_mismatch(const Operands<float>& o, const float* before, std::ptrdiff_t ldb, const Epi& epi = {}) {
  for (int j = 0; j < o.n; ++j)
    for (int i = 0; i < o.m; ++i) {
      float want = Accumulate ? before[i + j * ldb] : 0.f;
      for (int q = 0; q < o.k; ++q) want = std::fma(o.a[i + q * o.lda], o.b[q * o.bk + j * o.bn], want);
      want = epi.scalar(want, i, j);
      const float got = o.c[i + j * o.ldc];
      if (std::bit_cast<std::uint32_t>(got) != std::bit_cast<std::uint32_t>(want) && !(std::isnan(got) && std::isnan(want)))
        return ChainMismatch{i, j, got, want};
    }
  return std::nullopt;
}

template <bool Accumulate, class T, class Epi>
inline void product_unchecked(const Operands<T>& o, [[maybe_unused]] const Epi& epi);

/// C = A·B (Accumulate = false) or C += A·B, then the epilogue on each result vector before it is stored.
/// Float on AVX-512 or AVX2 + FMA takes a kernel; everything else Eigen (which takes no epilogue).
/// Built with EVNERF_CHECK_KERNELS (CMake option of that name), every kernel product is checked against
/// first_chain_mismatch and a mismatch ends the process with the product's shape: the check that a float
/// run gives the same bits on another CPU, in a real run rather than the tests' shapes.
template <bool Accumulate, class T, class Epi = NoEpilogue>
[[gnu::noinline]] void product(const Operands<T>& o, const Epi& epi = {}) {
#if defined(EVNERF_CHECK_KERNELS) && (defined(__AVX512F__) || defined(EVNERF_GEMM_AVX2))
  if constexpr (std::is_same_v<T, float>) {
    if (o.m > 0 && o.n > 0) {
      std::vector<float> before;
      if constexpr (Accumulate)
        for (int j = 0; j < o.n; ++j) before.insert(before.end(), o.c + j * o.ldc, o.c + j * o.ldc + o.m);
      product_unchecked<Accumulate>(o, epi);
      if (const auto bad = first_chain_mismatch<Accumulate>(o, before.data(), o.m, epi)) {
        std::fprintf(stderr,
                     "evnerf: EVNERF_CHECK_KERNELS: gemm::product (m %d, n %d, k %d, lda %td, bk %td, bn %td, ldc %td, %s, "
                     "%s) element (%d, %d) is %a where the fma chain gives %a\n",
                     o.m, o.n, o.k, o.lda, o.bk, o.bn, o.ldc, Accumulate ? "accumulating" : "overwriting",
                     Epi::active ? "with an epilogue" : "no epilogue", bad->i, bad->j, bad->got, bad->want);
        std::abort();
      }
      return;
    }
  }
#endif
  product_unchecked<Accumulate>(o, epi);
}

template <bool Accumulate, class T, class Epi>
inline void product_unchecked(const Operands<T>& o, [[maybe_unused]] const Epi& epi) {
  if (o.m <= 0 || o.n <= 0) return;
#if defined(__AVX512F__)
  if constexpr (std::is_same_v<T, float>) {
    detail::row_panels(o.m, [&](auto v, auto full, int i0, const __mmask16(&mask)[2]) {
      detail::column_blocks(o.n, [&](auto nr, int j) {
        detail::block<decltype(v)::value, decltype(nr)::value, Accumulate, decltype(full)::value>(
            o.k, o.a + i0, o.lda, o.b + j * o.bn, o.bk, o.bn, o.c + i0 + j * o.ldc, o.ldc, mask, epi, i0, j);
      });
    });
    return;
  }
#elif defined(EVNERF_GEMM_AVX2)
  if constexpr (std::is_same_v<T, float>) {
    // A long accumulating product (a weight gradient, k = the tile's samples) runs in chunks of k, so a row
    // panel's chunk of A stays in L1 while every column block reads it: the accumulators go through C
    // between chunks, which leaves each element's chain of FMAs as it is.
    constexpr int chunk = Accumulate && !Epi::active ? detail::k_chunk8 : 1 << 30;
    if (o.m == 1) {
      detail::one_row<Accumulate>(o.n, o.k, o.a, o.lda, o.b, o.bk, o.bn, o.c, o.ldc, epi);
      return;
    }
    int k0 = 0;
    do {  // at least once: with k = 0, C = 0 (through the epilogue) unless accumulating
      const int kc = std::min(chunk, o.k - k0);
      const float* a = o.a + k0 * o.lda;
      const float* b = o.b + k0 * o.bk;
      detail::row_panels8(o.m, [&](auto v, auto full, int i0, const __m256i(&mask)[2]) {
        constexpr int V = decltype(v)::value;
        // A row panel read by many column blocks is packed first (its 8·V rows of each k side by side) where
        // its leading dimension is a multiple of 1 KB (a 256-wide layer's): its k columns would fall into a
        // few L1 sets and be fetched again from L2 by every block. Packing moves values, not arithmetic.
        const float* ap = a + i0;
        std::ptrdiff_t lda = o.lda;
        if (o.n > 12 && kc > 16 && o.lda % 256 == 0) {
          ap = detail::pack_panel8<V>(a + i0, o.lda, kc, mask);
          lda = 8 * V;
        }
        detail::column_blocks8(o.n, [&](auto nr, int j) {
          detail::block8<V, decltype(nr)::value, Accumulate, decltype(full)::value>(kc, ap, lda, b + j * o.bn, o.bk, o.bn,
                                                                                    o.c + i0 + j * o.ldc, o.ldc, mask, epi, i0, j);
        });
      });
      k0 += chunk;
    } while (k0 < o.k);
    return;
  }
#endif
  static_assert(!Epi::active || has_kernel<T>(), "gemm::product: epilogues need a float kernel (AVX-512 or AVX2 + FMA)");
  eigen_product<Accumulate>(o);
}

}  // namespace evnerf::nn::gemm
