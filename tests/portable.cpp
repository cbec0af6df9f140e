// Built without -march=native (baseline x86-64, or whatever the compiler defaults to): the paths that
// builds for CPUs without AVX-512 take. The fused MLP (Fp32 and Bf16, which falls back to FP32 here) must
// match the plain reference and the hash grid's batch forward must match its point-by-point forward.
// Exit code 0 when all agree.
#include <evnerf/nn/encoding.hpp>
#include <evnerf/nn/mlp.hpp>
#include <evnerf/nn/reference.hpp>

#include <cstdio>
#include <vector>

using namespace evnerf;
using namespace evnerf::nn;

template <class M>
bool mlp_matches(int n) {
  Rng rng(5);
  std::vector<float> params(M::n_params), x(static_cast<std::size_t>(M::in_dims) * n), dy(static_cast<std::size_t>(M::out_dims) * n);
  M::init(params.data(), rng);
  for (auto& v : x) v = static_cast<float>(rng.uniform(-1, 1));
  for (auto& v : dy) v = static_cast<float>(rng.uniform(-1, 1));
  typename M::template Workspace<float> ws;
  const float* y = M::forward(params.data(), x.data(), n, ws);
  std::vector<float> dp(M::n_params, 0.f), dx(x.size(), 0.f);
  M::backward(params.data(), ws, dy.data(), dp.data(), dx.data());
  const auto ref = reference_mlp_forward_backward<M>(params, x, n, dy);
  auto worst = [](const std::vector<float>& want, const float* got) {
    double err = 0, scale = 1;
    for (std::size_t i = 0; i < want.size(); ++i) {
      err = std::max(err, std::abs(double(want[i]) - got[i]));
      scale = std::max(scale, std::abs(double(want[i])));
    }
    return err / scale;
  };
  const double e = std::max({worst(ref.y, y), worst(ref.dparams, dp.data()), worst(ref.dx, dx.data())});
  std::printf("%s: relative error %.2g\n", std::is_same_v<typename M::precision, Bf16> ? "Mlp Bf16" : "Mlp Fp32", e);
  return e < 1e-4;
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
