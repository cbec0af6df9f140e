// The library's paths for CPUs without AVX-512, built three ways (tests/CMakeLists.txt): at the compiler's
// baseline (no AVX: Eigen serves the products), for AVX2 + FMA (the 8-lane kernels, which an AVX-512 CPU
// runs too) and with -march=native. In each: the fused MLP (Fp32 and Bf16, which falls back to FP32 without
// AVX-512 BF16) matches the plain reference, the hash grid's batch forward matches its point-by-point
// forward, and where a float kernel is built, every product element is the scalar fused multiply-add chain
// to the bit. `--digest` prints a digest of a float network's forward and backward bits instead: the AVX2
// and the native build must print the same (portable.same_bits), which is what lets a float run give the
// same result on an AVX-512 and an AVX2 machine. Exit code 0 when all agree, 77 when this build's
// instructions are more than the CPU has.
#include <evnerf/nn/encoding.hpp>
#include <evnerf/nn/mlp.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "mlp_vs_reference.hpp"

using namespace evnerf;
using namespace evnerf::nn;

template <class M>
bool mlp_matches(int n) {
  const auto e = testing::mlp_vs_reference<M>(n);
  const double worst = std::max({e.y, e.dparams, e.dx});
  std::printf("%s: relative error %.2g\n", std::is_same_v<typename M::precision, Bf16> ? "Mlp Bf16" : "Mlp Fp32", worst);
  return worst < 1e-4;
}

namespace {

#if defined(__AVX512F__) || defined(EVNERF_GEMM_AVX2)
/// Ragged products in both B layouts, accumulating, overwriting and through both epilogues, each element
/// against the fma chain (gemm::first_chain_mismatch). Returns the number of products that disagree.
int kernel_mismatches() {
  Rng rng(13);
  int bad = 0, checked = 0;
  for (int m : {1, 7, 8, 9, 16, 17, 31, 64, 65})
    for (int n : {1, 3, 4, 6, 7, 12, 13, 45})
      for (int k : {0, 1, 31, 150})
        for (int layout : {0, 1, 2}) {
          // B column-major (k along a column, as a layer's input), row-major (a weight gradient's Xᵀ) or with
          // neither stride 1 (the kernels take any strides). m = 64 with a leading dimension of 256: the AVX2
          // kernel packs such row panels first.
          const std::ptrdiff_t lda = m == 64 ? 256 : m + 3, ldc = m + 1;
          const std::ptrdiff_t bk = layout == 0 ? 1 : layout == 1 ? n : 2, bn = layout == 0 ? k : layout == 1 ? 1 : 2 * k + 1;
          std::vector<float> a(static_cast<std::size_t>(lda) * k), b(static_cast<std::size_t>(2 * k + 1) * (n + 1)), bias(m),
              y(static_cast<std::size_t>(m) * n), c0(static_cast<std::size_t>(ldc) * n);
          for (auto* v : {&a, &b, &bias, &y, &c0})
            for (auto& e : *v) e = static_cast<float>(rng.uniform(-1, 1));
          std::vector<float> acc = c0, plain = c0, fwd = c0, bwd = c0;
          auto ops = [&](std::vector<float>& c) { return gemm::Operands<float>{m, n, k, a.data(), lda, b.data(), bk, bn, c.data(), ldc}; };
          const gemm::BiasActivation<ReLU> bias_relu{bias.data()};
          const gemm::ActivationGrad<ReLU> relu_grad{y.data(), m};
          gemm::product<true>(ops(acc));
          gemm::product<false>(ops(plain));
          gemm::product<false>(ops(fwd), bias_relu);
          gemm::product<false>(ops(bwd), relu_grad);
          bad += gemm::first_chain_mismatch<true>(ops(acc), c0.data(), ldc).has_value();
          bad += gemm::first_chain_mismatch<false>(ops(plain), nullptr, 0).has_value();
          bad += gemm::first_chain_mismatch<false>(ops(fwd), nullptr, 0, bias_relu).has_value();
          bad += gemm::first_chain_mismatch<false>(ops(bwd), nullptr, 0, relu_grad).has_value();
          checked += 4;
        }
  std::printf("float kernel products equal to the fma chain: %d of %d\n", checked - bad, checked);
  return bad;
}
#endif

/// gemm::transpose against its definition on ragged shapes (blocks, edges of every width, leading dimensions
/// wider than the matrix): every element moved exactly, and dst's padding untouched. Returns the shapes that
/// disagree.
int transpose_mismatches() {
  Rng rng(17);
  int bad = 0, checked = 0;
  for (int rows : {1, 5, 8, 9, 16, 17, 33})
    for (int cols : {1, 3, 8, 12, 16, 31}) {
      const std::ptrdiff_t ld = rows + 2, ldd = cols + 3;
      std::vector<float> src(static_cast<std::size_t>(ld) * cols), dst(static_cast<std::size_t>(ldd) * rows, -7.f);
      for (auto& v : src) v = static_cast<float>(rng.uniform(-1, 1));
      gemm::transpose(src.data(), rows, cols, ld, dst.data(), ldd);
      bool same = true;
      for (int i = 0; i < rows; ++i)
        for (int j = 0; j < ldd; ++j) same = same && dst[j + i * ldd] == (j < cols ? src[i + j * ld] : -7.f);
      bad += !same;
      ++checked;
    }
  std::printf("transposes equal to their definition: %d of %d\n", checked - bad, checked);
  return bad;
}

/// FNV-1a over the bits of a float network's output, parameter gradient and input gradient (64 wide, three
/// hidden layers with a skip connection, a ragged tile of 517 samples) on fixed data.
std::uint64_t network_digest() {
  using M = Mlp<39, 64, 3, 16, ReLU, Identity, 1>;
  const int n = 517;
  Rng rng(21);
  std::vector<float> params(M::n_params), x(static_cast<std::size_t>(M::in_dims) * n), dy(static_cast<std::size_t>(M::out_dims) * n);
  M::init(params.data(), rng);
  for (auto& v : x) v = static_cast<float>(rng.uniform(-1, 1));
  for (auto& v : dy) v = static_cast<float>(rng.uniform(-1, 1));
  typename M::template Workspace<float> ws;
  const float* out = M::forward(params.data(), x.data(), n, ws);
  std::vector<float> yv(out, out + static_cast<std::size_t>(M::out_dims) * n), dp(M::n_params, 0.f), dx(x.size(), 0.f);
  M::backward(params.data(), ws, dy.data(), dp.data(), dx.data());
  std::uint64_t h = 1469598103934665603ull;
  for (const auto* v : {&yv, &dp, &dx})
    for (float f : *v) {
      std::uint32_t u;
      std::memcpy(&u, &f, 4);
      for (int q = 0; q < 4; ++q) h = (h ^ ((u >> (8 * q)) & 0xFF)) * 1099511628211ull;
    }
  return h;
}

/// Whether this CPU runs what this build was compiled for (the vector extensions the kernels use).
bool cpu_runs_this_build() {
#if defined(__AVX512F__)
  if (!__builtin_cpu_supports("avx512f")) return false;
#endif
#if defined(__AVX2__) && defined(__FMA__)
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return false;
#endif
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (!cpu_runs_this_build()) {
    std::printf("this CPU lacks the vector extensions this build was compiled for: not run\n");
    return 77;
  }
  if (argc > 1 && std::strcmp(argv[1], "--digest") == 0) {
    std::printf("%016llx\n", static_cast<unsigned long long>(network_digest()));
    return 0;
  }
  std::printf("float kernel in this build: %s\n",
#if defined(__AVX512F__)
              "AVX-512"
#elif defined(EVNERF_GEMM_AVX2)
              "AVX2 + FMA"
#else
              "none (Eigen)"
#endif
  );
  bool ok = mlp_matches<Mlp<17, 40, 3, 5, ReLU, Identity, 1>>(37);
  ok = mlp_matches<Mlp<17, 40, 3, 5, ReLU, Identity, 1, Bf16>>(37) && ok;
  using G = HashGrid<6, 2, 10, 4, 96>;
  Rng rng(3);
  const int n = 61;
  std::vector<float> params(G::n_params), pts(3 * n), yb(static_cast<std::size_t>(n) * G::out_dims), yp(yb.size());
  for (auto& v : params) v = static_cast<float>(rng.uniform(-1, 1));
  for (auto& v : pts) v = static_cast<float>(rng.uniform(-0.1, 1.1));
  G::forward_batch(params.data(), pts.data(), n, yb.data());
  for (int j = 0; j < n; ++j)
    G::forward(params.data(), &pts[3 * static_cast<std::size_t>(j)], &yp[static_cast<std::size_t>(j) * G::out_dims]);
  std::printf("hash grid batch == point by point: %s\n", yb == yp ? "yes" : "no");
  ok = ok && yb == yp;
  ok = transpose_mismatches() == 0 && ok;
#if defined(__AVX512F__) || defined(EVNERF_GEMM_AVX2)
  ok = kernel_mismatches() == 0 && ok;
#endif
  std::printf("bf16 kernel in this build: %s\n", bf16::available() ? "yes" : "no (Bf16 computes in FP32)");
  return ok ? 0 : 1;
}
