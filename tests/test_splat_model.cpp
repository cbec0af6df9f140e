// Gaussians as a model's representation (model/splatting.hpp): the whole training loss's gradient against
// finite differences in double, training through the model's step, checkpoints, the trainer, renders.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <evnerf/model/model.hpp>
#include <evnerf/model/splatting.hpp>
#include <evnerf/eval/export.hpp>
#include <evnerf/eval/seeds.hpp>
#include <evnerf/loss/teacher.hpp>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "tiny_models.hpp"

using namespace evnerf;

namespace {
using Window3 = loss::WindowInterval<3, loss::HalfSlackCounts>;
template <class T>
using TinyScene = Splatting<splat::Layout<1, 1>, nn::Softplus, 48, 40, splat::Steps3dgs, splat::FixedGaussians, T>;
/// The double model's objective carries the teacher term (a weight of 1 that lasts), so that the whole
/// loss's differences include it where a test gives a teacher.
using SplatDouble = Model<TinyScene<double>, loss::JointThresholds, loss::DefaultNoise, loss::Plus<Window3, loss::Teacher<1000, 1000000>>>;
using SplatFloat = Model<TinyScene<float>, loss::ProjectedThresholds, loss::DefaultNoise, Window3>;

/// Gaussians made wider and more opaque than a fresh scene's, with colours that vary with direction, so
/// that most of them cover drawn pixels and every group of parameters has a gradient.
template <class M>
void spread(M& m, std::uint64_t seed) {
  using L = typename M::representation_type::layout;
  const auto& rep = m.renderer();
  Rng rng(seed);
  auto& p = m.params().values;
  for (std::size_t i = 0; i < M::representation_type::initial; ++i) {
    auto set = [&](int s, double real) { p[i * L::size + s] = static_cast<typename M::Scalar>(real / rep.unit(s)); };
    auto get = [&](int s) { return static_cast<double>(p[i * L::size + s]) * rep.unit(s); };
    for (int a = 0; a < 3; ++a) set(L::log_scale + a, get(L::log_scale + a) + std::log(2.0) + 0.3 * (rng.uniform() - 0.5));
    for (int a = 0; a < 4; ++a) set(L::rotation + a, (a == 0 ? 1.0 : 0.0) + 0.4 * (rng.uniform() - 0.5));
    set(L::opacity, 0.5 * (rng.uniform() - 0.5));
    for (int k = 0; k < L::sh; ++k) set(L::colour + k, get(L::colour + k) + 0.5 * (rng.uniform() - 0.5));
  }
}
}  // namespace

TEST_CASE(
    "splatting model: finite differences in double of the whole training loss (events and a teacher) for every parameter, threshold and "
    "the backdrop") {
  evtest::Fixture f;
  f.cfg.learn_background = true;
  Rng trng(7);  // a teacher's images: any luminance in [0.2, 0.8] at every boundary pose and pixel
  f.td.teacher.resize(f.td.boundary_poses.size() * static_cast<std::size_t>(f.td.camera.width()) * f.td.camera.height());
  for (float& v : f.td.teacher) v = static_cast<float>(0.2 + 0.6 * trng.uniform());
  SplatDouble m(f.td, train::scene_box(f.td, f.cfg), 5);
  spread(m, 3);
  Rng rng(11);
  for (std::size_t i = 0; i < m.n_slices(); ++i) {
    m.params().values[m.threshold_offset() + 2 * i] = 0.2 + 0.2 * rng.uniform();
    m.params().values[m.threshold_offset() + 2 * i + 1] = -(0.2 + 0.2 * rng.uniform());
  }
  m.params().values[SplatDouble::backdrop_offset()] = 0.3;
  using L = splat::Layout<1, 1>;
  for (const std::uint64_t seed : {1u, 2u}) {
    CAPTURE(seed);
    const auto st0 = m.gradients(f.td, 96, seed);
    REQUIRE(std::isfinite(st0.loss));
    REQUIRE(st0.loss > 0);
    CHECK(st0.term_loss[1] > 0);  // the teacher's term
    CHECK(st0.samples > 0);
    const std::vector<double> g = m.params().grads;
    auto& x = m.params().values;
    int checked = 0, kinks = 0, bad = 0, thresholds = 0;
    std::array<int, L::size> by_slot{};
    for (std::size_t i = 0; i < x.size(); ++i) {
      const bool gaussian = i < SplatDouble::backdrop_offset();
      if (gaussian && i / L::size >= 40) {  // unused slots: invisible, no gradient
        CHECK(g[i] == 0);
        continue;
      }
      const double x0 = x[i], h = 1e-6 * std::max(1.0, std::abs(x0));
      x[i] = x0 + h;
      const double lp = m.gradients(f.td, 96, seed).loss;
      x[i] = x0 - h;
      const double lm = m.gradients(f.td, 96, seed).loss;
      x[i] = x0;
      const double fwd = (lp - st0.loss) / h, bwd = (st0.loss - lm) / h, num = (lp - lm) / (2 * h);
      ++checked;
      if (std::abs(fwd - bwd) > 1e-3 * std::max(1.0, std::abs(num))) {  // a Gaussian crossing the 1/255 cut-off
        ++kinks;
        continue;
      }
      const double err = std::abs(num - g[i]) / std::max(1e-3, std::abs(num));
      if (err > 1e-4 && std::abs(num - g[i]) > 1e-9) {
        ++bad;
        MESSAGE("parameter " << i << ": analytic " << g[i] << ", finite differences " << num);
      }
      if (g[i] != 0 && gaussian) ++by_slot[i % L::size];
      if (g[i] != 0 && i >= m.threshold_offset()) ++thresholds;
    }
    CAPTURE(checked);
    CAPTURE(kinks);
    CHECK(bad == 0);
    CHECK(kinks * 20 < checked);
    for (int s = 0; s < L::size; ++s) {
      CAPTURE(s);
      CHECK(by_slot[s] >= 5);  // every group of parameters has gradients that were compared
    }
    CHECK(thresholds >= 2);
    CHECK(g[SplatDouble::backdrop_offset()] != 0);
  }
}

TEST_CASE("splatting model: the step lowers the loss, a checkpoint resumes bit for bit, another model's file is refused") {
  evtest::Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  SplatFloat m(f.td, box, 5);
  SplatFloat fresh_copy = m;
  for (int k = 0; k < 200; ++k) REQUIRE(std::isfinite(m.train_step(f.td, 256, 9).loss));
  // The same draws (window, pixels, noise: keyed by the step) scored by the fresh and the trained scene.
  fresh_copy.optimizer().set_step(m.step());
  double before = 0, after = 0;
  for (const std::uint64_t seed : {21u, 22u, 23u, 24u}) {
    before += fresh_copy.gradients(f.td, 1024, seed).event_loss;
    after += m.gradients(f.td, 1024, seed).event_loss;
  }
  CAPTURE(before);
  CAPTURE(after);
  CHECK(after < 0.9 * before);
  auto mean_loss = [&](SplatFloat& model, int steps) {
    for (int k = 0; k < steps; ++k) model.train_step(f.td, 256, 9);
  };

  const std::string bytes = m.serialize("splat", f.run());
  SplatFloat resumed;
  resumed.deserialize(bytes, "splat.ckpt");
  mean_loss(m, 10);
  mean_loss(resumed, 10);
  CHECK(m.params().values == resumed.params().values);
  CHECK(m.optimizer().m() == resumed.optimizer().m());

  // A field's checkpoint names another architecture; a scene's own, cut short, is refused too.
  using Field = EvNerf<TinyField, render::Stratified<16>, loss::ProjectedThresholds, loss::DefaultNoise, Window3>;
  Field other(f.td, box, 5);
  SplatFloat fresh;
  CHECK_THROWS_WITH_AS(fresh.deserialize(other.serialize("field", f.run()), "field.ckpt"), doctest::Contains("architecture"), Error);
  CHECK_THROWS_AS(fresh.deserialize(bytes.substr(0, bytes.size() / 2), "cut.ckpt"), Error);
}

TEST_CASE(
    "splatting model: densification grows and prunes the scene, and a run resumed between controls equals the whole run bit for bit") {
  evtest::Fixture f;
  // Controls every 10 steps from 10 to 60: the top 15 % grow, Gaussians under 0.5 % opacity are dropped.
  using Scene = Splatting<splat::Layout<1, 1>, nn::Softplus, 64, 24, splat::Steps3dgs, splat::Densify<10, 10, 60, 150, 10, 50>, float>;
  using M = Model<Scene, loss::ProjectedThresholds, loss::DefaultNoise, Window3>;
  M whole(f.td, train::scene_box(f.td, f.cfg), 5);
  whole.set_average(0.99);
  // A few Gaussians made faint enough to be pruned at the first control.
  using L = Scene::layout;
  for (std::size_t i = 0; i < 4; ++i)
    whole.params().values[i * L::size + L::opacity] = static_cast<float>(-7.0 / whole.renderer().unit(L::opacity));
  M part = whole;
  std::vector<std::size_t> used;
  int filled = 0;
  for (int k = 0; k < 45; ++k) {
    const auto before = whole.params().values;
    REQUIRE(std::isfinite(whole.train_step(f.td, 256, 4).loss));
    used.push_back(whole.renderer().in_use(whole.params().values.data()));
    // A slot the control filled starts with Adam's moments at zero and the average at its values.
    for (std::size_t i = 0; i < Scene::capacity; ++i) {
      const std::size_t o = i * L::size + L::opacity;
      if (before[o] * whole.renderer().unit(L::opacity) > Scene::kDeadLogit + 1 ||
          whole.params().values[o] * whole.renderer().unit(L::opacity) <= Scene::kDeadLogit + 1)
        continue;
      ++filled;
      for (int s = 0; s < L::size; ++s) {
        CHECK(whole.optimizer().m()[i * L::size + s] == 0);
        CHECK(whole.optimizer().v()[i * L::size + s] == 0);
        CHECK(whole.average().values()[i * L::size + s] == whole.params().values[i * L::size + s]);
      }
    }
  }
  CHECK(filled > 4);
  // One control by hand, every moment non-zero before it: the slots it changed (pruned, split, cloned into)
  // start over, the others keep their moments and average.
  {
    M m = whole;
    std::fill(m.params().grads.begin(), m.params().grads.end(), 0.01f);
    for (std::size_t k = 0; k < m.params().size(); ++k) m.optimizer().m()[k] = 0.5f, m.optimizer().v()[k] = 0.25f;
    m.params().values[5 * L::size + L::opacity] = static_cast<float>(-5.4 / m.renderer().unit(L::opacity));  // opacity 0.45 %: pruned
    const auto before = m.params().values;
    std::vector<float> shifted = before;
    for (float& v : shifted) v += 1;
    nn::ParameterAverage<float> average(0.99, shifted);
    Scene rep = m.renderer();
    rep.after_step(m.params().values, m.params().grads, m.optimizer(), average, f.td, 49, 1);
    int changed = 0, kept = 0;
    for (std::size_t i = 0; i < Scene::capacity; ++i) {
      bool differs = false;
      for (int s = 0; s < L::size; ++s) differs |= m.params().values[i * L::size + s] != before[i * L::size + s];
      for (int s = 0; s < L::size; ++s) {
        const std::size_t k = i * L::size + s;
        CHECK(m.optimizer().m()[k] == (differs ? 0.0f : 0.5f));
        CHECK(m.optimizer().v()[k] == (differs ? 0.0f : 0.25f));
        CHECK(average.values()[k] == (differs ? m.params().values[k] : before[k] + 1));
      }
      (differs ? changed : kept) += 1;
    }
    CHECK(m.params().values[5 * L::size + L::opacity] * m.renderer().unit(L::opacity) != doctest::Approx(-5.4));
    CHECK(changed >= 3);
    CHECK(kept > 10);
  }
  CAPTURE(used[8]);
  CAPTURE(used[9]);
  CHECK(used[8] == 24);          // nothing changes before the first control
  CHECK(used[9] != used[8]);     // the control at step 10
  CHECK(used.back() > used[8]);  // the scene grew
  for (std::size_t i = 0; i < 4; ++i)
    CHECK(whole.params().values[i * L::size + L::opacity] * whole.renderer().unit(L::opacity) >
          -7.5f);  // faint ones were refilled or pruned
  // Stopped at step 28 (statistics gathered since the control at 20), written, read, run on to 45.
  for (int k = 0; k < 28; ++k) part.train_step(f.td, 256, 4);
  M resumed;
  resumed.deserialize(part.serialize("splat", f.run()), "part.ckpt");
  for (int k = 28; k < 45; ++k) resumed.train_step(f.td, 256, 4);
  CHECK(resumed.params().values == whole.params().values);
  CHECK(resumed.optimizer().m() == whole.optimizer().m());
  CHECK(resumed.optimizer().v() == whole.optimizer().v());
  CHECK(resumed.average().values() == whole.average().values());
  // Without the statistics the resumed run would differ: a checkpoint whose statistics are cut is refused.
  M fresh;
  const std::string bytes = part.serialize("splat", f.run());
  CHECK_THROWS_AS(fresh.deserialize(bytes.substr(0, bytes.size() - 100), "cut.ckpt"), Error);
}

TEST_CASE("splatting model: trained by the trainer and rendered whole, the same scene for the same seed and threads") {
  evtest::Fixture f;
  auto cfg = f.run_config(30, 256);
  cfg.learn_background = false;
  cfg.background = 0.5;
  auto run = [&] {
    auto model = train::make_model<SplatFloat>(f.td, cfg);
    const auto r = train::run(model, f.td, cfg, {}, "splat", f.run());
    CHECK_FALSE(r.diverged);
    return model;
  };
  const auto a = run(), b = run();
  CHECK(a.params().values == b.params().values);
  const auto img = a.render(f.td.camera, f.td.pixel_dirs, f.td.boundary_poses[3]);
  REQUIRE(img.luminance.width == f.td.camera.width());
  double lo = 1e9, hi = -1e9;
  for (int y = 0; y < img.luminance.height; ++y)
    for (int x = 0; x < img.luminance.width; ++x) {
      const double v = img.luminance.at(x, y, 0), o = img.opacity.at(x, y);
      REQUIRE(std::isfinite(v));
      REQUIRE(o >= 0);
      REQUIRE(o <= 1);
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
  CHECK(hi > lo);  // the plane's checker shows
}

TEST_CASE("export: a Gaussian scene's drawn Gaussians in 3D Gaussian splatting's PLY layout") {
  evtest::Fixture f;
  SplatFloat m(f.td, train::scene_box(f.td, f.cfg), 5);
  auto& p = m.params().values;
  using Rep = SplatFloat::representation_type;
  using L = Rep::layout;
  const auto u = m.renderer().units();
  // Slot 0: a Gaussian set by hand (in the scene's units); slot 1 under 1/255 opacity; the unused slots
  // beyond `initial` are dead already.
  const double g0[] = {0.1, -0.2, 1.4, std::log(0.02), std::log(0.03), std::log(0.05), 2, 0, 0, 0, 1.5};
  for (int s = 0; s < 11; ++s) p[s] = static_cast<float>(g0[s] / u[s]);
  p[L::colour] = static_cast<float>(splat::activation_inverse<nn::Softplus>(0.8) / evaluation::kSh0 / u[L::colour]);
  p[L::size + L::opacity] = static_cast<float>(-6.0 / u[L::opacity]);  // sigmoid(−6) ≈ 0.0025 < 1/255
  const auto g = evaluation::gaussians_of(m.renderer(), p.data());
  CHECK(g.size() == Rep::initial - 1);
  REQUIRE(g.size() > 0);
  CHECK(g.mean[0][2] == doctest::Approx(1.4).epsilon(1e-5));
  CHECK(g.log_scale[0][1] == doctest::Approx(std::log(0.03)).epsilon(1e-5));
  CHECK(g.rotation[0][0] == doctest::Approx(1.0));  // (2, 0, 0, 0) normalised
  CHECK(g.opacity_logit[0] == doctest::Approx(1.5).epsilon(1e-5));
  CHECK(g.luminance[0] == doctest::Approx(0.8).epsilon(1e-4));
  const auto v = evaluation::gaussians_ply(g, 1.6);
  REQUIRE(v.names.size() == 17);
  CHECK(v.names[6] == "f_dc_0");
  CHECK(v.names[9] == "opacity");
  CHECK(v.names[16] == "rot_3");
  CHECK(v.floats[6] == doctest::Approx((0.8 / 1.6 - 0.5) / evaluation::kSh0).epsilon(1e-4));  // a viewer's 0.5 + kSh0 · f_dc
  CHECK(v.floats[7] == v.floats[6]);                                                          // grey in every channel
  CHECK(v.floats[10] == doctest::Approx(std::log(0.02)).epsilon(1e-5));
}

namespace {
constexpr double kStrip = 0.15;  ///< the half-width of strip_teacher's strip
/// Where the ray of pixel (x, y) at `pose` meets the fixture's plane z = 1.5, and its depth (0: never).
std::pair<Vec3, double> on_plane(const geometry::Camera& cam, const std::vector<Vec3f>& dirs, const geometry::Pose& pose, int x, int y) {
  const Vec3 d = pose.q * dirs[static_cast<std::size_t>(y) * cam.width() + x].cast<double>();
  const double s = (1.5 - pose.t.z()) / d.z();
  return {pose.t + s * d, s > 0 ? s : 0.0};  // the directions' camera z is 1: s is the depth
}
/// A teacher that knows the fixture's scene as a field would: the plane z = 1.5 opaque over |x| ≤ kStrip
/// (luminance 0.2 left of x = 0, 0.8 right of it) and empty elsewhere.
Rendering strip_teacher(const geometry::Camera& cam, const geometry::Pose& pose) {
  Rendering r{Image(cam.width(), cam.height()), Image(cam.width(), cam.height()), Image(cam.width(), cam.height())};
  const auto dirs = render::pixel_directions(cam);
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x) {
      const auto [p, s] = on_plane(cam, dirs, pose, x, y);
      if (!(s > 0) || std::abs(p.x()) > kStrip) continue;
      r.opacity.at(x, y) = 1;
      r.depth.at(x, y) = static_cast<float>(s);
      r.luminance.at(x, y) = p.x() < 0 ? 0.2f : 0.8f;
    }
  return r;
}
}  // namespace

TEST_CASE("splatting model: Gaussians started from a teacher's surfaces (train --start-from)") {
  evtest::Fixture f;
  const auto& poses = f.td.boundary_poses;
  REQUIRE(poses.size() >= 4);
  // Every opaque pixel of every pose, unmerged: a point on the plane inside the strip, as wide as a pixel.
  const auto all = evaluation::gaussian_seeds(strip_teacher, f.td.camera, poses, 1000000, {.stride = 2});
  std::size_t opaque = 0, pixels = 0;
  for (const auto& pose : poses) {
    const auto r = strip_teacher(f.td.camera.resized(16, 12), pose);
    for (float o : r.opacity.data) opaque += o > 0.5f, ++pixels;
  }
  REQUIRE(opaque > 0);
  REQUIRE(opaque < pixels);  // some rays see nothing: they seed nothing
  CHECK(all.size() == opaque);
  for (std::size_t i = 0; i < all.size(); ++i) {
    CHECK(all.position[i].z() == doctest::Approx(1.5).epsilon(1e-5));
    CHECK(std::abs(all.position[i].x()) <= kStrip + 1e-6);
    CHECK((all.luminance[i] == 0.2f || all.luminance[i] == 0.8f));
    CHECK(all.width[i] >= 1.5 / 15 - 1e-6);  // a pixel of the 16 x 12 camera (fx 15) at depth 1.5, or a little more off-axis
    CHECK(all.width[i] <= 1.5 * 1.25 / 15);
  }
  // Merged down to a capacity: the points of a lattice cell averaged, on the plane, as wide as the spacing.
  using Rep = SplatFloat::representation_type;
  auto seeds = evaluation::gaussian_seeds(strip_teacher, f.td.camera, poses, Rep::capacity - 4, {.stride = 2});
  CHECK(seeds.size() <= Rep::capacity - 4);
  CHECK(seeds.size() >= (Rep::capacity - 4) / 4);  // the smallest spacing that fits, not a coarse one
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    CHECK(seeds.position[i].z() == doctest::Approx(1.5).epsilon(1e-5));
    CHECK(seeds.luminance[i] >= 0.2f - 1e-6f);
    CHECK(seeds.luminance[i] <= 0.8f + 1e-6f);
    const double level = std::log2(seeds.width[i]);  // cells a power of two wide
    CHECK(level == std::round(level));
  }
  // The model takes the seeds, the teacher's thresholds and backdrop; the other slots stay unused.
  auto cfg = f.run_config(10, 128);
  SplatFloat m = train::make_model<SplatFloat>(f.td, cfg);
  for (std::size_t k = 0; k < m.n_slices(); ++k) seeds.thresholds.insert(seeds.thresholds.end(), {0.17 + 0.001 * k, -0.23});
  seeds.backdrop = {0.05};
  m.start_from(seeds);
  for (std::size_t k = 0; k < m.n_slices(); ++k) {
    CHECK(m.threshold_pos(k) == doctest::Approx(0.17 + 0.001 * k));
    CHECK(m.threshold_neg(k) == doctest::Approx(-0.23));
  }
  CHECK(m.renderer().learns_backdrop());
  CHECK((*m.renderer().backdrop(m.params().values.data()))[0] == doctest::Approx(0.05).epsilon(1e-3));
  const auto g = evaluation::gaussians_of(m.renderer(), m.params().values.data());
  REQUIRE(g.size() == seeds.size());
  for (std::size_t i = 0; i < g.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      CHECK(g.mean[i][a] == doctest::Approx(seeds.position[i][a]).epsilon(1e-4));
      CHECK(g.log_scale[i][a] == doctest::Approx(std::log(seeds.width[i])).epsilon(1e-4));
    }
    CHECK(g.opacity_logit[i] == doctest::Approx(0.0).epsilon(1e-5));  // opacity 0.5
    CHECK(g.luminance[i] == doctest::Approx(seeds.luminance[i]).epsilon(1e-3));
  }
  // Rendered at a recorded pose: the strip is drawn; the plane beyond three widths of the widest Gaussian
  // stays empty.
  const auto& pose = poses[poses.size() / 2];
  const auto img = m.render(f.td.camera, f.td.pixel_dirs, pose);
  const auto truth = strip_teacher(f.td.camera, pose);
  const double reach = kStrip + 3 * *std::max_element(seeds.width.begin(), seeds.width.end());
  double in = 0, out = 0;
  int n_in = 0, n_out = 0;
  for (int y = 0; y < img.opacity.height; ++y)
    for (int x = 0; x < img.opacity.width; ++x) {
      if (truth.opacity.at(x, y) > 0.5f) in += img.opacity.at(x, y), ++n_in;
      else if (std::abs(on_plane(f.td.camera, f.td.pixel_dirs, pose, x, y).first.x()) > reach) out += img.opacity.at(x, y), ++n_out;
    }
  REQUIRE(n_in > 0);
  REQUIRE(n_out > 0);
  CHECK(in / n_in > 0.3);
  CHECK(out / n_out < 0.1);
  // No seeds (a teacher opaque nowhere) is refused, and so is a model that has stepped.
  SplatFloat fresh = train::make_model<SplatFloat>(f.td, cfg);
  CHECK_THROWS_AS(fresh.start_from(splat::Seeds{}), Error);
  const auto r = train::run(m, f.td, cfg, {}, "splat", f.run());
  CHECK_FALSE(r.diverged);
  CHECK_THROWS_AS(m.start_from(seeds), Error);
}
