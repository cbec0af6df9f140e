#include <array>
#include <cmath>
#include <vector>

#include <evnerf/field/field.hpp>
#include <evnerf/loss/distortion.hpp>
#include <evnerf/loss/event_loss.hpp>
#include <evnerf/render/compositing.hpp>
#include <evnerf/render/occupancy.hpp>
#include <evnerf/render/sampler.hpp>

#include "common.hpp"

using namespace evnerf;

namespace {
/// One ray of S samples with C channels drawn from `seed` (densities in [−0.5, sigma_hi), luminance, depths,
/// density noise) and a random dL/dcolor.
struct RandomRay {
  int S, C;
  std::vector<double> sigma, raw, t, noise, dcolor;
  RandomRay(int s, int c, std::uint64_t seed, double sigma_hi) : S(s), C(c), sigma(s), raw(s * c), t(s), noise(s), dcolor(c) {
    Rng rng(seed);
    for (int k = 0; k < S; ++k) {
      sigma[k] = rng.uniform(-0.5, sigma_hi);
      t[k] = 0.5 + 0.3 * k + 0.1 * rng.uniform();
      noise[k] = 0.3 * rng.normal();
    }
    for (auto& v : raw) v = rng.uniform(-2, 2);
    for (auto& v : dcolor) v = rng.uniform(-1, 1);
  }
  /// The composite of densities `sg` and raw luminance `rw` (the ray's own by default) before `background`.
  template <class Act>
  render::RayComposite<double> composite(const double* background, const std::vector<double>* sg = nullptr,
                                         const std::vector<double>* rw = nullptr) const {
    render::RayComposite<double> r;
    render::composite_forward<double, Act>(S, C, (sg ? *sg : sigma).data(), 1, (rw ? *rw : raw).data(), t.data(), 1.2, noise.data(), r,
                                           nullptr, background);
    return r;
  }
  /// composite_backward's dL/dσ and dL/draw for L = dcolor · color, against finite differences in double.
  template <class Act>
  void check_gradients(const double* background) const {
    auto loss = [&](const std::vector<double>& sg, const std::vector<double>& rw) {
      const auto r = composite<Act>(background, &sg, &rw);
      double s = 0;
      for (int c = 0; c < C; ++c) s += dcolor[c] * r.color[c];
      return s;
    };
    const auto r = composite<Act>(background);
    std::vector<double> ds(S), dr(S * C);
    render::composite_backward<double>(S, C, r, dcolor.data(), ds.data(), 1, dr.data());
    CHECK(evtest::max_fd_error([&](const std::vector<double>& v) { return loss(v, raw); }, sigma, ds) < 1e-6);
    CHECK(evtest::max_fd_error([&](const std::vector<double>& v) { return loss(sigma, v); }, raw, dr) < 1e-6);
  }
};
}  // namespace

TEST_CASE_TEMPLATE("compositing: finite-difference check of colour w.r.t. densities and raw luminance", Act, nn::ReLU, nn::TruncExp) {
  const RandomRay q(9, 2, 3, 3.0);
  q.check_gradients<Act>(nullptr);
  const auto r = q.composite<Act>(nullptr);
  // Weights sum to the opacity, and an opaque last interval makes it 1.
  double wsum = 0;
  for (double w : r.weight) wsum += w;
  CHECK(wsum == doctest::Approx(r.opacity));
  CHECK(r.opacity <= 1.0 + 1e-9);
}

TEST_CASE_TEMPLATE("compositing before a background: finite differences, an empty ray shows the background, an opaque one hides it", Act,
                   nn::ReLU, nn::TruncExp) {
  const RandomRay q(9, 3, 4, 1.0);
  const int S = q.S, C = q.C;
  const std::vector<double> bg = {0.3, 0.5, 0.9};
  q.check_gradients<Act>(bg.data());
  const auto r = q.composite<Act>(bg.data());
  // The last interval is closed: light is left for the background, and the colour is the samples' plus its share.
  REQUIRE(r.rest > 0.01);
  CHECK(r.opacity + r.rest == doctest::Approx(1.0));
  for (int c = 0; c < C; ++c) {
    double samples = 0;
    for (int k = 0; k < S; ++k) samples += r.weight[k] * r.lum[k * C + c];
    CHECK(r.color[c] == doctest::Approx(samples + r.rest * bg[c]).epsilon(1e-12));
  }
  // Without a background the same samples differ (the last interval is open) and r.rest is 0.
  const auto open = q.composite<Act>(nullptr);
  CHECK(open.rest == 0);
  CHECK(open.color[0] != r.color[0]);
  // A ray through empty space is the background, exactly where the activation is 0 (ReLU below 0).
  if constexpr (std::is_same_v<Act, nn::ReLU>) {
    const std::vector<double> empty(S, -3.0);
    const auto e = q.composite<Act>(bg.data(), &empty);
    for (int c = 0; c < C; ++c) CHECK(e.color[c] == doctest::Approx(bg[c]).epsilon(1e-9));
    CHECK(e.opacity == 0);
  }
  // An opaque first sample hides the background.
  std::vector<double> wall = q.sigma;
  wall[0] = 100;  // α = 1 − e^{−36} under ReLU (δ 0.36), truncated to e^{15}·δ under TruncExp
  const auto h = q.composite<Act>(bg.data(), &wall);
  CHECK(h.rest < 1e-9);
  for (int c = 0; c < C; ++c) CHECK(h.color[c] == doctest::Approx(h.lum[c]).epsilon(1e-6));
}

TEST_CASE("distortion regulariser: equals the double sum, its weight gradient and its density gradient match finite differences") {
  const int S = 11;
  Rng rng(7);
  std::vector<double> w(S), t(S), sigma(S), raw(S), noise(S, 0.0);
  double at = 0.4;
  for (int k = 0; k < S; ++k) {
    w[k] = rng.uniform();
    t[k] = at;
    at += 0.05 + 0.3 * rng.uniform();
    sigma[k] = rng.uniform(-0.5, 3.0);
    raw[k] = rng.uniform(-2, 2);
  }
  // The plain O(S²) definition over the same intervals.
  auto plain = [&](const std::vector<double>& ws) {
    const double span = t[S - 1] - t[0];
    auto mid = [&](int k) { return k + 1 < S ? 0.5 * (t[k] + t[k + 1]) / span : t[k] / span; };
    auto len = [&](int k) { return k + 1 < S ? (t[k + 1] - t[k]) / span : 0.0; };
    double l = 0;
    for (int i = 0; i < S; ++i) {
      for (int j = 0; j < S; ++j) l += ws[i] * ws[j] * std::abs(mid(i) - mid(j));
      l += ws[i] * ws[i] * len(i) / 3;
    }
    return l;
  };
  std::vector<double> g(S);
  const double l = loss::distortion_loss<double>(S, w.data(), t.data(), g.data());
  CHECK(l == doctest::Approx(plain(w)).epsilon(1e-12));
  CHECK(l > 0);
  CHECK(evtest::max_fd_error(plain, w, g) < 1e-7);
  // One weight alone: only its own interval's third is left; a point (the open interval) costs nothing.
  std::vector<double> one(S, 0.0), go(S);
  one[3] = 0.8;
  CHECK(loss::distortion_loss<double>(S, one.data(), t.data(), go.data()) == doctest::Approx(0.64 * (t[4] - t[3]) / (t[S - 1] - t[0]) / 3));
  std::fill(one.begin(), one.end(), 0.0);
  one[S - 1] = 1;
  CHECK(loss::distortion_loss<double>(S, one.data(), t.data(), go.data()) == 0);
  // Weights spread over the ray cost more than the same weight on one sample.
  std::vector<double> spread(S, 1.0 / S), g2(S);
  one.assign(S, 0.0);
  one[S / 2] = 1;
  CHECK(loss::distortion_loss<double>(S, spread.data(), t.data(), g2.data()) >
        loss::distortion_loss<double>(S, one.data(), t.data(), go.data()));
  // Through compositing: dL/dw passed as composite_backward's dweight gives dL/dσ.
  auto loss_of_sigma = [&](const std::vector<double>& sg) {
    render::RayComposite<double> r;
    render::composite_forward<double, nn::ReLU>(S, 1, sg.data(), 1, raw.data(), t.data(), 1.3, noise.data(), r);
    std::vector<double> gw(S);
    return loss::distortion_loss<double>(S, r.weight.data(), t.data(), gw.data()) + 0.7 * r.color[0];
  };
  render::RayComposite<double> r;
  render::composite_forward<double, nn::ReLU>(S, 1, sigma.data(), 1, raw.data(), t.data(), 1.3, noise.data(), r);
  std::vector<double> gw(S), ds(S), dr(S);
  loss::distortion_loss<double>(S, r.weight.data(), t.data(), gw.data());
  const double dcolor = 0.7;
  render::composite_backward<double>(S, 1, r, &dcolor, ds.data(), 1, dr.data(), gw.data());
  CHECK(evtest::max_fd_error(loss_of_sigma, sigma, ds) < 1e-6);
}

TEST_CASE_TEMPLATE("compositing: finite-difference check through each radiance activation", Radiance, field::SigmoidRadiance,
                   field::ExpRadiance) {
  const int S = 7, C = 1;
  Rng rng(5);
  std::vector<double> sigma(S), raw(S), t(S);
  for (int k = 0; k < S; ++k) {
    sigma[k] = rng.uniform(0.1, 2.0);
    t[k] = 0.5 + 0.3 * k;
    raw[k] = rng.uniform(-3, 3);
  }
  using RA = typename Radiance::activation;
  auto lum = [&](const std::vector<double>& rw) {
    render::RayComposite<double> r;
    render::composite_forward<double, nn::ReLU, RA>(S, C, sigma.data(), 1, rw.data(), t.data(), 1.0, nullptr, r);
    return std::log(r.color[0] + Radiance::log_eps);
  };
  render::RayComposite<double> r;
  render::composite_forward<double, nn::ReLU, RA>(S, C, sigma.data(), 1, raw.data(), t.data(), 1.0, nullptr, r);
  // Each sample's luminance is the activation of its raw output.
  for (int k = 0; k < S; ++k) CHECK(r.lum[k] == doctest::Approx(RA::f(raw[k])).epsilon(1e-12));
  const double dcolor = 1.0 / (r.color[0] + Radiance::log_eps);
  std::vector<double> ds(S), dr(S);
  render::composite_backward<double>(S, C, r, &dcolor, ds.data(), 1, dr.data());
  CHECK(evtest::max_fd_error(lum, raw, dr) < 1e-6);
}

TEST_CASE_TEMPLATE("compositing: the shortcut for unevaluated samples writes the same bits as evaluating them", T, float, double) {
  // Samples at the renderer's skipped density (raw luminance 0) among evaluated ones, in runs and alone,
  // the last one open; two channels; each density activation whose value and slope vanish there.
  const int S = 12, C = 2;
  const T skipped = T(-1e4);
  Rng rng(11);
  std::vector<T> sigma(S), raw(S * C), t(S);
  for (int k = 0; k < S; ++k) {
    const bool skip = k == 0 || k == 3 || k == 4 || k == 5 || k == 9 || k == S - 1;
    sigma[k] = skip ? skipped : T(rng.uniform(-0.5, 3.0));
    for (int c = 0; c < C; ++c) raw[k * C + c] = skip ? T(0) : T(rng.uniform(-2, 2));
    t[k] = T(0.4 + 0.25 * k + 0.1 * rng.uniform());
  }
  auto same = [](const render::RayComposite<T>& a, const render::RayComposite<T>& b) {
    return a.alpha == b.alpha && a.dalpha_dsigma == b.dalpha_dsigma && a.trans == b.trans && a.weight == b.weight && a.lum == b.lum &&
           a.dlum_draw == b.dlum_draw && a.color == b.color && a.depth == b.depth && a.opacity == b.opacity;
  };
  // Training's density noise: drawn for the evaluated samples, 0 for the skipped ones (where the shortcut
  // applies); evaluating every sample with any noise of the size a normal takes there gives the same bits.
  std::vector<T> noise(S), noise_everywhere(S);
  for (int k = 0; k < S; ++k) {
    noise_everywhere[k] = T(8 * rng.normal());
    noise[k] = sigma[k] == skipped ? T(0) : noise_everywhere[k];
  }
  noise_everywhere[0] = T(38);  // about the largest a Box–Muller normal of 53-bit uniforms can be
  noise_everywhere[3] = T(-38);
  auto check = [&](auto act) {
    using Act = decltype(act);
    render::RayComposite<T> plain, fast;
    render::composite_forward<T, Act, nn::TruncExp>(S, C, sigma.data(), 1, raw.data(), t.data(), T(1.3), nullptr, plain);
    render::composite_forward<T, Act, nn::TruncExp>(S, C, sigma.data(), 1, raw.data(), t.data(), T(1.3), nullptr, fast, &skipped);
    CHECK(same(plain, fast));
    CHECK(plain.opacity > T(0));
    render::RayComposite<T> noisy, noisy_fast;
    render::composite_forward<T, Act, nn::TruncExp>(S, C, sigma.data(), 1, raw.data(), t.data(), T(1.3), noise_everywhere.data(), noisy);
    render::composite_forward<T, Act, nn::TruncExp>(S, C, sigma.data(), 1, raw.data(), t.data(), T(1.3), noise.data(), noisy_fast,
                                                    &skipped);
    CHECK(same(noisy, noisy_fast));
    CHECK_FALSE(same(noisy, plain));  // the noise reaches the evaluated samples
  };
  check(nn::ReLU{});
  check(nn::TruncExp{});
  check(nn::Softplus{});
}

TEST_CASE("radiance policies: the sigmoid cannot render more than 6.9 nats of log change, exp radiance can") {
  // The log change between a fully dark and a fully bright sample: bounded by log(1 + ε) − log(ε) for the
  // sigmoid, unbounded (up to the e^15 cut) for exp radiance; an HDR scene asks for 8–9 nats.
  auto range = [](auto radiance, double lo, double hi) {
    using R = decltype(radiance);
    return std::log(R::activation::f(hi) + R::log_eps) - std::log(R::activation::f(lo) + R::log_eps);
  };
  CHECK(range(field::SigmoidRadiance{}, -40, 40) < 6.91);
  CHECK(range(field::ExpRadiance{}, -5, 5) > 9.9);
  CHECK(field::Field<nn::Frequency<1>, nn::Frequency<1>, nn::Mlp<9, 8, 1, 2, nn::ReLU, nn::Identity>,
                     nn::Mlp<1 + 9, 8, 1, 1, nn::ReLU, nn::Identity>, nn::ReLU, field::ExpRadiance>::architecture()
            .ends_with(", radiance exp"));
  // The paper's fields keep the architecture text older checkpoints recorded.
  CHECK(field::Field<nn::Frequency<1>, nn::Frequency<1>, nn::Mlp<9, 8, 1, 2, nn::ReLU, nn::Identity>,
                     nn::Mlp<1 + 9, 8, 1, 1, nn::ReLU, nn::Identity>>::architecture()
            .find("radiance") == std::string::npos);
}

TEST_CASE_TEMPLATE("direction encoding: SphericalHarmonics<1> makes the luminance view-independent, degree 2 does not", Dir,
                   nn::SphericalHarmonics<1>, nn::SphericalHarmonics<2>) {
  // presets::FastDiffuse is Fast with the degree-1 (constant) direction encoding: the same point seen along
  // other directions must give the same density and luminance, exactly; with degree 2 the luminance moves.
  using F = field::FieldOf<nn::HashGrid<4, 2, 10, 4, 32>, Dir, nn::MlpShape{.width = 8, .hidden_layers = 1}, 3,
                           nn::MlpShape{.width = 8, .hidden_layers = 1}, 1, nn::ReLU, nn::Fp32, nn::ReLU, field::ExpRadiance>;
  std::vector<float> params(F::n_params);
  Rng rng(7);
  F::template init<float>(params.data(), rng);
  const int n = 16;
  std::vector<float> pts(3 * n), dirs_a(3 * n), dirs_b(3 * n);
  for (int j = 0; j < n; ++j) {
    Vec3 a(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)), b(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    a.normalize();
    b.normalize();
    for (int d = 0; d < 3; ++d) {
      pts[3 * j + d] = static_cast<float>(rng.uniform(-0.9, 0.9));
      dirs_a[3 * j + d] = static_cast<float>(a[d]);
      dirs_b[3 * j + d] = static_cast<float>(b[d]);
    }
  }
  typename F::template Workspace<float> wa, wb;
  const float *sa = nullptr, *la = nullptr, *sb = nullptr, *lb = nullptr;
  F::forward(params.data(), pts.data(), dirs_a.data(), n, wa, &sa, &la);
  F::forward(params.data(), pts.data(), dirs_b.data(), n, wb, &sb, &lb);
  double dlum = 0;
  for (int j = 0; j < n; ++j) {
    CHECK(sa[j * F::density_net::out_dims] == sb[j * F::density_net::out_dims]);
    dlum = std::max(dlum, std::abs(double(la[j]) - double(lb[j])));
  }
  if constexpr (Dir::out_dims == 1) {
    CHECK(dlum == 0.0);
    CHECK(F::architecture().find("direction spherical harmonics 1,") != std::string::npos);
    CHECK(F::view_begin == F::view_end);  // no weight carries view dependence
  } else {
    CHECK(dlum > 1e-4);
    // The view range (the weights through which the radiance depends on the direction): zeroed, the luminance no longer depends on the
    // direction; a weight just before it (band 0's, a bias) leaves it so, a weight inside it does not.
    static_assert(F::view_weights_known);
    CHECK(F::view_end - F::view_begin == std::size_t(Dir::out_dims - 1) * 8);
    for (std::size_t i = F::view_begin; i < F::view_end; ++i) params[i] = 0;
    auto max_change = [&] {
      F::forward(params.data(), pts.data(), dirs_a.data(), n, wa, &sa, &la);
      F::forward(params.data(), pts.data(), dirs_b.data(), n, wb, &sb, &lb);
      double d = 0;
      for (int j = 0; j < n; ++j) d = std::max(d, std::abs(double(la[j]) - double(lb[j])));
      return d;
    };
    CHECK(max_change() == 0.0);
    params[F::view_begin - 1] += 0.5f;
    CHECK(max_change() == 0.0);
    params[F::view_begin] += 0.5f;
    CHECK(max_change() > 1e-4);
  }
}

namespace {
// A colour network of a user's own that does not lay out its weights as nn::Mlp does (no layer_out): the
// field still compiles, with no view weights named.
struct OpaqueColourNet {
  [[maybe_unused]] static constexpr int in_dims = 3 + 4, out_dims = 1;  // read by Field only where it needs them
  [[maybe_unused]] static constexpr std::size_t n_params = 10;
  using output_activation = nn::Identity;
  static std::string name() { return "opaque"; }
};
using OpaqueField =
    field::Field<nn::HashGrid<4, 2, 10, 4, 32>, nn::SphericalHarmonics<2>, nn::Mlp<8, 8, 1, 4, nn::ReLU, nn::Identity>, OpaqueColourNet>;
static_assert(!OpaqueField::view_weights_known && OpaqueField::view_begin == OpaqueField::view_end,
              "a colour network without layer_out names no view weights");
}  // namespace

TEST_CASE("compositing: an opaque sample at depth d gives depth d and its luminance") {
  const int S = 4;
  std::vector<double> sigma{-5, -5, 50, -5}, raw{0, 0, 2, 0}, t{1, 2, 3, 4};
  render::RayComposite<double> r;
  render::composite_forward<double>(S, 1, sigma.data(), 1, raw.data(), t.data(), 1.0, nullptr, r);
  CHECK(r.depth == doctest::Approx(3.0).epsilon(1e-6));
  CHECK(r.color[0] == doctest::Approx(1 / (1 + std::exp(-2.0))).epsilon(1e-6));
}

TEST_CASE("event loss: zero inside the bounds, growing outside, gradients match finite differences") {
  loss::EventBounds none{0, 0};
  // No events: |Δlog| < B → zero loss.
  CHECK(none.evaluate(0.5, 0.5 * std::exp(0.1), 0.3, -0.3)[0] == doctest::Approx(0.0));
  const double small = none.evaluate(0.5, 0.5 * std::exp(0.4), 0.3, -0.3)[0];
  const double large = none.evaluate(0.5, 0.5 * std::exp(0.8), 0.3, -0.3)[0];
  CHECK(small > 0);
  CHECK(large > small);
  // Three positive events: the change must lie in [2B⁺, 4B⁺] with k = 1.
  loss::EventBounds three{3, 0};
  CHECK(three.evaluate(0.2, 0.2 * std::exp(0.9), 0.3, -0.3)[0] == doctest::Approx(0.0).epsilon(1e-9));
  CHECK(three.evaluate(0.2, 0.2 * std::exp(0.3), 0.3, -0.3)[0] > 0);
  for (auto [np, nn, kn, kp] : {std::array{2.0, 1.0, 1.0, 1.0}, std::array{0.0, 3.0, 1.0, 1.0}, std::array{0.0, 0.0, 1.0, 1.0},
                                std::array{2.0, 0.0, 0.0, 1.0}, std::array{0.0, 1.0, 1.0, 0.0}, std::array{1.0, 1.0, 2.0, 2.0}}) {
    loss::EventBounds lb{np, nn, kn, kp};
    const std::vector<double> x{0.3, 0.7, 0.27, -0.33};
    const auto r = lb.evaluate(x[0], x[1], x[2], x[3]);
    CHECK(evtest::max_fd_error([&](const std::vector<double>& v) { return lb.evaluate(v[0], v[1], v[2], v[3])[0]; }, x,
                               {r[1], r[2], r[3], r[4]}) < 1e-6);
  }
}

TEST_CASE("bound policies: split counts with slack K, the signed count and half slack give their intervals") {
  // The interval [lo, hi] of a policy, read off the loss: zero inside, slope 1 outside.
  auto interval = [](const loss::EventBounds& b) {
    const double bp = 0.3, bm = -0.3, l0 = 0.2;
    auto at = [&](double change) { return b.evaluate(l0, (l0 + b.eps) * std::exp(change) - b.eps, bp, bm)[0]; };
    const double lo = at(-5.0) - 5.0, hi = 5.0 - at(5.0);  // loss = lo − c below, c − hi above
    return std::pair{lo, hi};
  };
  auto near = [](std::pair<double, double> got, double lo, double hi) {
    return std::abs(got.first - lo) < 1e-9 && std::abs(got.second - hi) < 1e-9;
  };
  CHECK(near(interval(loss::SplitCounts<1>::make(0, 0)), -0.3, 0.3));
  CHECK(near(interval(loss::SplitCounts<1>::make(1, 0)), 0.0, 0.6));
  CHECK(near(interval(loss::SplitCounts<1>::make(3, 1)), 0.3, 0.9));
  CHECK(near(interval(loss::SplitCounts<2>::make(1, 0)), -0.3, 0.9));
  CHECK(near(interval(loss::SignedCount::make(0, 0)), -0.3, 0.3));
  CHECK(near(interval(loss::SignedCount::make(1, 0)), 0.3, 0.6));
  CHECK(near(interval(loss::SignedCount::make(0, 2)), -0.9, -0.6));
  CHECK(near(interval(loss::SignedCount::make(3, 1)), 0.6, 0.9));
  CHECK(near(interval(loss::SignedCount::make(2, 2)), -0.3, 0.3));
  CHECK(near(interval(loss::HalfSlackCounts::make(0, 0)), -0.3, 0.3));
  CHECK(near(interval(loss::HalfSlackCounts::make(1, 0)), 0.15, 0.45));
  CHECK(near(interval(loss::HalfSlackCounts::make(0, 2)), -0.75, -0.45));
  CHECK(near(interval(loss::HalfSlackCounts::make(3, 1)), 0.45, 0.75));
}

TEST_CASE("threshold floor: zero above |B| >= 0.3, gradient pushes thresholds back up") {
  auto f = loss::ThresholdFloor{};
  CHECK(ad::value(f, 0.35, -0.4) == doctest::Approx(0.0));
  const auto vg = ad::value_and_grad(f, std::array<double, 2>{0.2, -0.1});
  CHECK(vg.value == doctest::Approx(0.1 + 0.2));
  CHECK(vg.grad[0] == doctest::Approx(-1.0));  // descending increases B⁺
  CHECK(vg.grad[1] == doctest::Approx(1.0));   // descending decreases B⁻
  const std::vector<double> x{0.25, -0.21};
  CHECK(evtest::max_fd_error([&](const std::vector<double>& v) { return ad::value(f, v[0], v[1]); }, x, {vg.grad[0], vg.grad[1]}) < 1e-6);
}

TEST_CASE("samplers: depth spacing policies, uniform is stratified_depths bit for bit, log bins grow with depth") {
  constexpr int n = 32;
  const float near = 0.3f, far = 7.0f;
  std::vector<float> a(n), b(n), t(n);
  Rng r1(5), r2(5);
  render::stratified_depths(n, near, far, &r1, a.data());
  render::UniformDepth::depths(n, near, far, &r2, b.data());
  CHECK(a == b);
  // Log: bin centres near·r^((k + ½)/n), r = far/near, a constant ratio between neighbours.
  std::vector<double> c(n);
  render::LogDepth::depths<double>(n, 0.3, 7.0, nullptr, c.data());
  for (int k = 0; k < n; ++k) CHECK(c[k] == doctest::Approx(0.3 * std::pow(7.0 / 0.3, (k + 0.5) / n)).epsilon(1e-12));
  for (int k = 1; k < n; ++k) CHECK(c[k] / c[k - 1] == doctest::Approx(std::pow(7.0 / 0.3, 1.0 / n)).epsilon(1e-12));
  // Jittered: sample k inside bin k, so the samples are sorted and inside [near, far]; drawn uniformly in log depth.
  Rng rng(9);
  std::vector<double> logs;
  for (int rep = 0; rep < 200; ++rep) {
    render::LogDepth::depths<double>(n, 0.3, 7.0, &rng, c.data());
    for (int k = 0; k < n; ++k) {
      CHECK(c[k] >= 0.3 * std::pow(7.0 / 0.3, double(k) / n) * (1 - 1e-12));
      CHECK(c[k] <= 0.3 * std::pow(7.0 / 0.3, double(k + 1) / n) * (1 + 1e-12));
      logs.push_back(std::log(c[k] / 0.3) / std::log(7.0 / 0.3));  // uniform on [0, 1]
    }
  }
  double mean = 0;
  for (double u : logs) mean += u;
  mean /= static_cast<double>(logs.size());
  CHECK(mean == doctest::Approx(0.5).epsilon(0.01));
  // Float rays get the same depths to float precision.
  render::LogDepth::depths(n, near, far, nullptr, t.data());
  for (int k = 0; k < n; ++k) CHECK(t[k] == doctest::Approx(0.3 * std::pow(7.0 / 0.3, (k + 0.5) / n)).epsilon(1e-6));
  CHECK_THROWS_WITH_AS(render::LogDepth::check(0.0, 7.0), doctest::Contains("near 0 and far 7"), Error);
  CHECK_THROWS_WITH_AS(render::LogDepth::check(2.0, 1.0), doctest::Contains("0 < near < far"), Error);
  CHECK_NOTHROW(render::LogDepth::check(0.3, 7.0));
  // The policy names the sampler (so checkpoints tell the two apart); the uniform default keeps the old name.
  CHECK(render::OccupancySkipping<64, 64, 16, 256, 300>::name() == "occupancy 64 grid 64 every 16 after 256 alpha 300/1000");
  CHECK(render::OccupancySkipping<128, 64, 16, 256, 150, render::LogDepth>::name() ==
        "occupancy 128 grid 64 every 16 after 256 alpha 150/1000 log-spaced");
  CHECK(render::Stratified<8>::name() == "stratified 8");
  CHECK(render::Stratified<8, render::LogDepth>::name() == "stratified 8 log-spaced");
  static_assert(render::Sampler<render::Stratified<8, render::LogDepth>>);
  static_assert(render::Sampler<render::OccupancySkipping<8, 8, 1, 0, 10, render::LogDepth>>);
  // Log(z + c), c = 1: centres exp(a + (k + ½)·s/n) − 1, bins (z + 1)·s/n long, jittered samples inside their bins.
  using Off = render::OffsetLogDepth<100>;
  const double la = std::log(1.3), ls = std::log(8.0) - std::log(1.3);
  Off::depths<double>(n, 0.3, 7.0, nullptr, c.data());
  for (int k = 0; k < n; ++k) CHECK(c[k] == doctest::Approx(std::exp(la + (k + 0.5) * ls / n) - 1).epsilon(1e-12));
  for (int k = 1; k < n; ++k) CHECK((c[k] + 1) / (c[k - 1] + 1) == doctest::Approx(std::exp(ls / n)).epsilon(1e-12));
  for (int rep = 0; rep < 50; ++rep) {
    Off::depths<double>(n, 0.3, 7.0, &rng, c.data());
    for (int k = 0; k < n; ++k) {
      CHECK(c[k] >= (std::exp(la + k * ls / n) - 1) * (1 - 1e-12));
      CHECK(c[k] <= (std::exp(la + (k + 1) * ls / n) - 1) * (1 + 1e-12));
    }
  }
  CHECK_NOTHROW(Off::check(0.0, 7.0));  // near 0 is fine with an offset
  CHECK_THROWS_WITH_AS(Off::check(-1.5, 7.0), doctest::Contains("near + offset > 0"), Error);
  CHECK_THROWS_WITH_AS(Off::check(2.0, 1.0), doctest::Contains("near 2 and far 1"), Error);
  CHECK(render::OccupancySkipping<128, 64, 16, 256, 150, Off>::name() ==
        "occupancy 128 grid 64 every 16 after 256 alpha 150/1000 log-spaced offset 1");
  static_assert(render::Sampler<render::OccupancySkipping<8, 8, 1, 0, 10, Off>>);
}

TEST_CASE("samplers: stratified depths cover [near, far] in order, importance samples follow the weights") {
  std::vector<double> t(16);
  Rng rng(1);
  render::stratified_depths<double>(16, 1.0, 5.0, &rng, t.data());
  CHECK(std::is_sorted(t.begin(), t.end()));
  CHECK(t.front() >= 1.0);
  CHECK(t.back() <= 5.0);
  std::vector<double> w(16, 0.0);
  w[10] = 1.0;  // all mass around t[10]
  std::vector<double> out;
  render::importance_depths<double>(16, t.data(), w.data(), 64, &rng, out);
  CHECK(out.size() == 80);
  CHECK(std::is_sorted(out.begin(), out.end()));
  int near_peak = 0;
  for (std::size_t i = 0; i < out.size(); ++i)
    if (out[i] > 0.5 * (t[9] + t[10]) - 1e-9 && out[i] < 0.5 * (t[10] + t[11]) + 1e-9) ++near_peak;
  CHECK(near_peak >= 60);
}
