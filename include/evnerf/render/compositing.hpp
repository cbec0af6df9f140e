// render/compositing.hpp — volume rendering along one ray: alpha from density, transmittance, expected
// luminance (optionally before a known background), depth and opacity, forward and backward. The
// per-sample pieces (alpha from raw density, luminance from raw output) are written once with ad/; the
// transmittance scan's backward is a reverse suffix sum. Depends on ad/ only.
#pragma once
#include <cmath>
#include <vector>

#include "../ad/expr.hpp"
#include "../nn/activation.hpp"

namespace evnerf::render {

/// Length given to a ray's last interval (open to infinity, as in NeRF): its alpha is 1 unless σ = 0.
inline constexpr double kOpenInterval = 1e10;
/// Added to every 1 − α in the transmittance product, so that the backward's division by it stays finite.
inline constexpr double kTransmittanceEpsilon = 1e-10;

/// α = 1 − exp(−act(σ + noise)·δ), written once: value and dα/dσ both come from this text. `Act` is the
/// field's density activation (ReLU in the paper; TruncExp for Instant-NGP-style fields).
template <class Act = nn::ReLU>
struct AlphaOfDensity {
  double delta, noise;
  template <class S>
  auto operator()(const S& sigma) const {
    return 1.0 - ad::exp(-(Act::apply(sigma + noise) * delta));
  }
};
/// Luminance from the network's raw output through the field's radiance activation (nn::Sigmoid in the
/// paper; nn::TruncExp for radiance of any range).
template <class Act = nn::Sigmoid>
struct LuminanceOfRaw {
  template <class S>
  auto operator()(const S& raw) const {
    return Act::apply(raw);
  }
};

/// The length of sample k's interval in density units: to the next sample; the last one's is open
/// (kOpenInterval), or as long as the one before it when a background lies behind (open for S = 1).
template <class T>
double interval_length(int S, int k, const T* t, double dir_norm, bool background) {
  if (k + 1 < S) return double(t[k + 1] - t[k]) * dir_norm;
  return background && S > 1 ? double(t[k] - t[k - 1]) * dir_norm : kOpenInterval;
}

/// Per-ray result and what its backward needs.
template <class T>
struct RayComposite {
  std::vector<T> alpha, dalpha_dsigma, trans, weight, lum, dlum_draw;  // per sample (lum: C per sample)
  std::vector<T> color;                                                // C
  T depth = 0, opacity = 0;
  /// With a background: the transmittance left behind the last sample (the background's weight in color)
  /// and the background's C values (the caller's, kept alive until the backward); else 0 and null.
  T rest = 0;
  const T* background = nullptr;
};

/// Composites S samples of one ray with C channels. sigma[k·sigma_stride] raw density, raw[k·C + c] raw
/// luminance, t[k] distance along the ray (in units of dir, z-depth for our rays), dir_norm = |d| in
/// the units density is measured in (EvNerf: |d| / box().density_length), noise[k] density noise (or
/// null). The last interval is open (δ = kOpenInterval), as in NeRF: what a ray meets last stops it.
///
/// `background` (optional, C values): the luminance behind the samples, as when an object is seen before a
/// backdrop of known brightness (EventNeRF's object scenes). The last interval is then as long as the one
/// before it (open when S = 1), and the transmittance left behind the last sample, r.rest, weighs the
/// background: color = Σ w_k lum_k + rest · background. Depth and opacity are the samples' alone.
///
/// `skipped` (optional): the raw density that the renderer gives samples it did not evaluate (raw luminance
/// 0). Where act(skipped) and its derivative are both 0, every such sample with no noise (or noise 0) has
/// α = 0 and dα/dσ = 0 whatever its δ, so they are written without evaluating exp; the results are the
/// same bits.
template <class T, class DensityAct = nn::ReLU, class RadianceAct = nn::Sigmoid>
void composite_forward(int S, int C, const T* sigma, int sigma_stride, const T* raw, const T* t, T dir_norm, const T* noise,
                       RayComposite<T>& r, const T* skipped = nullptr, const T* background = nullptr) {
  r.alpha.resize(S);
  r.dalpha_dsigma.resize(S);
  r.trans.resize(S);
  r.weight.resize(S);
  r.lum.resize(static_cast<std::size_t>(S) * C);
  r.dlum_draw.resize(static_cast<std::size_t>(S) * C);
  r.color.assign(C, T(0));
  r.depth = r.opacity = 0;
  T trans = 1;
  // The shortcut for samples at `skipped`: their α (0 for every δ > 0) and their luminance at raw 0, once.
  bool shortcut = false;
  T alpha_skip = 0, dalpha_skip = 0, lum_zero = 0, dlum_zero = 0;
  if (skipped) {
    const auto a = ad::value_and_grad(AlphaOfDensity<DensityAct>{1.0, 0.0}, std::array<double, 1>{double(*skipped)});
    const auto f = ad::value_and_grad([](const auto& x) { return DensityAct::apply(x); }, std::array<double, 1>{double(*skipped)});
    shortcut = f.value == 0 && f.grad[0] == 0;
    alpha_skip = static_cast<T>(a.value);
    dalpha_skip = static_cast<T>(a.grad[0]);
    const auto l = ad::value_and_grad(LuminanceOfRaw<RadianceAct>{}, std::array<double, 1>{0.0});
    lum_zero = static_cast<T>(l.value);
    dlum_zero = static_cast<T>(l.grad[0]);
  }
  for (int k = 0; k < S; ++k) {
    const T sk = sigma[static_cast<std::size_t>(k) * sigma_stride];
    const bool skip = shortcut && sk == *skipped && (!noise || noise[k] == T(0));
    if (skip) {
      r.alpha[k] = alpha_skip;
      r.dalpha_dsigma[k] = dalpha_skip;
    } else {
      const double delta = interval_length(S, k, t, dir_norm, background != nullptr);
      const auto a =
          ad::value_and_grad(AlphaOfDensity<DensityAct>{delta, noise ? double(noise[k]) : 0.0}, std::array<double, 1>{double(sk)});
      r.alpha[k] = static_cast<T>(a.value);
      r.dalpha_dsigma[k] = static_cast<T>(a.grad[0]);
    }
    r.trans[k] = trans;
    const T w = trans * r.alpha[k];
    r.weight[k] = w;
    for (int c = 0; c < C; ++c) {
      const std::size_t i = static_cast<std::size_t>(k) * C + c;
      if (skip && raw[i] == T(0)) {
        r.lum[i] = lum_zero;
        r.dlum_draw[i] = dlum_zero;
      } else {
        const auto l = ad::value_and_grad(LuminanceOfRaw<RadianceAct>{}, std::array<double, 1>{double(raw[i])});
        r.lum[i] = static_cast<T>(l.value);
        r.dlum_draw[i] = static_cast<T>(l.grad[0]);
      }
      r.color[c] += w * r.lum[i];
    }
    r.depth += w * t[k];
    r.opacity += w;
    trans *= T(1) - r.alpha[k] + T(kTransmittanceEpsilon);
  }
  r.background = background;
  r.rest = background ? trans : T(0);
  if (background)
    for (int c = 0; c < C; ++c) r.color[c] += r.rest * background[c];
}

/// Backward of composite_forward for dL/dcolor (C values): writes dL/dsigma (stride sigma_stride) and
/// dL/draw (C per sample). Uses dout/dα_k = T_k c_k − (Σ_{j>k} w_j c_j + rest · b) / (1 − α_k + kTransmittanceEpsilon),
/// with b = Σ_c dcolor_c · background_c (0 without a background).
/// `dweight` (S values, or null) adds a loss's gradient w.r.t. the weights w_k themselves (a regulariser
/// such as loss::distortion_loss): colour is Σ w_k lum_k, so dL/dw_k enters exactly where dcolor · lum_k does.
template <class T>
void composite_backward(int S, int C, const RayComposite<T>& r, const T* dcolor, T* dsigma, int sigma_stride, T* draw,
                        const T* dweight = nullptr) {
  T suffix = 0;  // Σ_{j>k} w_j c_j with c_j = Σ_c dcolor_c · lum_jc (+ dL/dw_j), and the background's share
  if (r.background)
    for (int c = 0; c < C; ++c) suffix += r.rest * dcolor[c] * r.background[c];
  for (int k = S - 1; k >= 0; --k) {
    T ck = dweight ? dweight[k] : T(0);
    for (int c = 0; c < C; ++c) {
      const std::size_t i = static_cast<std::size_t>(k) * C + c;
      ck += dcolor[c] * r.lum[i];
      draw[i] = dcolor[c] * r.weight[k] * r.dlum_draw[i];
    }
    const T dalpha = r.trans[k] * ck - suffix / (T(1) - r.alpha[k] + T(kTransmittanceEpsilon));
    dsigma[static_cast<std::size_t>(k) * sigma_stride] = dalpha * r.dalpha_dsigma[k];
    suffix += r.weight[k] * ck;
  }
}

}  // namespace evnerf::render
