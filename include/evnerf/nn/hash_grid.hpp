// nn/hash_grid.hpp — HashGrid<Levels, F, Log2T, BaseRes, MaxRes>: the multiresolution hash encoding
// (Müller et al. 2022), an nn::Encoding with trainable tables, and its batched forward (eight points at a
// time where an entry holds two float features, checked against the point-by-point forward).
// Included by nn/encoding.hpp. Depends on core/ and ad/ only.
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

#include "encoding.hpp"

namespace evnerf::nn {

/// The spatial hash's per-axis multipliers (Teschner et al. 2003, as Instant-NGP uses them): x·1 ⊕ y·P1 ⊕ z·P2.
inline constexpr std::uint32_t kHashPrimeY = 2654435761u, kHashPrimeZ = 805459861u;

/// Multiresolution hash encoding (Müller et al. 2022) of a 3-D point in [0, 1]³. Level l has resolution
/// floor(BaseRes · b^l) with b chosen so that the last level reaches MaxRes; a level whose grid fits in
/// the table is indexed densely, otherwise by the spatial hash (x·1 ⊕ y·2654435761 ⊕ z·805459861) mod T.
/// Trilinear interpolation of F features per level; tables are the parameters (init U(−1e-4, 1e-4)).
template <int Levels, int F, int Log2T, int BaseRes, int MaxRes>
struct HashGrid {
  static_assert(Levels >= 1 && Levels <= 32, "HashGrid: Levels must be between 1 and 32.");
  static_assert(F >= 1 && F <= 8, "HashGrid: FeaturesPerLevel must be between 1 and 8.");
  static_assert(Log2T >= 4 && Log2T <= 24, "HashGrid: Log2TableSize must be between 4 and 24.");
  static_assert(BaseRes >= 2 && MaxRes >= BaseRes, "HashGrid: need 2 <= BaseRes <= MaxRes.");
  static constexpr int in_dims = 3, out_dims = Levels * F;
  static constexpr bool unit_cube_input = true;  ///< points in [0, 1]³ (field::Field maps the box to it)
  static std::string name() {
    return "hash grid " + std::to_string(Levels) + "x" + std::to_string(F) + " 2^" + std::to_string(Log2T) + " " + std::to_string(BaseRes) +
           ".." + std::to_string(MaxRes);
  }
  static constexpr std::uint32_t table_size = 1u << Log2T;
  static constexpr std::size_t n_params = static_cast<std::size_t>(Levels) * table_size * F;

  struct LevelInfo {
    double scale;
    std::uint64_t res;
    bool dense;
  };
  static const std::array<LevelInfo, Levels>& levels() {
    static const std::array<LevelInfo, Levels> info = [] {
      std::array<LevelInfo, Levels> a{};
      const double b = Levels == 1 ? 1.0 : std::exp((std::log(double(MaxRes)) - std::log(double(BaseRes))) / (Levels - 1));
      for (int l = 0; l < Levels; ++l) {
        a[l].scale = std::floor(BaseRes * std::pow(b, l));
        a[l].res = static_cast<std::uint64_t>(a[l].scale) + 1;
        a[l].dense = a[l].res * a[l].res * a[l].res <= table_size;
      }
      return a;
    }();
    return info;
  }
  static double scale(int l) { return levels()[l].scale; }
  template <class T>
  static void init(T* p, Rng& rng) {
    for (std::size_t i = 0; i < n_params; ++i) p[i] = static_cast<T>(rng.uniform(-1e-4, 1e-4));
  }
  static std::uint32_t index(int l, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    const auto& lv = levels()[l];
    if (lv.dense) return static_cast<std::uint32_t>(x + lv.res * (y + lv.res * z));
    return (x ^ (y * kHashPrimeY) ^ (z * kHashPrimeZ)) & (table_size - 1);
  }

  /// Visits the 8 corners of level l around point p: fn(table_index, weight, dweight/dp[3]). The weight is
  /// (wx·wy)·wz of the per-axis linear weights; dweight is only formed where fn reads it (it is inlined).
  template <class T, class Fn>
  static void corners(int l, const T* p, Fn&& fn) {
    const LevelInfo& lv = levels()[l];
    const T s = static_cast<T>(lv.scale);
    std::uint32_t base[3];
    T frac[3];
    for (int d = 0; d < 3; ++d) {
      const T c = std::clamp(p[d], T(0), T(1)) * s;
      T fl = std::floor(c);
      if (fl >= s) fl = s - 1;  // p = 1 falls in the last cell
      base[d] = static_cast<std::uint32_t>(fl);
      frac[d] = c - fl;
    }
    // Per-axis index terms: dense levels add x + res·y + res²·z, hashed ones xor x, y·π₂, z·π₃.
    std::uint32_t term[3][2];
    const auto res = static_cast<std::uint32_t>(lv.res);
    const std::uint32_t mul[3] = {1u, lv.dense ? res : kHashPrimeY, lv.dense ? res * res : kHashPrimeZ};
    for (int d = 0; d < 3; ++d) {
      term[d][0] = base[d] * mul[d];
      term[d][1] = (base[d] + 1) * mul[d];
    }
    const T wd[3][2] = {{T(1) - frac[0], frac[0]}, {T(1) - frac[1], frac[1]}, {T(1) - frac[2], frac[2]}};
    for (int c = 0; c < 8; ++c) {
      const int bx = c & 1, by = (c >> 1) & 1, bz = (c >> 2) & 1;
      const std::uint32_t idx =
          lv.dense ? term[0][bx] + term[1][by] + term[2][bz] : (term[0][bx] ^ term[1][by] ^ term[2][bz]) & (table_size - 1);
      const T w = (wd[0][bx] * wd[1][by]) * wd[2][bz];
      const T dw[3] = {(bx ? s : -s) * (wd[1][by] * wd[2][bz]), (by ? s : -s) * (wd[0][bx] * wd[2][bz]),
                       (bz ? s : -s) * (wd[0][bx] * wd[1][by])};
      fn(idx, w, dw);
    }
  }
  template <class T>
  static void forward(const T* params, const T* p, T* y) {
    for (int l = 0; l < Levels; ++l) {
      const T* table = params + static_cast<std::size_t>(l) * table_size * F;
      T acc[F] = {};
      corners<T>(l, p, [&](std::uint32_t idx, T w, const T*) {
        for (int f = 0; f < F; ++f) acc[f] += w * table[static_cast<std::size_t>(idx) * F + f];
      });
      for (int f = 0; f < F; ++f) y[l * F + f] = acc[f];
    }
  }
  /// Batch forward of n points (3 each) into y (out_dims each), level by level: one level's table
  /// (2^Log2T · F floats) stays in cache while every point visits it, instead of all levels' tables being
  /// touched by each point in turn. Same values as forward() point by point.
  template <class T>
  static void forward_batch(const T* params, const T* p, int n, T* y) {
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
    if constexpr (std::is_same_v<T, float> && F == 2) {
      forward_batch_pairs(params, p, n, y);
#if defined(EVNERF_CHECK_KERNELS)
      // The batch path's promise, checked point by point in a real run (gemm::product's check, for the grid).
      T one[out_dims];
      for (int j = 0; j < n; ++j) {
        forward(params, p + 3 * static_cast<std::size_t>(j), one);
        const T* yj = y + static_cast<std::size_t>(j) * out_dims;
        for (int f = 0; f < out_dims; ++f)
          if (std::bit_cast<std::uint32_t>(yj[f]) != std::bit_cast<std::uint32_t>(one[f])) {
            std::fprintf(stderr,
                         "evnerf: EVNERF_CHECK_KERNELS: HashGrid::forward_batch point %d of %d (%a %a %a), feature %d is %a where "
                         "forward() gives %a\n",
                         j, n, p[3 * j], p[3 * j + 1], p[3 * j + 2], f, yj[f], one[f]);
            std::abort();
          }
      }
#endif
      return;
    }
#endif
    for (int l = 0; l < Levels; ++l) {
      const T* table = params + static_cast<std::size_t>(l) * table_size * F;
      for (int j = 0; j < n; ++j) {
        T acc[F] = {};
        corners<T>(l, p + 3 * static_cast<std::size_t>(j), [&](std::uint32_t idx, T w, const T*) {
          for (int f = 0; f < F; ++f) acc[f] += w * table[static_cast<std::size_t>(idx) * F + f];
        });
        T* yj = y + static_cast<std::size_t>(j) * out_dims + l * F;
        for (int f = 0; f < F; ++f) yj[f] = acc[f];
      }
    }
  }
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
  /// The 8 corners of level `lv` around 8 points (lanes kept by k: a mask register on AVX-512, a lane mask
  /// on AVX2) of p: table indices and weights, as corners() computes them (per-axis weights, (wx·wy)·wz), so
  /// the values are bit-identical to it.
  struct Cells8 {
    __m256i idx[8];
    __m256 w[8];
  };
  template <class Mask>
  static Cells8 cells8(const LevelInfo& lv, const float* p, int j0, Mask k) {
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.f);
    const float sc = static_cast<float>(lv.scale);
    const __m256 s = _mm256_set1_ps(sc), last = _mm256_set1_ps(sc - 1);
    const auto res = static_cast<std::uint32_t>(lv.res);
    const __m256i mul[3] = {_mm256_set1_epi32(1), _mm256_set1_epi32(static_cast<int>(lv.dense ? res : kHashPrimeY)),
                            _mm256_set1_epi32(static_cast<int>(lv.dense ? res * res : kHashPrimeZ))};
    const __m256i at = _mm256_add_epi32(_mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21), _mm256_set1_epi32(3 * j0));
    __m256i term[3][2];
    __m256 wd[3][2];
    for (int d = 0; d < 3; ++d) {
      const __m256 x = gather8(p, _mm256_add_epi32(at, _mm256_set1_epi32(d)), k);
      const __m256 c = _mm256_mul_ps(_mm256_min_ps(_mm256_max_ps(x, zero), one), s);
      const __m256 fl = _mm256_min_ps(_mm256_floor_ps(c), last);
      const __m256i base = _mm256_cvttps_epi32(fl);
      const __m256 frac = _mm256_sub_ps(c, fl);
      term[d][0] = _mm256_mullo_epi32(base, mul[d]);
      term[d][1] = _mm256_mullo_epi32(_mm256_add_epi32(base, _mm256_set1_epi32(1)), mul[d]);
      wd[d][0] = _mm256_sub_ps(one, frac);
      wd[d][1] = frac;
    }
    const __m256i hash_mask = _mm256_set1_epi32(static_cast<int>(table_size - 1));
    Cells8 cell;
    for (int c = 0; c < 8; ++c) {
      const int bx = c & 1, by = (c >> 1) & 1, bz = (c >> 2) & 1;
      cell.idx[c] = lv.dense ? _mm256_add_epi32(_mm256_add_epi32(term[0][bx], term[1][by]), term[2][bz])
                             : _mm256_and_si256(_mm256_xor_si256(_mm256_xor_si256(term[0][bx], term[1][by]), term[2][bz]), hash_mask);
      cell.w[c] = _mm256_mul_ps(_mm256_mul_ps(wd[0][bx], wd[1][by]), wd[2][bz]);
    }
    return cell;
  }
#endif
#if defined(__AVX512F__)
  static __mmask8 lanes8(int n, int j0) { return n - j0 >= 8 ? __mmask8(0xFF) : static_cast<__mmask8>((1u << (n - j0)) - 1); }
  static __m256 gather8(const float* p, __m256i at, __mmask8 k) { return _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), k, at, p, 4); }

  /// forward_batch for float with two features per entry, 8 points at a time: an entry is one 64-bit
  /// pair, so each corner is one 8-lane gather and each level's result one 8-lane scatter; one fused
  /// multiply-add per corner in corners()' order, so the values equal forward()'s bit for bit (tested).
  static void forward_batch_pairs(const float* params, const float* p, int n, float* y) {
    const __m512i twice = _mm512_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    for (int l = 0; l < Levels; ++l) {
      const LevelInfo& lv = levels()[l];
      const double* table = reinterpret_cast<const double*>(params + static_cast<std::size_t>(l) * table_size * F);
      for (int j0 = 0; j0 < n; j0 += 8) {
        const __mmask8 k = lanes8(n, j0);
        const Cells8 cell = cells8(lv, p, j0, k);
        __m512 acc = _mm512_setzero_ps();
        for (int c = 0; c < 8; ++c) {
          const __m512d entry = _mm512_mask_i32gather_pd(_mm512_setzero_pd(), k, cell.idx[c], table, 8);
          // Both weights of a pair from lane c of w (zero-extended and maskz forms: GCC 12's plain intrinsics
          // pass an undefined vector and warn).
          const __m512 w16 = _mm512_castpd_ps(_mm512_maskz_insertf64x4(0xFF, _mm512_setzero_pd(), _mm256_castps_pd(cell.w[c]), 0));
          acc = _mm512_fmadd_ps(_mm512_maskz_permutexvar_ps(0xFFFF, twice, w16), _mm512_castpd_ps(entry), acc);
        }
        const __m256i row = _mm256_mullo_epi32(_mm256_add_epi32(lane, _mm256_set1_epi32(j0)), _mm256_set1_epi32(out_dims / 2));
        _mm512_mask_i32scatter_pd(y + l * F, k, row, _mm512_castps_pd(acc), 8);
      }
    }
  }

#elif defined(__AVX2__) && defined(__FMA__)
  static __m256i lanes8(int n, int j0) {  // lanes 0 .. n − j0 − 1 (all where n − j0 ≥ 8)
    return _mm256_cmpgt_epi32(_mm256_set1_epi32(n - j0), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  }
  static __m256 gather8(const float* p, __m256i at, __m256i k) {
    return _mm256_mask_i32gather_ps(_mm256_setzero_ps(), p, at, _mm256_castsi256_ps(k), 4);
  }

  /// forward_batch for float with two features per entry, 8 points at a time: an entry is one 64-bit pair,
  /// loaded one by one (AVX2 gathers measured 20 % slower here), four to a vector; one fused multiply-add per
  /// corner in corners()' order, so the values equal forward()'s bit for bit (tested).
  static void forward_batch_pairs(const float* params, const float* p, int n, float* y) {
    const __m256i dup_lo = _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3), dup_hi = _mm256_setr_epi32(4, 4, 5, 5, 6, 6, 7, 7);
    alignas(32) float out[16];
    for (int l = 0; l < Levels; ++l) {
      const LevelInfo& lv = levels()[l];
      const double* table = reinterpret_cast<const double*>(params + static_cast<std::size_t>(l) * table_size * F);
      for (int j0 = 0; j0 < n; j0 += 8) {
        const __m256i k = lanes8(n, j0);
        const Cells8 cell = cells8(lv, p, j0, k);
        __m256 acc_lo = _mm256_setzero_ps(), acc_hi = _mm256_setzero_ps();  // points 0–3 and 4–7, a pair each
        alignas(32) std::uint32_t ix[8][8];
        for (int c = 0; c < 8; ++c)  // lanes past the last point read entry 0
          _mm256_store_si256(reinterpret_cast<__m256i*>(ix[c]), _mm256_and_si256(cell.idx[c], k));
        for (int c = 0; c < 8; ++c) {
          const std::uint32_t* q = ix[c];
          const __m256d e_lo = _mm256_setr_pd(table[q[0]], table[q[1]], table[q[2]], table[q[3]]);
          const __m256d e_hi = _mm256_setr_pd(table[q[4]], table[q[5]], table[q[6]], table[q[7]]);
          acc_lo = _mm256_fmadd_ps(_mm256_permutevar8x32_ps(cell.w[c], dup_lo), _mm256_castpd_ps(e_lo), acc_lo);
          acc_hi = _mm256_fmadd_ps(_mm256_permutevar8x32_ps(cell.w[c], dup_hi), _mm256_castpd_ps(e_hi), acc_hi);
        }
        _mm256_store_ps(out, acc_lo);
        _mm256_store_ps(out + 8, acc_hi);
        const int m = std::min(8, n - j0);
        for (int q = 0; q < m; ++q) {
          float* yj = y + static_cast<std::size_t>(j0 + q) * out_dims + l * F;
          yj[0] = out[2 * q];
          yj[1] = out[2 * q + 1];
        }
      }
    }
  }
#endif
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
  /// backward_batch for float with two features per entry, levels [l0, l1): indices and weights 8 points
  /// at a time (cells8), the additions to the tables one by one in backward()'s order (points, then
  /// corners), so entries that several points touch get exactly the same sums.
  static void backward_batch_pairs(const float* p, int n, const float* dy, float* dparams, int l0 = 0, int l1 = Levels) {
    alignas(32) std::uint32_t idx[8][8];
    alignas(32) float w[8][8];
    for (int l = l0; l < l1; ++l) {
      const LevelInfo& lv = levels()[l];
      float* g = dparams + static_cast<std::size_t>(l) * table_size * F;
      for (int j0 = 0; j0 < n; j0 += 8) {
        const auto k = lanes8(n, j0);  // a mask register (AVX-512) or lane mask (AVX2)
        const Cells8 cell = cells8(lv, p, j0, k);
        for (int c = 0; c < 8; ++c) {
          _mm256_store_si256(reinterpret_cast<__m256i*>(idx[c]), cell.idx[c]);
          _mm256_store_ps(w[c], cell.w[c]);
        }
        const int m = std::min(8, n - j0);
        for (int q = 0; q < m; ++q) {
          const float* dyj = dy + static_cast<std::size_t>(j0 + q) * out_dims + l * F;
          for (int c = 0; c < 8; ++c) {
            float* e = g + static_cast<std::size_t>(idx[c][q]) * F;
            e[0] += w[c][q] * dyj[0];
            e[1] += w[c][q] * dyj[1];
          }
        }
      }
    }
  }
#endif
  /// Batch backward to the tables only (no input gradient), level by level like forward_batch; adds
  /// exactly what backward() would, in the same order per table entry.
  template <class T>
  static void backward_batch(const T* p, int n, const T* dy, T* dparams) {
    backward_batch_levels(p, n, dy, dparams, 0, Levels);
  }
  /// The levels' tables are disjoint, so backward_batch splits into levels: levels [l0, l1) of it add to
  /// their tables exactly what backward_batch does there (threads may take different levels at once).
  static constexpr int batch_parts = Levels;
  template <class T>
  static void backward_batch_levels(const T* p, int n, const T* dy, T* dparams, int l0, int l1) {
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
    if constexpr (std::is_same_v<T, float> && F == 2) {
      backward_batch_pairs(p, n, dy, dparams, l0, l1);
      return;
    }
#endif
    for (int l = l0; l < l1; ++l) {
      T* g = dparams + static_cast<std::size_t>(l) * table_size * F;
      for (int j = 0; j < n; ++j) {
        const T* dyj = dy + static_cast<std::size_t>(j) * out_dims + l * F;
        corners<T>(l, p + 3 * static_cast<std::size_t>(j), [&](std::uint32_t idx, T w, const T*) {
          for (int f = 0; f < F; ++f) g[static_cast<std::size_t>(idx) * F + f] += w * dyj[f];
        });
      }
    }
  }
  /// Scatters dy into the tables' gradients; dx (may be null) gets the gradient w.r.t. the point
  /// (zero outside the unit cube, where the encoding is clamped).
  /// The input gradient alone, through levels [0, levels) only (all of them for levels ≥ Levels): what the
  /// coarse levels say of where the point is, without the fine levels' tables (larger, hashed, and sharper
  /// in the point than a pose gradient wants). Adds to dx.
  template <class T>
  static void input_backward(const T* params, const T* p, const T* dy, T* dx, int levels) {
    const int l1 = std::min(levels, Levels);
    for (int l = 0; l < l1; ++l) {
      const std::size_t off = static_cast<std::size_t>(l) * table_size * F;
      corners<T>(l, p, [&](std::uint32_t idx, T, const T* dw) {
        const std::size_t at = off + static_cast<std::size_t>(idx) * F;
        T dot = 0;
        for (int f = 0; f < F; ++f) dot += params[at + f] * dy[l * F + f];
        for (int d = 0; d < 3; ++d)
          if (p[d] > T(0) && p[d] < T(1)) dx[d] += dot * dw[d];
      });
    }
  }
  template <class T>
  static void backward(const T* params, const T* p, const T* dy, T* dparams, T* dx) {
    if (!dx && !dparams) return;
    for (int l = 0; l < Levels; ++l) {
      const std::size_t off = static_cast<std::size_t>(l) * table_size * F;
      if (!dx) {  // the common case in training (positions are data): only the table gradients
        corners<T>(l, p, [&](std::uint32_t idx, T w, const T*) {
          const std::size_t at = off + static_cast<std::size_t>(idx) * F;
          for (int f = 0; f < F; ++f) dparams[at + f] += w * dy[l * F + f];
        });
        continue;
      }
      corners<T>(l, p, [&](std::uint32_t idx, T w, const T* dw) {
        const std::size_t at = off + static_cast<std::size_t>(idx) * F;
        T dot = 0;
        for (int f = 0; f < F; ++f) {
          if (dparams) dparams[at + f] += w * dy[l * F + f];
          dot += params[at + f] * dy[l * F + f];
        }
        for (int d = 0; d < 3; ++d)
          if (p[d] > T(0) && p[d] < T(1)) dx[d] += dot * dw[d];
      });
    }
  }
};

static_assert(Encoding<IdentityEncoding<3>> && Encoding<Frequency<4>> && Encoding<SphericalHarmonics<4>> &&
              Encoding<HashGrid<2, 2, 6, 2, 8>>);

}  // namespace evnerf::nn
