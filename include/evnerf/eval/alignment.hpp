// eval/alignment.hpp — the alignments events require before any metric (brightness is fixed only up to gain
// and offset: global and per-image log-affine fits, EventNeRF's, min-max, none), the scores under them for
// images and sequences, the HDR truth's tone, and the mean of scores. Depends on eval/metrics.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "metrics.hpp"

namespace evnerf::eval {

/// How a reconstruction is brought to the ground truth's brightness before scoring (events fix brightness
/// only up to gain and offset in log space).
///   GlobalLogAffine  one affine map in log intensity per channel, fitted over all frames of the sequence
///                    (as Robust e-NeRF scores): the primary alignment.
///   LogAffine        the same fitted per image (all channels together).
///   EventNerf        EventNeRF's: one affine map per channel over the sequence, in log(x^2.2 + 0.1)
///                    (gamma-decoded intensity with an offset) instead of log(x + ε).
///   GlobalLogOffset  one offset in log intensity per channel over the sequence, the gain left at 1 (E-3DGS's
///                    log correction): what is left when the model's contrast must be right on its own.
///   MinMax           each image, prediction and ground truth, scaled to [0, 1].
///   None             as rendered.
enum class Alignment { GlobalLogAffine, LogAffine, MinMax, None, EventNerf, GlobalLogOffset };
inline const char* to_string(Alignment a) {
  switch (a) {
    case Alignment::GlobalLogAffine:
      return "global-log-affine";
    case Alignment::LogAffine:
      return "log-affine";
    case Alignment::MinMax:
      return "min-max";
    case Alignment::EventNerf:
      return "eventnerf";
    case Alignment::GlobalLogOffset:
      return "global-log-offset";
    default:
      return "none";
  }
}
inline Alignment parse_alignment(const std::string& s) {
  if (s == "global-log-affine") return Alignment::GlobalLogAffine;
  if (s == "log-affine") return Alignment::LogAffine;
  if (s == "min-max") return Alignment::MinMax;
  if (s == "none") return Alignment::None;
  if (s == "eventnerf") return Alignment::EventNerf;
  if (s == "global-log-offset") return Alignment::GlobalLogOffset;
  throw Error("unknown alignment '" + s + "' (expected global-log-affine, log-affine, eventnerf, global-log-offset, min-max or none)");
}

/// ε of the log-domain alignments (as in the loss).
inline constexpr double kLogEps = 1e-3;

/// The space a sequence-level fit works in: x ↦ log(x^gamma + offset). The default is log(x + ε); EventNeRF
/// fits in log(x^2.2 + 0.1).
struct LogTransform {
  double gamma = 1.0, offset = kLogEps;
  double forward(double x) const {
    const double v = std::max(0.0, x);
    return std::log((gamma == 1.0 ? v : std::pow(v, gamma)) + offset);
  }
  double inverse(double y) const {
    const double v = std::max(0.0, std::exp(y) - offset);
    return gamma == 1.0 ? v : std::pow(v, 1.0 / gamma);
  }
};
inline constexpr LogTransform kEventNerfTransform{2.2, 0.1};

/// y ≈ a·x + b in the transform's space (log(· + ε) by default), the least-squares map of one channel.
struct LogAffine {
  double a = 1, b = 0;
  LogTransform space{};
  double max = 1.0;  ///< the result is clipped to [0, max]: 1 for frames, unbounded for HDR truth
  float apply(float v) const { return static_cast<float>(std::clamp(space.inverse(a * space.forward(v) + b), 0.0, max)); }
};

/// Least-squares log-affine maps, one per channel, over every pixel of every (prediction, ground truth)
/// pair, in `space`. A prediction with no variance in a channel gets a = 0 (its best constant). With
/// `offset_only`, a = 1 and b is the mean difference.
inline std::vector<LogAffine> fit_log_affine(const std::vector<Image>& preds, const std::vector<Image>& gts, LogTransform space = {},
                                             bool offset_only = false) {
  require(!preds.empty() && preds.size() == gts.size(), "fit_log_affine: need as many predictions as ground-truth images");
  const int C = preds.front().channels;
  std::vector<double> n(C, 0), sx(C, 0), sy(C, 0), sxx(C, 0), sxy(C, 0);
  for (std::size_t f = 0; f < preds.size(); ++f) {
    require_same_shape(preds[f], gts[f]);
    require(preds[f].channels == C, "fit_log_affine: frames differ in channels");
    const auto& p = preds[f].data;
    const auto& g = gts[f].data;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const int c = static_cast<int>(i % static_cast<std::size_t>(C));
      const double x = space.forward(p[i]), y = space.forward(g[i]);
      n[c] += 1;
      sx[c] += x;
      sy[c] += y;
      sxx[c] += x * x;
      sxy[c] += x * y;
    }
  }
  std::vector<LogAffine> fit(C);
  for (int c = 0; c < C; ++c) {
    const double var = sxx[c] - sx[c] * sx[c] / n[c];
    fit[c].a = offset_only ? 1.0 : var > 1e-12 * n[c] ? (sxy[c] - sx[c] * sy[c] / n[c]) / var : 0.0;
    fit[c].b = (sy[c] - fit[c].a * sx[c]) / n[c];
    fit[c].space = space;
  }
  return fit;
}
inline Image apply_log_affine(const Image& pred, const std::vector<LogAffine>& fit) {
  require(static_cast<int>(fit.size()) == pred.channels, "apply_log_affine: one map per channel");
  Image o = pred;
  for (std::size_t i = 0; i < o.data.size(); ++i) o.data[i] = fit[i % fit.size()].apply(o.data[i]);
  return o;
}

inline Image min_max(const Image& a) {
  Image o = a;
  const auto [lo, hi] = std::minmax_element(a.data.begin(), a.data.end());
  const float span = *hi - *lo;
  for (auto& v : o.data) v = span > 0 ? (v - *lo) / span : 0.f;
  return o;
}

/// Brings `pred` to `gt`'s brightness. LogAffine: least squares a·log(p+ε)+b ≈ log(g+ε) over all
/// pixels, then exp(·)−ε clamped to [0, 1] (ε = 1e-3 as in the loss). MinMax: both to [0, 1] (changes
/// gt too). Returns the aligned prediction and the (possibly normalised) ground truth.
inline std::pair<Image, Image> align(const Image& pred, const Image& gt, Alignment how) {
  require_same_shape(pred, gt);
  if (how == Alignment::None) return {pred, gt};
  if (how == Alignment::MinMax) return {min_max(pred), min_max(gt)};
  if (how == Alignment::GlobalLogAffine) return {apply_log_affine(pred, fit_log_affine({pred}, {gt})), gt};
  if (how == Alignment::EventNerf) return {apply_log_affine(pred, fit_log_affine({pred}, {gt}, kEventNerfTransform)), gt};
  if (how == Alignment::GlobalLogOffset) return {apply_log_affine(pred, fit_log_affine({pred}, {gt}, {}, true)), gt};
  const double eps = 1e-3;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(pred.data.size());
  for (std::size_t i = 0; i < pred.data.size(); ++i) {
    const double x = std::log(std::max(0.0, double(pred.data[i])) + eps), y = std::log(std::max(0.0, double(gt.data[i])) + eps);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double var = sxx - sx * sx / n;
  const double a = var > 1e-12 ? (sxy - sx * sy / n) / var : 0.0, b = (sy - a * sx) / n;
  Image o = pred;
  for (auto& v : o.data) v = static_cast<float>(std::clamp(std::exp(a * std::log(std::max(0.0, double(v)) + eps) + b) - eps, 0.0, 1.0));
  return {o, gt};
}

struct Scores {
  double mse = 0, psnr = 0, ssim = 0;
};
inline Scores score(const Image& pred, const Image& gt, Alignment how) {
  const auto [p, g] = align(pred, gt, how);
  return {mse(p, g), psnr(p, g), ssim(p, g)};
}

/// Scoring against high-dynamic-range truth (linear radiance, unclipped, from the simulator's linear/): an
/// image is scored in log(x + offset), the space the sensor's events live in, put on [0, 1] by the truth's
/// range over the sequence (lo, hi = the 0.1 and 99.9 percentiles of the truth's log, so that a few extreme
/// pixels do not set it), so PSNR and SSIM weigh the dark end as much as the bright one. Predictions are
/// aligned in that space and are not clipped before.
struct HdrTone {
  double offset = 1e-4, lo = 0, hi = 1;
  static constexpr double kTail = 0.001;  ///< share of the truth's pixels left outside [lo, hi] at each end
  static HdrTone of(const std::vector<Image>& gts, double offset) {
    require(offset > 0, "HdrTone: the log offset must be positive");
    std::vector<double> l;
    for (const auto& g : gts)
      for (float v : g.data) l.push_back(std::log(std::max(0.0, double(v)) + offset));
    require(!l.empty(), "HdrTone: no ground truth");
    const auto at = [&](double q) {
      const auto k = static_cast<std::ptrdiff_t>(std::llround(q * static_cast<double>(l.size() - 1)));
      std::nth_element(l.begin(), l.begin() + k, l.end());
      return l[static_cast<std::size_t>(k)];
    };
    HdrTone t{offset, at(kTail), at(1 - kTail)};
    require(t.hi > t.lo, "HdrTone: the ground truth has no range");
    return t;
  }
  LogTransform space() const { return {1.0, offset}; }
  float operator()(float x) const {
    return static_cast<float>(std::clamp((std::log(std::max(0.0, double(x)) + offset) - lo) / (hi - lo), 0.0, 1.0));
  }
  Image apply(const Image& a) const {
    Image o = a;
    for (auto& v : o.data) v = (*this)(v);
    return o;
  }
  /// Min-max in the log space (the HDR form of the min-max alignment).
  Image log_min_max(const Image& a) const {
    Image o = a;
    for (auto& v : o.data) v = static_cast<float>(std::log(std::max(0.0, double(v)) + offset));
    return min_max(o);
  }
};

/// The HDR form of score_sequence: alignments fit in the tone's space (EventNerf in its own) with no clipping,
/// then prediction and truth are both tone-mapped; MinMax compares the log images, each put on [0, 1].
inline std::vector<Scores> score_sequence_hdr(const std::vector<Image>& preds, const std::vector<Image>& gts, Alignment how,
                                              const HdrTone& tone, std::vector<Image>* aligned) {
  std::vector<Scores> out;
  std::vector<LogAffine> fit;
  auto unclipped = [](std::vector<LogAffine> f) {
    for (auto& m : f) m.max = INFINITY;
    return f;
  };
  if (how == Alignment::GlobalLogAffine) fit = unclipped(fit_log_affine(preds, gts, tone.space()));
  if (how == Alignment::EventNerf) fit = unclipped(fit_log_affine(preds, gts, kEventNerfTransform));
  if (how == Alignment::GlobalLogOffset) fit = unclipped(fit_log_affine(preds, gts, tone.space(), true));
  for (std::size_t f = 0; f < preds.size(); ++f) {
    require_same_shape(preds[f], gts[f]);
    Image p, g;
    if (how == Alignment::MinMax) {
      p = tone.log_min_max(preds[f]);
      g = tone.log_min_max(gts[f]);
    } else {
      if (how == Alignment::LogAffine) p = apply_log_affine(preds[f], unclipped(fit_log_affine({preds[f]}, {gts[f]}, tone.space())));
      else if (how == Alignment::None) p = preds[f];
      else p = apply_log_affine(preds[f], fit);
      p = tone.apply(p);
      g = tone.apply(gts[f]);
    }
    out.push_back({mse(p, g), psnr(p, g), ssim(p, g)});
    if (aligned) aligned->push_back(std::move(p));
  }
  return out;
}

/// Scores a sequence frame by frame. GlobalLogAffine, EventNerf and GlobalLogOffset fit their maps once over all frames; the
/// others align each frame on its own. `aligned`, when given, receives the aligned predictions. With `hdr`,
/// the truth is linear radiance and the scores are score_sequence_hdr's.
inline std::vector<Scores> score_sequence(const std::vector<Image>& preds, const std::vector<Image>& gts, Alignment how,
                                          std::vector<Image>* aligned = nullptr, const HdrTone* hdr = nullptr) {
  require(preds.size() == gts.size(), "score_sequence: need as many predictions as ground-truth images");
  std::vector<Scores> out;
  if (aligned) aligned->clear();
  if (preds.empty()) return out;
  if (hdr) return score_sequence_hdr(preds, gts, how, *hdr, aligned);
  std::vector<LogAffine> fit;
  const bool sequence = how == Alignment::GlobalLogAffine || how == Alignment::EventNerf || how == Alignment::GlobalLogOffset;
  if (sequence)
    fit = fit_log_affine(preds, gts, how == Alignment::EventNerf ? kEventNerfTransform : LogTransform{}, how == Alignment::GlobalLogOffset);
  for (std::size_t f = 0; f < preds.size(); ++f) {
    const auto [p, g] = sequence ? std::pair<Image, Image>{apply_log_affine(preds[f], fit), gts[f]} : align(preds[f], gts[f], how);
    out.push_back({mse(p, g), psnr(p, g), ssim(p, g)});
    if (aligned) aligned->push_back(p);
  }
  return out;
}
/// The truth as score_sequence compares it under `how`: put on [0, 1] under MinMax; with `hdr`, tone-mapped
/// (or its log put on [0, 1] under MinMax); else as it is.
inline Image scored_truth(const Image& g, Alignment how, const HdrTone* hdr = nullptr) {
  if (how == Alignment::MinMax) return hdr ? hdr->log_min_max(g) : min_max(g);
  return hdr ? hdr->apply(g) : g;
}
/// The mean of per-frame scores (PSNR averaged in dB, as the field reports it).
inline Scores mean(const std::vector<Scores>& s) {
  Scores m;
  for (const auto& x : s) {
    m.mse += x.mse / static_cast<double>(s.size());
    m.psnr += x.psnr / static_cast<double>(s.size());
    m.ssim += x.ssim / static_cast<double>(s.size());
  }
  return m;
}

}  // namespace evnerf::eval
