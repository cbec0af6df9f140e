#include <evnerf/events/hot_pixels.hpp>
#include <evnerf/events/slicing.hpp>

#include "common.hpp"

using namespace evnerf;
using namespace evnerf::events;

namespace {
EventStream random_stream(std::size_t n, int w, int h, std::uint64_t seed) {
  Rng rng(seed);
  EventStream ev;
  ev.width = w;
  ev.height = h;
  double t = 0;
  for (std::size_t i = 0; i < n; ++i) {
    t += rng.uniform() * 1e-3;
    if (rng.below(10) == 0) t += 0;  // repeated timestamps are allowed
    ev.push_back(t, static_cast<int>(rng.below(w)), static_cast<int>(rng.below(h)), rng.below(2) ? 1 : -1);
  }
  return ev;
}
}  // namespace

TEST_CASE("slicing counts positive and negative events per pixel exactly like a brute-force count") {
  auto ev = random_stream(20000, 17, 11, 3);
  std::vector<double> b{ev.t[100], ev.t[5000] + 1e-9, ev.t[5000] + 2e-9, ev.t[12000], ev.t[19990]};
  auto set = slice_events(ev, b);
  REQUIRE(set.size() == 4);
  for (std::size_t s = 0; s < set.size(); ++s) {
    std::vector<int> pos(17 * 11, 0), neg(17 * 11, 0);
    std::size_t total = 0;
    for (std::size_t k = 0; k < ev.size(); ++k)
      if (ev.t[k] >= b[s] && ev.t[k] < b[s + 1]) {
        (ev.polarity[k] > 0 ? pos : neg)[ev.y[k] * 17 + ev.x[k]]++;
        ++total;
      }
    CAPTURE(s);
    CHECK(set.slices[s].total == total);
    std::size_t active = 0;
    for (int p = 0; p < 17 * 11; ++p) {
      CHECK(set.slices[s].pos[p] == pos[p]);
      CHECK(set.slices[s].neg[p] == neg[p]);
      active += (pos[p] || neg[p]);
    }
    CHECK(set.slices[s].active.size() == active);
  }
  CHECK(set.slices[1].total == 0);  // an empty slice between two close boundaries
}

TEST_CASE("slicing keeps each event's interval since the pixel's previous event, signed by its polarity, per active pixel") {
  // Pixel 0 fires ON at 0.1000 and 0.1012 across the boundary 0.101; pixel 1 OFF three times 2 ms apart;
  // pixel 2 OFF then ON 0.5 ms apart in slice 2; pixel 3 fired once before T_0, which its interval counts from.
  EventStream ev;
  ev.width = 4, ev.height = 1;
  ev.push_back(0.0980, 3, 0, 1);
  ev.push_back(0.0995, 1, 0, -1);
  ev.push_back(0.1000, 0, 0, 1);
  ev.push_back(0.1005, 3, 0, 1);
  ev.push_back(0.1012, 0, 0, 1);
  ev.push_back(0.1015, 1, 0, -1);
  ev.push_back(0.1030, 2, 0, -1);
  ev.push_back(0.1035, 1, 0, -1);
  ev.push_back(0.1035, 2, 0, 1);
  const std::vector<double> b{0.099, 0.101, 0.103, 0.104};
  const auto plain = slice_events(ev, b);
  for (const auto& s : plain.slices) CHECK(!s.has_intervals());
  const auto set = slice_events(ev, b, true);
  REQUIRE(set.size() == 3);
  const float inf = std::numeric_limits<float>::infinity();
  auto gaps = [&](std::size_t slice, std::uint32_t pix) {
    const auto [g0, g1] = set.slices[slice].intervals(pix);
    return std::vector<float>(g0, g1);
  };
  for (std::size_t i = 0; i < 3; ++i) {
    CAPTURE(i);
    CHECK(set.slices[i].pos == plain.slices[i].pos);  // the counts themselves do not change
    CHECK(set.slices[i].neg == plain.slices[i].neg);
    CHECK(set.slices[i].gap.size() == set.slices[i].total);
  }
  CHECK(gaps(0, 0) == std::vector<float>{inf});
  CHECK(gaps(0, 1) == std::vector<float>{-inf});
  CHECK(gaps(0, 2).empty());
  CHECK(gaps(0, 3) == std::vector<float>{static_cast<float>(0.1005 - 0.0980)});
  CHECK(gaps(1, 0) == std::vector<float>{static_cast<float>(0.1012 - 0.1000)});
  CHECK(gaps(1, 1) == std::vector<float>{-static_cast<float>(0.1015 - 0.0995)});
  CHECK(gaps(2, 1) == std::vector<float>{-static_cast<float>(0.1035 - 0.1015)});
  CHECK(gaps(2, 2) == std::vector<float>{-inf, static_cast<float>(0.1035 - 0.1030)});  // in time order, either polarity before
  // Noise injection makes counts without intervals.
  Rng rng(1);
  CHECK(!inject_noise(set.slices[0], 0.5, rng).has_intervals());
}

TEST_CASE("dead-time weight: gap / (gap - period) crossings per event, saturated within 1.5 periods, its derivative exact") {
  const double tau = 1e-4;
  CHECK(dead_time_weight(2e-4, tau).weight == doctest::Approx(2.0));
  CHECK(dead_time_weight(1e-3, tau).weight == doctest::Approx(1e-3 / 9e-4));
  CHECK(!dead_time_weight(1.6e-4, tau).saturated);
  const auto sat = dead_time_weight(1.2e-4, tau);
  CHECK(sat.saturated);
  CHECK(sat.weight == doctest::Approx(3.0));  // the weight at the saturation's edge, continuous there
  CHECK(dead_time_weight(1.5e-4 * (1 + 1e-9), tau).weight == doctest::Approx(3.0).epsilon(1e-6));
  CHECK(sat.dweight == 0.0);
  const auto first = dead_time_weight(std::numeric_limits<double>::infinity(), tau);
  CHECK(first.weight == 1.0);
  CHECK(first.dweight == 0.0);
  // No period: one crossing per event, and the derivative is the slope at 0 (1 / gap).
  CHECK(dead_time_weight(2e-4, 0).weight == 1.0);
  CHECK(dead_time_weight(2e-4, 0).dweight == doctest::Approx(5e3));
  // The derivative against central differences, at and away from 0.
  for (const double g : {1.7e-4, 3e-4, 2e-3})
    for (const double t : {0.0, 2e-5, 1e-4}) {
      if (g <= 1.5 * t) continue;
      CAPTURE(g);
      CAPTURE(t);
      const double h = 1e-9, tl = std::max(0.0, t - h), th = t + h;
      const double fd = (dead_time_weight(g, th).weight - dead_time_weight(g, tl).weight) / (th - tl);
      CHECK(dead_time_weight(g, t).dweight == doctest::Approx(fd).epsilon(1e-4));
    }
}

TEST_CASE("uniform boundaries and bad boundaries") {
  auto b = uniform_boundaries(1.0, 2.0, 4);
  CHECK(b.size() == 5);
  CHECK(b[2] == doctest::Approx(1.5));
  EventStream ev;
  ev.width = ev.height = 2;
  CHECK_THROWS_WITH(slice_events(ev, {1.0, 1.0}), doctest::Contains("boundaries must increase strictly"));
}

TEST_CASE("noise injection adds round(ratio × count) events with balanced polarity, redrawn per call") {
  auto ev = random_stream(40000, 64, 48, 9);
  auto set = slice_events(ev, {ev.t.front(), ev.t.back() + 1});
  const auto& s = set.slices[0];
  Rng rng(4);
  auto noisy = inject_noise(s, 0.05, rng);
  const std::size_t added = noisy.total - s.total;
  CHECK(added == 2000);
  long dpos = 0, dneg = 0;
  for (std::size_t p = 0; p < s.pixels(); ++p) {
    dpos += noisy.pos[p] - s.pos[p];
    dneg += noisy.neg[p] - s.neg[p];
  }
  CHECK(dpos + dneg == 2000);
  CHECK(std::abs(dpos - dneg) < 200);  // ~4.5 σ of a fair coin over 2000 draws
  auto again = inject_noise(s, 0.05, rng);
  CHECK(again.pos != noisy.pos);
  Rng r1(4);
  CHECK(inject_noise(s, 0.05, r1).pos == noisy.pos);  // same seed, same noise
  CHECK(inject_noise(s, 0.0, rng).pos == s.pos);
  CHECK_THROWS(inject_noise(s, -1.0, rng));
}

TEST_CASE("event stream validation names the offending event") {
  EventStream ev;
  ev.width = 4;
  ev.height = 4;
  ev.push_back(0.1, 1, 1, 1);
  ev.push_back(0.05, 1, 1, 1);
  CHECK_THROWS_WITH(ev.validate("s"), doctest::Contains("s: event 1 goes back in time"));
}

TEST_CASE("count prefix: every window's counts equal a brute-force sum over its slices") {
  auto ev = random_stream(30000, 13, 9, 5);
  auto set = slice_events(ev, uniform_boundaries(ev.t[0], ev.t[29999], 7));
  const CountPrefix pre(set);
  REQUIRE(pre.n_slices == 7);
  for (std::size_t a = 0; a <= 7; ++a)
    for (std::size_t b = a; b <= 7; ++b)
      for (std::size_t p = 0; p < 13 * 9; ++p) {
        int np = 0, nn = 0;
        for (std::size_t k = a; k < b; ++k) {
          np += set.slices[k].pos[p];
          nn += set.slices[k].neg[p];
        }
        REQUIRE(pre.window_pos(a, b, p) == np);
        REQUIRE(pre.window_neg(a, b, p) == nn);
      }
}

TEST_CASE("hot pixels behind a colour mosaic: an object of one filter's colour is not suspected, a hot pixel among it is") {
  // An RGGB sensor sees a red object over x, y in [8, 24): only its red sites (even x, even y) fire, 100
  // events each; their eight nearest pixels are green and blue sites with none. One green site at (13, 12)
  // fires 300 times on its own.
  EventStream ev;
  ev.width = 32;
  ev.height = 32;
  double t = 0;
  const auto fire = [&](int x, int y, int n) {
    for (int k = 0; k < n; ++k) ev.push_back(t += 1e-6, x, y, k % 2 ? 1 : -1);
  };
  for (int y = 8; y < 24; y += 2)
    for (int x = 8; x < 24; x += 2) fire(x, y, 100);
  SUBCASE("the red sites share their count with the red sites two apart: none is suspected") { CHECK(suspected_hot_pixels(ev).empty()); }
  SUBCASE("the hot green site stands out against its neighbours and against the green sites two apart") {
    fire(13, 12, 300);
    const auto hot = suspected_hot_pixels(ev);
    REQUIRE(hot.size() == 1);
    CHECK(hot[0].x == 13);
    CHECK(hot[0].y == 12);
    CHECK(hot[0].events == 300);
    CHECK(hot[0].neighbours == 100);  // its red neighbours at (12, 12) and (14, 12)
  }
  SUBCASE("a lone busy pixel on a plain sensor is suspected") {
    EventStream one;
    one.width = one.height = 16;
    for (int k = 0; k < 60; ++k) one.push_back(1e-6 * k, 5, 7, 1);
    const auto hot = suspected_hot_pixels(one);
    REQUIRE(hot.size() == 1);
    CHECK(hot[0].neighbours == 0);
  }
}
