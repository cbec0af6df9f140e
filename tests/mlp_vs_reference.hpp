// Runs a fused nn::Mlp forward and backward on random data and the plain reference on the same data, and
// returns the worst max-norm errors relative to the reference's max norms (at least 1). Shared by
// test_nn.cpp and portable.cpp (which has no doctest).
#pragma once
#include <evnerf/nn/mlp.hpp>
#include <evnerf/nn/detail/reference.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace evnerf::testing {

struct MlpErrors {
  double y, dparams, dx;
};

template <class M>
MlpErrors mlp_vs_reference(int n, std::uint64_t seed = 5) {
  Rng rng(seed);
  std::vector<float> params(M::n_params), x(static_cast<std::size_t>(M::in_dims) * n), dy(static_cast<std::size_t>(M::out_dims) * n);
  M::init(params.data(), rng);
  for (auto& p : params) p += static_cast<float>(rng.uniform(-0.01, 0.01));
  for (auto& v : x) v = static_cast<float>(rng.uniform(-1, 1));
  for (auto& v : dy) v = static_cast<float>(rng.uniform(-1, 1));
  typename M::template Workspace<float> ws;
  const float* y = M::forward(params.data(), x.data(), n, ws);
  std::vector<float> dp(M::n_params, 0.f), dx(x.size(), 0.f);
  M::backward(params.data(), ws, dy.data(), dp.data(), dx.data());
  const auto ref = nn::reference_mlp_forward_backward<M>(params, x, n, dy);
  auto worst = [](const std::vector<float>& want, const float* got) {
    double err = 0, scale = 1;
    for (std::size_t i = 0; i < want.size(); ++i) {
      err = std::max(err, std::abs(double(want[i]) - got[i]));
      scale = std::max(scale, std::abs(double(want[i])));
    }
    return err / scale;
  };
  return {worst(ref.y, y), worst(ref.dparams, dp.data()), worst(ref.dx, dx.data())};
}

}  // namespace evnerf::testing
