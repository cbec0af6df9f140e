// nn/detail/bf16.hpp — mixed-precision matrix products for the fused MLP: operands rounded to bfloat16 and packed
// in pairs along the reduction dimension, products accumulated in FP32 (AVX-512 BF16's vdpbf16ps does 32
// such multiply-adds per instruction, twice the FP32 FMA's 16). Parameters, gradients, activations and every
// sum stay FP32; only the two factors of each product are rounded. Depends on nn/detail/gemm.hpp only.
//
// Packed layout: a "pair" is one 32-bit word holding two bf16 values, element k in the low half and k+1 in
// the high half (an odd K gets a zero high half on its last pair). A is packed so that the pairs of 16
// consecutive rows are contiguous (pair (m, p) at a[m + p·lda]); B's pair (p, j) is at b[p·bk + j·bn].
#pragma once
#include <bit>
#include <cmath>
#include <cstddef>
#include <climits>
#include <cstdint>

#include "gemm.hpp"

namespace evnerf::nn {

/// Precision policies of nn::Mlp. Fp32: FP32 products. Bf16: products of bf16-rounded operands with FP32
/// accumulation (parameters, gradients and activations stay FP32). Bf16 needs AVX-512 BF16; built for a CPU
/// without it, it computes in FP32. For double (the gradient checks) both mean plain double.
struct Fp32 {};
struct Bf16 {};

namespace bf16 {

/// Whether this build has the BF16 kernel (else Bf16 networks compute in FP32).
constexpr bool available() {
#if defined(__AVX512BF16__) && defined(__AVX512BW__)
  return true;
#else
  return false;
#endif
}

/// Round to the nearest bf16, ties to even (what the hardware conversion does); NaN stays NaN.
inline std::uint16_t round(float f) {
  const std::uint32_t u = std::bit_cast<std::uint32_t>(f);
  if (std::isnan(f)) return static_cast<std::uint16_t>((u >> 16) | 0x40u);
  return static_cast<std::uint16_t>((u + 0x7FFFu + ((u >> 16) & 1u)) >> 16);
}
inline float widen(std::uint16_t h) { return std::bit_cast<float>(static_cast<std::uint32_t>(h) << 16); }
inline std::uint32_t pair(float lo, float hi) {
  return static_cast<std::uint32_t>(round(lo)) | (static_cast<std::uint32_t>(round(hi)) << 16);
}

/// Pairs along k from two columns: src element (m, k) at src[m + k·ld] (M rows contiguous); pair (m, p) goes
/// to dst[m + p·ldd]. Used for A operands stored row-contiguous (weights; a tile's gradients for dW) and
/// for B operands whose pairs run across columns (a tile's inputs for dW).
inline void pack_across(const float* src, int M, int K, std::ptrdiff_t ld, std::uint32_t* dst, std::ptrdiff_t ldd) {
  const int P = (K + 1) / 2;
  for (int p = 0; p < P; ++p) {
    const float* lo = src + 2 * p * ld;
    const float* hi = 2 * p + 1 < K ? lo + ld : nullptr;
    std::uint32_t* d = dst + p * ldd;
    int m = 0;
#if defined(__AVX512BF16__) && defined(__AVX512BW__)
    // cvtne2ps gives [lo0..lo15, hi0..hi15]; the permutation interleaves them into 16 pairs.
    const __m512i order = _mm512_set_epi16(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6, 21, 5, 20, 4, 19, 3,
                                           18, 2, 17, 1, 16, 0);
    for (; m < M; m += 16) {
      const __mmask16 k = M - m >= 16 ? __mmask16(0xFFFF) : static_cast<__mmask16>((1u << (M - m)) - 1);
      const __m512 l = _mm512_maskz_loadu_ps(k, lo + m);
      const __m512 h = hi ? _mm512_maskz_loadu_ps(k, hi + m) : _mm512_setzero_ps();
      const __m512i v = _mm512_permutexvar_epi16(order, reinterpret_cast<__m512i>(_mm512_cvtne2ps_pbh(h, l)));
      _mm512_mask_storeu_epi32(d + m, k, v);
    }
#endif
    for (; m < M; ++m) d[m] = pair(lo[m], hi ? hi[m] : 0.f);
  }
}

/// Pairs along k within a column: src element (k, j) at src[k + j·ld] (K contiguous); pair (p, j) goes to
/// dst[p·dp + j·dj]. Used for B operands stored K-contiguous (a layer's input, a tile's gradients for dX)
/// and, with dp = rows and dj = 1, for the transposed weights of dX.
inline void pack_along(const float* src, int K, int N, std::ptrdiff_t ld, std::uint32_t* dst, std::ptrdiff_t dp, std::ptrdiff_t dj) {
  const int P = (K + 1) / 2;
  for (int j = 0; j < N; ++j) {
    const float* s = src + j * ld;
    std::uint32_t* d = dst + j * dj;
    int p = 0;
#if defined(__AVX512BF16__) && defined(__AVX512BW__)
    if (dp == 1) {  // contiguous output: 16 floats → 8 pairs per conversion
      for (; 2 * p + 16 <= K; p += 8)
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(d + p), reinterpret_cast<__m256i>(_mm512_cvtneps_pbh(_mm512_loadu_ps(s + 2 * p))));
    } else if (dp <= INT32_MAX / 16) {  // strided output: 32 floats → 16 pairs, scattered
      const __m512i at = _mm512_mullo_epi32(_mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15),
                                            _mm512_set1_epi32(static_cast<int>(dp)));
      for (; p < P; p += 16) {
        const int left = K - 2 * p;  // floats from s + 2p on
        const __mmask16 lo = left >= 16 ? __mmask16(0xFFFF) : static_cast<__mmask16>((1u << left) - 1);
        const __mmask16 hi = left >= 32 ? __mmask16(0xFFFF) : left > 16 ? static_cast<__mmask16>((1u << (left - 16)) - 1) : 0;
        const __mmask16 out = P - p >= 16 ? __mmask16(0xFFFF) : static_cast<__mmask16>((1u << (P - p)) - 1);
        const __m512bh v = _mm512_cvtne2ps_pbh(_mm512_maskz_loadu_ps(hi, s + 2 * p + 16), _mm512_maskz_loadu_ps(lo, s + 2 * p));
        _mm512_mask_i32scatter_epi32(d + p * dp, out, at, reinterpret_cast<__m512i>(v), 4);
      }
    }
#endif
    for (; p < P; ++p) d[p * dp] = pair(s[2 * p], 2 * p + 1 < K ? s[2 * p + 1] : 0.f);
  }
}

/// Operands of a packed product: C (m × n, FP32, column-major ldc) (+)= A·B with kp pairs along k.
struct Operands {
  int m, n, kp;
  const std::uint32_t* a;
  std::ptrdiff_t lda;
  const std::uint32_t* b;
  std::ptrdiff_t bk, bn;
  float* c;
  std::ptrdiff_t ldc;
};

/// The plain path (and the kernel's reference): widen every pair and accumulate in FP32, k in order.
template <bool Accumulate>
void reference_product(const Operands& o) {
  for (int j = 0; j < o.n; ++j)
    for (int i = 0; i < o.m; ++i) {
      float s = Accumulate ? o.c[i + j * o.ldc] : 0.f;
      for (int p = 0; p < o.kp; ++p) {
        const std::uint32_t a = o.a[i + p * o.lda], b = o.b[p * o.bk + j * o.bn];
        s += widen(static_cast<std::uint16_t>(a)) * widen(static_cast<std::uint16_t>(b));
        s += widen(static_cast<std::uint16_t>(a >> 16)) * widen(static_cast<std::uint16_t>(b >> 16));
      }
      o.c[i + j * o.ldc] = s;
    }
}

#if defined(__AVX512BF16__) && defined(__AVX512BW__)
namespace detail {

/// One (16·V) × NR block of C, as gemm::detail::block but one vdpbf16ps (two k) per FMA slot; the
/// blocking around it is gemm::detail's.
template <int V, int NR, bool Accumulate, bool Full, class Epi>
inline void block(int KP, const std::uint32_t* __restrict a, std::ptrdiff_t lda, const std::uint32_t* __restrict b, std::ptrdiff_t bk,
                  std::ptrdiff_t bn, float* __restrict c, std::ptrdiff_t ldc, const __mmask16 (&mask)[2], const Epi& epi, int i0, int j0) {
  __m512 acc[V][NR];
  gemm::detail::load_block<V, NR, Accumulate, Full>(acc, c, ldc, mask);
  for (int p = 0; p < KP; ++p) {
    const std::uint32_t* ap = a + p * lda;
    __m512bh av[V];
    for (int v = 0; v < V; ++v)
      av[v] = reinterpret_cast<__m512bh>(Full ? _mm512_loadu_si512(ap + 16 * v) : _mm512_maskz_loadu_epi32(mask[v], ap + 16 * v));
    const std::uint32_t* bp = b + p * bk;
#pragma GCC unroll 12
    for (int j = 0; j < NR; ++j) {
      const __m512bh bj = reinterpret_cast<__m512bh>(_mm512_set1_epi32(static_cast<int>(bp[j * bn])));
      for (int v = 0; v < V; ++v) acc[v][j] = _mm512_dpbf16_ps(acc[v][j], av[v], bj);
    }
  }
  gemm::detail::store_block<V, NR, Full>(acc, c, ldc, mask, epi, i0, j0);
}

}  // namespace detail
#endif

/// C = A·B or C += A·B over packed operands, then the epilogue (gemm::BiasActivation, gemm::ActivationGrad)
/// on each result vector. Needs available(); the reference path takes no epilogue.
template <bool Accumulate, class Epi = gemm::NoEpilogue>
[[gnu::noinline]] void product(const Operands& o, [[maybe_unused]] const Epi& epi = {}) {
  if (o.m <= 0 || o.n <= 0) return;
#if defined(__AVX512BF16__) && defined(__AVX512BW__)
  gemm::detail::row_panels(o.m, [&](auto v, auto full, int i0, const __mmask16(&mask)[2]) {
    gemm::detail::column_blocks(o.n, [&](auto nr, int j) {
      detail::block<decltype(v)::value, decltype(nr)::value, Accumulate, decltype(full)::value>(
          o.kp, o.a + i0, o.lda, o.b + j * o.bn, o.bk, o.bn, o.c + i0 + j * o.ldc, o.ldc, mask, epi, i0, j);
    });
  });
#else
  static_assert(!Epi::active, "bf16::product: epilogues need the AVX-512 BF16 kernel");
  reference_product<Accumulate>(o);
#endif
}

}  // namespace bf16
}  // namespace evnerf::nn
