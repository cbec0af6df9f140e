// eval/metrics.hpp — image quality against ground truth: MSE, PSNR, SSIM as in Wang et al. 2004 with
// scikit-image's Gaussian settings, and grey luminance. The alignments events require before any metric
// (eval/alignment.hpp) and the error split by scale (eval/error_scales.hpp) are included at the end. Depends on core/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"

namespace evnerf::eval {

inline void require_same_shape(const Image& a, const Image& b) {
  require(a.width == b.width && a.height == b.height && a.channels == b.channels, "metrics: images differ in size or channels");
}

inline double mse(const Image& a, const Image& b) {
  require_same_shape(a, b);
  double s = 0;
  for (std::size_t i = 0; i < a.data.size(); ++i) s += double(a.data[i] - b.data[i]) * (a.data[i] - b.data[i]);
  return a.data.empty() ? 0 : s / a.data.size();
}
inline double psnr(const Image& a, const Image& b) {
  const double m = mse(a, b);
  return m <= 0 ? INFINITY : 10 * std::log10(1.0 / m);
}

/// One plane of W×H values (row-major) filtered by a Gaussian of `sigma` pixels truncated at `radius` and
/// normalised over its taps, separably (rows, then columns), with 'reflect' borders (…2 1 0 | 0 1 2…, as
/// scikit-image's SSIM and scipy's gaussian_filter use).
inline std::vector<double> gaussian_filter(const std::vector<double>& in, int W, int H, double sigma, int radius) {
  require(sigma > 0 && std::isfinite(sigma) && radius >= 0 && in.size() == static_cast<std::size_t>(W) * H,
          "gaussian_filter: bad arguments");
  const int R = radius;
  std::vector<double> k(static_cast<std::size_t>(2 * R + 1));
  double ks = 0;
  for (int i = -R; i <= R; ++i) ks += k[static_cast<std::size_t>(i + R)] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= ks;
  auto reflect = [](int i, int n) {
    while (i < 0 || i >= n) i = i < 0 ? -i - 1 : 2 * n - i - 1;
    return i;
  };
  std::vector<double> tmp(in.size()), out(in.size());
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      double s = 0;
      for (int i = -R; i <= R; ++i) s += k[static_cast<std::size_t>(i + R)] * in[static_cast<std::size_t>(y) * W + reflect(x + i, W)];
      tmp[static_cast<std::size_t>(y) * W + x] = s;
    }
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      double s = 0;
      for (int i = -R; i <= R; ++i) s += k[static_cast<std::size_t>(i + R)] * tmp[static_cast<std::size_t>(reflect(y + i, H)) * W + x];
      out[static_cast<std::size_t>(y) * W + x] = s;
    }
  return out;
}

/// SSIM with an 11-tap Gaussian window (σ 1.5), K1 0.01, K2 0.03, data range 1, population covariances,
/// 'reflect' borders and the mean over the interior (5 px cropped), per channel then averaged — the
/// settings of skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5,
/// use_sample_covariance=False, data_range=1).
inline double ssim(const Image& a, const Image& b) {
  require_same_shape(a, b);
  const int W = a.width, H = a.height, C = a.channels, R = 5;
  require(W > 2 * R && H > 2 * R, "ssim: images must be larger than 11x11");
  auto filter = [&](const std::vector<double>& in) { return gaussian_filter(in, W, H, 1.5, R); };
  const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  double total = 0;
  for (int c = 0; c < C; ++c) {
    std::vector<double> x(a.pixels()), y(a.pixels()), xx(a.pixels()), yy(a.pixels()), xy(a.pixels());
    for (std::size_t i = 0; i < a.pixels(); ++i) {
      x[i] = a.data[i * C + c];
      y[i] = b.data[i * C + c];
      xx[i] = x[i] * x[i];
      yy[i] = y[i] * y[i];
      xy[i] = x[i] * y[i];
    }
    const auto ux = filter(x), uy = filter(y), uxx = filter(xx), uyy = filter(yy), uxy = filter(xy);
    double s = 0;
    std::size_t n = 0;
    for (int yy_ = R; yy_ < H - R; ++yy_)
      for (int xx_ = R; xx_ < W - R; ++xx_) {
        const std::size_t i = static_cast<std::size_t>(yy_) * W + xx_;
        const double vx = uxx[i] - ux[i] * ux[i], vy = uyy[i] - uy[i] * uy[i], vxy = uxy[i] - ux[i] * uy[i];
        s += ((2 * ux[i] * uy[i] + c1) * (2 * vxy + c2)) / ((ux[i] * ux[i] + uy[i] * uy[i] + c1) * (vx + vy + c2));
        ++n;
      }
    total += s / n;
  }
  return total / C;
}

/// Converts a colour image to grey luminance (Rec. 601 weights); grey images pass through.
inline Image to_grey(const Image& a) {
  if (a.channels == 1) return a;
  Image o(a.width, a.height, 1);
  for (std::size_t i = 0; i < a.pixels(); ++i)
    o.data[i] = 0.299f * a.data[i * a.channels] + 0.587f * a.data[i * a.channels + 1] + 0.114f * a.data[i * a.channels + 2];
  return o;
}

}  // namespace evnerf::eval

#include "alignment.hpp"
#include "error_scales.hpp"
