#include <evnerf/eval/baselines.hpp>
#include <evnerf/eval/export.hpp>
#include <evnerf/eval/metrics.hpp>
#include <evnerf/eval/report.hpp>
#include <evnerf/view/session.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>

#include <stb_image.h>

#include <unistd.h>

#include "common.hpp"

using namespace evnerf;

namespace {
Image det(int w, int h, double a, double b) {
  Image im(w, h, 1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) im.at(x, y) = static_cast<float>(0.5 + 0.4 * std::sin(a * x + 0.3 * y) * std::cos(b * y - 0.2 * x));
  return im;
}
}  // namespace

TEST_CASE("SSIM matches scikit-image's values on fixed images") {
  // Reference values computed once with Debian's python3-skimage 0.19:
  // structural_similarity(P, Q, gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1).
  const Image A = det(24, 20, 0.37, 0.21), C = det(24, 20, 0.11, 0.52);
  Image B = A;
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 24; ++x) B.at(x, y) = std::clamp(A.at(x, y) + 0.1f * float(std::sin(1.3 * x * y * 0.1)), 0.f, 1.f);
  CHECK(eval::ssim(A, B) == doctest::Approx(0.8759339457900506).epsilon(2e-5));
  CHECK(eval::ssim(A, C) == doctest::Approx(0.22534423274536586).epsilon(2e-5));
  CHECK(eval::ssim(A, A) == doctest::Approx(1.0));
}

TEST_CASE("MSE and PSNR") {
  Image a(4, 4, 1, 0.5f), b(4, 4, 1, 0.6f);
  CHECK(eval::mse(a, b) == doctest::Approx(0.01).epsilon(1e-5));
  CHECK(eval::psnr(a, b) == doctest::Approx(20.0).epsilon(1e-4));
  CHECK_THROWS_AS(eval::mse(a, Image(3, 4, 1)), Error);
}

TEST_CASE("alignment: log-affine undoes a gain and gamma in log space, min-max normalises") {
  Image gt = det(30, 20, 0.2, 0.3), pred(30, 20, 1);
  for (std::size_t i = 0; i < gt.data.size(); ++i)
    pred.data[i] = static_cast<float>(std::exp(0.5 * std::log(gt.data[i] + 1e-3) - 0.7) - 1e-3);
  auto s = eval::score(pred, gt, eval::Alignment::LogAffine);
  CHECK(s.mse < 1e-8);
  CHECK(eval::score(pred, gt, eval::Alignment::None).mse > 1e-3);
  auto [p, g] = eval::align(pred, gt, eval::Alignment::MinMax);
  CHECK(*std::max_element(p.data.begin(), p.data.end()) == doctest::Approx(1.0));
  CHECK(*std::min_element(g.data.begin(), g.data.end()) == doctest::Approx(0.0));
  CHECK(eval::parse_alignment("min-max") == eval::Alignment::MinMax);
  CHECK_THROWS(eval::parse_alignment("bogus"));
}

TEST_CASE("baselines: direct integration sums polarity × contrast, the high-pass filter forgets") {
  events::EventStream ev;
  ev.width = 2;
  ev.height = 1;
  ev.push_back(0.1, 0, 0, 1);
  ev.push_back(0.2, 0, 0, 1);
  ev.push_back(0.3, 1, 0, -1);
  auto di = eval::direct_integration(ev, {0.15, 0.35}, 0.25);
  CHECK(std::log(di[0].at(0, 0)) == doctest::Approx(0.25));
  CHECK(std::log(di[1].at(0, 0)) == doctest::Approx(0.5));
  CHECK(std::log(di[1].at(1, 0)) == doctest::Approx(-0.25));
  auto hp = eval::high_pass_filter(ev, {0.2 + 1e-9, 10.0}, 0.25, 5.0);
  CHECK(std::log(hp[0].at(0, 0)) == doctest::Approx(0.25 * std::exp(-5 * 0.1) + 0.25).epsilon(1e-6));
  CHECK(std::abs(std::log(hp[1].at(0, 0))) < 1e-6);  // forgotten: back to the reference after ~10 s
  CHECK(std::abs(std::log(hp[1].at(1, 0))) < 1e-6);
  CHECK(std::log(hp[0].at(1, 0)) == doctest::Approx(0.0));  // no event yet at pixel 1 at 0.2 s
}

TEST_CASE("alignment: the sequence-level log-affine fit recovers one known map per channel exactly") {
  // Three frames of a 2-channel sequence; the prediction is the ground truth under a known log-affine map
  // per channel (a = 0.5, b = −0.7 and a = 1.6, b = 0.2 in log(x + ε)). The fit over the sequence finds both maps.
  std::vector<Image> gts, preds;
  const double A[2] = {0.5, 1.6}, B[2] = {-0.7, 0.2};
  for (int f = 0; f < 3; ++f) {
    const Image g1 = det(30, 20, 0.2 + 0.05 * f, 0.3), g2 = det(30, 20, 0.1, 0.25 + 0.07 * f);
    Image gt(30, 20, 2), pred(30, 20, 2);
    for (std::size_t i = 0; i < g1.pixels(); ++i) {
      gt.data[2 * i] = 0.3f * g1.data[i];  // dim channel: stays within [0, 1] under the inverse map
      gt.data[2 * i + 1] = 0.2f * g2.data[i];
      for (int c = 0; c < 2; ++c) {
        const double y = std::log(gt.data[2 * i + c] + 1e-3);
        pred.data[2 * i + c] = static_cast<float>(std::exp((y - B[c]) / A[c]) - 1e-3);
      }
    }
    gts.push_back(gt);
    preds.push_back(pred);
  }
  const auto fit = eval::fit_log_affine(preds, gts);
  REQUIRE(fit.size() == 2);
  for (int c = 0; c < 2; ++c) {
    CHECK(fit[c].a == doctest::Approx(A[c]).epsilon(1e-5));
    CHECK(fit[c].b == doctest::Approx(B[c]).epsilon(1e-5));
  }
  for (const auto& s : eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine)) CHECK(s.mse < 1e-9);
  // One map for the whole sequence: a frame whose brightness differs from the rest is not refitted alone.
  for (auto& v : preds[1].data) v = static_cast<float>(std::min(1.0, v * 1.5));
  CHECK(eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine)[1].mse > 1e-6);
  CHECK(eval::parse_alignment("global-log-affine") == eval::Alignment::GlobalLogAffine);
}

TEST_CASE("alignment: EventNeRF's fit recovers a known map per channel in log(x^2.2 + 0.1)") {
  std::vector<Image> gts, preds;
  const double A[3] = {1.2, 1.5, 1.1}, B[3] = {-0.1, 0.2, 0.05};  // a ≥ 1: the inverse map stays above the offset
  const eval::LogTransform T = eval::kEventNerfTransform;
  for (int f = 0; f < 2; ++f) {
    const Image g = det(24, 16, 0.15 + 0.1 * f, 0.3);
    Image gt(24, 16, 3), pred(24, 16, 3);
    for (std::size_t i = 0; i < g.pixels(); ++i)
      for (int c = 0; c < 3; ++c) {
        gt.data[3 * i + c] = (0.4f + 0.1f * c) * g.data[i];
        // pred = T⁻¹((T(gt) − b) / a): the ground truth under the inverse map, kept inside the transform's range
        pred.data[3 * i + c] = static_cast<float>(T.inverse((T.forward(gt.data[3 * i + c]) - B[c]) / A[c]));
      }
    gts.push_back(gt);
    preds.push_back(pred);
  }
  const auto fit = eval::fit_log_affine(preds, gts, T);
  for (int c = 0; c < 3; ++c) {
    CHECK(fit[c].a == doctest::Approx(A[c]).epsilon(1e-4));
    CHECK(fit[c].b == doctest::Approx(B[c]).epsilon(1e-4));
  }
  for (const auto& s : eval::score_sequence(preds, gts, eval::Alignment::EventNerf)) CHECK(s.mse < 1e-8);
  // The plain log-affine space is another space: its fit cannot undo this map exactly.
  CHECK(eval::mean(eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine)).mse > 1e-7);
  CHECK(eval::parse_alignment("eventnerf") == eval::Alignment::EventNerf);
  CHECK(std::string(eval::to_string(eval::Alignment::EventNerf)) == "eventnerf");
}

TEST_CASE("alignment: the offset-only fit undoes a log offset per channel over the sequence, and no gain") {
  std::vector<Image> gts, preds;
  const double B[3] = {-0.4, -0.1, -0.25};  // b ≤ 0: the prediction stays non-negative
  for (int f = 0; f < 2; ++f) {
    const Image g = det(24, 16, 0.15 + 0.1 * f, 0.3);
    Image gt(24, 16, 3), pred(24, 16, 3);
    for (std::size_t i = 0; i < g.pixels(); ++i)
      for (int c = 0; c < 3; ++c) {
        gt.data[3 * i + c] = (0.3f + 0.1f * c) * g.data[i];
        pred.data[3 * i + c] = static_cast<float>(std::exp(std::log(gt.data[3 * i + c] + eval::kLogEps) - B[c]) - eval::kLogEps);
      }
    gts.push_back(gt);
    preds.push_back(pred);
  }
  const auto fit = eval::fit_log_affine(preds, gts, {}, true);
  for (int c = 0; c < 3; ++c) {
    CHECK(fit[c].a == 1.0);
    CHECK(fit[c].b == doctest::Approx(B[c]).epsilon(1e-4));
  }
  for (const auto& s : eval::score_sequence(preds, gts, eval::Alignment::GlobalLogOffset)) CHECK(s.mse < 1e-9);
  // A gain in log space is not undone: the log-affine fit removes it, the offset-only one does not.
  for (auto& p : preds)
    for (auto& v : p.data) v = static_cast<float>(std::exp(0.7 * std::log(v + eval::kLogEps)) - eval::kLogEps);
  CHECK(eval::mean(eval::score_sequence(preds, gts, eval::Alignment::GlobalLogOffset)).mse > 1e-4);
  CHECK(eval::mean(eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine)).mse < 1e-6);
  CHECK(eval::parse_alignment("global-log-offset") == eval::Alignment::GlobalLogOffset);
  CHECK(std::string(eval::to_string(eval::Alignment::GlobalLogOffset)) == "global-log-offset");
}

TEST_CASE(
    "flat frames: the log-affine and offset-only fits bring them to the views' mean log brightness per channel, below a true render") {
  std::vector<Image> gts;
  for (int f = 0; f < 3; ++f) {
    const Image g = det(24, 16, 0.1 + 0.2 * f, 0.5);
    Image gt(24, 16, 3);
    for (std::size_t i = 0; i < g.pixels(); ++i)
      for (int c = 0; c < 3; ++c) gt.data[3 * i + c] = (0.2f + 0.3f * c) * g.data[i];
    gts.push_back(gt);
  }
  const auto flat = eval::flat_frames(gts);
  CHECK(flat.name == "flat");
  REQUIRE(flat.images.size() == gts.size());
  CHECK(flat.images[1].channels == 3);
  // The level each channel should get: exp(mean of log(x + ε) over every pixel of every view) − ε.
  double level[3] = {0, 0, 0};
  for (const auto& g : gts)
    for (std::size_t i = 0; i < g.data.size(); ++i) level[i % 3] += std::log(g.data[i] + eval::kLogEps);
  const double n = static_cast<double>(gts.size() * gts[0].pixels());
  for (auto al : {eval::Alignment::GlobalLogAffine, eval::Alignment::GlobalLogOffset}) {
    const auto s = eval::score_methods({flat, {"truth", gts}}, gts, al, true);
    for (const auto& im : s.aligned[0])
      for (std::size_t i = 0; i < im.data.size(); ++i)
        REQUIRE(im.data[i] == doctest::Approx(std::exp(level[i % 3] / n) - eval::kLogEps).epsilon(1e-5));
    CHECK(eval::mean(s.per_frame[0]).psnr < 40);
    CHECK(eval::mean(s.per_frame[1]).psnr > 60);
  }
}

TEST_CASE("HDR scoring: the truth's log range is put on [0, 1], a known map is undone, clipping is seen") {
  // Linear truth spanning 9 nats (1e-4 .. 0.8); a prediction that is a power law of it (exact in log space
  // when the offset is negligible) scores perfectly under the sequence fit, and the same prediction clipped
  // at 1 after a gain of 20 (what a frame does to highlights) scores worse.
  std::vector<Image> gts, preds, clipped;
  for (int f = 0; f < 3; ++f) {
    Image g = det(32, 24, 0.21 + 0.04 * f, 0.33);
    for (auto& v : g.data) v = static_cast<float>(1e-4 * std::exp(9.0 * (v - 0.1) / 0.8));
    Image p = g, q = g;
    for (std::size_t i = 0; i < g.data.size(); ++i) {
      p.data[i] = static_cast<float>(3.0 * std::pow(double(g.data[i]), 0.7));
      q.data[i] = std::min(1.0f, 20.0f * g.data[i]);
    }
    gts.push_back(g);
    preds.push_back(p);
    clipped.push_back(q);
  }
  const auto tone = eval::HdrTone::of(gts, 1e-9);
  float lo = 1, hi = 0;
  for (const auto& g : gts)
    for (float v : g.data) {
      lo = std::min(lo, tone(v));
      hi = std::max(hi, tone(v));
    }
  CHECK(lo == 0.0f);  // the extreme 0.1 % at each end sits at the ends
  CHECK(hi == 1.0f);
  std::size_t n = 0, inside = 0;
  for (const auto& g : gts)
    for (float v : g.data) {
      ++n;
      inside += tone(v) > 0.0f && tone(v) < 1.0f;
    }
  CHECK(inside >= n * 99 / 100);
  for (const auto& s : eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine, nullptr, &tone)) CHECK(s.psnr > 80);
  for (const auto& s : eval::score_sequence(preds, gts, eval::Alignment::LogAffine, nullptr, &tone)) CHECK(s.psnr > 80);
  const double clip = eval::mean(eval::score_sequence(clipped, gts, eval::Alignment::GlobalLogAffine, nullptr, &tone)).psnr;
  CHECK(clip < 40);
  // Without the HDR path the same (unclipped) prediction cannot be scored against linear truth above 1:
  // the LDR fit clips its output to [0, 1].
  std::vector<Image> bright = gts;
  for (auto& g : bright)
    for (auto& v : g.data) v *= 4.0f;
  const double ldr = eval::mean(eval::score_sequence(preds, bright, eval::Alignment::GlobalLogAffine)).psnr;
  const auto tone4 = eval::HdrTone::of(bright, 1e-9);
  const double hdr = eval::mean(eval::score_sequence(preds, bright, eval::Alignment::GlobalLogAffine, nullptr, &tone4)).psnr;
  CHECK(hdr > 80);
  CHECK(ldr < hdr);
  CHECK_THROWS_WITH(eval::HdrTone::of({Image(4, 4, 1)}, 1e-4), doctest::Contains("no range"));
}

TEST_CASE("gaussian_blur keeps constants, spreads an impulse symmetrically with unit mass, and refuses sigma <= 0") {
  const Image flat(17, 13, 2, 0.4f);
  const Image b = eval::gaussian_blur(flat, 3.0);
  for (float v : b.data) CHECK(v == doctest::Approx(0.4f).epsilon(1e-5));
  Image imp(41, 41, 1, 0.f);
  imp.at(20, 20) = 1.f;
  const Image g = eval::gaussian_blur(imp, 2.0);
  double sum = 0;
  for (float v : g.data) sum += v;
  CHECK(sum == doctest::Approx(1.0).epsilon(1e-5));
  CHECK(g.at(17, 20) == doctest::Approx(g.at(23, 20)));
  CHECK(g.at(20, 17) == doctest::Approx(g.at(20, 23)));
  CHECK(g.at(20, 20) > g.at(21, 20));
  // Against the continuous Gaussian's ratio between neighbours (kernel normalised, so ratios are exact).
  CHECK(g.at(21, 20) / g.at(20, 20) == doctest::Approx(std::exp(-0.5 / 4.0)).epsilon(1e-4));
  CHECK_THROWS_AS(eval::gaussian_blur(flat, 0.0), Error);
}

TEST_CASE("error_scales: a brightness offset is coarse error, a pixel-scale pattern is fine error, and the parts add up") {
  const Image truth = det(64, 48, 0.2, 0.3);
  Image offset = truth, pattern = truth, both = truth;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const float c = ((x + y) % 2 ? 0.05f : -0.05f);
      offset.at(x, y) += 0.1f;
      pattern.at(x, y) += c;
      both.at(x, y) += 0.1f + c;
    }
  const auto o = eval::error_scales(offset, truth);
  CHECK(o.coarse_mse == doctest::Approx(0.01).epsilon(1e-4));
  CHECK(o.fine_mse < 1e-10);
  CHECK(o.coarse_psnr() == doctest::Approx(20.0).epsilon(1e-4));
  const auto p = eval::error_scales(pattern, truth);
  CHECK(p.fine_mse == doctest::Approx(0.0025).epsilon(0.02));
  CHECK(p.coarse_psnr() > 50);  // a 1-px checker averages out (the borders' reflection leaves a trace)
  const auto b = eval::error_scales(both, truth);
  CHECK(b.coarse_mse + b.fine_mse == doctest::Approx(eval::mse(both, truth)).epsilon(1e-3));
  CHECK(eval::error_scales(truth, truth).coarse_psnr() == INFINITY);
  CHECK_THROWS_AS(eval::error_scales(truth, Image(3, 3, 1)), Error);
}

TEST_CASE("fine_error_by_depth: a pixel-scale error on the near pixels lands in the near band, and the bands add up") {
  // Left third of the image 1 m away, middle 3 m, right 6 m; a 1-px checker error on the near third only,
  // then on every pixel.
  const int W = 48, H = 32;
  const Image truth = det(W, H, 0.2, 0.3);
  Image near_err = truth, all_err = truth;
  std::vector<float> depth(static_cast<std::size_t>(W) * H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float c = ((x + y) % 2 ? 0.05f : -0.05f);
      depth[static_cast<std::size_t>(y) * W + x] = x < 16 ? 1.0f : x < 32 ? 3.0f : 6.0f;
      if (x < 12) near_err.at(x, y) += c;  // away from the band's border, where the blur mixes bands
      all_err.at(x, y) += c;
    }
  const std::vector<std::vector<float>> d{depth, depth};
  const auto n = eval::fine_error_by_depth({near_err, near_err}, {truth, truth}, d, 7.0);
  REQUIRE(n.edges.size() == 4);
  CHECK(n.edges == std::vector<double>{1.0, 3.0, 6.0, 6.0});
  for (const double s : n.pixel_share) CHECK(s == doctest::Approx(1.0 / 3));
  CHECK(n.fine_mse[0] == doctest::Approx(0.0025 * 12 / W).epsilon(0.05));
  CHECK(n.fine_mse[1] < 1e-3 * n.fine_mse[0]);
  CHECK(n.fine_mse[2] < 1e-6);
  // Every pixel in error: the bands add up to the whole fine MSE.
  const auto a = eval::fine_error_by_depth({all_err}, {truth}, {depth}, 7.0);
  const auto whole = eval::error_scales(all_err, truth);
  CHECK(a.fine_mse[0] + a.fine_mse[1] + a.fine_mse[2] == doctest::Approx(whole.fine_mse).epsilon(1e-9));
  // Depths that are not finite or not nearer than far count in no band; none usable gives no bands.
  std::vector<float> holes = depth;
  for (int y = 0; y < H; ++y) holes[static_cast<std::size_t>(y) * W + W - 1] = INFINITY;
  for (int y = 0; y < H; ++y) holes[static_cast<std::size_t>(y) * W] = 7.5f;
  const auto h = eval::fine_error_by_depth({all_err}, {truth}, {holes}, 7.0);
  CHECK(h.pixel_share[0] + h.pixel_share[1] + h.pixel_share[2] == doctest::Approx(double(W - 2) / W));
  CHECK(eval::fine_error_by_depth({truth}, {truth}, {std::vector<float>(depth.size(), 9.0f)}, 7.0).edges.empty());
  CHECK_THROWS_WITH_AS(eval::fine_error_by_depth({truth}, {truth}, {std::vector<float>(5, 1.0f)}, 7.0),
                       doctest::Contains("5 values for 1536 pixels"), Error);
  CHECK_THROWS_AS(eval::fine_error_by_depth({truth}, {truth, truth}, d, 7.0), Error);
}

TEST_CASE("error_scales: the row and column parts are the error's row and column means") {
  // Error = f(y) + g(x) with f and g of zero mean: every row's mean error is f(y), every column's g(x).
  const int W = 40, H = 30;
  const Image truth = det(W, H, 0.2, 0.3);
  Image pred = truth;
  double f2 = 0, g2 = 0;
  auto f = [](int y) { return 0.02 * std::cos(2 * std::numbers::pi * (y + 0.5) / 30.0) + (y % 2 ? 0.01 : -0.01); };
  auto g = [](int x) { return 0.03 * std::sin(2 * std::numbers::pi * (x + 0.5) / 40.0); };
  for (int y = 0; y < H; ++y) f2 += f(y) * f(y) / H;
  for (int x = 0; x < W; ++x) g2 += g(x) * g(x) / W;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) pred.at(x, y) = static_cast<float>(truth.at(x, y) + f(y) + g(x));
  const auto e = eval::error_scales(pred, truth);
  CHECK(e.row_mse == doctest::Approx(f2).epsilon(1e-4));
  CHECK(e.column_mse == doctest::Approx(g2).epsilon(1e-4));
  CHECK(e.row_psnr() == doctest::Approx(10 * std::log10(1 / f2)).epsilon(1e-4));
  // A pattern with zero mean along every row and every column has neither part; the exact prediction neither.
  Image checker = truth;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) checker.at(x, y) += ((x + y) % 2 ? 0.05f : -0.05f);
  const auto c = eval::error_scales(checker, truth);
  CHECK(c.row_mse < 1e-12);
  CHECK(c.column_mse < 1e-12);
  CHECK(eval::error_scales(truth, truth).row_psnr() == INFINITY);
  // Per channel: opposite offsets in two channels do not cancel.
  Image rgb(4, 3, 3), rgb_pred(4, 3, 3);
  for (std::size_t i = 0; i < rgb.pixels(); ++i) {
    rgb_pred.data[i * 3] = 0.1f;
    rgb_pred.data[i * 3 + 1] = -0.1f;
  }
  CHECK(eval::error_scales(rgb_pred, rgb).row_mse == doctest::Approx(0.02 / 3).epsilon(1e-5));
}

TEST_CASE("offset_oracle: recovers log offsets per row, per column and both, constant over the sequence, per channel") {
  const int W = 40, H = 30, C = 3;
  auto truth_frame = [&](double phase) {  // values in [0.2, 0.7]: no offset below pushes one past [0, 1]
    Image im(W, H, C);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (int c = 0; c < C; ++c)
          im.data[(static_cast<std::size_t>(y) * W + x) * C + c] =
              static_cast<float>(0.45 + 0.25 * std::sin(0.3 * x + 0.2 * y + phase + c) * std::cos(0.17 * y - 0.1 * x));
    return im;
  };
  const std::vector<Image> truths{truth_frame(0), truth_frame(1.3), truth_frame(2.1)};
  auto f = [](int y, int c) { return 0.1 * std::cos(0.4 * y + c) + (c == 1 ? 0.05 : -0.03); };
  auto g = [](int x, int c) { return 0.08 * std::sin(0.3 * x - c); };
  // Predictions whose log differs from the truth's by wr·f(row) + wc·g(column) (+ a per-frame part).
  auto predict = [&](double wr, double wc, double per_frame) {
    std::vector<Image> out;
    for (std::size_t k = 0; k < truths.size(); ++k) {
      Image p = truths[k];
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          for (int c = 0; c < C; ++c) {
            auto& v = p.data[(static_cast<std::size_t>(y) * W + x) * C + c];
            const double o = wr * f(y, c) + wc * g(x, c) + per_frame * (k == 1 ? 0.1 : -0.05) * std::cos(0.5 * y);
            v = static_cast<float>(std::exp(std::log(v + eval::kLogEps) + o) - eval::kLogEps);
          }
      out.push_back(std::move(p));
    }
    return out;
  };
  double base = 0;
  const auto rows = predict(1, 0, 0), cols = predict(0, 1, 0), both = predict(1, 1, 0);
  for (std::size_t k = 0; k < truths.size(); ++k) base += eval::psnr(both[k], truths[k]) / truths.size();
  REQUIRE(base < 30);
  const auto r = eval::offset_oracle(rows, truths), c = eval::offset_oracle(cols, truths), b = eval::offset_oracle(both, truths);
  CHECK(r.rows_psnr > 90);  // float rounding only
  CHECK(r.columns_psnr < 40);
  CHECK(r.both_psnr > 90);
  CHECK(c.columns_psnr > 90);
  CHECK(c.rows_psnr < 40);
  CHECK(c.both_psnr > 90);
  CHECK(b.both_psnr > 90);
  CHECK(b.rows_psnr < 40);
  CHECK(b.columns_psnr < 40);
  // Row offsets that change from frame to frame are not what one offset per row over the sequence removes.
  const auto moving = eval::offset_oracle(predict(1, 0, 1), truths);
  CHECK(moving.rows_psnr < 50);
  CHECK(moving.rows_psnr > base);
  // The exact prediction stays exact; mismatched inputs are refused.
  CHECK(eval::offset_oracle(truths, truths).both_psnr == INFINITY);
  CHECK_THROWS_AS(eval::offset_oracle({truths[0]}, truths), Error);
  CHECK_THROWS_AS(eval::offset_oracle({Image(3, 3, 3)}, {truths[0]}), Error);
}

TEST_CASE("error_scales_json: per method from the primary alignment's aligned images, refused without them") {
  const Image truth = det(32, 24, 0.2, 0.3);
  Image mapped = truth;  // an affine map in log(x + ε): undone by the fit up to rounding
  for (auto& v : mapped.data) v = static_cast<float>(std::exp(0.5 * std::log(v + 1e-3) - 0.7) - 1e-3);
  eval::Method exact{"exact", {truth, truth}}, gain{"gain", {mapped, mapped}};
  const auto a = eval::score_methods({exact, gain}, {truth, truth}, eval::Alignment::GlobalLogAffine, true);
  const auto j = eval::error_scales_json(a, {truth, truth});
  CHECK(j.at("sigma_px").get<double>() == eval::kErrorScaleSigma);
  const auto& exact_coarse = j.at("methods").at("exact").at("coarse_psnr");  // rounding only (null if none at all)
  CHECK((exact_coarse.is_null() || exact_coarse.get<double>() > 100));
  CHECK(j.at("methods").at("gain").at("fine_psnr").get<double>() > 60);
  CHECK(j.at("methods").at("gain").at("coarse_psnr").get<double>() > 60);
  CHECK(j.at("methods").at("gain").at("row_psnr").get<double>() > 60);
  CHECK(j.at("methods").at("gain").contains("column_mse"));
  CHECK(j.at("methods").at("gain").at("oracle_both_psnr").get<double>() > 60);
  CHECK(j.at("methods").at("gain").contains("oracle_rows_psnr"));
  CHECK(j.at("methods").at("gain").contains("oracle_columns_psnr"));
  const auto kept_not = eval::score_methods({exact}, {truth, truth}, eval::Alignment::GlobalLogAffine, false);
  CHECK_THROWS_AS(eval::error_scales_json(kept_not, {truth, truth}), Error);
}

TEST_CASE("export: a PLY file round-trips, and a file of another shape is refused by line or byte") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("evnerf_ply_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  io::PlyVertices v;
  v.names = {"x", "y", "z"};
  v.floats = {1.5f, -2.f, 3.25f, 0.f, -0.f, 1e-30f};
  v.colour = true;
  v.rgb = {0, 128, 255, 7, 8, 9};
  io::write_ply(dir / "a.ply", v, {"made by a test"});
  const auto back = io::read_ply(dir / "a.ply");
  CHECK(back.names == v.names);
  CHECK(back.floats == v.floats);
  CHECK(back.rgb == v.rgb);
  CHECK(back.colour);
  // No vertices: the header still declares the colours.
  v.floats.clear();
  v.rgb.clear();
  io::write_ply(dir / "none.ply", v);
  const auto none = io::read_ply(dir / "none.ply");
  CHECK(none.size() == 0);
  CHECK(none.colour);
  const std::string text = read_file(dir / "a.ply");
  CHECK(text.rfind("ply\nformat binary_little_endian 1.0\ncomment made by a test\nelement vertex 2\nproperty float x\n", 0) == 0);
  write_file_atomic(dir / "cut.ply", text.substr(0, text.size() - 1));
  CHECK_THROWS_WITH(io::read_ply(dir / "cut.ply"), doctest::Contains("2 vertices of 15 bytes need 30 bytes, the file has 29"));
  write_file_atomic(dir / "ascii.ply", "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n");
  CHECK_THROWS_WITH(io::read_ply(dir / "ascii.ply"), doctest::Contains("ascii.ply:2: expected 'format binary_little_endian 1.0'"));
  write_file_atomic(dir / "double.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty double x\nend_header\n");
  CHECK_THROWS_WITH(io::read_ply(dir / "double.ply"), doctest::Contains("double.ply:4: unsupported property"));
  write_file_atomic(dir / "open.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\n");
  CHECK_THROWS_WITH(io::read_ply(dir / "open.ply"), doctest::Contains("the header ends before end_header"));
  // Triangles: a face element after the vertices; a face of another size or naming a vertex beyond them is refused.
  io::PlyVertices t;
  t.names = {"x", "y", "z"};
  t.floats = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  t.faces = {{0, 1, 2}, {0, 2, 3}};
  io::write_ply(dir / "tri.ply", t);
  const auto tri = io::read_ply(dir / "tri.ply");
  CHECK(tri.faces == t.faces);
  CHECK(tri.floats == t.floats);
  std::string bytes = read_file(dir / "tri.ply");
  CHECK(bytes.find("element face 2\nproperty list uchar uint vertex_indices\nend_header\n") != std::string::npos);
  const std::size_t first_face = bytes.size() - 26;
  bytes[first_face + 1] = 9;  // face 0's first vertex: 9 of 4
  write_file_atomic(dir / "far.ply", bytes);
  const std::string far = "byte " + std::to_string(first_face) + ": face 0 names vertex 9 of 4";
  CHECK_THROWS_WITH(io::read_ply(dir / "far.ply"), doctest::Contains(far.c_str()));
  bytes[first_face + 1] = 0;
  bytes[first_face] = 4;
  write_file_atomic(dir / "quad.ply", bytes);
  CHECK_THROWS_WITH(io::read_ply(dir / "quad.ply"), doctest::Contains("face 0 has 4 vertices, not 3"));
  t.faces = {{0, 1, 4}};
  CHECK_THROWS_WITH(io::write_ply(dir / "bad.ply", t), doctest::Contains("a triangle names a vertex the file does not have"));
  CHECK_FALSE(fs::exists(dir / "bad.ply"));
  fs::remove_all(dir);
}

TEST_CASE("mesh: marching tetrahedra of a sphere is closed, faces outward, on the sphere, and holds its volume") {
  const double r = 0.8;
  const auto L =
      evaluation::lattice_over(Vec3::Constant(-1), Vec3::Constant(1), 40, [&](const std::vector<Vec3>& p, std::vector<float>& v) {
        v.resize(p.size());
        for (std::size_t i = 0; i < p.size(); ++i) v[i] = static_cast<float>(r - p[i].norm());  // inside: positive
      });
  CHECK(L.n == std::array<int, 3>{41, 41, 41});
  CHECK(L.spacing == doctest::Approx(0.05));
  const auto m = evaluation::marching_tetrahedra(L, 0.0);
  REQUIRE(m.triangles.size() > 1000);
  for (const auto& v : m.vertices) CHECK(std::abs(v.norm() - r) < 0.01);
  // Closed and consistently oriented: every directed edge once, and its reverse once.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  double volume = 0;
  int inward = 0;  // a triangle whose vertices coincide (a lattice value exactly at the level) faces nowhere
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
    const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
    volume += a.dot(b.cross(c)) / 6;
    inward += (b - a).cross(c - a).dot(a + b + c) < -1e-12;
  }
  bool closed = true;
  for (const auto& [e, n] : edges) closed = closed && n == 1 && edges.count({e.second, e.first}) == 1;
  CHECK(closed);
  CHECK(inward == 0);
  CHECK(volume == doctest::Approx(4.0 / 3.0 * std::numbers::pi * r * r * r).epsilon(0.02));
  // Nothing to cut: no triangle.
  CHECK(evaluation::marching_tetrahedra(L, 5.0).triangles.empty());
  CHECK(evaluation::marching_tetrahedra(L, -5.0).triangles.empty());
}

TEST_CASE("mesh: a field's surface at the density its points sit in, inside their region, coloured as the field shows it") {
  // A ball around (1, 0, 0) whose density falls linearly from 1000 at the centre to 0 at radius 0.5, whose
  // luminance is the height y + 1 (a second channel twice it); its points on the sphere of radius 0.4 (density
  // 200) and one stray point far off, whose density is 0.
  evaluation::FieldProbe f;
  f.channels = 3;
  f.density_length = 2;
  const Vec3 centre(1, 0, 0);
  f.at = [&](const std::vector<Vec3>& p, const std::vector<Vec3>& d, std::vector<float>& sigma, std::vector<float>& lum) {
    REQUIRE(d.size() == p.size());
    sigma.resize(p.size());
    lum.resize(3 * p.size());
    for (std::size_t i = 0; i < p.size(); ++i) {
      sigma[i] = static_cast<float>(1000 * std::max(0.0, 1 - (p[i] - centre).norm() / 0.5));
      for (int c = 0; c < 3; ++c) lum[3 * i + c] = static_cast<float>((c + 1) * (p[i].y() + 1));
    }
  };
  std::vector<Vec3> cloud;
  for (int k = 0; k < 200; ++k) {
    const double u = k * 2.399963, z = 1 - 2 * (k + 0.5) / 200;  // a Fibonacci sphere's points
    cloud.push_back(centre + 0.4 * Vec3(std::cos(u) * std::sqrt(1 - z * z), std::sin(u) * std::sqrt(1 - z * z), z));
  }
  cloud.push_back(Vec3(40, 40, 40));  // a stray point is not in the region
  const auto [lo, hi] = evaluation::robust_bounds(cloud);
  CHECK(hi.x() < 2);
  std::vector<float> lum;
  const auto m = evaluation::field_mesh(f, cloud, {Vec3(1, 0, -3)}, 48, 0.5, lum);
  REQUIRE(m.vertices.size() > 100);
  REQUIRE(lum.size() == 3 * m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    CHECK(std::abs((m.vertices[i] - centre).norm() - 0.4) < 0.01);  // the level of the points' median density, 200
    CHECK(lum[3 * i + 1] == doctest::Approx(2 * (m.vertices[i].y() + 1)));
  }
  const auto ply = evaluation::mesh_ply(m, lum, 3);
  CHECK(ply.faces == m.triangles);
  CHECK(ply.names == std::vector<std::string>{"x", "y", "z", "luminance"});
  // A higher quantile, a denser level: a smaller sphere. Nothing above the level: no surface.
  const auto inner = evaluation::field_mesh(f, cloud, {Vec3(1, 0, -3)}, 48, 1.0, lum);
  REQUIRE(!inner.vertices.empty());
  for (const auto& v : inner.vertices) CHECK((v - centre).norm() < 0.41);
  std::vector<Vec3> stray(10, Vec3(40, 40, 40));
  CHECK(evaluation::field_mesh(f, stray, {Vec3::Zero()}, 8, 0.5, lum).triangles.empty());
  CHECK_THROWS_WITH(evaluation::field_mesh(evaluation::FieldProbe{}, cloud, {Vec3::Zero()}, 8, 0.5, lum), doctest::Contains("not a field"));
  CHECK_THROWS_WITH(evaluation::lattice_over(lo, hi, 0, [](const std::vector<Vec3>&, std::vector<float>&) {}),
                    doctest::Contains("between 1 and 1024 cells"));
}

TEST_CASE("export: a point cloud lies where the rendered depth puts it, the cameras in nerfstudio's convention") {
  // A model that renders a plane at z-depth 2 in front of every camera, opaque on the left half only.
  io::CheckpointRun m;
  const geometry::Camera cam(8, 6, 10, 10, 4, 3);
  m.camera = cam;
  geometry::Pose a, b;
  b.t = Vec3(1, 0, 0);
  b.q = Quat(Eigen::AngleAxisd(0.3, Vec3::UnitY()));
  m.poses = {a, b};
  m.times = {0.0, 0.5};
  const auto plane = [](const geometry::Pose&) {
    Rendering r{Image(8, 6, 1, 0.25f), Image(8, 6, 1, 0.f), Image(8, 6, 1, 0.f)};
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 4; ++x) {
        r.opacity.at(x, y) = 0.95f;
        r.depth.at(x, y) = 2.f * 0.95f;  // the expected depth times the opacity, as the compositing gives it
      }
    return r;
  };
  const auto pts = evaluation::point_cloud(m, plane, 1, 1, 0.9, 0.5);
  REQUIRE(pts.size() == 2 * 4 * 6);
  REQUIRE(pts.names == std::vector<std::string>{"x", "y", "z", "luminance"});
  const auto dirs = render::pixel_directions(cam);
  std::size_t i = 0;
  for (const auto& pose : m.poses)
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 4; ++x, ++i) {
        const Vec3 want = pose.t + pose.q * (dirs[static_cast<std::size_t>(y) * 8 + x].cast<double>() * 2.0);
        const Vec3 got(pts.floats[4 * i], pts.floats[4 * i + 1], pts.floats[4 * i + 2]);
        CHECK((got - want).norm() < 1e-5);
        CHECK((pose.q.conjugate() * (got - pose.t)).z() == doctest::Approx(2.0).epsilon(1e-6));  // on the plane
        CHECK(pts.rgb[3 * i] == 128);                                                            // 0.25 of a white of 0.5
      }
  CHECK_THROWS_WITH(evaluation::point_cloud(m, plane, 0), doctest::Contains("strides must be at least 1"));
  // transforms.json: OpenCV intrinsics, and each camera-to-world with y and z flipped (OpenGL's axes).
  const auto j = evaluation::transforms_json(m);
  CHECK(j["camera_model"] == "OPENCV");
  CHECK(j["fl_x"] == 10.0);
  CHECK(j["w"] == 8);
  REQUIRE(j["frames"].size() == 2);
  CHECK(j["frames"][1]["file_path"] == "boundary_0001.png");
  CHECK(j["frames"][1]["time"] == 0.5);
  const auto& t = j["frames"][1]["transform_matrix"];
  const Mat3 R = b.q.toRotationMatrix();
  for (int r = 0; r < 3; ++r) {
    CHECK(t[r][0].get<double>() == doctest::Approx(R(r, 0)));
    CHECK(t[r][1].get<double>() == doctest::Approx(-R(r, 1)));
    CHECK(t[r][2].get<double>() == doctest::Approx(-R(r, 2)));
    CHECK(t[r][3].get<double>() == doctest::Approx(b.t[r]));
  }
  CHECK(t[3][3].get<double>() == 1.0);
}

TEST_CASE("view: a frame request read from a query, and a session's info, tone and frames") {
  using view::parse_frame_request;
  std::map<std::string, std::string> q;
  const auto param = [&q](const std::string& k) -> std::optional<std::string> {
    const auto it = q.find(k);
    return it == q.end() ? std::nullopt : std::optional<std::string>(it->second);
  };
  geometry::Pose p;
  p.q = Quat(Eigen::AngleAxisd(0.4, Vec3(1, 2, 3).normalized()));
  p.t = Vec3(0.5, -1, 2);
  std::string numbers;
  for (const double v : view::pose_numbers(p)) {
    char b[32];
    std::snprintf(b, sizeof b, "%.17g", v);
    numbers += (numbers.empty() ? "" : ",") + std::string(b);
  }
  q["pose"] = numbers;
  auto r = parse_frame_request(param);
  CHECK(r.pose.q.angularDistance(p.q) < 1e-9);
  CHECK((r.pose.t - p.t).norm() < 1e-12);
  CHECK(r.scale == 1);
  CHECK(!r.depth);
  q["scale"] = "4";
  q["show"] = "depth";
  r = parse_frame_request(param);
  CHECK(r.scale == 4);
  CHECK(r.depth);
  const auto refused = [&](const char* key, const std::string& value, const char* words) {
    auto bad = q;
    bad[key] = value;
    std::swap(bad, q);
    CHECK_THROWS_WITH(parse_frame_request(param), doctest::Contains(words));
    std::swap(bad, q);
  };
  refused("pose", "1,0,0,0,0,1,0,0,0,0,1", "twelve numbers");
  refused("pose", "1,0,0,0,0,1,0,0,0,0,1,0,5", "twelve numbers");
  refused("pose", "1,0,0,0,0,1,0,0,0,0,1,x", "pose value 12 'x'");
  refused("pose", "1,0,0,0,0,1,0,0,0,0,1,inf", "not a finite number");
  refused("pose", "-1,0,0,0,0,1,0,0,0,0,1,0", "not a rotation");
  refused("pose", "2,0,0,0,0,1,0,0,0,0,1,0", "not a rotation");
  refused("scale", "0", "scale '0'");
  refused("scale", "17", "scale '17'");
  refused("scale", "2.5", "scale '2.5'");
  refused("show", "colour", "show 'colour'");
  q.erase("pose");
  CHECK_THROWS_WITH(parse_frame_request(param), doctest::Contains("no pose"));

  // A scene that renders a horizontal ramp of luminance at depth 2, opaque where x < width / 2.
  evaluation::Renderable m;
  m.name = "ramp";
  m.desc.camera = geometry::Camera(16, 12, 20, 20, 8, 6);
  m.desc.poses = {geometry::Pose{}, p};
  m.desc.times = {0.0, 1.0};
  m.near = 0.5;
  m.far = 5;
  float peak = 0.8f;
  m.render_with = [&peak](const geometry::Camera& cam, const geometry::Pose&) {
    render::Rendering out{Image(cam.width(), cam.height(), 1), Image(cam.width(), cam.height(), 1), Image(cam.width(), cam.height(), 1)};
    for (int y = 0; y < cam.height(); ++y)
      for (int x = 0; x < cam.width(); ++x) {
        out.luminance.at(x, y) = peak * static_cast<float>(x + 1) / static_cast<float>(cam.width());
        out.opacity.at(x, y) = x < cam.width() / 2 ? 1.f : 0.f;
        out.depth.at(x, y) = 2.f * out.opacity.at(x, y);
      }
    return out;
  };
  const view::Session s(m);
  const auto info = s.info();
  CHECK(info["width"] == 16);
  CHECK(info["kind"] == "field");
  CHECK(info["moving_scale"] == 2);
  CHECK(info["focus"].get<double>() == doctest::Approx(2.0));
  CHECK(info["tone"]["kind"] == "clamp");
  REQUIRE(info["recorded"].size() == 2);
  CHECK(info["recorded"][1].get<std::vector<double>>() == view::pose_numbers(p));
  CHECK(info["novel"].size() == view::Session::kNovelViews);
  // Up on the page: the first camera's −y in the world (the identity's: −y).
  CHECK(info["up"].get<std::vector<double>>() == std::vector<double>{0.0, -1.0, 0.0});
  // Frames at the requested resolution, toned as info says; JPEG bytes that decode to the same image.
  view::FrameRequest fr;
  fr.scale = 2;
  const Image img = s.image(fr);
  CHECK(img.width == 8);
  CHECK(img.height == 6);
  CHECK(img.at(7, 0) == doctest::Approx(0.8));
  const auto f = s.frame(fr);
  CHECK(f.width == 8);
  int w = 0, h = 0, c = 0;
  unsigned char* px =
      stbi_load_from_memory(reinterpret_cast<const unsigned char*>(f.jpeg.data()), static_cast<int>(f.jpeg.size()), &w, &h, &c, 1);
  REQUIRE(px != nullptr);
  CHECK(w == 8);
  CHECK(h == 6);
  double err = 0;
  for (int i = 0; i < w * h; ++i) err += std::abs(px[i] / 255.0 - img.data[static_cast<std::size_t>(i)]);
  stbi_image_free(px);
  CHECK(err / (w * h) < 0.02);
  fr.depth = true;
  const Image d = s.image(fr);
  CHECK(d.channels == 3);
  // Brighter than 1 somewhere: the log tone of the sampled views, fixed for the session.
  peak = 4.f;
  const view::Session bright(m);
  REQUIRE(bright.tone().has_value());
  CHECK(bright.info()["tone"]["kind"] == "log");
  fr.depth = false;
  const Image t = bright.image(fr);
  CHECK(t.at(7, 0) == doctest::Approx(1.0));
  CHECK(t.at(0, 0) < 0.1f);
  m.render_with = nullptr;
  CHECK_THROWS_WITH(view::Session{m}, doctest::Contains("view takes a model.ckpt"));
}
