// eval/metrics.hpp — image quality against ground truth (MSE, PSNR, SSIM as in Wang et al. 2004 with
// scikit-image's Gaussian settings) and the alignments events require before any metric (brightness is
// fixed only up to gain and offset). Depends on core/ only.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"

namespace evnerf::eval {

inline void require_same_shape(const Image& a, const Image& b) {
  require(a.width == b.width && a.height == b.height && a.channels == b.channels,
          "metrics: images differ in size or channels");
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
  require(sigma > 0 && std::isfinite(sigma) && radius >= 0 && in.size() == static_cast<std::size_t>(W) * H, "gaussian_filter: bad arguments");
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

/// How a reconstruction is brought to the ground truth's brightness before scoring (events fix brightness
/// only up to gain and offset in log space).
///   GlobalLogAffine  one affine map in log intensity per channel, fitted over all frames of the sequence
///                    (as Robust e-NeRF scores): the primary alignment.
///   LogAffine        the same fitted per image (all channels together).
///   EventNerf        EventNeRF's: one affine map per channel over the sequence, in log(x^2.2 + 0.1)
///                    (gamma-decoded intensity with an offset) instead of log(x + ε).
///   MinMax           each image, prediction and ground truth, scaled to [0, 1].
///   None             as rendered.
enum class Alignment { GlobalLogAffine, LogAffine, MinMax, None, EventNerf };
inline const char* to_string(Alignment a) {
  switch (a) {
    case Alignment::GlobalLogAffine: return "global-log-affine";
    case Alignment::LogAffine: return "log-affine";
    case Alignment::MinMax: return "min-max";
    case Alignment::EventNerf: return "eventnerf";
    default: return "none";
  }
}
inline Alignment parse_alignment(const std::string& s) {
  if (s == "global-log-affine") return Alignment::GlobalLogAffine;
  if (s == "log-affine") return Alignment::LogAffine;
  if (s == "min-max") return Alignment::MinMax;
  if (s == "none") return Alignment::None;
  if (s == "eventnerf") return Alignment::EventNerf;
  throw Error("unknown alignment '" + s + "' (expected global-log-affine, log-affine, eventnerf, min-max or none)");
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
/// pair, in `space`. A prediction with no variance in a channel gets a = 0 (its best constant).
inline std::vector<LogAffine> fit_log_affine(const std::vector<Image>& preds, const std::vector<Image>& gts,
                                             LogTransform space = {}) {
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
    fit[c].a = var > 1e-12 * n[c] ? (sxy[c] - sx[c] * sy[c] / n[c]) / var : 0.0;
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
  for (auto& v : o.data)
    v = static_cast<float>(std::clamp(std::exp(a * std::log(std::max(0.0, double(v)) + eps) + b) - eps, 0.0, 1.0));
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

/// Scores a sequence frame by frame. GlobalLogAffine and EventNerf fit their maps once over all frames; the
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
  const bool sequence = how == Alignment::GlobalLogAffine || how == Alignment::EventNerf;
  if (sequence) fit = fit_log_affine(preds, gts, how == Alignment::EventNerf ? kEventNerfTransform : LogTransform{});
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

/// A Gaussian blur of standard deviation `sigma` pixels (gaussian_filter truncated at 3σ), each channel on
/// its own. sigma must be positive.
inline Image gaussian_blur(const Image& a, double sigma) {
  require(sigma > 0 && std::isfinite(sigma), "gaussian_blur: sigma must be positive");
  const int C = a.channels, R = std::max(1, static_cast<int>(std::ceil(3 * sigma)));
  Image out(a.width, a.height, C);
  std::vector<double> plane(a.pixels());
  for (int c = 0; c < C; ++c) {
    for (std::size_t i = 0; i < a.pixels(); ++i) plane[i] = a.data[i * C + c];
    const auto f = gaussian_filter(plane, a.width, a.height, sigma, R);
    for (std::size_t i = 0; i < a.pixels(); ++i) out.data[i * C + c] = static_cast<float>(f[i]);
  }
  return out;
}

/// An aligned prediction's error split by scale: the error image e = prediction − truth, its coarse part
/// blur_σ(e) (what varies over more than about σ pixels: the brightness of whole regions, which events
/// constrain only through the edges around them, and not at all along edges parallel to the motion) and its
/// fine part e − blur_σ(e) (edges and texture: sharpness and registration). Each part's MSE and PSNR as if
/// it were the only error. The two MSEs add up to about the whole MSE (exactly where the parts are
/// uncorrelated); a method can gain in one part and lose in the other, which the whole PSNR hides.
/// Two more views of the same error, not a third part: its row part, each image row's mean error (per
/// channel) spread along the row, and its column part, likewise per column. A camera translating along its
/// x axis (a slider) never moves a point to another row, so adding any function of the row to the log
/// brightness changes no event: the row part is close to what no event of such a motion can see (and the
/// column part, of a motion along y). Compare the row part with the whole to see how much of an error on
/// a slider recording is in that blind spot.
struct ErrorScales {
  double coarse_mse = 0, fine_mse = 0, row_mse = 0, column_mse = 0;
  static double psnr_of(double mse) { return mse <= 0 ? INFINITY : 10 * std::log10(1.0 / mse); }
  double coarse_psnr() const { return psnr_of(coarse_mse); }
  double fine_psnr() const { return psnr_of(fine_mse); }
  double row_psnr() const { return psnr_of(row_mse); }
  double column_psnr() const { return psnr_of(column_mse); }
};
/// The scale at which eval splits the error (pixels).
inline constexpr double kErrorScaleSigma = 8.0;
/// The error image e = prediction − truth and its coarse part blur_σ(e) (the fine part is e − blur_σ(e)).
struct ErrorParts {
  Image error, coarse;
};
inline ErrorParts error_parts(const Image& aligned_pred, const Image& truth, double sigma = kErrorScaleSigma) {
  require_same_shape(aligned_pred, truth);
  Image e = aligned_pred;
  for (std::size_t i = 0; i < e.data.size(); ++i) e.data[i] = aligned_pred.data[i] - truth.data[i];
  Image lo = gaussian_blur(e, sigma);
  return {std::move(e), std::move(lo)};
}
inline ErrorScales error_scales(const Image& aligned_pred, const Image& truth, double sigma = kErrorScaleSigma) {
  const auto [e, lo] = error_parts(aligned_pred, truth, sigma);
  ErrorScales s;
  for (std::size_t i = 0; i < e.data.size(); ++i) {
    const double c = lo.data[i], f = double(e.data[i]) - lo.data[i];
    s.coarse_mse += c * c;
    s.fine_mse += f * f;
  }
  if (!e.data.empty()) {
    s.coarse_mse /= static_cast<double>(e.data.size());
    s.fine_mse /= static_cast<double>(e.data.size());
  }
  // Row and column parts: each row's (column's) mean error, per channel, counted at every pixel of it.
  const int W = e.width, H = e.height, C = e.channels;
  std::vector<double> row(static_cast<std::size_t>(H) * C, 0.0), col(static_cast<std::size_t>(W) * C, 0.0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < C; ++c) {
        const double v = e.data[(static_cast<std::size_t>(y) * W + x) * C + c];
        row[static_cast<std::size_t>(y) * C + c] += v;
        col[static_cast<std::size_t>(x) * C + c] += v;
      }
  if (!e.data.empty()) {
    for (const double r : row) s.row_mse += (r / W) * (r / W) * W;
    for (const double k : col) s.column_mse += (k / H) * (k / H) * H;
    s.row_mse /= static_cast<double>(e.data.size());
    s.column_mse /= static_cast<double>(e.data.size());
  }
  return s;
}

/// What a sequence's score would be if the brightness a straight camera motion never shows the events were
/// right. A camera translating along its x axis never moves a point to another image row, so adding any
/// function of the row to the log brightness of the whole sequence changes no event; likewise any function
/// of the column under a motion along y, and, where the radiance depends on the view, any function of the
/// pixel under a translation. The oracle fits such offsets to the truth: one log offset per image row (per
/// channel), constant over the sequence, that is a gain k on x + ε (exp(log(x + ε) + log k) − ε); likewise
/// one per column; and both together (a row gain times a column gain). The gains minimise the squared
/// error of the aligned predictions against the truth over the sequence, as the scores weigh it (a fit in
/// log space lets the darkest pixels decide, and can lower the score of a recording with black regions);
/// one gain alone in closed form, both by alternating the two closed forms until they settle. Each is
/// applied to every aligned prediction, which is scored again (clamped to [0, 1]; PSNR per frame, averaged
/// over the frames, as the scores). A large gain says the error sits where the motion is blind, which no
/// objective on these events can remove; a small one, that it is elsewhere. The offsets see the truth: a
/// diagnosis, never a score.
struct OffsetOracle {
  double rows_psnr = 0, columns_psnr = 0, both_psnr = 0;
};
inline OffsetOracle offset_oracle(const std::vector<Image>& aligned, const std::vector<Image>& truths, double eps = kLogEps) {
  require(aligned.size() == truths.size() && !truths.empty(), "offset_oracle: need one aligned prediction per truth, and at least one");
  for (std::size_t f = 0; f < truths.size(); ++f) {
    require_same_shape(aligned[f], truths[f]);
    require_same_shape(aligned[f], truths.front());
  }
  require(eps > 0, "offset_oracle: ε must be positive");
  const int W = truths.front().width, H = truths.front().height, C = truths.front().channels;
  const auto F = truths.size();
  const std::size_t nr = static_cast<std::size_t>(H) * C, nc = static_cast<std::size_t>(W) * C;
  // Visits every value of the sequence with its row and column slots and a = prediction + ε, b = truth + ε.
  auto each = [&](auto&& visit) {
    for (std::size_t f = 0; f < F; ++f)
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          for (int c = 0; c < C; ++c) {
            const std::size_t i = (static_cast<std::size_t>(y) * W + x) * C + c;
            visit(f, i, static_cast<std::size_t>(y) * C + c, static_cast<std::size_t>(x) * C + c, double(aligned[f].data[i]) + eps,
                  double(truths[f].data[i]) + eps);
          }
  };
  // The gains along one direction that minimise Σ (a · other · k − b)², given the other direction's gains.
  auto fit = [&](bool rows, const std::vector<double>& other) {
    std::vector<double> ab(rows ? nr : nc, 0.0), aa(rows ? nr : nc, 0.0);
    each([&](std::size_t, std::size_t, std::size_t r, std::size_t k, double a, double b) {
      const double ao = a * other[rows ? k : r];
      ab[rows ? r : k] += ao * b;
      aa[rows ? r : k] += ao * ao;
    });
    std::vector<double> g(ab.size());
    for (std::size_t j = 0; j < g.size(); ++j) g[j] = aa[j] > 0 ? ab[j] / aa[j] : 1.0;
    return g;
  };
  auto score = [&](const std::vector<double>& row_gain, const std::vector<double>& col_gain) {
    std::vector<Image> q(F, Image(W, H, C));
    each([&](std::size_t f, std::size_t i, std::size_t r, std::size_t k, double a, double) {
      q[f].data[i] = static_cast<float>(std::clamp(a * row_gain[r] * col_gain[k] - eps, 0.0, 1.0));
    });
    double sum = 0;
    for (std::size_t f = 0; f < F; ++f) sum += psnr(q[f], truths[f]);
    return sum / double(F);
  };
  const std::vector<double> ones_r(nr, 1.0), ones_c(nc, 1.0);
  OffsetOracle o;
  o.rows_psnr = score(fit(true, ones_c), ones_c);
  o.columns_psnr = score(ones_r, fit(false, ones_r));
  std::vector<double> gr(nr, 1.0), gc(nc, 1.0);
  for (int round = 0; round < 200; ++round) {  // alternating least squares: each half-step lowers the error
    gr = fit(true, gc);
    const auto next = fit(false, gr);
    double change = 0;
    for (std::size_t j = 0; j < nc; ++j) change = std::max(change, std::abs(next[j] - gc[j]) / std::max(1e-300, std::abs(gc[j])));
    gc = next;
    if (change < 1e-10) break;
  }
  o.both_psnr = score(gr, gc);
  return o;
}

/// The fine part of a sequence's error (ErrorScales' e − blur_σ(e)) split by the true depth of each pixel:
/// where sampler and geometry changes act (a texture 1 m away needs shorter depth bins than one 6 m away).
/// `edges` are the depth quantiles k/B of the pixels with a usable true depth (finite, > 0, < far) over the
/// whole sequence, so each of the B bands holds about a B-th of them. `pixel_share[b]` is band b's share of
/// all pixels, `fine_mse[b]` its pixels' squared fine error summed over the channels and divided by all
/// values (as ErrorScales::fine_mse), so the bands add up to the whole fine MSE less the pixels without a
/// usable depth.
struct FineByDepth {
  std::vector<double> edges, pixel_share, fine_mse;
};
inline FineByDepth fine_error_by_depth(const std::vector<Image>& aligned, const std::vector<Image>& truths,
                                       const std::vector<std::vector<float>>& depth, double far, int bands = 3,
                                       double sigma = kErrorScaleSigma) {
  require(bands >= 1, "fine_error_by_depth: need at least one band, got " + std::to_string(bands));
  require(aligned.size() == truths.size() && depth.size() == truths.size(),
          "fine_error_by_depth: need as many renders and depth maps as frames, got " + std::to_string(aligned.size()) + ", " +
              std::to_string(depth.size()) + " and " + std::to_string(truths.size()));
  const auto usable = [far](float z) { return std::isfinite(z) && z > 0 && z < far; };
  std::vector<float> all;
  for (std::size_t f = 0; f < truths.size(); ++f) {
    require_same_shape(aligned[f], truths[f]);  // before any work, as the depth sizes
    require(depth[f].size() == truths[f].pixels(), "fine_error_by_depth: frame " + std::to_string(f) + "'s depth map has " +
                                                       std::to_string(depth[f].size()) + " values for " +
                                                       std::to_string(truths[f].pixels()) + " pixels");
    for (const float z : depth[f])
      if (usable(z)) all.push_back(z);
  }
  FineByDepth r;
  if (all.empty()) return r;
  std::sort(all.begin(), all.end());
  for (int b = 0; b <= bands; ++b)
    r.edges.push_back(all[std::min(all.size() - 1, static_cast<std::size_t>(double(b) / bands * static_cast<double>(all.size())))]);
  r.pixel_share.assign(static_cast<std::size_t>(bands), 0.0);
  r.fine_mse.assign(static_cast<std::size_t>(bands), 0.0);
  double values = 0, pixels = 0;
  for (std::size_t f = 0; f < truths.size(); ++f) {
    const auto [e, lo] = error_parts(aligned[f], truths[f], sigma);
    const int C = e.channels;
    for (std::size_t p = 0; p < e.pixels(); ++p) {
      const float z = depth[f][p];
      if (usable(z)) {
        // band b holds edges[b] <= z < edges[b + 1] (the last band includes its top edge)
        const auto b = std::min<std::size_t>(static_cast<std::size_t>(bands) - 1,
                                             static_cast<std::size_t>(std::upper_bound(r.edges.begin() + 1, r.edges.end() - 1, z) -
                                                                      (r.edges.begin() + 1)));
        r.pixel_share[b] += 1;
        for (int c = 0; c < C; ++c) {
          const double v = double(e.data[p * C + c]) - lo.data[p * C + c];
          r.fine_mse[b] += v * v;
        }
      }
    }
    values += static_cast<double>(e.data.size());
    pixels += static_cast<double>(e.pixels());
  }
  for (auto& v : r.fine_mse) v /= values;
  for (auto& v : r.pixel_share) v /= pixels;
  return r;
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
