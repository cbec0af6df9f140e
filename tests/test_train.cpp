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
#include "tiny_scene.hpp"

using namespace evnerf;
namespace fs = std::filesystem;

namespace {
// A small field and model so that training tests run in seconds.
using TinyField = field::Field<nn::HashGrid<6, 2, 12, 4, 64>, nn::SphericalHarmonics<2>, nn::Mlp<12, 16, 1, 5, nn::ReLU, nn::Identity>,
                               nn::Mlp<4 + 4, 16, 1, 1, nn::ReLU, nn::Identity>>;
using Tiny = EvNerf<TinyField, render::Stratified<16>>;

using evtest::Fixture;
}  // namespace

using TinySigned = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise, loss::SignedCount>;
using TinyHalf = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise, loss::HalfSlackCounts>;
// The same model with mixed-precision networks (bf16 factors, FP32 accumulation).
using TinyBf16Field = field::Field<nn::HashGrid<6, 2, 12, 4, 64>, nn::SphericalHarmonics<2>,
                                   nn::Mlp<12, 16, 1, 5, nn::ReLU, nn::Identity, -1, nn::Bf16>,
                                   nn::Mlp<4 + 4, 16, 1, 1, nn::ReLU, nn::Identity, -1, nn::Bf16>>;
using TinyBf16 = EvNerf<TinyBf16Field, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise, loss::HalfSlackCounts>;
// Windows of 1..4 slices at event pixels (the Fast preset's kind of objective).
using TinyWindow = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise,
                          loss::WindowInterval<4, loss::HalfSlackCounts, events::EventPixels<100>>>;

TEST_CASE_TEMPLATE("training: a short run on a tiny simulated scene lowers the loss", Model, Tiny, TinySigned, TinyHalf,
                   TinyBf16, TinyWindow) {
  Fixture f;
  Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
  double first = 0, last = 0;
  for (int s = 0; s < 150; ++s) {
    const auto st = m.train_step(f.td, 256, 3);
    REQUIRE(std::isfinite(st.loss));
    if (s < 15) first += st.event_loss / 15;
    if (s >= 135) last += st.event_loss / 15;
  }
  CAPTURE(first);
  CAPTURE(last);
  CHECK(last < 0.7 * first);
  // Joint thresholds stay above the floor.
  for (std::size_t i = 0; i < m.n_slices(); ++i) {
    CHECK(m.threshold_pos(i) > 0.25f);
    CHECK(m.threshold_neg(i) < -0.25f);
  }
}

TEST_CASE("training: fixed thresholds never move; noise-free and noisy variants differ") {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  EvNerf<TinyField, render::Stratified<16>, loss::FixedThresholds> m(f.td.slices.size(), box, 7);
  EvNerf<TinyField, render::Stratified<16>, loss::FixedThresholds, loss::NoNoise> quiet(f.td.slices.size(), box, 7);
  REQUIRE(m.params().values == quiet.params().values);
  for (int s = 0; s < 5; ++s) {
    m.train_step(f.td, 128, 3);
    quiet.train_step(f.td, 128, 3);
  }
  for (std::size_t i = 0; i < m.n_slices(); ++i) {  // every slice, exactly, and the fields did train
    CHECK(m.threshold_pos(i) == 0.3f);
    CHECK(m.threshold_neg(i) == -0.3f);
    CHECK(m.optimizer().m()[m.threshold_offset() + 2 * i] == 0.f);
  }
  CHECK(m.params().values != quiet.params().values);
}
TEST_CASE_TEMPLATE("training: deterministic for a seed and thread count; resume equals uninterrupted; checkpoints round-trip",
                   Model, Tiny, TinyBf16, TinyWindow) {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  Model a(f.td.slices.size(), box, 7), b(f.td.slices.size(), box, 7);
  for (int s = 0; s < 6; ++s) {
    a.train_step(f.td, 128, 3);
    b.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == b.params().values);
  // Save after 6 steps, continue both the original and a restored copy.
  const std::string bytes = a.serialize("tiny", "meta");
  Model c;
  CHECK(c.deserialize(bytes, "tiny", "mem") == "meta");
  for (int s = 0; s < 4; ++s) {
    a.train_step(f.td, 128, 3);
    c.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == c.params().values);
  CHECK(a.step() == c.step());
  // A restored model renders bit-identically.
  Model e;
  e.deserialize(a.serialize("tiny", ""), "tiny", "mem");
  const auto dirs = render::pixel_directions(f.td.camera);
  CHECK(a.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data ==
        e.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data);
}

TEST_CASE_TEMPLATE("field: keep_only and deferred table gradients equal evaluating the kept samples alone", F, TinyField,
                   TinyBf16Field) {
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
  const std::vector<float> sig_ref(sig, sig + static_cast<std::size_t>(m) * so), lum_ref(lum, lum + static_cast<std::size_t>(m) * F::channels);
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
  CHECK(std::equal(g.begin() + tables, g.end(), g_ref.begin() + tables));              // the networks' are
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
    // The colour: the full pass's, less at most the cut's share of what lies behind the stop.
    float behind = 0;
    for (int k = end; k < S; ++k) behind = std::max(behind, pf.comp[r].lum[k]);
    CHECK(std::abs(ps.comp[r].color[0] - pf.comp[r].color[0]) <= R::kMinTransmittance * 1.01f * behind + 1e-6f * std::abs(pf.comp[r].color[0]));
  }
  CHECK(wrong == 0);
  CAPTURE(stopped);
  CHECK(stopped * 4 >= n_rays);   // many rays stopped
  CHECK(stopped <= opaque);       // only those that the full pass makes opaque
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

TEST_CASE("occupancy grid: marks the cells of a dense region, and round-trips") {
  render::OccupancyGrid g(16);
  CHECK(g.occupied_fraction() == 1.0);
  const float inside[3] = {0.1f, -0.2f, 0.05f}, outside_box[3] = {1.5f, 0.f, 0.f}, far_cell[3] = {0.9f, 0.9f, -0.9f};
  CHECK(g.occupied(far_cell));  // before the first update nothing is skipped
  auto ball = [](const float* p, std::size_t n, float* out) {
    for (std::size_t i = 0; i < n; ++i) {
      const float r2 = p[3 * i] * p[3 * i] + p[3 * i + 1] * p[3 * i + 1] + p[3 * i + 2] * p[3 * i + 2];
      out[i] = r2 < 0.25f ? 50.f : 0.f;
    }
  };
  g.update(ball, Rng(1), 1.f);
  CHECK(g.occupied(inside));
  CHECK_FALSE(g.occupied(far_cell));
  CHECK(g.occupied(outside_box));  // outside the box: never skipped
  // Cells fully inside the ball (radius 0.5 of the half-width 1) are about 4/3·π·0.5³ / 8 of the grid.
  CHECK(g.occupied_fraction() > 0.04);
  CHECK(g.occupied_fraction() < 0.08);
  CHECK(g.seen_fraction() == 1.0);
  // Seen cells: half the grid (x < 0); the occupied share among them is twice the share of the grid.
  render::OccupancyGrid s(16);
  std::vector<std::uint8_t> half(s.cells(), 0);
  for (std::size_t c = 0; c < s.cells(); ++c) {
    float p[3];
    s.cell_centre(c, p);
    half[c] = p[0] < 0 ? 1 : 0;
  }
  s.set_visible(half);
  CHECK(s.seen_fraction() == doctest::Approx(0.5));
  s.update(ball, Rng(1), 1.f);
  CHECK(s.occupied_fraction() == doctest::Approx(0.5 * g.occupied_fraction()).epsilon(0.1));
  // Decay: with zero density everywhere the occupied set shrinks to nothing after enough updates.
  render::OccupancyGrid h(16);
  CHECK(h.deserialize(g.serialize()));
  CHECK(h.occupied(inside));
  CHECK_FALSE(h.occupied(far_cell));
  CHECK_FALSE(render::OccupancyGrid(8).deserialize(g.serialize()));
}

TEST_CASE("occupancy skipping: a cell is occupied when its density gives the template's alpha at the sample spacing") {
  // Box: near 0, far 8, density per world unit; 8 samples per ray, spacing 1. A density of σ gives a sample
  // α = 1 − exp(−σ). Half the box (x < 0) holds σ = 0.05 (α ≈ 0.049), the other half σ = 2 (the mean,
  // about 1, stays above both thresholds). Alpha 1 % keeps both halves, alpha 10 % only the dense one.
  render::SceneBox box;
  box.near = 0;
  box.far = 8;
  box.density_length = 1;
  render::SamplerUpdate u;
  u.box = box;
  u.density = [](const float* p, std::size_t n, float* out) {
    for (std::size_t i = 0; i < n; ++i) out[i] = p[3 * i] < 0 ? 0.05f : 2.f;
  };
  const float thin[3] = {-0.5f, 0.1f, 0.1f}, dense[3] = {0.5f, 0.1f, 0.1f};
  render::OccupancySkipping<8, 8, 1, 0> one_percent;
  render::OccupancySkipping<8, 8, 1, 0, 100> ten_percent;
  one_percent.update(u);
  ten_percent.update(u);
  CHECK(one_percent.evaluates(thin));
  CHECK(one_percent.evaluates(dense));
  CHECK_FALSE(ten_percent.evaluates(thin));
  CHECK(ten_percent.evaluates(dense));
  CHECK(one_percent.occupied_fraction() == 1.0);
  CHECK(ten_percent.occupied_fraction() == doctest::Approx(0.5));
  // The default's name is what checkpoints have always recorded; another alpha says so.
  CHECK(decltype(one_percent)::name() == "occupancy 8 grid 8 every 1 after 0");
  CHECK(decltype(ten_percent)::name() == "occupancy 8 grid 8 every 1 after 0 alpha 100/1000");
}

TEST_CASE("occupancy skipping: renders like full sampling, stays deterministic, and resumes exactly") {
  using TinyOcc = EvNerf<TinyField, render::OccupancySkipping<16, 16, 4, 8>>;
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  TinyOcc a(f.td.slices.size(), box, 7, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
  for (int s = 0; s < 60; ++s) REQUIRE(std::isfinite(a.train_step(f.td, 256, 3).loss));
  REQUIRE(a.sampler().skipping());
  const double frac = a.sampler().occupied_fraction();
  MESSAGE("occupied fraction after 60 steps: ", frac);
  CHECK(frac < 0.9);
  // The same parameters without a grid (fresh model: grid inactive) render almost the same image.
  TinyOcc full(f.td.slices.size(), box, 7);
  full.params().values = a.params().values;
  const auto dirs = render::pixel_directions(f.td.camera);
  const auto ra = a.render(f.td.camera, dirs, f.td.boundary_poses[1]);
  const auto rf = full.render(f.td.camera, dirs, f.td.boundary_poses[1]);
  double diff = 0;
  for (std::size_t i = 0; i < ra.luminance.data.size(); ++i) diff += std::abs(ra.luminance.data[i] - rf.luminance.data[i]);
  diff /= static_cast<double>(ra.luminance.data.size());
  CAPTURE(diff);
  CHECK(diff < 0.02);
  // Checkpoint between grid updates, then continue through the next ones: identical to uninterrupted.
  TinyOcc c(1, box, 1, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});  // the trainer sets Adam's config
  c.deserialize(a.serialize("tinyocc", ""), "tinyocc", "mem");
  for (int s = 0; s < 9; ++s) {
    a.train_step(f.td, 128, 3);
    c.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == c.params().values);
  CHECK(a.sampler().serialize() == c.sampler().serialize());
  // A grid-less model refuses a checkpoint with a grid: another sampler is another architecture.
  Tiny t;
  CHECK_THROWS_WITH(t.deserialize(a.serialize("tiny", ""), "tiny", "x.ckpt"),
                    doctest::Contains("sampler occupancy 16 grid 16 every 4 after 8'; this model is"));
}

// Two variants of one field whose occupancy grids differ (occupied alpha 1 % and 30 %): a file written as
// "fast" by the first must go to the variant that has its grid, and a file of the second to its own name.
TEST_CASE("checkpoint_variant: a file goes to the variant of its architecture, by name among equals") {
  using Dense = EvNerf<TinyField, render::OccupancySkipping<16, 16, 4, 8>>;
  using Pruned = EvNerf<TinyField, render::OccupancySkipping<16, 16, 4, 8, 300>>;
  REQUIRE(Dense::architecture() != Pruned::architecture());
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  const auto dir = std::filesystem::temp_directory_path() / ("evnerf_test_variant_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& bytes, const std::string& file) {
    std::ofstream(dir / file, std::ios::binary) << bytes;
    return dir / file;
  };
  const auto old_fast = write(Dense(f.td.slices.size(), box, 7).serialize("fast", ""), "old.ckpt");
  const auto new_fast = write(Pruned(f.td.slices.size(), box, 7).serialize("fast-prune", ""), "new.ckpt");
  using List = std::tuple<Variant<Pruned, "fast">, Variant<Dense, "dense">, Variant<Pruned, "fast-prune">>;
  auto pick = [](const std::filesystem::path& p) {
    return [&]<class... V>(std::tuple<V...>*) { return checkpoint_variant<V...>(p); }(static_cast<List*>(nullptr));
  };
  CHECK(pick(old_fast) == "dense");  // its name is a label; its grid decides
  CHECK(pick(new_fast) == "fast-prune");       // two names of one type: the file's own name
  // Without a variant of the old grid, the old file is refused with what it was written by.
  using OnlyNew = Variant<Pruned, "fast">;
  CHECK_THROWS_WITH(checkpoint_variant<OnlyNew>(old_fast), doctest::Contains("written by variant 'fast'"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("checkpoints: corrupt, truncated or mismatched files are refused with a clear error") {
  Fixture f;
  Tiny a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  std::string bytes = a.serialize("tiny", "");
  Tiny b;
  std::string bad = bytes;
  bad[bad.size() / 2] ^= 0x55;
  CHECK_THROWS_WITH(b.deserialize(bad, "tiny", "x.ckpt"), doctest::Contains("x.ckpt:0: corrupt or mismatched checkpoint: checksum mismatch"));
  CHECK_THROWS_WITH(b.deserialize(bytes.substr(0, 100), "tiny", "x.ckpt"), doctest::Contains("checksum mismatch"));
  // The architecture decides, not the name: a file of this model under another name loads, a model of
  // another architecture refuses it with both descriptions.
  CHECK_NOTHROW(b.deserialize(bytes, "paper", "x.ckpt"));
  using Wider = EvNerf<field::FieldOf<nn::HashGrid<6, 2, 12, 4, 64>, nn::SphericalHarmonics<2>, nn::MlpShape{.width = 32}, 4,
                                      nn::MlpShape{.width = 16}>,
                       render::Stratified<16>>;
  static_assert(Wider::field_params != Tiny::field_params);
  Wider wider;
  CHECK_THROWS_WITH(wider.deserialize(bytes, "tiny", "x.ckpt"),
                    doctest::Contains("written by a model of another architecture ('position hash grid 6x2 2^12 4..64, direction "
                                      "spherical harmonics 2, density mlp 12>16x1>5 relu/identity, colour mlp 8>16x1>1 "
                                      "relu/identity, density activation relu; sampler stratified 16'; this model is"));
  using OtherSampler = EvNerf<TinyField, render::Stratified<24>>;
  OtherSampler other;
  CHECK_THROWS_WITH(other.deserialize(bytes, "tiny", "x.ckpt"), doctest::Contains("sampler stratified 24"));
  CHECK_THROWS_WITH(b.deserialize("hello", "tiny", "x.ckpt"), doctest::Contains("not an evnerf checkpoint"));
  // Found by tests/fuzz (fuzz_checkpoint): a header whose slice and parameter counts agree with each other
  // but not with the file's size made the loader allocate 64 GB. Now refused before allocating.
  {
    std::string huge = bytes.substr(0, bytes.size() - 8);
    const std::uint64_t slices = std::uint64_t{1} << 33, n = Tiny::n_fields * Tiny::field_params + 2 * slices;
    const std::size_t at = 16 + 8 + 4;  // after the magic, the version and the name "tiny" (length, bytes)
    std::memcpy(huge.data() + at, &n, 8);
    std::memcpy(huge.data() + at + 8, &slices, 8);
    const std::uint64_t sum = fnv1a64(huge);
    huge.append(reinterpret_cast<const char*>(&sum), 8);
    CHECK_THROWS_WITH(b.deserialize(huge, "tiny", "x.ckpt"), doctest::Contains("x.ckpt:0: corrupt or mismatched checkpoint: truncated: 171799"));
  }
  // The trainer's file path: atomic write and load.
  const fs::path dir = fs::temp_directory_path() / ("evnerf_ck_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  train::save_checkpoint(dir / "m.ckpt", a, "tiny", "meta");
  Tiny c;
  CHECK(train::load_checkpoint(dir / "m.ckpt", c, "tiny") == "meta");
  fs::remove_all(dir);
}

TEST_CASE("checkpoints: a NaN or infinite value (or a negative second moment) behind a valid checksum is refused, naming it") {
  Fixture f;
  Tiny a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  a.set_average(0.99);
  for (int s = 0; s < 2; ++s) a.train_step(f.td, 128, 3);
  const std::string good = a.serialize("tiny", "meta");
  const std::size_t n = a.params().size();
  const std::size_t header = 8 + 8 + (8 + 4) + 8 + 8 + 8 + 6 * 8 + 8 + (8 + Tiny::loss_description().size()) +
                             (8 + Tiny::architecture().size());
  // Values as 4-byte floats: the parameters, Adam's m and v, then the average's count and decay, its values.
  auto with = [&](std::size_t at, float value) {
    std::string b = good.substr(0, good.size() - 8);
    std::memcpy(b.data() + at, &value, 4);
    const std::uint64_t sum = fnv1a64(b);
    b.append(reinterpret_cast<const char*>(&sum), 8);
    return b;
  };
  {
    Tiny t;
    REQUIRE_NOTHROW(t.deserialize(with(header + 4 * 5, static_cast<float>(a.params().values[5])), "tiny", "x.ckpt"));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  Tiny t;
  CHECK_THROWS_WITH(t.deserialize(with(header + 4 * 5, nan), "tiny", "x.ckpt"),
                    doctest::Contains(("x.ckpt:0: corrupt or mismatched checkpoint: parameter 5 of " + std::to_string(n) + " is NaN").c_str()));
  CHECK_THROWS_WITH(t.deserialize(with(header + 4 * (n + 2), -inf), "tiny", "x.ckpt"),
                    doctest::Contains(("Adam's first moment of parameter 2 of " + std::to_string(n) + " is infinite").c_str()));
  CHECK_THROWS_WITH(t.deserialize(with(header + 4 * (2 * n + 7), -1.0f), "tiny", "x.ckpt"),
                    doctest::Contains(("Adam's second moment of parameter 7 of " + std::to_string(n) + " is negative").c_str()));
  CHECK_THROWS_WITH(t.deserialize(with(header + 12 * n + 16 + 4 * (n - 1), nan), "tiny", "x.ckpt"),
                    doctest::Contains(("the parameter average's value " + std::to_string(n - 1) + " of " + std::to_string(n) + " is NaN").c_str()));
  // The refused loads left the model as it was (a default model: no parameters).
  CHECK(t.params().size() == 0);
}

TEST_CASE("checkpoints: version 6 records the parameter average, 5 the architecture, 4 the loss; versions 5, 4, 3 and 2 load") {
  Fixture f;
  f.cfg.density_per_box = true;
  const auto box = train::scene_box(f.td, f.cfg);
  REQUIRE(box.scale > 1.5);
  CHECK(box.density_length == box.scale);
  Tiny a(f.td.slices.size(), box, 7);
  for (int s = 0; s < 4; ++s) a.train_step(f.td, 128, 3);
  REQUIRE_FALSE(a.average().active());
  const std::string v6 = a.serialize("tiny", "meta");
  auto with_sum = [](std::string b) {
    const std::uint64_t sum = fnv1a64(b);
    b.append(reinterpret_cast<const char*>(&sum), 8);
    return b;
  };
  auto as_version = [&](std::string b, std::uint64_t version) {  // b without its checksum
    std::memcpy(b.data() + 8, &version, 8);
    return with_sum(std::move(b));
  };
  // Rewrite as version 5: no parameter average (its count, 0 here, and its decay) after Adam's moments.
  const std::size_t header = 8 + 8 + (8 + 4) + 8 + 8 + 8 + 6 * 8 + 8 + (8 + Tiny::loss_description().size()) +
                             (8 + Tiny::architecture().size());
  const std::size_t moments_end = header + 12 * a.params().size();
  std::string v5 = v6.substr(0, v6.size() - 8);
  {
    std::uint64_t count = 1;
    double decay = 1;
    std::memcpy(&count, v5.data() + moments_end, 8);
    std::memcpy(&decay, v5.data() + moments_end + 8, 8);
    REQUIRE(count == 0);
    REQUIRE(decay == 0.0);
    v5.erase(moments_end, 16);
    v5 = as_version(std::move(v5), 5);
  }
  {
    Tiny t;
    CHECK(t.deserialize(v5, "tiny", "m.ckpt") == "meta");
    CHECK(t.params().values == a.params().values);
    CHECK_FALSE(t.average().active());
    CHECK(t.load_note().empty());
  }
  // Rewrite as version 4: no architecture after the loss; the variant's name is checked instead.
  const std::size_t at = 8 + 8 + (8 + 4) + 8 + 8 + 8 + 6 * 8;
  std::string v4 = v5.substr(0, v5.size() - 8);
  {
    const std::size_t arch = at + 8 + 8 + Tiny::loss_description().size();
    std::uint64_t len = 0;
    std::memcpy(&len, v4.data() + arch, 8);
    REQUIRE(len == Tiny::architecture().size());
    REQUIRE(v4.substr(arch + 8, len) == Tiny::architecture());
    v4.erase(arch, 8 + len);
    v4 = as_version(std::move(v4), 4);
  }
  {
    Tiny t;
    CHECK(t.deserialize(v4, "tiny", "m.ckpt") == "meta");
    CHECK(t.params().values == a.params().values);
    CHECK_THROWS_WITH(t.deserialize(v4, "paper", "m.ckpt"), doctest::Contains("written by preset 'tiny', loading as 'paper'"));
  }
  // The same model type loads it with no note; one trained with other bounds or without noise refuses it.
  Tiny same;
  CHECK(same.deserialize(v4, "tiny", "m.ckpt") == "meta");
  CHECK(same.load_note().empty());
  CHECK(Tiny::loss_description() == "bounds split 1, thresholds joint, noise 50 per mille");
  using TinyHalfSlack = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise, loss::HalfSlackCounts>;
  TinyHalfSlack other;
  CHECK_THROWS_WITH(other.deserialize(v4, "tiny", "m.ckpt"),
                    doctest::Contains("m.ckpt:0: corrupt or mismatched checkpoint: trained with the loss 'bounds split 1, "
                                      "thresholds joint, noise 50 per mille', this model's is 'bounds half-slack, thresholds joint, noise 50 per mille'"));
  // Rewrite as version 3: no loss description after the density length.
  std::string v3 = v4.substr(0, v4.size() - 8);
  std::uint64_t loss_len = 0;
  std::memcpy(&loss_len, v3.data() + at + 8, 8);
  REQUIRE(loss_len == Tiny::loss_description().size());
  v3.erase(at + 8, 8 + loss_len);
  const std::uint64_t three = 3;
  std::memcpy(v3.data() + 8, &three, 8);
  CHECK(same.deserialize(with_sum(v3), "tiny", "old.ckpt") == "meta");
  CHECK(same.params().values == a.params().values);
  CHECK(same.box().density_length == box.scale);
  CHECK(same.load_note() == "old.ckpt: checkpoint version 3 does not record the loss it was trained with; continuing with "
                            "'bounds split 1, thresholds joint, noise 50 per mille'");
  // Rewrite as version 2: no density length after the box either.
  std::string v2 = v3;
  double length = 0;
  std::memcpy(&length, v2.data() + at, 8);
  REQUIRE(length == box.scale);
  v2.erase(at, 8);
  const std::uint64_t two = 2;
  std::memcpy(v2.data() + 8, &two, 8);
  Tiny b;
  CHECK(b.deserialize(with_sum(v2), "tiny", "old.ckpt") == "meta");
  CHECK(b.box().density_length == 1.0);
  CHECK(b.params().values == a.params().values);
  const auto dirs = render::pixel_directions(f.td.camera);
  CHECK(a.render(f.td.camera, dirs, f.td.boundary_poses[0]).opacity.data !=
        b.render(f.td.camera, dirs, f.td.boundary_poses[0]).opacity.data);
  // A file with a nonsensical length is refused.
  std::string bad = v5.substr(0, v5.size() - 8);
  const double zero = 0.0;
  std::memcpy(bad.data() + at, &zero, 8);
  CHECK_THROWS_WITH(b.deserialize(with_sum(bad), "tiny", "x.ckpt"), doctest::Contains("density length is not a positive number"));
  std::string future = v6.substr(0, v6.size() - 8);
  const std::uint64_t seven = 7;
  std::memcpy(future.data() + 8, &seven, 8);
  CHECK_THROWS_WITH(b.deserialize(with_sum(future), "tiny", "x.ckpt"), doctest::Contains("unsupported version 7"));
  // A version-6 file whose average does not match the model, or whose decay is out of range, is refused.
  Tiny avg(f.td.slices.size(), box, 7);
  avg.set_average(0.9);
  avg.train_step(f.td, 128, 3);
  const std::string with_average = avg.serialize("tiny", "meta");
  std::string wrong = with_average.substr(0, with_average.size() - 8);
  const std::uint64_t three_values = 3;
  std::memcpy(wrong.data() + moments_end, &three_values, 8);
  CHECK_THROWS_WITH(b.deserialize(with_sum(wrong), "tiny", "x.ckpt"), doctest::Contains("the parameter average has 3 values"));
  wrong = with_average.substr(0, with_average.size() - 8);
  const double one = 1.0;
  std::memcpy(wrong.data() + moments_end + 8, &one, 8);
  CHECK_THROWS_WITH(b.deserialize(with_sum(wrong), "tiny", "x.ckpt"), doctest::Contains("decay is not in (0, 1)"));
}

TEST_CASE("parameter average: TensorFlow's warm-up; never changes training; renders use it; checkpoints keep it") {
  // The weight of step n's parameters: 1 − min(decay, (1 + n) / (10 + n)).
  CHECK(nn::ParameterAverage<float>::weight(0.998, 1) == doctest::Approx(9.0 / 11));
  CHECK(nn::ParameterAverage<float>::weight(0.998, 90) == doctest::Approx(0.09));
  CHECK(nn::ParameterAverage<float>::weight(0.998, 4490) == doctest::Approx(0.002));
  CHECK(nn::ParameterAverage<float>::weight(0.998, 100000) == doctest::Approx(0.002));
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  Tiny a(f.td.slices.size(), box, 7), b(f.td.slices.size(), box, 7);
  a.set_average(0.9);
  REQUIRE(a.average().active());
  CHECK(a.average().values() == a.params().values);  // it starts at the parameters
  // Against a plain average in double: a_n = a_{n-1} + w(n) (p_n − a_{n-1}).
  std::vector<double> ref(a.params().values.begin(), a.params().values.end());
  for (int s = 0; s < 6; ++s) {
    a.train_step(f.td, 128, 3);
    b.train_step(f.td, 128, 3);
    const double w = nn::ParameterAverage<float>::weight(0.9, a.step());
    for (std::size_t i = 0; i < ref.size(); ++i) ref[i] += w * (double(a.params().values[i]) - ref[i]);
  }
  CHECK(a.params().values == b.params().values);  // averaging never feeds back into training
  CHECK(a.average().values() != a.params().values);
  double worst = 0;
  for (std::size_t i = 0; i < ref.size(); ++i)
    worst = std::max(worst, std::abs(double(a.average().values()[i]) - ref[i]) / (1e-3 + std::abs(ref[i])));
  CHECK(worst < 1e-5);
  // Renders use the average: the same as a model holding the average as its parameters.
  const auto dirs = render::pixel_directions(f.td.camera);
  const auto& pose = f.td.boundary_poses[1];
  Tiny as_params = a;
  as_params.set_average(0);
  CHECK_FALSE(as_params.average().active());
  as_params.params().values = a.average().values();
  CHECK(a.render(f.td.camera, dirs, pose).luminance.data == as_params.render(f.td.camera, dirs, pose).luminance.data);
  CHECK(a.render(f.td.camera, dirs, pose).luminance.data != b.render(f.td.camera, dirs, pose).luminance.data);
  // Checkpoints keep it; a restored model goes on as the original does.
  Tiny c;
  CHECK(c.deserialize(a.serialize("tiny", "meta"), "tiny", "mem") == "meta");
  CHECK(c.average().decay() == 0.9);
  CHECK(c.average().values() == a.average().values());
  for (int s = 0; s < 3; ++s) {
    a.train_step(f.td, 128, 3);
    c.train_step(f.td, 128, 3);
  }
  CHECK(c.params().values == a.params().values);
  CHECK(c.average().values() == a.average().values());
  // A new decay keeps the values; a model without an average loads as one without.
  c.set_average(0.99);
  CHECK(c.average().decay() == 0.99);
  CHECK(c.average().values() == a.average().values());
  Tiny d;
  d.deserialize(b.serialize("tiny", ""), "tiny", "mem");
  CHECK_FALSE(d.average().active());
  CHECK_THROWS_WITH(d.set_average(1.0), doctest::Contains("decay must be in [0, 1)"));
}

TEST_CASE("training data: poses that do not cover the events are an error; clamping is explicit") {
  Fixture f;
  io::Dataset d = f.d;
  d.frames = {};
  std::vector<double> t{10.0, 11.0};
  d.trajectory = geometry::Trajectory(t, {geometry::Pose{}, geometry::Pose{}});
  CHECK_THROWS_WITH(train::prepare(d, f.cfg), doctest::Contains("do not cover the events"));
}

TEST_CASE("noise injection inside training draws a fresh noise map per step") {
  Fixture f;
  TrainingData td = f.td;
  for (std::size_t i = 0; i < td.slice_enabled.size(); ++i) td.slice_enabled[i] = i == 1;  // always slice 1
  const std::size_t hw = td.slices.slices[1].pixels();
  const auto box = train::scene_box(td, f.cfg);
  Tiny noisy(td.slices.size(), box, 7);
  EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::NoNoise> clean(td.slices.size(), box, 7);
  // Every pixel of the slice in every step: the counts a step sees minus the recording's are its noise.
  auto noise_map = [&](const auto& draw) {
    REQUIRE(draw.first == 1);
    REQUIRE(draw.pixels.size() == hw);
    std::vector<int> n(hw, 0);
    for (std::size_t i = 0; i < hw; ++i) {
      const auto p = draw.pixels[i];
      n[p] = draw.npos[i] - td.slices.slices[1].pos[p] + draw.nneg[i] - td.slices.slices[1].neg[p];
    }
    return n;
  };
  std::vector<std::vector<int>> maps;
  for (int s = 0; s < 3; ++s) {
    noisy.train_step(td, static_cast<int>(hw), 3);
    clean.train_step(td, static_cast<int>(hw), 3);
    maps.push_back(noise_map(noisy.last_draw()));
    const auto none = noise_map(clean.last_draw());
    CHECK(std::all_of(none.begin(), none.end(), [](int c) { return c == 0; }));  // no noise without the policy
    long added = 0;
    for (int c : maps.back()) {
      CHECK(c >= 0);
      added += c;
    }
    // 5 % of the slice's events (saturation aside)
    CHECK(added == static_cast<long>(std::llround(0.05 * static_cast<double>(td.slices.slices[1].total))));
  }
  CHECK(maps[0] != maps[1]);
  CHECK(maps[1] != maps[2]);
}
TEST_CASE("training: windows span 1..W trainable slices, every length occurs, held-out slices are never inside one") {
  Fixture f;
  REQUIRE(f.td.slices.size() == 4);
  TinyWindow m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  std::set<std::size_t> lengths;
  for (int s = 0; s < 40; ++s) {
    const auto st = m.train_step(f.td, 64, 3);
    REQUIRE(st.window >= 1);
    REQUIRE(st.first_slice + st.window <= 4);
    lengths.insert(st.window);
  }
  CHECK(lengths.size() == 4);
  TrainingData td = f.td;
  td.slice_enabled[1] = false;  // a held-out slice splits the recording: windows fit in [0] or [2, 3]
  for (int s = 0; s < 40; ++s) {
    const auto st = m.train_step(td, 64, 3);
    for (std::size_t k = st.first_slice; k < st.first_slice + st.window; ++k) REQUIRE(td.slice_enabled[k]);
  }
  // The one-slice objective draws one slice per step.
  Tiny one(td.slices.size(), train::scene_box(td, f.cfg), 7);
  CHECK(one.train_step(td, 64, 3).window == 1);
}

TEST_CASE("training: a model refuses training data with another slicing (a resume with other slices) with a clear error") {
  Fixture f;
  Tiny m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  m.train_step(f.td, 64, 3);
  const std::string bytes = m.serialize("tiny", "");
  // The same recording cut into fewer slices.
  train::Config cfg = f.cfg;
  io::Dataset d = f.d;
  d.frames.t.resize(d.frames.t.size() / 2);
  d.frames.paths.resize(d.frames.t.size());
  const auto td2 = train::prepare(d, cfg);
  REQUIRE(td2.slices.size() != f.td.slices.size());
  Tiny r;
  r.deserialize(bytes, "tiny", "mem");
  try {
    r.train_step(td2, 64, 3);
    FAIL("a model trained on other slices was not refused");
  } catch (const Error& e) {
    CHECK_CONTAINS(e.what(), "slices");
    CHECK_CONTAINS(e.what(), std::to_string(f.td.slices.size()));
    CHECK_CONTAINS(e.what(), std::to_string(td2.slices.size()));
  }
}

TEST_CASE("training loop: a fresh run starts a fresh log of period means; the callback can stop it; the thread count is restored") {
  Fixture f;
  const fs::path out = fs::temp_directory_path() / "evnerf_test_run_loop";
  fs::remove_all(out);
  fs::create_directories(out);
  { std::ofstream(out / "log.jsonl") << "a line of an earlier run\n"; }
  Tiny m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  train::Config cfg = f.cfg;
  cfg.iterations = 60;
  cfg.pixels = 64;
  cfg.progress = false;
  cfg.threads = 1;
  const int before = thread_count();
  std::vector<double> losses;
  double logged_mean = -1;
  long seen = 0;
  auto r = train::run(m, f.td, cfg, out, "tiny", "meta", [&](const train::StepReport& rep) {
    ++seen;
    CHECK(thread_count() == 1);
    losses.push_back(rep.stats.loss);
    if (rep.logged) logged_mean = rep.mean_loss;
    return rep.step < 55;  // stop after step 55
  });
  CHECK(thread_count() == before);
  CHECK(r.stopped);
  CHECK(seen == 55);
  CHECK(m.step() == 55);
  CHECK(fs::exists(out / "model.ckpt"));  // written before stopping
  // One line (step 50), and its loss is the mean of steps 1..50, like its parts.
  std::ifstream in(out / "log.jsonl");
  std::string line, all;
  int lines = 0;
  while (std::getline(in, line)) {
    ++lines;
    all = line;
  }
  CHECK(lines == 1);
  const auto j = nlohmann::json::parse(all);
  CHECK(j["step"] == 50);
  CHECK(j["steps_in_mean"] == 50);
  double mean = 0;
  for (int s = 0; s < 50; ++s) mean += losses[s] / 50;
  CHECK(j["loss"].get<double>() == doctest::Approx(mean));
  CHECK(logged_mean == doctest::Approx(mean));
  CHECK(j["loss"].get<double>() == doctest::Approx(j["event_loss"].get<double>() + j["threshold_loss"].get<double>()));
  // settings.json records what trained the run: every setting, from step 0.
  auto settings = [&] { return nlohmann::json::parse(read_file(out / "settings.json")); };
  auto first = settings();
  CHECK(first["variant"] == "tiny");
  REQUIRE(first["runs"].size() == 1);
  CHECK(first["runs"][0]["from_step"] == 0);
  CHECK(first["runs"][0]["iterations"] == 60);
  CHECK(first["runs"][0]["pixels"] == 64);
  CHECK(first["runs"][0]["seed"] == cfg.seed);
  CHECK(first["runs"][0]["tv"].is_null());  // a variant without the term, and cfg leaves it unset
  CHECK(train::settings_json(cfg)["tv"].is_null());
  CHECK(first["runs"][0].size() == train::settings_json(cfg).size() + 1);
  // A resumed run appends, to the log and to the settings.
  cfg.iterations = 100;
  cfg.lr = 2e-3;
  train::run(m, f.td, cfg, out, "tiny", "meta");
  CHECK(m.ray_cut() == train::kRayCut);  // training rays stop behind the library's cut
  std::ifstream in2(out / "log.jsonl");
  lines = 0;
  while (std::getline(in2, line)) ++lines;
  CHECK(lines == 2);
  auto both = settings();
  REQUIRE(both["runs"].size() == 2);
  CHECK(both["runs"][0] == first["runs"][0]);
  CHECK(both["runs"][1]["from_step"] == 55);
  CHECK(both["runs"][1]["iterations"] == 100);
  CHECK(both["runs"][1]["lr"] == 2e-3);
  // A call resumed from an earlier step drops the entries that started at or after it; a settings file that
  // is not the record is refused, naming it, and left as it was.
  write_file_atomic(out / "settings.json", "{\"runs\": 3}");
  cfg.iterations = 110;
  write_file_atomic(out / "log.jsonl", read_file(out / "log.jsonl") + "{\"step\": 999}\n");  // a resume would drop it
  const std::string log_before = read_file(out / "log.jsonl");
  CHECK_THROWS_WITH_AS(train::run(m, f.td, cfg, out, "tiny", "meta"), doctest::Contains("settings.json"), Error);
  CHECK(read_file(out / "settings.json") == "{\"runs\": 3}");
  CHECK(read_file(out / "log.jsonl") == log_before);  // refused before the log was touched
  nlohmann::json later = both;
  later["runs"].push_back(both["runs"][1]);
  later["runs"][2]["from_step"] = 500;
  write_file_atomic(out / "settings.json", later.dump());
  train::run(m, f.td, cfg, out, "tiny", "meta");
  auto kept = settings();
  REQUIRE(kept["runs"].size() == 3);
  CHECK(kept["runs"][1] == both["runs"][1]);
  CHECK(kept["runs"][2]["from_step"] == 100);
  CHECK(kept["runs"][2]["iterations"] == 110);
  fs::remove_all(out);
}

TEST_CASE("training loop: without an output folder nothing is written and the model trains the same; bad settings are refused") {
  Fixture f;
  train::Config cfg = f.cfg;
  cfg.iterations = 20;
  cfg.pixels = 64;
  cfg.progress = false;
  cfg.threads = 1;
  cfg.checkpoint_every = 5;
  const fs::path cwd = fs::current_path();
  const fs::path here = fs::temp_directory_path() / "evnerf_test_no_out";
  fs::remove_all(here);
  fs::create_directories(here);
  fs::current_path(here);  // a relative "model.ckpt" or "log.jsonl" would land here
  Tiny a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7), b(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  const auto r = train::run(a, f.td, cfg, fs::path(), "tiny", "meta");
  fs::current_path(cwd);
  CHECK(r.steps == 20);
  CHECK(fs::is_empty(here));
  train::run(b, f.td, cfg, here / "run", "tiny", "meta");
  CHECK(a.params().values == b.params().values);
  fs::remove_all(here);
  // train::check names the setting.
  auto refused = [&](auto change, const std::string& what) {
    train::Config c = cfg;
    change(c);
    try {
      train::check(c);
      FAIL("accepted: " << what);
    } catch (const Error& e) {
      CHECK(std::string(e.what()).find(what) != std::string::npos);
    }
  };
  refused([](train::Config& c) { c.far = c.near / 2; }, "far must be greater than near");
  refused([](train::Config& c) { c.iterations = 0; }, "iterations must be > 0, got 0");
  refused([](train::Config& c) { c.pixels = 0; }, "pixels must be in [1, 4194304], got 0");
  refused([](train::Config& c) { c.lr = -1; }, "lr must be > 0, got -1");
  refused([](train::Config& c) { c.subslices = 65; }, "subslices must be in [1, 64], got 65");
  refused([](train::Config& c) { c.distortion = std::nan(""); }, "distortion must be >= 0, got nan");
  refused([](train::Config& c) { c.tv = std::numeric_limits<double>::infinity(); }, "tv must be >= 0, got inf");
  refused([](train::Config& c) { c.average = 1.0; }, "average must be in [0, 1), got 1");
  Tiny m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  train::Config bad = cfg;
  bad.threads = -1;
  CHECK_THROWS_WITH_AS(train::run(m, f.td, bad, fs::path(), "tiny", "meta"), doctest::Contains("threads must be in [0, 4096], got -1"), Error);
  CHECK(m.step() == 0);
  // The total-variation weight: unset, the model keeps its own; set, the Config's replaces it; a variant
  // without the term refuses a weight (it would do nothing) but takes 0.
  using TinyTv = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise,
                        loss::Plus<loss::SliceInterval<>, loss::TotalVariation<125>>>;
  TinyTv t(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  train::Config two = cfg;
  two.iterations = 2;
  train::run(t, f.td, two, fs::path(), "tiny", "meta");
  CHECK(t.term<loss::TvTerm>()->weight == 0.125);
  two.tv = 0.0;
  train::run(t, f.td, two, fs::path(), "tiny", "meta");
  CHECK(t.term<loss::TvTerm>()->weight == 0.0);
  two.tv = 0.25;
  const long at = m.step();
  CHECK_THROWS_WITH_AS(train::run(m, f.td, two, fs::path(), "tiny", "meta"), doctest::Contains("weight of 0.25 for a variant without the term"),
                       Error);
  CHECK(m.step() == at);
  two.tv = 0.0;
  CHECK_NOTHROW(train::run(m, f.td, two, fs::path(), "tiny", "meta"));
}

TEST_CASE("lazy Adam: a threshold of a slice no step touched keeps its value and its moments") {
  Fixture f;
  TrainingData td = f.td;
  for (std::size_t i = 1; i < td.slice_enabled.size(); ++i) td.slice_enabled[i] = false;  // train slice 0 only
  Tiny m(td.slices.size(), train::scene_box(td, f.cfg), 7);
  for (int s = 0; s < 10; ++s) m.train_step(td, 64, 3);
  CHECK(m.threshold_pos(0) != 0.3f);
  for (std::size_t i = 1; i < m.n_slices(); ++i) {
    CHECK(m.threshold_pos(i) == 0.3f);
    CHECK(m.threshold_neg(i) == -0.3f);
    CHECK(m.optimizer().m()[m.threshold_offset() + 2 * i] == 0.f);
  }
}

TEST_CASE("projected thresholds: learned, never inside the floor, no floor loss") {
  Fixture f;
  using M = EvNerf<TinyField, render::Stratified<16>, loss::ProjectedThresholds, loss::DefaultNoise,
                   loss::WindowInterval<3, loss::HalfSlackCounts>>;
  M m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7, nn::AdamConfig{5e-2, 0.9, 0.999, 1e-7, 0.1, 250000});
  for (int s = 0; s < 40; ++s) {
    const auto st = m.train_step(f.td, 64, 3);
    CHECK(st.threshold_loss == 0.0);
    for (std::size_t i = 0; i < m.n_slices(); ++i) {
      REQUIRE(m.threshold_pos(i) >= 0.3f);
      REQUIRE(m.threshold_neg(i) <= -0.3f);  // on this scene the event loss pushes them inwards (joint ones end below)
    }
  }
}

TEST_CASE_TEMPLATE("render: early termination changes a pixel by less than the transmittance where rays stop", Model, Tiny,
                   TinyWindow) {
  Fixture f;
  Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
  for (int s = 0; s < 80; ++s) m.train_step(f.td, 128, 3);
  const auto dirs = render::pixel_directions(f.td.camera);
  const auto a = m.render(f.td.camera, dirs, f.td.boundary_poses[1], true);
  const auto b = m.render(f.td.camera, dirs, f.td.boundary_poses[1], false);
  double worst = 0, worst_depth = 0;
  for (std::size_t i = 0; i < a.luminance.data.size(); ++i) worst = std::max(worst, double(std::abs(a.luminance.data[i] - b.luminance.data[i])));
  for (std::size_t i = 0; i < a.depth.data.size(); ++i) worst_depth = std::max(worst_depth, double(std::abs(a.depth.data[i] - b.depth.data[i])));
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

TEST_CASE("train::Trainer: the Config decides box and Adam; a stopped run resumed ends where an uninterrupted one does, in its own box") {
  Fixture f;
  train::Config cfg = f.run_config(30, 64);
  cfg.threads = 2;
  cfg.near = 0.6;
  cfg.far = 2.5;
  cfg.lr = 2e-3;
  cfg.checkpoint_every = 0;
  const fs::path base = fs::temp_directory_path() / ("evnerf_trainer_" + std::to_string(::getpid()));
  train::Trainer<Tiny> whole(f.td, cfg, base / "whole", "tiny", "meta");
  CHECK(whole.model().box().near == 0.6);
  CHECK(whole.model().box().far == 2.5);
  CHECK(whole.model().optimizer().config().lr == 2e-3);
  CHECK_FALSE(whole.resume());  // nothing to resume from
  whole.run();
  CHECK(whole.model().step() == 30);
  {
    train::Trainer<Tiny> first(f.td, cfg, base / "split", "tiny", "meta");
    const auto r = first.run([](const train::StepReport& rep) { return rep.step < 12; });
    CHECK(r.stopped);
  }
  train::Trainer<Tiny> second(f.td, cfg, base / "split", "tiny", "meta");
  REQUIRE(second.resume());
  CHECK(second.model().step() == 12);
  second.run();
  CHECK(second.model().step() == 30);
  CHECK(second.model().params().values == whole.model().params().values);
  // The default Config keeps the parameter average, and the checkpoint carries it across the resume.
  CHECK(whole.model().average().active());
  CHECK(whole.model().average().decay() == 0.998);
  CHECK(second.model().average().values() == whole.model().average().values());
  // A checkpoint keeps its scene box: a call with another near and far resumes it as it was, and its Config
  // (what settings.json records) takes the checkpoint's near and far over.
  train::Config other = cfg;
  other.near = 0.4;
  other.far = 3.0;
  other.iterations = 32;
  train::Trainer<Tiny> third(f.td, other, base / "split", "tiny", "meta");
  CHECK(third.model().box().far == 3.0);  // before the resume: the Config's box
  REQUIRE(third.resume());
  CHECK(third.config().near == 0.6);
  CHECK(third.config().far == 2.5);
  CHECK(third.model().box().scale == whole.model().box().scale);
  CHECK(third.model().box().far == 2.5);
  third.run();
  const auto record = nlohmann::json::parse(read_file(base / "split" / "settings.json"));
  REQUIRE(record["runs"].size() == 3);
  CHECK(record["runs"][2]["near"] == 0.6);
  CHECK(record["runs"][2]["far"] == 2.5);
  fs::remove_all(base);
}

TEST_CASE("the settings table: every setting round-trips through settings.json and is refused outside its interval, by name") {
  // Each row once: a value inside its interval (not its default, where there is room) read back equal from
  // settings.json's object; each end of its interval passed by one refused with a message naming it.
  std::set<std::string> names;
  for (const auto& s : train::settings()) {
    CAPTURE(s.name);
    CHECK(names.insert(s.name).second);  // one name per setting
    CHECK(std::string(s.help).size() > 10);
    CHECK(s.flag() == "--" + [&] { std::string n = s.name; std::replace(n.begin(), n.end(), '_', '-'); return n; }());
    train::Config c;
    const auto j0 = train::settings_json(c);
    REQUIRE(j0.contains(s.name));
    nlohmann::json other = s.get(c);
    if (s.numeric()) {
      const double lo = std::isfinite(s.lo) ? s.lo : 0, hi = std::isfinite(s.hi) ? s.hi : lo + 100;
      double v = s.integral() ? std::floor(lo + 1) : 0.5 * (lo + hi);
      if (!s.allows(v)) v = std::isfinite(s.hi) ? s.hi - (s.hi_open ? 0.5 : 0) : lo + 1;
      REQUIRE(s.allows(v));
      other = s.integral() ? nlohmann::json(static_cast<long>(v)) : nlohmann::json(v);
    } else if (other.is_boolean()) {
      other = !other.get<bool>();
    } else {
      other = "sparse";
    }
    nlohmann::json j = j0;
    j[s.name] = other;
    const train::Config back = train::config_from_json(j, "test");
    CHECK(s.get(back) == other);
    CHECK(train::settings_json(back)[s.name] == other);
    if (!s.numeric()) continue;
    std::vector<double> outside;
    if (std::isfinite(s.lo)) outside.push_back(s.lo_open ? s.lo : s.lo - 1);
    if (std::isfinite(s.hi)) outside.push_back(s.hi_open ? s.hi : s.hi + 1);
    if (!s.integral()) outside.push_back(std::nan(""));
    for (double v : outside) {
      if (std::holds_alternative<std::uint64_t train::Config::*>(s.member) && v < 0) {
        nlohmann::json k = j0;
        k[s.name] = static_cast<long>(v);
        CHECK_THROWS_WITH_AS(train::config_from_json(k, "test"), doctest::Contains((std::string(s.name) + " must be an integer").c_str()), Error);
        continue;
      }
      train::Config d;
      std::visit(
          [&](auto m) {
            using V = std::decay_t<decltype(d.*m)>;
            if constexpr (std::is_same_v<V, std::optional<double>>) d.*m = v;
            else if constexpr (std::is_arithmetic_v<V> && !std::is_same_v<V, bool>) d.*m = static_cast<V>(v);
          },
          s.member);
      CHECK_THROWS_WITH_AS(train::check(d), doctest::Contains(("train: " + std::string(s.name) + " must be " + s.range_text()).c_str()), Error);
    }
  }
  CHECK_THROWS_WITH_AS(train::setting("iters", "train"), doctest::Contains("unknown setting 'iters' (known: iterations, pixels"), Error);
  CHECK_THROWS_WITH_AS(train::config_from_json(nlohmann::json{{"pixels", "many"}}, "settings.json"),
                       doctest::Contains("settings.json: pixels must be an integer, got \"many\""), Error);
}

TEST_CASE("collapse detection: a forced collapse stops the run with what it saw; a healthy run is not stopped") {
  Fixture f;
  train::Config cfg = f.run_config(300, 128);
  cfg.collapse_check_from = 100;
  cfg.collapse_check_every = 100;
  const fs::path base = fs::temp_directory_path() / ("evnerf_collapse_" + std::to_string(::getpid()));
  {
    // Forced: every parameter zero and no learning rate. No density, so every render is black and the
    // loss never moves.
    cfg.lr = 1e-30;
    train::Trainer<Tiny> t(f.td, cfg, base / "dead", "tiny", "meta");
    std::fill(t.model().params().values.begin(), t.model().params().values.end(), 0.f);
    const auto r = t.run();
    CHECK(r.collapsed);
    CHECK(t.model().step() == 100);  // stopped at the first check
    REQUIRE(r.checks.size() == 1);
    CHECK(r.checks[0].flat_renders);
    CHECK(r.checks[0].log_spread < 1e-6);
    CHECK(r.checks[0].loss_stuck);
    CHECK_CONTAINS(r.checks[0].describe(), "at step 100: the renders are almost constant");
    CHECK(fs::exists(base / "dead" / "model.ckpt"));
    // Asked to go on, it does, and still reports it.
    cfg.allow_collapse = true;
    train::Trainer<Tiny> u(f.td, cfg, base / "dead2", "tiny", "meta");
    std::fill(u.model().params().values.begin(), u.model().params().values.end(), 0.f);
    const auto r2 = u.run();
    CHECK(r2.collapsed);
    CHECK(u.model().step() == 300);
    CHECK(r2.checks.size() == 3);
    cfg.allow_collapse = false;
  }
  {
    // Healthy: the windowed half-slack objective of the Fast presets on the tiny model.
    cfg.lr = 5e-3;
    using Healthy = EvNerf<TinyField, render::Stratified<16>, loss::ProjectedThresholds, loss::DefaultNoise, loss::WindowInterval<4>>;
    train::Trainer<Healthy> t(f.td, cfg, base / "healthy", "tiny", "meta");
    const auto r = t.run();
    for (const auto& c : r.checks) MESSAGE(c.describe());
    CHECK_FALSE(r.collapsed);
    CHECK(t.model().step() == 300);
    REQUIRE(r.checks.size() == 3);
    for (const auto& c : r.checks) {
      CAPTURE(c.describe());
      CHECK(c.log_spread > 3 * train::CollapseCheck::kMinLogSpread);
      CHECK(c.recent_loss < c.start_loss);
    }
  }
  cfg.collapse_check_every = 75;  // not a multiple of the log period
  train::Trainer<Tiny> bad(f.td, cfg, base / "bad", "tiny", "meta");
  CHECK_THROWS_WITH(bad.run(), doctest::Contains("multiples of 50"));
  fs::remove_all(base);
}

TEST_CASE("training data: subslices put evenly spaced boundaries between frames and keep the frames' own") {
  Fixture f;
  train::Config cfg = f.cfg;
  cfg.subslices = 3;
  std::vector<std::size_t> frames;
  const TrainingData td = train::prepare(f.d, cfg, &frames);
  REQUIRE(td.slices.size() == 3 * f.td.slices.size());
  REQUIRE(frames.size() == td.slices.boundaries.size());
  for (std::size_t i = 0; i < f.td.slices.boundaries.size(); ++i) {
    CHECK(td.slices.boundaries[3 * i] == f.td.slices.boundaries[i]);  // the frame boundaries stay
    if (i + 1 < f.td.slices.boundaries.size()) {
      const double step = (f.td.slices.boundaries[i + 1] - f.td.slices.boundaries[i]) / 3;
      CHECK(td.slices.boundaries[3 * i + 1] == doctest::Approx(f.td.slices.boundaries[i] + step));
      CHECK(frames[3 * i + 1] == static_cast<std::size_t>(-1));
    }
  }
  std::size_t events = 0, fine_events = 0;
  for (const auto& s : f.td.slices.slices) events += s.total;
  for (const auto& s : td.slices.slices) fine_events += s.total;
  CHECK(fine_events == events);  // the same events, cut finer
  cfg.holdout = 4;
  CHECK_THROWS_WITH(train::prepare(f.d, cfg), doctest::Contains("subslices and holdout cannot be combined"));
}

TEST_CASE("training data: with subslices a window objective's windows span W frame intervals, not W slices") {
  Fixture f;
  train::Config cfg = f.cfg;
  cfg.subslices = 3;
  TrainingData td = train::prepare(f.d, cfg);
  REQUIRE(td.slices.size() == 12);
  CHECK(td.slices_per_interval == 3);
  TinyWindow m(td.slices.size(), train::scene_box(td, f.cfg), 7);  // W = 4 intervals: 1..12 slices
  std::size_t longest = 0;
  for (int s = 0; s < 40; ++s) {
    const auto st = m.train_step(td, 64, 3);
    REQUIRE(st.first_slice + st.window <= 12);
    longest = std::max(longest, st.window);
  }
  CHECK(longest > 4);
  td.slices_per_interval = 1;  // the same slices taken as the recording's own cut: at most W slices
  for (int s = 0; s < 40; ++s) CHECK(m.train_step(td, 64, 3).window <= 4);
  td.slices_per_interval = 0;
  CHECK_THROWS_WITH(m.train_step(td, 64, 3), doctest::Contains("slices per interval"));
}

// ---- faults a long run meets (the process-level ones, SIGKILL and SIGINT, are in tests/faults.sh) ----

namespace {
/// The files of a folder whose names hold ".tmp." (left behind by an interrupted atomic write).
std::vector<std::string> temporaries(const fs::path& dir) {
  std::vector<std::string> t;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) t.push_back(e.path().string());
  return t;
}
}  // namespace

TEST_CASE("faults: a NaN in the parameters stops the run with a message and keeps the last good checkpoint") {
  Fixture f;
  const fs::path base = fs::temp_directory_path() / ("evnerf_nan_" + std::to_string(::getpid()));
  // Injected after step 3 into every parameter, or after step 4 into one: the checkpoint due at step 4 finds
  // them (a NaN parameter need not make the loss NaN: ReLU and clamps absorb it, so the loss check alone
  // would miss it) and the run stops there.
  for (const long inject : {3L, 4L}) {
    CAPTURE(inject);
    train::Config cfg = f.run_config(10, 64);
    cfg.threads = 1;
    cfg.checkpoint_every = 2;
    const fs::path out = base / std::to_string(inject);
    train::Trainer<Tiny> t(f.td, cfg, out, "tiny", "meta");
    std::string good;
    const auto r = t.run([&](const train::StepReport& rep) {
      if (rep.step == 3) good = read_file(out / "model.ckpt");  // written at step 2
      auto& v = t.model().params().values;
      if (rep.step == inject && inject == 3) std::fill(v.begin(), v.end(), std::numeric_limits<float>::quiet_NaN());
      if (rep.step == inject && inject == 4) v[v.size() / 3] = std::numeric_limits<float>::quiet_NaN();
      return true;
    });
    CHECK(r.diverged);
    CHECK(t.model().step() == 4);
    REQUIRE_FALSE(good.empty());
    CHECK(read_file(out / "model.ckpt") == good);
    CHECK(temporaries(out).empty());
    Tiny back;  // the kept checkpoint loads and is finite
    train::load_checkpoint(out / "model.ckpt", back, "tiny");
    CHECK(back.step() == 2);
    CHECK(std::all_of(back.params().values.begin(), back.params().values.end(), [](float x) { return std::isfinite(x); }));
  }
  fs::remove_all(base);
}

TEST_CASE("faults: a full disk or an unwritable folder is a clear error; no partial file, the earlier checkpoint intact") {
  Fixture f;
  const fs::path base = fs::temp_directory_path() / ("evnerf_full_" + std::to_string(::getpid()));
  const fs::path out = base / "run";
  train::Config cfg = f.run_config(4, 64);
  cfg.threads = 1;
  cfg.checkpoint_every = 2;
  train::Trainer<Tiny>(f.td, cfg, out, "tiny", "meta").run();
  const std::string good = read_file(out / "model.ckpt");
  REQUIRE(good.size() > 128 * 1024);

  // A disk that takes at most 64 KB per file: RLIMIT_FSIZE makes write() fail with EFBIG as a full disk
  // fails with ENOSPC (SIGXFSZ ignored), in this process only.
  cfg.iterations = 8;
  train::Trainer<Tiny> more(f.td, cfg, out, "tiny", "meta");
  REQUIRE(more.resume());
  rlimit old{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &old) == 0);
  auto* old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit small = old;
  small.rlim_cur = 64 * 1024;
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
  std::string error;
  try {
    more.run();
  } catch (const Error& e) {
    error = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  CHECK_CONTAINS(error, (out / "model.ckpt").string() + ":0: write failed after");
  CHECK_CONTAINS(error, std::strerror(EFBIG));
  CHECK_CONTAINS(error, "the previous file, if any, is unchanged");
  CHECK(read_file(out / "model.ckpt") == good);
  CHECK(temporaries(out).empty());

  // An output folder that cannot exist (a file stands in its path), and a checkpoint path that is a folder.
  write_file_atomic(base / "plain", "x");
  train::Trainer<Tiny> nowhere(f.td, cfg, base / "plain" / "run", "tiny", "meta");
  const std::string nowhere_error = (base / "plain" / "run").string() + ":0: cannot create the output folder";
  CHECK_THROWS_WITH(nowhere.run(), doctest::Contains(nowhere_error.c_str()));
  fs::create_directories(base / "blocked" / "model.ckpt");
  train::Trainer<Tiny> blocked(f.td, cfg, base / "blocked", "tiny", "meta");
  CHECK_THROWS_WITH(blocked.run(), doctest::Contains("cannot rename the temporary file into place"));
  CHECK(temporaries(base / "blocked").empty());
  fs::remove_all(base);
}

// ---- data-parallel steps (StepShards, train::GradientExchange) ----------------------------------------

TEST_CASE("data-parallel steps: two processes' shards, summed, equal one process computing both, bit for bit") {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  // One process, two shards per step; and the two halves of the same step as two processes would compute
  // them: rank 1's gradients are taken first (its own step is discarded), rank 0 adds them as the exchange.
  TinyWindow one(f.td.slices.size(), box, 7), r0(f.td.slices.size(), box, 7), r1;
  std::vector<float> g1;
  std::vector<double> t1;
  for (int s = 0; s < 5; ++s) {
    r1.deserialize(r0.serialize("tiny", ""), "tiny", "mem");
    r1.train_step(f.td, 128, 3, 0, StepShards{2, 1, 2}, [&](std::vector<float>& g, std::vector<double>& t) { g1 = g, t1 = t; });
    const auto a = one.train_step(f.td, 128, 3, 0, StepShards{2, 0, 1}, [](std::vector<float>&, std::vector<double>&) {});
    const auto b = r0.train_step(f.td, 128, 3, 0, StepShards{2, 0, 2}, [&](std::vector<float>& g, std::vector<double>& t) {
      REQUIRE(g.size() == g1.size());
      for (std::size_t i = 0; i < g.size(); ++i) g[i] += g1[i];
      for (std::size_t i = 0; i < t.size(); ++i) t[i] += t1[i];
    });
    CHECK(a.loss == b.loss);
    CHECK(a.rays == b.rays);
    CHECK(a.rays == 2 * 2 * 128);
    REQUIRE(one.params().values == r0.params().values);
  }
  // A second shard is another draw: a two-shard step is not the one-shard step, and its loss is the mean.
  TinyWindow single(f.td.slices.size(), box, 7), two(f.td.slices.size(), box, 7);
  const auto s1 = single.gradients(f.td, 128, 3, 0, 0);
  const auto s2 = single.gradients(f.td, 128, 3, 0, 1);
  const auto both = two.train_step(f.td, 128, 3, 0, StepShards{2, 0, 1}, [](std::vector<float>&, std::vector<double>&) {});
  CHECK(both.loss == doctest::Approx(0.5 * (s1.loss + s2.loss)).epsilon(1e-12));
  CHECK(s1.loss != s2.loss);
  // One shard through the data-parallel path is the plain step.
  TinyWindow plain(f.td.slices.size(), box, 7), path(f.td.slices.size(), box, 7);
  for (int s = 0; s < 3; ++s) {
    plain.train_step(f.td, 128, 3);
    path.train_step(f.td, 128, 3, 0, StepShards{}, [](std::vector<float>&, std::vector<double>&) {});
  }
  CHECK(plain.params().values == path.params().values);
  CHECK_THROWS_WITH(path.train_step(f.td, 128, 3, 0, StepShards{3, 0, 2}, [](std::vector<float>&, std::vector<double>&) {}),
                    doctest::Contains("shards per step (3) must be a positive multiple of the processes (2)"));
}

namespace {
// Two threads as a train::Group (each thread one rank), for testing the exchange without MPI: every
// collective meets at a barrier and combines rank 0's buffer with rank 1's in that order.
struct Pair {
  std::barrier<> meet{2};
  const void* buf[2] = {nullptr, nullptr};
};
class ThreadGroup final : public train::Group {
 public:
  ThreadGroup(Pair& p, int rank) : p_(p), rank_(rank) {}
  int rank() const override { return rank_; }
  int size() const override { return 2; }
  void sum(float* x, std::size_t n) override { all(x, n, [](float a, float b) { return a + b; }); }
  void sum(double* x, std::size_t n) override { all(x, n, [](double a, double b) { return a + b; }); }
  void bit_or(std::uint64_t* x, std::size_t n) override { all(x, n, [](std::uint64_t a, std::uint64_t b) { return a | b; }); }
  void broadcast(std::string& bytes) override { all(&bytes, 1, [](const std::string& a, const std::string&) { return a; }); }
  [[noreturn]] void abort(const std::string& m, int) override { throw std::runtime_error(m); }

 private:
  template <class T, class Op>
  void all(T* x, std::size_t n, Op op) {
    p_.buf[rank_] = x;
    p_.meet.arrive_and_wait();
    const T* a = static_cast<const T*>(p_.buf[0]);
    const T* b = static_cast<const T*>(p_.buf[1]);
    std::vector<T> r(n);
    for (std::size_t i = 0; i < n; ++i) r[i] = op(a[i], b[i]);
    p_.meet.arrive_and_wait();
    std::copy(r.begin(), r.end(), x);
    p_.meet.arrive_and_wait();
  }
  Pair& p_;
  int rank_;
};
}  // namespace

TEST_CASE("gradient exchange: dense, sparse and auto give the same sums; sparse sends only the touched blocks") {
  constexpr std::size_t n = 16 * 40 + 5;  // a partial last block
  auto grads_of = [&](int rank) {
    std::vector<float> g(n, 0.0f);
    for (std::size_t i = 0; i < n; ++i)
      if ((rank == 0 && (i < 40 || i + 3 >= n)) || (rank == 1 && i >= 100 && i < 130)) g[i] = 0.25f * float(i % 7) + float(rank) + 0.5f;
    return g;
  };
  std::vector<float> expect(n);
  for (std::size_t i = 0; i < n; ++i) expect[i] = grads_of(0)[i] + grads_of(1)[i];
  for (auto mode : {train::Exchange::Dense, train::Exchange::Sparse, train::Exchange::Auto}) {
    CAPTURE(int(mode));
    Pair p;
    std::vector<float> got[2];
    std::vector<double> totals[2];
    double bytes[2] = {0, 0};
    long sparse[2] = {0, 0};
    bool same[2] = {false, false}, differ[2] = {true, true};
    auto work = [&](int rank) {
      ThreadGroup g(p, rank);
      train::GradientExchange ex(&g, mode);
      got[rank] = grads_of(rank);
      totals[rank] = {1.0 + rank, 10.0 * rank};
      ex(got[rank], totals[rank]);
      bytes[rank] = ex.bytes();
      sparse[rank] = ex.sparse_steps();
      same[rank] = g.same(42);
      differ[rank] = g.same(std::uint64_t(rank));
    };
    std::thread t1(work, 1);
    work(0);
    t1.join();
    for (int r = 0; r < 2; ++r) {
      CHECK(got[r] == expect);
      CHECK(totals[r] == std::vector<double>{3.0, 10.0});
      CHECK(same[r]);
      CHECK_FALSE(differ[r]);  // every rank learns that the values differ
    }
    // Touched blocks: 0..2 and the partial last one (40) of rank 0, 6..8 of rank 1: 7 of 41 blocks.
    const double bitmap = 8, sparse_bytes = 2 * 8 + bitmap + 7 * 16 * 4, dense_bytes = 2 * 8 + double(n) * 4;
    CHECK(bytes[0] == (mode == train::Exchange::Dense ? dense_bytes : sparse_bytes));
    CHECK(sparse[0] == (mode == train::Exchange::Dense ? 0 : 1));
  }
}
