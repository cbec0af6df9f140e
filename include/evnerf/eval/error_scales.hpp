// eval/error_scales.hpp — where an aligned image's error sits: split into a coarse (Gaussian-blurred) and a
// fine part, per row and column, the offset oracle (the score with the truth's log offsets per row, column
// or both: what a straight motion never shows the events; a diagnosis, never a score), and the fine error by
// true depth. Depends on eval/alignment.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "alignment.hpp"

namespace evnerf::eval {

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
        const auto b = std::min<std::size_t>(
            static_cast<std::size_t>(bands) - 1,
            static_cast<std::size_t>(std::upper_bound(r.edges.begin() + 1, r.edges.end() - 1, z) - (r.edges.begin() + 1)));
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

}  // namespace evnerf::eval
