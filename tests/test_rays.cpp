// What a training step samples and renders: the field evaluated in pieces or on the kept samples only,
// rays that stop early, render bits independent of batching and threads, the per-sample density noise.
#include <barrier>
#include <bit>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <variant>
#include <thread>
#include <tuple>

#include <sys/resource.h>

#include <evnerf/sim/simulator.hpp>
#include <evnerf/train/trainer.hpp>
#include <evnerf/model/variants.hpp>

#include "common.hpp"
#include "tiny_models.hpp"

using namespace evnerf;
namespace fs = std::filesystem;
using evtest::Fixture;

TEST_CASE_TEMPLATE("field: keep_only and deferred table gradients equal evaluating the kept samples alone", F, TinyField, TinyBf16Field) {
  Rng rng(11);
  std::vector<float> params(F::n_params);
  F::init(params.data(), rng);
  // Two tiles of samples; of the first, only some are kept (as behind-the-surface samples are dropped).
  const int na = 41, nb = 19;
  auto samples = [&](int n, std::vector<float>& pts, std::vector<float>& dirs) {
    pts.resize(3 * static_cast<std::size_t>(n));
    dirs.resize(pts.size());
    for (int j = 0; j < n; ++j) {
      const Vec3 d = Vec3(rng.normal(), rng.normal(), rng.normal()).normalized();
      for (int k = 0; k < 3; ++k) {
        pts[3 * j + k] = static_cast<float>(rng.uniform(-1.1, 1.1));  // a few outside the box: clamped
        dirs[3 * j + k] = static_cast<float>(d[k]);
      }
    }
  };
  std::vector<float> pa, da, pb, db;
  samples(na, pa, da);
  samples(nb, pb, db);
  std::vector<int> keep;
  for (int j = 0; j < na; ++j)
    if (j % 3 != 1 && j != 0) keep.push_back(j);
  const int m = static_cast<int>(keep.size());
  std::vector<float> pk, dk;
  for (int j : keep)
    for (int k = 0; k < 3; ++k) {
      pk.push_back(pa[3 * j + k]);
      dk.push_back(da[3 * j + k]);
    }
  std::vector<float> dsig(std::max(na, nb)), dlum(dsig.size() * F::channels);
  for (auto* v : {&dsig, &dlum})
    for (auto& e : *v) e = static_cast<float>(rng.uniform(-1, 1));
  constexpr int so = F::density_net::out_dims;

  // Reference: the kept samples and the second tile evaluated on their own, gradients applied at once.
  typename F::template Workspace<float> ref;
  std::vector<float> g_ref(F::n_params, 0.f);
  const float *sig = nullptr, *lum = nullptr;
  F::forward(params.data(), pk.data(), dk.data(), m, ref, &sig, &lum);
  const std::vector<float> sig_ref(sig, sig + static_cast<std::size_t>(m) * so),
      lum_ref(lum, lum + static_cast<std::size_t>(m) * F::channels);
  F::backward(params.data(), ref, dsig.data(), dlum.data(), g_ref.data());
  F::forward(params.data(), pb.data(), db.data(), nb, ref, &sig, &lum);
  F::backward(params.data(), ref, dsig.data(), dlum.data(), g_ref.data());

  // All of the first tile, compacted to the kept samples; table gradients deferred over both tiles.
  typename F::template Workspace<float> ws;
  ws.defer_encoding_grad = true;
  std::vector<float> g(F::n_params, 0.f);
  F::forward(params.data(), pa.data(), da.data(), na, ws, &sig, &lum);
  F::keep_only(ws, keep.data(), m, &sig, &lum);
  CHECK(std::vector<float>(sig, sig + static_cast<std::size_t>(m) * so) == sig_ref);
  CHECK(std::vector<float>(lum, lum + static_cast<std::size_t>(m) * F::channels) == lum_ref);
  F::backward(params.data(), ws, dsig.data(), dlum.data(), g.data());
  F::forward(params.data(), pb.data(), db.data(), nb, ws, &sig, &lum);
  F::backward(params.data(), ws, dsig.data(), dlum.data(), g.data());
  const auto tables = static_cast<std::ptrdiff_t>(F::pos_encoding::n_params);
  CHECK(std::all_of(g.begin(), g.begin() + tables, [](float v) { return v == 0.f; }));  // not yet applied
  CHECK(std::equal(g.begin() + tables, g.end(), g_ref.begin() + tables));               // the networks' are
  // The same deferred gradients applied in parts (a hash grid's levels), last part first: each part adds to
  // tables of its own, so the order of the parts does not matter and together they equal one flush.
  REQUIRE(F::encoding_grad_parts == F::pos_encoding::batch_parts);
  REQUIRE(F::deferred_count(ws) == static_cast<std::size_t>(m + nb));
  std::vector<float> before = g;
  for (int q = F::encoding_grad_parts - 1; q >= 0; --q) {
    F::flush_encoding_grad_part(ws, q);
    // Part q wrote inside level q's tables only.
    const std::size_t lo = static_cast<std::size_t>(q) * F::pos_encoding::table_size * 2, hi = lo + F::pos_encoding::table_size * 2;
    for (std::size_t i = 0; i < g.size(); ++i)
      if ((i < lo || i >= hi) && !(std::bit_cast<std::uint32_t>(g[i]) == std::bit_cast<std::uint32_t>(before[i]))) {
        FAIL_CHECK("part " << q << " changed entry " << i << " outside its level");
        break;
      }
    before = g;
  }
  CHECK(g == g_ref);
  CHECK(F::deferred_count(ws) == static_cast<std::size_t>(m + nb));  // parts leave them held
  F::clear_deferred(ws);
  CHECK(F::deferred_count(ws) == 0);
  // And one flush of the same gradients into the saved state gives the same bits.
  F::forward(params.data(), pa.data(), da.data(), na, ws, &sig, &lum);
  F::keep_only(ws, keep.data(), m, &sig, &lum);
  std::vector<float> g_once(F::n_params, 0.f);
  F::backward(params.data(), ws, dsig.data(), dlum.data(), g_once.data());
  F::forward(params.data(), pb.data(), db.data(), nb, ws, &sig, &lum);
  F::backward(params.data(), ws, dsig.data(), dlum.data(), g_once.data());
  F::flush_encoding_grad(ws);
  CHECK(g_once == g_ref);  // the same additions per table entry in the same order: bit-identical
  CHECK(ws.deferred_points.empty());
}

TEST_CASE_TEMPLATE("field: forward_at in pieces equals one forward of all the samples, outputs and gradients bit for bit", F, TinyField,
                   TinyBf16Field) {
  Rng rng(23);
  std::vector<float> params(F::n_params);
  F::init(params.data(), rng);
  for (std::size_t i = 0; i < F::pos_encoding::n_params; ++i) params[i] = static_cast<float>(rng.uniform() - 0.5);
  const int n = 53;
  std::vector<float> pts(3 * n), dirs(3 * n), dsig(n), dlum(static_cast<std::size_t>(n) * F::channels);
  for (int j = 0; j < n; ++j) {
    const Vec3 d = Vec3(rng.normal(), rng.normal(), rng.normal()).normalized();
    for (int k = 0; k < 3; ++k) {
      pts[3 * j + k] = static_cast<float>(rng.uniform(-1, 1));
      dirs[3 * j + k] = static_cast<float>(d[k]);
    }
  }
  for (auto* v : {&dsig, &dlum})
    for (auto& e : *v) e = static_cast<float>(rng.uniform(-1, 1));
  constexpr int so = F::density_net::out_dims;
  typename F::template Workspace<float> one, parts;
  const float *sig = nullptr, *lum = nullptr;
  F::forward(params.data(), pts.data(), dirs.data(), n, one, &sig, &lum);
  const std::vector<float> sig1(sig, sig + static_cast<std::size_t>(n) * so), lum1(lum, lum + static_cast<std::size_t>(n) * F::channels);
  std::vector<float> g1(F::n_params, 0.f), g2(F::n_params, 0.f);
  F::backward(params.data(), one, dsig.data(), dlum.data(), g1.data());
  // A larger batch first, so that the pieces' workspace holds stale samples beyond the new ones.
  std::vector<float> big_pts(3 * 2 * n, 0.25f), big_dirs(3 * 2 * n, 0.f);
  for (int j = 0; j < 2 * n; ++j) big_dirs[3 * j] = 1.f;
  F::forward(params.data(), big_pts.data(), big_dirs.data(), 2 * n, parts, &sig, &lum);
  F::forward(params.data(), pts.data(), dirs.data(), 0, parts, &sig, &lum);  // start afresh: 0 samples held
  int at = 0;
  for (const int m : {7, 0, 1, 24, 21}) {  // 53 in pieces, one of them empty
    F::forward_at(params.data(), pts.data() + 3 * at, dirs.data() + 3 * at, at, m, parts, &sig, &lum);
    at += m;
  }
  REQUIRE(at == n);
  CHECK(parts.n == n);
  CHECK(std::vector<float>(sig, sig + static_cast<std::size_t>(n) * so) == sig1);
  CHECK(std::vector<float>(lum, lum + static_cast<std::size_t>(n) * F::channels) == lum1);
  F::backward(params.data(), parts, dsig.data(), dlum.data(), g2.data());
  CHECK(g1 == g2);
  // Appending after more samples than the workspace holds is refused.
  CHECK_THROWS_AS(F::forward_at(params.data(), pts.data(), dirs.data(), n + 1, 1, parts, &sig, &lum), Error);
}

TEST_CASE("training rays that stop early: the samples before each stop as without it, the composite within the cut, the step close") {
  // Workspace::training_termination: each ray's evaluated samples are those the full pass evaluates up to
  // a chunk boundary (kEvalChunk bins), with the same outputs and the same noise; a ray stops only where its
  // transmittance has fallen to the backward pass's cut; its colour differs from the full pass's by less
  // than that cut times the luminance behind; and a training step's loss and gradients stay close.
  // 32 bins per ray: four chunks of kEvalChunk, so a ray can stop before its end.
  using TinyOcc = EvNerf<TinyField, render::OccupancySkipping<32, 8, 1, 0>>;
  using R = TinyOcc::renderer_type;
  static_assert(R::n_coarse == 4 * R::kEvalChunk);
  Fixture f;
  TinyOcc m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  Rng tables(11);
  for (std::size_t i = 0; i < TinyField::pos_encoding::n_params; ++i) m.params().values[i] = static_cast<float>(tables.uniform() - 0.5);
  const int n_rays = 96, S = R::n_coarse;
  std::vector<Vec3> origin, dir;
  std::vector<Rng> rng;
  for (int r = 0; r < n_rays; ++r) {
    const auto ray = geometry::Camera::ray_along(f.td.boundary_poses[r % f.td.boundary_poses.size()],
                                                 f.td.pixel_dirs[static_cast<std::size_t>(41 * r) % f.td.pixel_dirs.size()].cast<double>());
    origin.push_back(ray.origin);
    dir.push_back(ray.dir);
    rng.push_back(Rng(29).split(static_cast<std::uint64_t>(r)));
  }
  // The density network's output bias raised until between a quarter and nine tenths of the rays fall below
  // the cut before their last chunk (by the full pass), so that the comparison covers both kinds.
  const std::size_t sigma_bias = TinyField::density_offset + TinyField::density_net::bias_offset(TinyField::density_net::n_layers - 1);
  int opaque = 0;
  for (float bias = 0; bias <= 16; bias += 0.25f) {
    m.params().values[sigma_bias] = bias;
    m.update_sampler(f.td, 0, 3);
    std::vector<Rng> g = rng;
    R::Workspace w;
    m.renderer().forward_train(m.params().values.data(), origin.data(), dir.data(), g.data(), n_rays, w);
    opaque = 0;
    for (int r = 0; r < n_rays; ++r) opaque += w.pass[0].comp[r].trans[S - R::kEvalChunk] <= R::kMinTransmittance;
    if (opaque * 4 >= n_rays) break;
  }
  CAPTURE(opaque);
  CAPTURE(m.params().values[sigma_bias]);
  REQUIRE(opaque * 4 >= n_rays);
  REQUIRE(opaque * 10 <= n_rays * 9);
  REQUIRE(m.sampler().skipping());
  std::vector<Rng> rng_full = rng, rng_stop = rng;
  R::Workspace full, stop;
  stop.training_termination = true;
  m.renderer().forward_train(m.params().values.data(), origin.data(), dir.data(), rng_full.data(), n_rays, full);
  m.renderer().forward_train(m.params().values.data(), origin.data(), dir.data(), rng_stop.data(), n_rays, stop);
  const auto &pf = full.pass[0], &ps = stop.pass[0];
  const auto shown = m.renderer().backdrop(m.params().values.data());  // the default Config learns one
  REQUIRE(shown.has_value());
  const float backdrop = (*shown)[0];
  for (int r = 0; r < n_rays; ++r) {  // the random streams end in the same place
    CHECK(rng_full[static_cast<std::size_t>(r)].state() == rng_stop[static_cast<std::size_t>(r)].state());
  }
  std::vector<char> in_full(static_cast<std::size_t>(n_rays) * S, 0), in_stop(in_full.size(), 0);
  for (int i : pf.active) in_full[static_cast<std::size_t>(i)] = 1;
  for (int i : ps.active) in_stop[static_cast<std::size_t>(i)] = 1;
  CHECK(ps.ws.n == static_cast<int>(ps.active.size()));
  int stopped = 0;
  std::size_t wrong = 0;
  for (int r = 0; r < n_rays; ++r) {
    // The stop: the first bin after the last evaluated one, rounded up to a chunk boundary.
    int last = -1;
    for (int k = 0; k < S; ++k)
      if (in_stop[static_cast<std::size_t>(r) * S + k]) last = k;
    int end = S;
    for (int k = 0; k < S; ++k) {
      const std::size_t i = static_cast<std::size_t>(r) * S + k;
      if (in_full[i] && !in_stop[i]) {
        end = k;
        break;
      }
    }
    CAPTURE(r);
    CHECK(end > last);
    if (end < S) {
      ++stopped;
      CHECK(end % R::kEvalChunk == 0);
      // Stopped only where the transmittance had fallen to the cut (by the full pass's composite).
      CHECK(pf.comp[r].trans[end] <= R::kMinTransmittance * 1.01f);
    }
    for (int k = 0; k < S; ++k) {
      const std::size_t i = static_cast<std::size_t>(r) * S + k;
      const bool want = in_full[i] && k < end;
      wrong += in_stop[i] != want;
      if (in_stop[i]) {
        wrong += ps.sig_full[i] != pf.sig_full[i] || ps.raw_full[i] != pf.raw_full[i] || ps.noise[i] != pf.noise[i];
      } else {
        wrong += ps.noise[i] != 0.f || ps.sig_full[i] != R::kSkippedDensity;
      }
    }
    // The colour: the full pass's, less at most the cut's share of what lies behind the stop (the samples
    // there and the backdrop).
    float behind = backdrop;
    for (int k = end; k < S; ++k) behind = std::max(behind, pf.comp[r].lum[k]);
    CHECK(std::abs(ps.comp[r].color[0] - pf.comp[r].color[0]) <=
          R::kMinTransmittance * 1.01f * behind + 1e-6f * std::abs(pf.comp[r].color[0]));
  }
  CHECK(wrong == 0);
  CAPTURE(stopped);
  CHECK(stopped * 4 >= n_rays);  // many rays stopped
  CHECK(stopped <= opaque);      // only those that the full pass makes opaque
  CHECK(ps.active.size() < pf.active.size());
  // A training step: fewer samples forward, the same ones backward (those before the cut), a close loss
  // and close gradients.
  const auto a = m.gradients(f.td, 64, 5);
  const std::vector<float> ga = m.params().grads;
  m.set_ray_termination(true);
  const auto b = m.gradients(f.td, 64, 5);
  const std::vector<float> gb = m.params().grads;
  CHECK(b.samples < a.samples);
  CHECK(b.backward_samples <= a.backward_samples);
  CHECK(b.backward_samples * 100 >= a.backward_samples * 99);
  CHECK(b.loss == doctest::Approx(a.loss).epsilon(1e-3));
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < ga.size(); ++i) {
    diff += (double(ga[i]) - gb[i]) * (double(ga[i]) - gb[i]);
    norm += double(ga[i]) * ga[i];
  }
  CAPTURE(std::sqrt(diff / norm));
  CHECK(std::sqrt(diff) <= 1e-2 * std::sqrt(norm));
  // A larger cut (Workspace::training_cut, set_ray_termination's second argument): rays stop where the full
  // pass's transmittance has fallen to it, evaluate a prefix of what the default cut evaluates, and their
  // colour stays within that cut's share of what lies behind.
  {
    const float big = 1e-2f;
    std::vector<Rng> rng_big = rng;
    R::Workspace wide;
    wide.training_termination = true;
    wide.training_cut = big;
    m.renderer().forward_train(m.params().values.data(), origin.data(), dir.data(), rng_big.data(), n_rays, wide);
    const auto& pb = wide.pass[0];
    std::vector<char> in_big(in_full.size(), 0);
    for (int i : pb.active) in_big[static_cast<std::size_t>(i)] = 1;
    std::size_t bad = 0;
    int earlier = 0;
    for (int r = 0; r < n_rays; ++r) {
      int end = S;
      for (int k = 0; k < S; ++k) {
        const std::size_t i = static_cast<std::size_t>(r) * S + k;
        bad += in_big[i] && !in_stop[i];  // a subset of the default cut's samples
        if (in_stop[i] && !in_big[i] && end == S) end = k;
      }
      CAPTURE(r);
      if (end < S) {
        ++earlier;
        CHECK(end % R::kEvalChunk == 0);
        CHECK(pf.comp[r].trans[end] <= big * 1.01f);
      }
      float behind = 0;
      for (int k = end; k < S; ++k) behind = std::max(behind, pf.comp[r].lum[k]);
      CHECK(std::abs(pb.comp[r].color[0] - pf.comp[r].color[0]) <= big * 1.01f * behind + 1e-6f * std::abs(pf.comp[r].color[0]));
    }
    CHECK(bad == 0);
    CAPTURE(earlier);
    CHECK(earlier > 0);  // some rays stop before they would at the default cut
    CHECK(pb.active.size() < ps.active.size());
    // A step: fewer samples forward and backward than at the default cut.
    m.set_ray_termination(true, big);
    CHECK(m.ray_cut() == doctest::Approx(big));
    const auto d = m.gradients(f.td, 64, 5);
    CHECK(d.samples < b.samples);
    CHECK(d.backward_samples < b.backward_samples);
    CHECK(d.loss == doctest::Approx(a.loss).epsilon(2e-2));
    // The default cut named explicitly is the default, bit for bit.
    m.set_ray_termination(true, 1e-4);
    const auto e = m.gradients(f.td, 64, 5);
    CHECK(e.loss == b.loss);
    CHECK(e.samples == b.samples);
    CHECK(m.params().grads == gb);
    CHECK_THROWS_AS(m.set_ray_termination(true, 0.0), Error);
    CHECK_THROWS_AS(m.set_ray_termination(true, 1.0), Error);
    CHECK_THROWS_AS(m.set_ray_termination(true, std::nan("")), Error);
  }
  m.set_ray_termination(false);
  const auto c = m.gradients(f.td, 64, 5);
  CHECK(c.loss == a.loss);  // off again: the step as without the setting, bit for bit
  CHECK(m.params().grads == ga);
}

TEST_CASE_TEMPLATE("render: early termination changes a pixel by less than the transmittance where rays stop", Model, Tiny, TinyWindow) {
  Fixture f;
  Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
  for (int s = 0; s < 80; ++s) m.train_step(f.td, 128, 3);
  const auto dirs = render::pixel_directions(f.td.camera);
  const auto a = m.render(f.td.camera, dirs, f.td.boundary_poses[1], true);
  const auto b = m.render(f.td.camera, dirs, f.td.boundary_poses[1], false);
  double worst = 0, worst_depth = 0;
  for (std::size_t i = 0; i < a.luminance.data.size(); ++i)
    worst = std::max(worst, double(std::abs(a.luminance.data[i] - b.luminance.data[i])));
  for (std::size_t i = 0; i < a.depth.data.size(); ++i)
    worst_depth = std::max(worst_depth, double(std::abs(a.depth.data[i] - b.depth.data[i])));
  CAPTURE(worst);
  CAPTURE(worst_depth);
  CHECK(worst <= 1.5e-4);
  CHECK(worst_depth <= 1.5e-4 * f.cfg.far * 1.5);
}

TEST_CASE("render: a pixel's bits depend on neither the rows per batch nor the thread count") {
  using TinyOcc = EvNerf<TinyField, render::OccupancySkipping<16, 16, 4, 8>>;  // skipping and early termination
  Fixture f;
  TinyOcc m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
  for (int s = 0; s < 40; ++s) m.train_step(f.td, 128, 3);
  REQUIRE(m.sampler().skipping());
  const auto dirs = render::pixel_directions(f.td.camera);
  const auto& pose = f.td.boundary_poses[1];
  auto same = [](const Rendering& a, const Rendering& b) {
    return a.luminance.data == b.luminance.data && a.depth.data == b.depth.data && a.opacity.data == b.opacity.data;
  };
  const auto one_row = [&] {
    ScopedThreadCount t(1);
    return m.render(f.td.camera, dirs, pose, true, 1);
  }();
  const int H = f.td.camera.height();
  for (int rows : {2, 3, TinyOcc::renderer_type::kRenderRows, H, H + 5}) {
    CAPTURE(rows);
    ScopedThreadCount t(2);
    CHECK(same(m.render(f.td.camera, dirs, pose, true, rows), one_row));
  }
  // Without early termination too (every sample of every ray), and the image is not constant.
  ScopedThreadCount t(2);
  CHECK(same(m.render(f.td.camera, dirs, pose, false, 1), m.render(f.td.camera, dirs, pose, false, 5)));
  const auto& l = one_row.luminance.data;
  CHECK(*std::max_element(l.begin(), l.end()) > *std::min_element(l.begin(), l.end()));
}

TEST_CASE("training forward: each sample's density noise is its ray's next normal, drawn only where the sample is evaluated") {
  // A sampler that skips, so that some samples are not evaluated: theirs is 0 (their α and dα/dσ are the
  // same for any noise, the compositing test checks); the others' is the normal that drawing one per sample
  // in order from the ray's stream gives them, and the stream ends where that drawing leaves it.
  using TinyOcc = EvNerf<TinyField, render::OccupancySkipping<8, 8, 1, 0>>;
  using R = TinyOcc::renderer_type;
  Fixture f;
  TinyOcc m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  Rng tables(11);  // tables far from their tiny initial values: a density that some cells pass and some do not
  for (std::size_t i = 0; i < TinyField::pos_encoding::n_params; ++i) m.params().values[i] = static_cast<float>(tables.uniform() - 0.5);
  m.update_sampler(f.td, 0, 3);
  REQUIRE(m.sampler().skipping());
  CAPTURE(m.sampler().occupied_fraction());
  REQUIRE(m.sampler().occupied_fraction() < 0.9);
  static_assert(R::networks == 1);
  const int n_rays = 64;
  std::vector<Vec3> origin, dir;
  std::vector<Rng> rng, start;
  for (int r = 0; r < n_rays; ++r) {
    const auto ray = geometry::Camera::ray_along(f.td.boundary_poses[r % f.td.boundary_poses.size()],
                                                 f.td.pixel_dirs[static_cast<std::size_t>(37 * r) % f.td.pixel_dirs.size()].cast<double>());
    origin.push_back(ray.origin);
    dir.push_back(ray.dir);
    rng.push_back(Rng(19).split(static_cast<std::uint64_t>(r)));
  }
  start = rng;
  R::Workspace w;
  m.renderer().forward_train(m.params().values.data(), origin.data(), dir.data(), rng.data(), n_rays, w);
  const auto& p = w.pass[0];
  REQUIRE(p.noise.size() == static_cast<std::size_t>(n_rays) * R::n_coarse);
  std::vector<char> active(p.noise.size(), 0);
  for (int i : p.active) active[static_cast<std::size_t>(i)] = 1;
  const auto evaluated = static_cast<std::size_t>(std::count(active.begin(), active.end(), 1));
  CHECK(evaluated > 0);
  CHECK(evaluated < active.size());  // some samples skipped
  std::vector<float> depths(R::n_coarse);
  std::size_t wrong = 0;
  for (int r = 0; r < n_rays; ++r) {
    Rng g = start[static_cast<std::size_t>(r)];
    m.sampler().coarse_depths(R::n_coarse, float(m.box().near), float(m.box().far), &g, depths.data());
    for (int k = 0; k < R::n_coarse; ++k) {
      const std::size_t i = static_cast<std::size_t>(r) * R::n_coarse + k;
      const float want = static_cast<float>(g.normal());
      wrong += p.noise[i] != (active[i] ? want : 0.f);
      wrong += p.t[i] != depths[static_cast<std::size_t>(k)];
    }
    CHECK(rng[static_cast<std::size_t>(r)].state() == g.state());
    CHECK(rng[static_cast<std::size_t>(r)].key() == g.key());
  }
  CHECK(wrong == 0);
}
