// Objectives (loss/objective.hpp), the total-variation penalty (loss/total_variation.hpp), the teacher term
// (loss/teacher.hpp) and pixel policies (events/pixels.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include <evnerf/loss/objective.hpp>
#include <evnerf/loss/teacher.hpp>
#include <evnerf/loss/total_variation.hpp>

#include "common.hpp"

using namespace evnerf;

namespace {
/// A window's counts as the crossings they stand for (loss::DeadTimeCounts' storage); empty: plain counts.
struct Weighted {
  std::vector<double> wp, wm, dwp, dwm;
  std::vector<std::uint8_t> lim;
  loss::DeadTimeCounts view() const {
    if (wp.empty()) return {};
    return {wp.data(), wm.data(), dwp.data(), dwm.data(), lim.data()};
  }
};
/// The counts as they are, with saturated bits `lim` (empty: none).
Weighted with_bits(const std::vector<int>& np, const std::vector<int>& nn, const std::vector<std::uint8_t>& lim) {
  if (lim.empty()) return {};
  Weighted w;
  w.wp.assign(np.begin(), np.end());
  w.wm.assign(nn.begin(), nn.end());
  w.dwp.assign(np.size(), 0.0);
  w.dwm.assign(np.size(), 0.0);
  w.lim = lim;
  return w;
}
/// Loss of one pixel over a window with x = (l0, l1, B⁺_0, B⁻_0, …, B⁺_{L-1}, B⁻_{L-1}).
template <class Bound>
double window_value(const std::vector<double>& x, const std::vector<int>& np, const std::vector<int>& nn, const Weighted& w = {}) {
  const int L = static_cast<int>(np.size());
  std::vector<double> bp(L), bm(L), g1(L), g2(L);
  for (int k = 0; k < L; ++k) {
    bp[k] = x[2 + 2 * k];
    bm[k] = x[3 + 2 * k];
  }
  return loss::window_pixel_loss<Bound>(x[0], x[1], L, np.data(), nn.data(), bp.data(), bm.data(), g1.data(), g2.data(), 1e-3, w.view())
      .value;
}
/// The gradient for x, and dloss/dτ appended where `gtau` is given.
template <class Bound>
std::vector<double> window_grad(const std::vector<double>& x, const std::vector<int>& np, const std::vector<int>& nn,
                                const Weighted& w = {}, double* gtau = nullptr) {
  const int L = static_cast<int>(np.size());
  std::vector<double> bp(L), bm(L), g1(L, 0.0), g2(L, 0.0);
  for (int k = 0; k < L; ++k) {
    bp[k] = x[2 + 2 * k];
    bm[k] = x[3 + 2 * k];
  }
  const auto r =
      loss::window_pixel_loss<Bound>(x[0], x[1], L, np.data(), nn.data(), bp.data(), bm.data(), g1.data(), g2.data(), 1e-3, w.view(), gtau);
  std::vector<double> g{r.dl0, r.dl1};
  for (int k = 0; k < L; ++k) {
    g.push_back(g1[k]);
    g.push_back(g2[k]);
  }
  return g;
}
}  // namespace

TEST_CASE_TEMPLATE("window objective: finite differences in double match the gradient for every luminance and threshold", Bound,
                   loss::SplitCounts<1>, loss::HalfSlackCounts, loss::SignedCount) {
  Rng rng(4);
  int checked_nonzero = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int L = 1 + static_cast<int>(rng.below(5));
    std::vector<int> np(L), nn(L);
    for (int k = 0; k < L; ++k) {
      np[k] = static_cast<int>(rng.below(4));
      nn[k] = trial % 3 == 0 ? 0 : static_cast<int>(rng.below(3));  // windows without negative events too
    }
    std::vector<double> x{0.05 + 0.9 * rng.uniform(), 0.05 + 0.9 * rng.uniform()};
    for (int k = 0; k < L; ++k) {
      x.push_back(0.15 + 0.4 * rng.uniform());
      x.push_back(-0.15 - 0.4 * rng.uniform());
    }
    std::vector<std::uint8_t> lim;  // every fourth window with rate-limited counts (one end open)
    if (trial % 4 == 1)
      for (int k = 0; k < L; ++k) lim.push_back(static_cast<std::uint8_t>(k == 0 ? 1 + rng.below(2) : 0));
    const Weighted w = with_bits(np, nn, lim);
    const auto g = window_grad<Bound>(x, np, nn, w);
    const double err = evtest::max_fd_error([&](const std::vector<double>& v) { return window_value<Bound>(v, np, nn, w); }, x, g);
    // The hinge has kinks; a draw within h of one is skipped by the value check below.
    const double v = window_value<Bound>(x, np, nn, w);
    if (v > 1e-3) {
      ++checked_nonzero;
      CAPTURE(trial);
      CHECK(err < 1e-5);
    }
  }
  CHECK(checked_nonzero > 50);  // the check saw the hinge's active side often
}

TEST_CASE_TEMPLATE("window objective under a refractory period: finite differences in double for the luminances, thresholds and the period",
                   Bound, loss::SplitCounts<1>, loss::HalfSlackCounts) {
  // Each slice's events with random intervals (some a pixel's first, some saturated at the period of the
  // draw); the period is x's last entry, in units of 0.1 ms, so that the difference step stays far inside
  // every interval's distance to its saturation.
  Rng rng(9);
  int checked = 0, moved = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int L = 1 + static_cast<int>(rng.below(4));
    const double tau0 = 1e-4 * (0.2 + 1.5 * rng.uniform());
    std::vector<int> np(L), nn(L);
    std::vector<std::vector<double>> gaps(L);  // signed, as SliceCounts::gap
    for (int k = 0; k < L; ++k) {
      np[k] = static_cast<int>(rng.below(4));
      nn[k] = static_cast<int>(rng.below(3));
      for (int e = 0; e < np[k] + nn[k]; ++e) {
        const double u = rng.uniform();
        const double g = u < 0.15  ? std::numeric_limits<double>::infinity()
                         : u < 0.3 ? tau0 * (0.5 + rng.uniform())
                                   : tau0 * (1.7 + 8 * rng.uniform());
        gaps[k].push_back(e < np[k] ? g : -g);
      }
    }
    auto weighted = [&](double tau) {
      Weighted w;
      w.wp.assign(L, 0.0), w.wm.assign(L, 0.0), w.dwp.assign(L, 0.0), w.dwm.assign(L, 0.0), w.lim.assign(L, 0);
      for (int k = 0; k < L; ++k)
        for (const double g : gaps[k]) {
          const auto d = events::dead_time_weight(std::abs(g), tau);
          (g > 0 ? w.wp : w.wm)[k] += d.weight;
          (g > 0 ? w.dwp : w.dwm)[k] += d.dweight;
          if (d.saturated) w.lim[k] |= g > 0 ? 1 : 2;
        }
      return w;
    };
    std::vector<double> x{0.05 + 0.9 * rng.uniform(), 0.05 + 0.9 * rng.uniform()};
    for (int k = 0; k < L; ++k) {
      x.push_back(0.15 + 0.4 * rng.uniform());
      x.push_back(-0.15 - 0.4 * rng.uniform());
    }
    x.push_back(tau0 / 1e-4);
    auto f = [&](const std::vector<double>& v) {
      return window_value<Bound>(std::vector<double>(v.begin(), v.end() - 1), np, nn, weighted(v.back() * 1e-4));
    };
    double gtau = 0;
    auto g = window_grad<Bound>(std::vector<double>(x.begin(), x.end() - 1), np, nn, weighted(tau0), &gtau);
    g.push_back(gtau * 1e-4);
    if (f(x) > 1e-3) {
      ++checked;
      moved += gtau != 0;
      CAPTURE(trial);
      CHECK(evtest::max_fd_error(f, x, g) < 1e-5);
    }
  }
  CHECK(checked > 60);
  CHECK(moved > 30);  // the period's gradient was not trivially zero
}

TEST_CASE("window objective: with every weight one, a refractory period's path is the plain counts' path to the bit") {
  Rng rng(2);
  for (int trial = 0; trial < 100; ++trial) {
    const int L = 1 + static_cast<int>(rng.below(6));
    std::vector<int> np(L), nn(L);
    std::vector<double> x{0.05 + 0.9 * rng.uniform(), 0.05 + 0.9 * rng.uniform()};
    for (int k = 0; k < L; ++k) {
      np[k] = static_cast<int>(rng.below(4));
      nn[k] = static_cast<int>(rng.below(3));
      x.push_back(0.15 + 0.4 * rng.uniform());
      x.push_back(-0.15 - 0.4 * rng.uniform());
    }
    const Weighted w = with_bits(np, nn, std::vector<std::uint8_t>(L, 0));
    CHECK(window_grad<loss::HalfSlackCounts>(x, np, nn, w) == window_grad<loss::HalfSlackCounts>(x, np, nn));
    CHECK(window_value<loss::HalfSlackCounts>(x, np, nn, w) == window_value<loss::HalfSlackCounts>(x, np, nn));
  }
}

TEST_CASE("window objective: one slice is spec §2's EventBounds exactly, the window's centre is Σ n_k B_k") {
  const int np = 3, nn = 1;
  const double bp = 0.27, bm = -0.33, l0 = 0.2, l1 = 0.9;
  double g1 = 0, g2 = 0;
  const auto r = loss::window_pixel_loss<loss::SplitCounts<1>>(l0, l1, 1, &np, &nn, &bp, &bm, &g1, &g2);
  const auto e = loss::SplitCounts<1>::make(np, nn).evaluate(l0, l1, bp, bm);
  CHECK(r.value == e[0]);
  CHECK(r.dl0 == e[1]);
  CHECK(r.dl1 == e[2]);
  CHECK(g1 == e[3]);
  CHECK(g2 == e[4]);
  // Two slices with different thresholds: a change exactly at the centre Σ n_k B_k costs nothing, one
  // just outside the slack costs its distance.
  const int np2[2] = {2, 1}, nn2[2] = {0, 1};
  const double bp2[2] = {0.2, 0.4}, bm2[2] = {-0.3, -0.5};
  const double centre = 2 * 0.2 + 1 * 0.4 - 0.5;
  double gp[2] = {0, 0}, gm[2] = {0, 0};
  const double a = 0.3, b = std::exp(centre) * (a + 1e-3) - 1e-3;
  CHECK(loss::window_pixel_loss<loss::SplitCounts<1>>(a, b, 2, np2, nn2, bp2, bm2, gp, gm).value == doctest::Approx(0.0));
  // Beyond the upper end (centre + B⁺_eff, B⁺_eff = (2·0.2 + 0.4)/3) by 0.1.
  const double hi = centre + (2 * 0.2 + 0.4) / 3 + 0.1, b2 = std::exp(hi) * (a + 1e-3) - 1e-3;
  CHECK(loss::window_pixel_loss<loss::SplitCounts<1>>(a, b2, 2, np2, nn2, bp2, bm2, gp, gm).value == doctest::Approx(0.1));
}

TEST_CASE("window objective: a saturated count opens its end of the interval and leaves the other end as it was") {
  // Two slices, 3 ON and 1 OFF event; B± = ±0.25. The interval (half slack) is μ ± 0.125, μ = 0.5.
  const int np[2] = {2, 1}, nn[2] = {0, 1};
  const double bp[2] = {0.25, 0.25}, bm[2] = {-0.25, -0.25}, l0 = 0.3;
  auto cost = [&](double change, std::vector<std::uint8_t> lim) {
    double gp[2] = {0, 0}, gm[2] = {0, 0};
    const double l1 = std::exp(change) * (l0 + 1e-3) - 1e-3;
    const Weighted w = with_bits({np[0], np[1]}, {nn[0], nn[1]}, lim);
    return loss::window_pixel_loss<loss::HalfSlackCounts>(l0, l1, 2, np, nn, bp, bm, gp, gm, 1e-3, w.view()).value;
  };
  CHECK(cost(1.5, {}) == doctest::Approx(1.5 - 0.625));
  CHECK(cost(-0.5, {}) == doctest::Approx(0.375 + 0.5));
  CHECK(cost(1.5, {0, 1}) == 0.0);                      // ON limited in the window's second slice: no upper end
  CHECK(cost(-0.5, {0, 1}) == doctest::Approx(0.875));  // the lower end stays
  CHECK(cost(-0.5, {2, 0}) == 0.0);                     // OFF limited: no lower end
  CHECK(cost(1.5, {2, 0}) == doctest::Approx(0.875));
  CHECK(cost(9.0, {3, 0}) == 0.0);
  CHECK(cost(0.5, {0, 0}) == 0.0);  // inside: nothing either way
}

TEST_CASE("total variation of log-luminance: Cauchy penalty of the log step, symmetric, its gradient matches finite differences") {
  const loss::LogTv f{1e-3, 0.1};
  // Equal neighbours cost nothing; the cost is δ² log(1 + d²/δ²), the same from either side.
  CHECK(f.evaluate(0.4, 0.4)[0] == 0.0);
  const double d = std::log(0.8 + 1e-3) - std::log(0.2 + 1e-3);
  CHECK(f.evaluate(0.8, 0.2)[0] == doctest::Approx(0.01 * std::log(1 + d * d / 0.01)));
  CHECK(f.evaluate(0.2, 0.8)[0] == doctest::Approx(f.evaluate(0.8, 0.2)[0]));
  // Small steps: about d² (grain is penalised like a square).
  const double s = std::log(0.3015 + 1e-3) - std::log(0.3 + 1e-3);
  CHECK(f.evaluate(0.3015, 0.3)[0] == doctest::Approx(s * s).epsilon(1e-3));
  // Edges: the pull on a step of height d is 2d/(1 + d²/δ²), weaker on a high step than on one of δ.
  auto pull = [&](double a, double b) { return std::abs(f.evaluate(a, b)[1]) * (a + 1e-3); };  // |∂/∂d|
  CHECK(pull(0.8, 0.2) == doctest::Approx(2 * d / (1 + d * d / 0.01)));
  const double at_delta = 0.3 * std::exp(0.1) - 1e-3 * (1 - std::exp(0.1));  // log step of exactly δ
  CHECK(pull(at_delta, 0.3) == doctest::Approx(0.1).epsilon(1e-6));
  CHECK(pull(0.8, 0.05) < pull(0.8, 0.2));
  CHECK(pull(0.8, 0.2) < 0.2 * pull(at_delta, 0.3));
  // Gradients against central differences, across the quadratic and the linear regime.
  for (const auto& x : std::vector<std::vector<double>>{{0.3, 0.3015}, {0.8, 0.2}, {0.01, 0.5}, {2.0, 1.9}}) {
    const auto r = f.evaluate(x[0], x[1]);
    CAPTURE(x[0]);
    CAPTURE(x[1]);
    CHECK(evtest::max_fd_error([&](const std::vector<double>& p) { return f.evaluate(p[0], p[1])[0]; }, x, {r[1], r[2]}) < 1e-7);
    CHECK(r[1] == doctest::Approx(-r[2] * (x[1] + 1e-3) / (x[0] + 1e-3)));  // opposite pulls in log space
  }
}

TEST_CASE(
    "teacher term: Charbonnier pull of the log toward a teacher's images at the window's ends, fading to 0, and by finite differences") {
  const loss::TeacherPull f{1e-3, 0.01, 0.4};
  CHECK(f.evaluate(0.4)[0] == 0.0);
  CHECK(f.evaluate(0.4)[1] == 0.0);
  const double d = std::log(0.8 + 1e-3) - std::log(0.4 + 1e-3);
  CHECK(f.evaluate(0.8)[0] == doctest::Approx(std::sqrt(d * d + 1e-4) - 0.01));  // about |d| away from the teacher
  for (double l : {0.01, 0.39, 0.41, 0.8, 3.0}) {
    CAPTURE(l);
    CHECK(evtest::max_fd_error([&](const std::vector<double>& p) { return f.evaluate(p[0])[0]; }, {l}, {f.evaluate(l)[1]}) < 1e-7);
  }
  // A step of three pixels over the window [1, 3) of a 4 × 3 sensor. The teacher's image at pose k is
  // 0.1 · (k + 1) + 0.01 · pixel.
  using Term = loss::Teacher<500, 100>;  // weight 0.5 falling to 0 at step 100
  CHECK(Term::weight(0) == 0.5);
  CHECK(Term::weight(50) == doctest::Approx(0.25));
  CHECK(Term::weight(100) == 0.0);
  CHECK(Term::weight(300) == 0.0);
  const geometry::Camera cam(4, 3, 3, 3, 2, 1.5);
  loss::StepDraw draw;
  draw.first = 1;
  draw.len = 2;
  draw.pixels = {5, 2, 11};
  std::vector<float> teacher;
  for (int k = 0; k < 4; ++k)
    for (int p = 0; p < 12; ++p) teacher.push_back(static_cast<float>(0.1 * (k + 1) + 0.01 * p));
  loss::TileView t;
  t.draw = &draw;
  t.P = 3;
  t.batch = 3;
  t.camera = &cam;
  t.step = 20;
  t.teacher = teacher.data();
  const Term term;
  Term::scratch sc;
  loss::WindowThresholds<double> th;
  auto score = [&](const std::vector<double>& x, std::vector<double>* grad) {
    std::vector<double> g(6, 0.0);
    struct Values {  // the rendered values in double, for the differences
      const std::vector<double>* x;
      double* g;
      double at(int ray, int) const { return (*x)[ray]; }
      void add(int ray, int, double v) const { g[ray] += v; }
    } v{&x, g.data()};
    const double l = term.score(t, v, th, sc);
    if (grad) *grad = g;
    return l;
  };
  const std::vector<double> x{0.25, 0.5, 0.3, 0.41, 0.6, 0.2};
  std::vector<double> g;
  const double l = score(x, &g);
  // By hand: weight 0.4 at step 20, a mean over 3 pixels, 1 channel and 2 ends.
  auto pull = [](double v, double tv) { return loss::TeacherPull{1e-3, 0.01, tv}.evaluate(v)[0]; };
  const double expect = 0.4 / 6 *
                        (pull(0.25, float(0.2 + 0.05)) + pull(0.5, float(0.4 + 0.05)) + pull(0.3, float(0.2 + 0.02)) +
                         pull(0.41, float(0.4 + 0.02)) + pull(0.6, float(0.2 + 0.11)) + pull(0.2, float(0.4 + 0.11)));
  CHECK(l == doctest::Approx(expect).epsilon(1e-12));
  CHECK(evtest::max_fd_error([&](const std::vector<double>& p) { return score(p, nullptr); }, x, g) < 1e-7);
  // Past the schedule's end, or without a teacher, the term adds nothing.
  t.step = 100;
  CHECK(score(x, &g) == 0.0);
  CHECK(g == std::vector<double>(6, 0.0));
  t.step = 20;
  t.teacher = nullptr;
  CHECK(score(x, &g) == 0.0);
  CHECK(g == std::vector<double>(6, 0.0));
}

namespace {
/// One slice of a 10×10 sensor with one event at each pixel p where fires(p) (odd p positive).
template <class Fires>
events::SliceSet one_slice_10x10(Fires&& fires) {
  events::SliceSet set;
  set.boundaries = {0.0, 1.0};
  events::SliceCounts c;
  c.width = c.height = 10;
  c.pos.assign(100, 0);
  c.neg.assign(100, 0);
  for (int p = 0; p < 100; ++p)
    if (fires(p)) (p % 2 ? c.pos : c.neg)[p] = 1;
  set.slices.push_back(c);
  return set;
}
}  // namespace

TEST_CASE("pixel policies: distinct pixels, EventPixels draws its share of empty pixels and the rest where events fired") {
  // 10×10 sensor, one slice, events at pixels 0..29.
  const events::CountPrefix pre(one_slice_10x10([](int p) { return p < 30; }));
  const events::PixelWindow w{100, 0, 1, &pre};
  std::vector<std::uint8_t> taken(100, 0);
  std::vector<std::uint32_t> out;
  Rng rng(9);
  events::UniformPixels::draw(w, 40, rng, out, taken);
  CHECK(out.size() == 40);
  CHECK(std::set<std::uint32_t>(out.begin(), out.end()).size() == 40);
  CHECK(std::count(taken.begin(), taken.end(), 1) == 0);  // scratch handed back clean
  events::EventPixels<100>::draw(w, 20, rng, out, taken);
  REQUIRE(out.size() == 20);
  CHECK(std::set<std::uint32_t>(out.begin(), out.end()).size() == 20);
  CHECK(std::count_if(out.begin(), out.end(), [](std::uint32_t p) { return p >= 30; }) == 2);  // 10 % of 20
  // More pixels than there are event pixels: all 30 event pixels, the rest from the empty ones.
  events::EventPixels<100>::draw(w, 60, rng, out, taken);
  REQUIRE(out.size() == 60);
  CHECK(std::count_if(out.begin(), out.end(), [](std::uint32_t p) { return p < 30; }) == 30);
  CHECK(std::set<std::uint32_t>(out.begin(), out.end()).size() == 60);
  // All pixels.
  events::EventPixels<100>::draw(w, 500, rng, out, taken);
  CHECK(out.size() == 100);
  CHECK(std::count(taken.begin(), taken.end(), 1) == 0);
}

TEST_CASE("pixel policies and noise keep to a sensor's sites (a mosaic channel at the full sensor), no sites draws over the whole sensor") {
  // 10×10 sensor, one slice; the sites are the pixels of even x + y (a green quincunx); events fire at the
  // sites among pixels 0..29.
  std::vector<std::uint8_t> mask(100, 0);
  for (int p = 0; p < 100; ++p) mask[p] = ((p % 10) + (p / 10)) % 2 == 0;
  const events::PixelSites sites(mask);
  REQUIRE(sites.list.size() == 50);
  CHECK(!sites.all());
  CHECK(events::PixelSites().all());
  CHECK_THROWS_WITH_AS(events::PixelSites(std::vector<std::uint8_t>(4, 0)), doctest::Contains("no site"), Error);
  const events::CountPrefix pre(one_slice_10x10([&](int p) { return p < 30 && mask[p]; }));
  const events::PixelWindow w{100, 0, 1, &pre, &sites};
  std::vector<std::uint8_t> taken(100, 0);
  std::vector<std::uint32_t> out;
  Rng rng(4);
  auto on_sites = [&] { return std::all_of(out.begin(), out.end(), [&](std::uint32_t p) { return mask[p] == 1; }); };
  events::UniformPixels::draw(w, 30, rng, out, taken);
  CHECK(out.size() == 30);
  CHECK(on_sites());
  CHECK(std::set<std::uint32_t>(out.begin(), out.end()).size() == 30);
  events::UniformPixels::draw(w, 80, rng, out, taken);  // more than there are sites: every site once
  CHECK(out.size() == 50);
  CHECK(on_sites());
  CHECK(std::set<std::uint32_t>(out.begin(), out.end()).size() == 50);
  events::EventPixels<500>::draw(w, 20, rng, out, taken);  // 10 empty pixels: sites without events
  REQUIRE(out.size() == 20);
  CHECK(on_sites());
  CHECK(std::count_if(out.begin(), out.end(), [](std::uint32_t p) { return p >= 30; }) == 10);
  events::EventPixels<100>::draw(w, 100, rng, out, taken);  // all sites, none of the other pixels
  CHECK(out.size() == 50);
  CHECK(on_sites());
  CHECK(std::count(taken.begin(), taken.end(), 1) == 0);
  // Noise lands on sites only; without sites it draws exactly what it drew before sites existed.
  std::vector<events::NoiseEvent> noise, plain, none;
  Rng a(11), b(11), n(11);
  events::draw_noise(4000, 0.05, 100, 3, a, noise, &sites.list);
  CHECK(noise.size() == 200);
  CHECK(std::all_of(noise.begin(), noise.end(), [&](const events::NoiseEvent& e) { return mask[e.pixel] == 1; }));
  events::draw_noise(4000, 0.05, 100, 3, b, plain);
  events::draw_noise(4000, 0.05, 100, 3, n, none, nullptr);
  REQUIRE(plain.size() == none.size());
  CHECK(std::equal(plain.begin(), plain.end(), none.begin(),
                   [](const auto& x, const auto& y) { return x.pixel == y.pixel && x.slice == y.slice && x.positive == y.positive; }));
  CHECK(std::any_of(plain.begin(), plain.end(), [&](const events::NoiseEvent& e) { return mask[e.pixel] == 0; }));
  // No sites in the window (null, or every pixel): the same draw as a window without the field.
  const events::PixelSites everywhere;
  const events::PixelWindow w0{100, 0, 1, &pre}, w1{100, 0, 1, &pre, &everywhere};
  std::vector<std::uint32_t> o0, o1;
  Rng r0(5), r1(5);
  events::EventPixels<100>::draw(w0, 40, r0, o0, taken);
  events::EventPixels<100>::draw(w1, 40, r1, o1, taken);
  CHECK(o0 == o1);
}
