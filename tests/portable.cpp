// Built without -march=native (baseline x86-64, or whatever the compiler defaults to): the paths that
// builds for CPUs without AVX-512 take. The fused MLP (Fp32 and Bf16, which falls back to FP32 here) must
// match the plain reference and the hash grid's batch forward must match its point-by-point forward.
// Exit code 0 when all agree.
#include <evnerf/nn/encoding.hpp>
#include <evnerf/nn/mlp.hpp>

#include <algorithm>
#include <cstdio>
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

int main() {
  bool ok = mlp_matches<Mlp<17, 40, 3, 5, ReLU, Identity, 1>>(37);
  ok = mlp_matches<Mlp<17, 40, 3, 5, ReLU, Identity, 1, Bf16>>(37) && ok;
  using G = HashGrid<6, 2, 10, 4, 96>;
  Rng rng(3);
  const int n = 61;
  std::vector<float> params(G::n_params), pts(3 * n), yb(static_cast<std::size_t>(n) * G::out_dims), yp(yb.size());
  for (auto& v : params) v = static_cast<float>(rng.uniform(-1, 1));
  for (auto& v : pts) v = static_cast<float>(rng.uniform(-0.1, 1.1));
  G::forward_batch(params.data(), pts.data(), n, yb.data());
  for (int j = 0; j < n; ++j) G::forward(params.data(), &pts[3 * static_cast<std::size_t>(j)], &yp[static_cast<std::size_t>(j) * G::out_dims]);
  std::printf("hash grid batch == point by point: %s\n", yb == yp ? "yes" : "no");
  ok = ok && yb == yp;
  std::printf("bf16 kernel in this build: %s\n", bf16::available() ? "yes" : "no (Bf16 computes in FP32)");
  return ok ? 0 : 1;
}
