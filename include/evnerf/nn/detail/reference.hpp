// nn/detail/reference.hpp — a plain, unfused MLP (Eigen, layer by layer, whole batch per layer, double
// accumulation) used to test the fused Mlp and as the bench's reference twin. Not for training.
// Depends on nn/mlp.hpp only.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "../mlp.hpp"

namespace evnerf::nn {

template <class T>
struct ReferenceResult {
  std::vector<T> y, dparams, dx;
};

/// Runs M's computation layer by layer on the whole batch: each layer is one product, then a separate
/// pass for bias and activation; the backward mirrors it. Uses double internally. For a float network whose
/// products run on bf16 pairs (M::bf16_products<float>()), both factors of every product are rounded to
/// bf16 first, as the fused kernel does, so the two agree to FP32 summation error.
template <class M, class T>
ReferenceResult<T> reference_mlp_forward_backward(const std::vector<T>& params, const std::vector<T>& x, int n, const std::vector<T>& dy) {
  using Mat = Eigen::MatrixXd;
  const auto R = [](const Mat& m) -> Mat {
    if constexpr (M::template bf16_products<T>())
      return m.unaryExpr([](double v) { return double(bf16::widen(bf16::round(static_cast<float>(v)))); });
    else return m;
  };
  std::vector<Mat> inputs(M::n_layers + 1);
  Mat X = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>(x.data(), M::in_dims, n).template cast<double>();
  auto W = [&](int l) {
    return Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>(params.data() + M::weight_offset(l), M::layer_out(l),
                                                                              M::layer_in(l))
        .template cast<double>()
        .eval();
  };
  auto B = [&](int l) {
    return Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>>(params.data() + M::bias_offset(l), M::layer_out(l))
        .template cast<double>()
        .eval();
  };
  inputs[0] = X;
  for (int l = 0; l < M::n_layers; ++l) {
    Mat z = R(W(l)) * R(inputs[l]);
    z.colwise() += B(l);
    const bool last = l == M::depth;
    Mat y = z.unaryExpr([&](double v) { return last ? M::output_activation::f(v) : M::hidden_activation::f(v); });
    if (l == M::skip && M::skip >= 0) {
      Mat cat(y.rows() + X.rows(), n);
      cat << y, X;
      y = cat;
    }
    inputs[l + 1] = y;
  }
  ReferenceResult<T> r;
  const Mat& Y = inputs[M::n_layers];
  r.y.assign(Y.data(), Y.data() + Y.size());
  for (auto& v : r.y) v = static_cast<T>(v);
  std::vector<double> dp(M::n_params, 0.0);
  Mat G = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>>(dy.data(), M::out_dims, n).template cast<double>();
  Mat dX = Mat::Zero(M::in_dims, n);
  for (int l = M::depth; l >= 0; --l) {
    const bool last = l == M::depth;
    const Mat& out = inputs[l + 1];
    Mat dz(M::layer_out(l), n);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < M::layer_out(l); ++i)
        dz(i, j) = G(i, j) * (last ? M::output_activation::df_from_y(out(i, j)) : M::hidden_activation::df_from_y(out(i, j)));
    Eigen::Map<Mat>(dp.data() + M::weight_offset(l), M::layer_out(l), M::layer_in(l)) += R(dz) * R(inputs[l]).transpose();
    Eigen::Map<Eigen::VectorXd>(dp.data() + M::bias_offset(l), M::layer_out(l)) += R(dz).rowwise().sum();
    Mat din = R(W(l)).transpose() * R(dz);
    if (l == 0) {
      dX += din;
    } else {
      if (l == M::skip + 1 && M::skip >= 0) dX += din.bottomRows(M::in_dims);
      G = din.topRows(M::width);
    }
  }
  r.dparams.assign(dp.begin(), dp.end());
  r.dx.assign(dX.data(), dX.data() + dX.size());
  return r;
}

}  // namespace evnerf::nn
