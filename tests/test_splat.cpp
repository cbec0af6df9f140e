// Gaussian splatting's rasterizer (splat/): the tiled compositing against a visit of every Gaussian at every
// pixel, a subset of pixels against the whole image, threads against one, and the whole backward (pixels →
// projection → parameters and backdrop) against finite differences in double.
#include <doctest/doctest.h>

#include <cmath>
#include <type_traits>
#include <vector>

#include "evnerf/core/parallel.hpp"
#include "evnerf/core/rng.hpp"
#include "evnerf/geometry/camera.hpp"
#include "evnerf/nn/activation.hpp"
#include "evnerf/loss/objective.hpp"
#include "evnerf/model/poses.hpp"
#include "evnerf/render/scene.hpp"
#include "evnerf/splat/pass.hpp"
#include "evnerf/splat/rasterizer.hpp"

using namespace evnerf;

namespace {

/// Equal but for rounding: the compiler contracts a·b + c into one FMA differently on different paths
/// (-march=native), so a path and its reference agree to a few float ulps, not to the bit.
template <class T>
void check_close(const std::vector<T>& a, const std::vector<T>& b) {
  REQUIRE(a.size() == b.size());
  const double tol = std::is_same_v<T, float> ? 2e-5 : 1e-12;
  std::size_t bad = 0;
  for (std::size_t i = 0; i < a.size(); ++i) bad += !(std::abs(double(a[i]) - double(b[i])) <= tol * (1 + std::abs(double(b[i]))));
  CHECK(bad == 0);
}

/// n Gaussians scattered in a box 2–4 units in front of a camera at the origin looking down +z, of scales
/// `scale` (log-scales spread ±0.3 about its log), random rotations, opacity logits in [lo, hi] and colour
/// coefficients about 0.5.
template <class L, class T>
std::vector<T> scene(std::size_t n, std::uint64_t seed, double scale, double lo = -1, double hi = 2) {
  Rng rng(seed);
  std::vector<T> p(n * L::size);
  for (std::size_t i = 0; i < n; ++i) {
    T* g = p.data() + i * L::size;
    g[L::mean] = static_cast<T>(rng.uniform(-1.2, 1.2));
    g[L::mean + 1] = static_cast<T>(rng.uniform(-0.9, 0.9));
    g[L::mean + 2] = static_cast<T>(rng.uniform(2.0, 4.0));
    for (int a = 0; a < 3; ++a) g[L::log_scale + a] = static_cast<T>(std::log(scale) + rng.uniform(-0.3, 0.3));
    for (int a = 0; a < 4; ++a) g[L::rotation + a] = static_cast<T>(rng.uniform(-1, 1));
    g[L::opacity] = static_cast<T>(rng.uniform(lo, hi));
    for (int k = 0; k < L::channels * L::sh; ++k)
      g[L::colour + k] = static_cast<T>(k % L::sh == 0 ? rng.uniform(0.2, 1.5) : rng.uniform(-0.4, 0.4));
  }
  return p;
}

splat::View view(int w, int h) {
  splat::View v;
  v.fx = v.fy = 0.9 * w;
  v.cx = 0.5 * w + 0.3, v.cy = 0.5 * h - 0.2;
  v.width = w, v.height = h;
  v.pose.q = Quat(Eigen::AngleAxisd(0.05, Vec3(0.3, 1, 0).normalized()));
  v.pose.t = Vec3(0.05, -0.02, -0.1);
  return v;
}

template <class T>
std::vector<T> all_pixels(int w, int h) {
  std::vector<T> px;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) px.push_back(static_cast<T>(x + 0.5)), px.push_back(static_cast<T>(y + 0.5));
  return px;
}

}  // namespace

TEST_CASE_TEMPLATE("splat: the tiled compositing equals a visit of every Gaussian, for any subset of pixels and thread count", T, float,
                   double) {
  using L = splat::Layout<3, 1>;
  constexpr int C = 3;
  const int w = 70, h = 50;
  const auto params = scene<L, T>(300, 7, 0.08);
  const auto v = view(w, h);
  splat::Projection<T, C> proj;
  splat::project<L, nn::Softplus>(params.data(), 300, v, proj);
  std::size_t shown = 0;
  for (auto s : proj.visible) shown += s;
  CHECK(shown > 200);
  const auto px = all_pixels<T>(w, h);
  const std::size_t P = px.size() / 2;
  const T bg[C] = {T(0.3), T(0.5), T(0.7)};
  std::vector<T> ref_c(C * P), ref_d(P), ref_a(P);
  splat::reference_composite(proj, px.data(), P, bg, ref_c.data(), ref_d.data(), ref_a.data());
  double covered = 0;
  for (auto a : ref_a) covered += a > T(0.5);
  CHECK(covered > 0.3 * P);  // the scene covers much of the image: the test composites real overlaps
  splat::Rasterizer<T, C> raster;
  std::vector<T> one;
  for (int threads : {1, 2, 3}) {
    ScopedThreadCount tc(threads);
    std::vector<T> c(C * P), d(P), a(P);
    raster.forward(proj, v, px.data(), P, bg, c.data(), d.data(), a.data(), false);
    check_close(c, ref_c);
    check_close(d, ref_d);
    check_close(a, ref_a);
    if (threads == 1) one = c;
    CHECK(c == one);  // the thread count changes nothing, to the bit
  }
  // A scattered subset (with coordinates between pixel centres) renders as the whole image does there.
  Rng rng(3);
  std::vector<T> sub;
  for (int k = 0; k < 97; ++k) sub.push_back(static_cast<T>(rng.uniform(0, w))), sub.push_back(static_cast<T>(rng.uniform(0, h)));
  std::vector<T> c(C * 97), d(97), a(97), rc(C * 97), rd(97), ra(97);
  raster.forward(proj, v, sub.data(), 97, bg, c.data(), d.data(), a.data(), true);
  splat::reference_composite(proj, sub.data(), 97, bg, rc.data(), rd.data(), ra.data());
  check_close(c, rc);
  check_close(d, rd);
  std::vector<T> c2(C * 97);  // the tile path (rendering, nothing kept) on the same scattered pixels
  raster.forward(proj, v, sub.data(), 97, bg, c2.data(), d.data(), a.data(), false);
  check_close(c2, rc);
  CHECK(raster.pairs() < 300u * 9u);  // only the tiles that hold a pixel were filled
}

TEST_CASE("splat: finite differences in double of a loss of the rendered pixels, for every parameter and the backdrop") {
  using L = splat::Layout<2, 1>;
  constexpr int C = 2;
  const std::size_t n = 6;
  const int w = 24, h = 18;
  auto params = scene<L, double>(n, 11, 0.35, -0.5, 0.5);
  const auto v = view(w, h);
  Rng rng(5);
  std::vector<double> px, wt;
  for (int k = 0; k < 40; ++k) px.push_back(rng.uniform(2, w - 2)), px.push_back(rng.uniform(2, h - 2));
  for (int k = 0; k < 40 * C; ++k) wt.push_back(rng.uniform(-1, 1));
  double bg[C] = {0.4, 0.6};
  const std::size_t P = 40;
  splat::Rasterizer<double, C> raster;
  // The loss: Σ_p Σ_c wt · colour², so that the colour's gradient differs pixel to pixel.
  auto loss = [&](const std::vector<double>& prm, const double* b) {
    splat::Projection<double, C> proj;
    splat::project<L, nn::Softplus>(prm.data(), n, v, proj);
    std::vector<double> c(C * P);
    raster.forward(proj, v, px.data(), P, b, c.data(), nullptr, nullptr, false);
    double s = 0;
    for (std::size_t k = 0; k < C * P; ++k) s += wt[k] * c[k] * c[k];
    return s;
  };
  splat::Projection<double, C> proj;
  splat::project<L, nn::Softplus>(params.data(), n, v, proj);
  for (auto s : proj.visible) REQUIRE(s);
  std::vector<double> c(C * P), dc(C * P);
  raster.forward(proj, v, px.data(), P, bg, c.data(), nullptr, nullptr, true);
  for (std::size_t k = 0; k < C * P; ++k) dc[k] = 2 * wt[k] * c[k];
  splat::ProjectionGrad<double, C> pg;
  double dbg[C] = {0, 0};
  raster.backward(proj, px.data(), dc.data(), bg, pg, dbg);
  std::vector<double> grad(params.size(), 0.0);
  splat::project_backward<L, nn::Softplus>(params.data(), n, v, proj, pg, grad.data());
  const double eps = 1e-6;
  int checked = 0, nonzero = 0;
  for (std::size_t i = 0; i < params.size(); ++i) {
    auto p = params;
    p[i] += eps;
    const double up = loss(p, bg);
    p[i] -= 2 * eps;
    const double down = loss(p, bg);
    const double fd = (up - down) / (2 * eps);
    CHECK_MESSAGE(grad[i] == doctest::Approx(fd).epsilon(1e-5).scale(1e-3), "parameter ", i % L::size, " of Gaussian ", i / L::size);
    ++checked;
    nonzero += std::abs(fd) > 1e-4;
  }
  for (int k = 0; k < C; ++k) {
    double b[C] = {bg[0], bg[1]};
    b[k] += eps;
    const double up = loss(params, b);
    b[k] -= 2 * eps;
    const double fd = (up - loss(params, b)) / (2 * eps);
    CHECK(dbg[k] == doctest::Approx(fd).epsilon(1e-5).scale(1e-3));
  }
  CHECK(checked == static_cast<int>(n * L::size));
  CHECK(nonzero > static_cast<int>(n * L::size) * 3 / 4);  // the check sees the gradients, not zeros
}

TEST_CASE("splat: the compositing's exponential in float is within 2 ulp of std::exp") {
  float worst = 0;
  for (int k = 0; k <= 200000; ++k) {
    const float x = -87.0f * static_cast<float>(k) / 200000.0f;
    const float want = std::exp(x), got = splat::gaussian_exp(x);
    worst = std::max(worst, std::abs(got - want) / want);
  }
  CHECK(worst < 2.5e-7f);  // 2 ulp of a float is 2.4e-7 relative at worst
  CHECK(splat::gaussian_exp(-1000.0f) == splat::gaussian_exp(-87.0f));
  CHECK(splat::gaussian_exp(0.0f) == 1.0f);
}

TEST_CASE(
    "splat: an event objective scores Gaussians unchanged; finite differences in double of its loss for every parameter and threshold") {
  // A window of three slices between four poses moving sideways, Ev-NeRF's interval loss on 60 pixels of a
  // distorted 32 x 24 sensor, the rays the objective asks for rendered by a training pass.
  using L = splat::Layout<1, 1>;
  const std::size_t n = 7;
  const int w = 32, h = 24;
  auto params = scene<L, double>(n, 21, 0.4, -0.5, 1.0);
  const geometry::Camera cam(w, h, 0.9 * w, 0.9 * w, 0.5 * w + 0.3, 0.5 * h - 0.2, {0.05, -0.01, 0, 0, 0});
  const auto dirs = render::pixel_directions(cam);
  std::vector<geometry::Pose> poses(5);
  for (int k = 0; k < 5; ++k) {
    poses[k].q = Quat(Eigen::AngleAxisd(0.02 * k, Vec3(0, 1, 0)));
    poses[k].t = Vec3(0.03 * k, -0.01 * k, 0);
  }
  Rng rng(8);
  loss::StepDraw draw;
  draw.first = 1, draw.len = 3;
  const int P = 60;
  for (int i = 0; i < P; ++i) {
    draw.pixels.push_back(static_cast<std::uint32_t>(rng.below(static_cast<std::uint64_t>(w * h))));
    for (int k = 0; k < 3; ++k) {
      draw.npos.push_back(static_cast<int>(rng.below(3)));
      draw.nneg.push_back(static_cast<int>(rng.below(3)));
    }
  }
  loss::TileView t;
  t.draw = &draw, t.P = P, t.batch = P, t.camera = &cam, t.poses = poses.data(), t.pixel_dirs = dirs.data();
  using Objective = loss::WindowInterval<3, loss::HalfSlackCounts>;
  const Objective objective;
  loss::RayList rays;
  Objective::scratch sc;
  objective.rays(t, rays, sc);
  REQUIRE(rays.size() == 2 * P);
  std::vector<double> th{0.3, -0.25, 0.2, -0.3, 0.25, -0.2};  // B⁺_k, B⁻_k
  const double bg = 0.35;
  splat::TrainingPass<L, nn::Sigmoid, double> pass;
  auto loss_of = [&](const std::vector<double>& prm, const std::vector<double>& b, std::vector<double>* grad) {
    std::vector<double> bp{b[0], b[2], b[4]}, bm{b[1], b[3], b[5]};
    std::vector<double> gth(6, 0.0);
    pass.forward(prm.data(), n, cam, poses.data(), rays, dirs.data(), &bg);
    const loss::WindowThresholds<double> wt{3, bp.data(), bm.data(), grad ? gth.data() : nullptr, nullptr};
    double l[1] = {0};
    objective.score(t, pass.values(), wt, sc, l);
    if (grad) {
      grad->assign(prm.size() + 6, 0.0);
      pass.backward(prm.data(), grad->data());
      std::copy(gth.begin(), gth.end(), grad->begin() + static_cast<std::ptrdiff_t>(prm.size()));
    }
    return l[0];
  };
  std::vector<double> grad;
  const double l0 = loss_of(params, th, &grad);
  CHECK(l0 > 0.05);  // the hinge's active side, for most pixels
  CHECK(pass.poses() == 2u);
  const double eps = 1e-6;
  int nonzero = 0;
  for (std::size_t i = 0; i < params.size() + th.size(); ++i) {
    auto p = params;
    auto b = th;
    double& x = i < params.size() ? p[i] : b[i - params.size()];
    x += eps;
    const double up = loss_of(p, b, nullptr);
    x -= 2 * eps;
    const double fd = (up - loss_of(p, b, nullptr)) / (2 * eps);
    CHECK_MESSAGE(grad[i] == doctest::Approx(fd).epsilon(1e-5).scale(1e-4), "value ", i);
    nonzero += std::abs(fd) > 1e-5;
  }
  CHECK(nonzero > static_cast<int>(params.size() + th.size()) * 3 / 4);

  // The camera gradient: each end pose's twist ε of pose ∘ Exp(ε), against finite differences.
  std::vector<std::array<double, 6>> dpose(poses.size());
  {
    pass.forward(params.data(), n, cam, poses.data(), rays, dirs.data(), &bg);
    std::vector<double> gth(6, 0.0), bp{th[0], th[2], th[4]}, bm{th[1], th[3], th[5]}, dp(params.size());
    const loss::WindowThresholds<double> wt{3, bp.data(), bm.data(), gth.data(), nullptr};
    double l[1] = {0};
    objective.score(t, pass.values(), wt, sc, l);
    pass.backward(params.data(), dp.data(), nullptr, dpose.data());
  }
  const auto saved = poses;
  int moved = 0;
  for (std::size_t k : {std::size_t{1}, std::size_t{4}})
    for (int a = 0; a < 6; ++a) {
      auto at = [&](double e) {
        Vec3 phi = Vec3::Zero(), rho = Vec3::Zero();
        (a < 3 ? phi : rho)[a % 3] = e;
        poses = saved;
        poses[k] = saved[k] * twist_exp(phi, rho);
        return loss_of(params, th, nullptr);
      };
      const double fd = (at(eps) - at(-eps)) / (2 * eps);
      poses = saved;
      CHECK_MESSAGE(dpose[k][a] == doctest::Approx(fd).epsilon(1e-5).scale(1e-4), "pose ", k, " twist ", a);
      moved += std::abs(fd) > 1e-3;
    }
  CHECK(moved >= 10);
  for (std::size_t k : {std::size_t{0}, std::size_t{2}, std::size_t{3}}) CHECK(dpose[k] == std::array<double, 6>{});
}

TEST_CASE("splat: a training pass's value at (pose, pixel) is that pixel of the pose's whole rendered image") {
  using L = splat::Layout<1, 0>;
  const std::size_t n = 40;
  const int w = 40, h = 30;
  const auto params = scene<L, float>(n, 3, 0.3);
  const geometry::Camera cam(w, h, 0.9 * w, 0.9 * w, 0.5 * w + 0.3, 0.5 * h - 0.2);
  const auto dirs = render::pixel_directions(cam);
  std::vector<geometry::Pose> poses(3);
  poses[1].t = Vec3(0.1, 0, 0), poses[2].q = Quat(Eigen::AngleAxisd(0.05, Vec3(1, 0, 0)));
  loss::RayList rays;
  Rng rng(2);
  for (int r = 0; r < 50; ++r) rays.add(2 - r % 3, static_cast<std::uint32_t>(rng.below(static_cast<std::uint64_t>(w * h))), 0);
  const float bg = 0.2f;
  splat::TrainingPass<L, nn::Sigmoid, float> pass;
  pass.forward(params.data(), n, cam, poses.data(), rays, dirs.data(), &bg);
  CHECK(pass.poses() == 3u);
  const auto px = all_pixels<float>(w, h);
  for (std::size_t k = 0; k < 3; ++k) {
    const auto v = splat::view_of(cam, poses[k], 0.01);
    splat::Projection<float, 1> proj;
    splat::project<L, nn::Sigmoid>(params.data(), n, v, proj);
    splat::Rasterizer<float, 1> raster;
    std::vector<float> image(static_cast<std::size_t>(w * h));
    raster.forward(proj, v, px.data(), image.size(), &bg, image.data(), nullptr, nullptr, false);
    int seen = 0;
    for (int r = 0; r < rays.size(); ++r)
      if (rays.pose[r] == k) {
        CHECK(pass.values().at(r, 0) == doctest::Approx(image[rays.pixel[r]]).epsilon(2e-5));
        ++seen;
      }
    CHECK(seen > 10);
  }
}
