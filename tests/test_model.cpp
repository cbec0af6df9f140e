// The whole training loss of tiny models in double precision against central finite differences: every
// network parameter (both networks of a hierarchical sampler) and every per-slice threshold, for each
// sampler (Stratified, Hierarchical, OccupancySkipping with an active grid) and for 1 and 3 (RGGB) channels.
#include <algorithm>
#include <cmath>
#include <optional>

#include <evnerf/evnerf.hpp>

#include "../examples/parts/eventnerf_mse.hpp"
#include "../examples/parts/inverse_depth.hpp"
#include "../examples/parts/quiet_pixels.hpp"
#include "../examples/parts/shot_noise_counts.hpp"
#include "../examples/parts/triangle_wave.hpp"
#include "common.hpp"
#include "tiny_scene.hpp"

using namespace evnerf;

namespace {
// Tiny fields: a hash grid of 2 levels × 32 entries with small networks, and a paper-like frequency
// field with a skip connection (the Paper model's shape, a few hundred parameters).
template <int C>
using HashTiny = field::Field<nn::HashGrid<2, 2, 5, 2, 4>, nn::SphericalHarmonics<2>, nn::Mlp<4, 8, 1, 4, nn::ReLU, nn::Identity>,
                              nn::Mlp<3 + 4, 8, 1, C, nn::ReLU, nn::Identity>>;
template <int C>
using FreqTiny = field::Field<nn::Frequency<1>, nn::Frequency<1>, nn::Mlp<9, 8, 3, 9, nn::ReLU, nn::Identity, 0>,
                              nn::Mlp<8 + 9, 4, 1, C, nn::ReLU, nn::Identity>>;
using Window = loss::WindowInterval<4, loss::HalfSlackCounts>;
// The paper's objective with its λ = 1000 floor; the Fast presets' windowed one with projected thresholds.
template <int C>
using StratifiedModel = EvNerf<HashTiny<C>, render::Stratified<8>, loss::JointThresholds, loss::DefaultNoise, loss::SplitCounts<1>, double>;
template <int C>
using HierarchicalModel =
    EvNerf<FreqTiny<C>, render::Hierarchical<8, 8>, loss::JointThresholds, loss::DefaultNoise, loss::SplitCounts<1>, double>;
template <int C>
using OccupancyModel =
    EvNerf<HashTiny<C>, render::OccupancySkipping<8, 8, 1, 0>, loss::ProjectedThresholds, loss::DefaultNoise, Window, double>;
// Samples spaced in log depth (render::LogDepth): uneven intervals between samples.
template <int C>
using LogOccupancyModel = EvNerf<HashTiny<C>, render::OccupancySkipping<8, 8, 1, 0, 10, render::LogDepth>, loss::ProjectedThresholds,
                                 loss::DefaultNoise, Window, double>;
// 24 samples per ray (three chunks of the renderer's kEvalChunk): rays that stop early can skip some.
template <int C>
using LongOccupancyModel =
    EvNerf<HashTiny<C>, render::OccupancySkipping<24, 8, 1, 0>, loss::ProjectedThresholds, loss::DefaultNoise, Window, double>;
template <int C>
using WindowHierarchicalModel = EvNerf<FreqTiny<C>, render::Hierarchical<8, 8>, loss::JointThresholds, loss::DefaultNoise, Window, double>;

// Radiance of any range (field::ExpRadiance: exp of the colour output, the loss's log with ε = 1e-4).
template <int C>
using ExpRadianceModel =
    EvNerf<field::Field<nn::HashGrid<2, 2, 5, 2, 4>, nn::SphericalHarmonics<2>, nn::Mlp<4, 8, 1, 4, nn::ReLU, nn::Identity>,
                        nn::Mlp<3 + 4, 8, 1, C, nn::ReLU, nn::Identity>, nn::ReLU, field::ExpRadiance>,
           render::OccupancySkipping<8, 8, 1, 0>, loss::ProjectedThresholds, loss::DefaultNoise, Window, double>;

// The examples' parts (examples/parts/) in one tiny model: a sampler, an encoding and a bound policy of a user's own.
using CustomParts =
    EvNerf<field::FieldOf<mylab::TriangleWave<2>, nn::SphericalHarmonics<2>, nn::MlpShape{.width = 8}, 3, nn::MlpShape{.width = 8}>,
           mylab::InverseDepth<8>, loss::ProjectedThresholds, loss::DefaultNoise,
           loss::WindowInterval<4, mylab::ShotNoiseCounts, events::EventPixels<100>>, double>;

// Model M with the total-variation and distortion terms added to its objective (terms 1 and 2), each off
// until a test gives it a weight.
template <class M>
using TvOf = EvNerf<typename M::field_type, typename M::sampler_type, typename M::threshold_policy, typename M::noise_policy,
                    loss::Plus<typename M::objective_type, loss::TotalVariation<0>, loss::Distortion<0>>, double>;

// The examples' objective and regulariser (examples/parts/): EventNeRF's normalised squared loss with the
// paper's floor on its thresholds, and Window plus the total-variation and quiet-pixels terms.
template <int C>
using EventNerfModel =
    EvNerf<HashTiny<C>, render::OccupancySkipping<8, 8, 1, 0>, loss::JointThresholds, loss::DefaultNoise, mylab::EventNerfMse<4>, double>;
template <int C>
using QuietModel = EvNerf<HashTiny<C>, render::Stratified<8>, loss::ProjectedThresholds, loss::DefaultNoise,
                          loss::Plus<Window, loss::TotalVariation<300>, mylab::QuietPixels<2000>>, double>;

struct GradCheck {
  std::size_t checked = 0, nonzero = 0, kinks = 0, bad = 0;
  double worst = 0;
};

/// Central differences of Model::gradients()'s loss for every parameter. A parameter where the two
/// one-sided differences disagree sits on a kink (ReLU, hinge) and is counted, not compared. The coarse
/// network of a two-network sampler is compared with its own pass's loss: the fine depths it decides are
/// held fixed in the backward, as in NeRF.
template <class Model>
GradCheck check_all(Model& m, const TrainingData& td, int pixels, std::uint64_t seed) {
  auto loss_for = [&](std::size_t i, const StepStats& st) {
    if (Model::n_fields == 2 && i < Model::field_params) return st.pass_event_loss[0] + st.threshold_loss;
    return st.loss;
  };
  const auto st0 = m.gradients(td, pixels, seed, 4);
  const std::vector<double> g = m.params().grads;
  auto& x = m.params().values;
  GradCheck r;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double x0 = x[i], h = 1e-7 * std::max(1.0, std::abs(x0)), l0 = loss_for(i, st0);
    x[i] = x0 + h;
    const double lp = loss_for(i, m.gradients(td, pixels, seed, 4));
    x[i] = x0 - h;
    const double lm = loss_for(i, m.gradients(td, pixels, seed, 4));
    x[i] = x0;
    const double fwd = (lp - l0) / h, bwd = (l0 - lm) / h, num = (lp - lm) / (2 * h);
    ++r.checked;
    if (std::abs(fwd - bwd) > 1e-3 * std::max(1.0, std::abs(num))) {
      ++r.kinks;
      continue;
    }
    if (g[i] != 0) ++r.nonzero;
    const double err = std::abs(num - g[i]) / std::max(1.0, std::abs(num));
    r.worst = std::max(r.worst, err);
    if (err > 1e-5) {
      ++r.bad;
      MESSAGE("parameter " << i << ": analytic " << g[i] << ", finite differences " << num);
    }
  }
  return r;
}

/// `dead_time`: the counts read under a learned refractory period (each event stands for the crossings
/// events::dead_time_weight gives), on the fixture with a finer threshold, at the period that saturates
/// about a third of its events; dloss/dτ is checked too.
/// `background`: the scene box's background luminance (train::Config::background), unset for none.
/// `learn_background`: a learned backdrop (train::Config::learn_background), its raw values checked too.
template <class Model>
void check_model(double distortion = 0, double tv = 0, bool terminate = false, loss::TvNeighbours neighbours = loss::TvNeighbours::Any,
                 double tv_share = 1, bool dead_time = false, std::optional<double> background = {}, bool learn_background = false) {
  evtest::Fixture f(dead_time ? 0.08 : 0.25);
  f.cfg.background = background;
  f.cfg.learn_background = learn_background;
  double refractory = 0;
  if (dead_time) {
    std::vector<double> gaps;
    for (const auto& s : f.td.slices.slices)
      for (const float g : s.gap) gaps.push_back(std::abs(static_cast<double>(g)));
    REQUIRE(gaps.size() > 1000);
    std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 3, gaps.end());
    refractory = std::min(RefractoryState::kMax, gaps[gaps.size() / 3] / events::kSaturatedPeriods);
    std::size_t saturated = 0, events = 0;
    for (const double g : gaps) {
      ++events;
      saturated += events::dead_time_weight(g, refractory).saturated;
    }
    CAPTURE(saturated);
    CAPTURE(events);
    REQUIRE(saturated * 10 > events);  // a share of the events saturated, not all
    REQUIRE(saturated * 5 < events * 4);
  }
  Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  if (refractory > 0) m.set_refractory(refractory, true);
  if (auto* term = m.template term<loss::DistortionTerm>()) term->set_weight(distortion);
  else REQUIRE(distortion == 0);
  if (auto* term = m.template term<loss::TvTerm>()) {
    term->set_weight(tv);
    term->neighbours = neighbours;
    term->set_share(tv_share);
  } else {
    REQUIRE(tv == 0);
  }
  m.set_ray_termination(terminate);
  // Hash tables away from their tiny initial values: the hidden units' inputs are then far from the ReLU's
  // kink compared with the step of the differences (the comparison is of a smooth function).
  Rng rng(11);
  for (int net = 0; net < Model::n_fields; ++net)
    for (std::size_t i = 0; i < Model::field_type::pos_encoding::n_params; ++i)
      m.params().values[net * Model::field_params + i] = rng.uniform() - 0.5;
  // Thresholds spread around the floor, so that the floor term (where there is one) is both active and not.
  for (std::size_t i = 0; i < m.n_slices(); ++i) {
    m.params().values[m.threshold_offset() + 2 * i] = 0.2 + 0.2 * rng.uniform();
    m.params().values[m.threshold_offset() + 2 * i + 1] = -(0.2 + 0.2 * rng.uniform());
  }
  // A backdrop away from the activation's middle, one value per channel.
  for (int c = 0; c < Model::channels; ++c) m.params().values[Model::backdrop_offset() + c] = rng.uniform() - 0.5;
  if (terminate) {
    // A density high enough that rays become opaque inside the box (the first output's bias raised), so
    // that they stop before their last samples.
    using D = typename Model::field_type::density_net;
    m.params().values[Model::field_type::density_offset + D::bias_offset(D::n_layers - 1)] = 8;
  }
  if constexpr (Model::sampler_type::skips_samples) {
    m.update_sampler(f.td, 0, 3);  // an active grid: some samples are skipped, and get no gradient
    const double occ = m.sampler().occupied_fraction();
    CAPTURE(occ);
    REQUIRE(occ > 0);
    REQUIRE(occ < 1);
  }
  int threshold_grads = 0;
  for (const std::uint64_t seed : {1u, 2u}) {
    const auto st = m.gradients(f.td, 16, seed, 4);
    CAPTURE(seed);
    REQUIRE(std::isfinite(st.loss));
    REQUIRE(st.loss > 0);
    if (distortion > 0) {
      REQUIRE(std::string(Model::term_name(2)) == "distortion");
      CHECK(st.term_loss[2] > 0);
    } else if (Model::n_terms > 2 && std::string(Model::term_name(2)) == "distortion") {
      CHECK(st.term_loss[2] == 0);
    }
    if (tv > 0) CHECK(st.term_loss[1] > 0);
    else CHECK(st.term_loss[1] == 0);
    // Two rays per pixel, one more for the TV neighbour (for some of the pixels at a share under 1).
    if (tv_share < 1) {
      CHECK(st.rays > 2u * 16u);
      CHECK(st.rays < 3u * 16u);
    } else {
      CHECK(st.rays == (2u + (tv > 0 ? 1u : 0u)) * 16u);
    }
    if constexpr (Model::sampler_type::skips_samples) {
      CHECK(st.samples > 0);
      CHECK(st.samples < st.rays * Model::Nc);
    }
    if (terminate) {  // rays did stop: the same step without termination evaluates more samples
      m.set_ray_termination(false);
      const auto full = m.gradients(f.td, 16, seed, 4);
      m.set_ray_termination(true);
      CAPTURE(full.samples);
      CAPTURE(st.samples);
      CHECK(st.samples < full.samples);
      CHECK(st.backward_samples <= full.backward_samples);
      CHECK(st.loss == doctest::Approx(full.loss).epsilon(1e-3));
    }
    const GradCheck r = check_all(m, f.td, 16, seed);
    CAPTURE(r.checked);
    CAPTURE(r.kinks);
    CAPTURE(r.nonzero);
    CAPTURE(r.worst);
    CHECK(r.checked == Model::renderer_type::n_params + 2 * m.n_slices());
    // The backdrop's raw values have a gradient only when it is learned (the comparison above covered
    // them); then some of them do, unless every ray stops before it (terminate: opaque rays).
    int backdrop_grads = 0;
    for (int c = 0; c < Model::channels; ++c) backdrop_grads += m.params().grads[Model::backdrop_offset() + c] != 0;
    if (!learn_background) CHECK(backdrop_grads == 0);
    else if (!terminate) CHECK(backdrop_grads > 0);
    CHECK(r.bad == 0);
    CHECK(r.kinks * 50 <= r.checked);   // kinks are rare: the comparison covers almost every parameter
    CHECK(r.nonzero * 3 >= r.checked);  // and most of them get a gradient at all
    // Only the window's thresholds can have a gradient.
    const std::size_t to = m.threshold_offset();
    for (std::size_t i = 0; i < m.n_slices(); ++i) {
      const bool inside = i >= st.first_slice && i < st.first_slice + st.window;
      for (int k = 0; k < 2; ++k) {
        const double gi = m.params().grads[to + 2 * i + k];
        if (inside) threshold_grads += gi != 0;
        else CHECK(gi == 0);
      }
    }
  }
  CHECK(threshold_grads > 0);  // and some of them did (the comparison above covered them)
  if (refractory > 0) {
    // The period against central differences of the whole loss (a step of 1e-4 of it; a draw that puts an
    // interval's saturation within the step shows as a kink and is not compared).
    int compared = 0;
    for (const std::uint64_t seed : {1u, 2u, 3u, 4u}) {
      const double g = m.gradients(f.td, 16, seed, 4).refractory_grad, h = refractory * 1e-4;
      auto at = [&](double tau) {
        m.set_refractory(tau, true);
        const double l = m.gradients(f.td, 16, seed, 4).loss;
        m.set_refractory(refractory, true);
        return l;
      };
      const double lp = at(refractory + h), l0 = at(refractory), lm = at(refractory - h);
      const double fwd = (lp - l0) / h, bwd = (l0 - lm) / h, num = (lp - lm) / (2 * h);
      if (std::abs(fwd - bwd) > 1e-3 * std::max(1.0, std::abs(num))) continue;
      ++compared;
      CAPTURE(seed);
      CHECK(num != 0);
      CHECK(g == doctest::Approx(num).epsilon(1e-5).scale(1.0));
    }
    CHECK(compared >= 2);
  }
}
}  // namespace

/// Pose refinement (model/poses.hpp): the whole training loss's gradient for each knot's correction (a twist
/// at 0 in its camera's frame) and for the clock offset, against central differences, on the fixture with
/// every knot corrected and an offset of 3 ms. The first knot's gradient is 0 (the gauge).
template <class Model>
void check_pose_gradients() {
  evtest::Fixture f;
  Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  Rng rng(11);
  for (int net = 0; net < Model::n_fields; ++net)
    for (std::size_t i = 0; i < Model::field_type::pos_encoding::n_params; ++i)
      m.params().values[net * Model::field_params + i] = rng.uniform() - 0.5;
  PoseRefinementSettings s;
  s.poses = s.offset = true;
  s.prior_rotation = 30, s.prior_translation = 50;  // the pull toward the given poses, in the loss and its gradient
  m.set_pose_refinement(f.td, s);
  for (std::size_t i = 1; i <= m.n_slices(); ++i)
    m.set_pose_correction(f.td, i,
                          twist_exp(Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 0.02,
                                    Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 0.02));
  m.set_time_offset(f.td, 0.003);
  if constexpr (Model::sampler_type::skips_samples) m.update_sampler(f.td, 0, 3);
  const double h = 1e-6;
  std::size_t compared = 0, kinks = 0, nonzero = 0;
  for (const std::uint64_t seed : {1u, 2u}) {
    CAPTURE(seed);
    const auto st = m.gradients(f.td, 16, seed, 4);
    const auto g = m.pose_gradient();
    const double go = m.offset_gradient();
    REQUIRE(g.size() == m.n_slices() + 1);
    CHECK(g[0] == std::array<double, 6>{});
    auto compare = [&](double analytic, double lp, double l0, double lm, double step) {
      const double fwd = (lp - l0) / step, bwd = (l0 - lm) / step, num = (lp - lm) / (2 * step);
      if (std::abs(fwd - bwd) > 1e-3 * std::max(1.0, std::abs(num))) {
        ++kinks;
        return;
      }
      ++compared;
      nonzero += analytic != 0;
      CHECK(analytic == doctest::Approx(num).epsilon(1e-5).scale(1.0));
    };
    // The knots of the step's window (the others have no ray) and one beyond it.
    for (std::size_t i = std::max<std::size_t>(1, st.first_slice); i <= std::min(m.n_slices(), st.first_slice + st.window + 1); ++i) {
      CAPTURE(i);
      const geometry::Pose c = m.pose_refinement().correction[i];
      for (int k = 0; k < 6; ++k) {
        CAPTURE(k);
        auto at = [&](double e) {
          Vec3 phi = Vec3::Zero(), rho = Vec3::Zero();
          (k < 3 ? phi : rho)[k % 3] = e;
          m.set_pose_correction(f.td, i, c * twist_exp(phi, rho));
          const double l = m.gradients(f.td, 16, seed, 4).loss;
          m.set_pose_correction(f.td, i, c);
          return l;
        };
        compare(g[i][k], at(h), at(0), at(-h), h);
      }
    }
    auto at_offset = [&](double e) {
      m.set_time_offset(f.td, 0.003 + e);
      const double l = m.gradients(f.td, 16, seed, 4).loss;
      m.set_time_offset(f.td, 0.003);
      return l;
    };
    compare(go, at_offset(h), at_offset(0), at_offset(-h), h);
    CHECK(go != 0);
  }
  CAPTURE(kinks);
  CHECK(compared >= 20);
  CHECK(kinks * 10 <= compared);
  CHECK(nonzero * 2 >= compared);
}

// The pull toward the given poses: its gradient for the twist of c ∘ Exp(ε) against central differences, at
// corrections far from small (the rotation's gradient is exact at any angle below π).
TEST_CASE("pose refinement: the pull toward the given poses, finite differences in double at large corrections") {
  PoseRefinementSettings s;
  s.prior_rotation = 3, s.prior_translation = 7;
  Rng rng(4);
  for (int trial = 0; trial < 20; ++trial) {
    const Vec3 phi0 = Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5).normalized() * rng.uniform(0.01, 2.5);
    const geometry::Pose c = twist_exp(phi0, Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5));
    std::array<double, 6> g{};
    const double l = pose_prior(s, c, g);
    CHECK(l == doctest::Approx(0.5 * (3 * phi0.squaredNorm() + 7 * c.t.squaredNorm())));
    for (int k = 0; k < 6; ++k) {
      auto at = [&](double e) {
        Vec3 phi = Vec3::Zero(), rho = Vec3::Zero();
        (k < 3 ? phi : rho)[k % 3] = e;
        std::array<double, 6> unused{};
        return pose_prior(s, c * twist_exp(phi, rho), unused);
      };
      const double h = 1e-6;
      CHECK(g[k] == doctest::Approx((at(h) - at(-h)) / (2 * h)).epsilon(1e-6).scale(1.0));
    }
  }
}

TEST_CASE_TEMPLATE("pose refinement: finite differences in double of the whole training loss for the corrections and the offset", Model,
                   StratifiedModel<1>, StratifiedModel<3>, OccupancyModel<1>, CustomParts) {
  check_pose_gradients<Model>();
}

TEST_CASE_TEMPLATE("whole training loss: finite differences in double for every parameter and threshold", Model, StratifiedModel<1>,
                   StratifiedModel<3>, HierarchicalModel<1>, HierarchicalModel<3>, OccupancyModel<1>, OccupancyModel<3>,
                   LogOccupancyModel<1>, WindowHierarchicalModel<1>, ExpRadianceModel<1>, ExpRadianceModel<3>, CustomParts) {
  check_model<Model>();
}

// Counts read under a learned refractory period: weighted events, saturated windows without one end, and
// the period's own gradient.
TEST_CASE_TEMPLATE("whole training loss under a learned refractory period: finite differences in double, the period too", Model,
                   StratifiedModel<1>, WindowHierarchicalModel<1>) {
  check_model<Model>(0, 0, false, loss::TvNeighbours::Any, 1, true);
}

TEST_CASE("samples spaced in log depth: a box with near <= 0 is refused when the model is made, not inside a render") {
  const evtest::Fixture f;
  render::SceneBox bx = train::scene_box(f.td, f.cfg);
  REQUIRE(bx.near > 0);
  CHECK_NOTHROW(LogOccupancyModel<1>(f.td.slices.size(), bx, 5));
  bx.near = 0;
  CHECK_THROWS_WITH_AS(LogOccupancyModel<1>(f.td.slices.size(), bx, 5), doctest::Contains("log depth need 0 < near < far, got near 0"),
                       Error);
  CHECK_NOTHROW(OccupancyModel<1>(f.td.slices.size(), bx, 5));  // uniform spacing has no such need
}

// An objective and a regulariser of a user's own, through the same model: the whole loss, every parameter.
TEST_CASE_TEMPLATE("whole training loss with the examples' objective and regulariser: finite differences in double", Model,
                   EventNerfModel<1>, EventNerfModel<3>, QuietModel<1>, QuietModel<3>) {
  if constexpr (Model::n_terms == 3) {
    check_model<Model>(0, 0.3);
    // The quiet-pixels term did score some pixels (those whose window holds no event).
    const evtest::Fixture f;
    Model m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
    double quiet = 0;
    for (std::uint64_t seed = 1; seed <= 8; ++seed) quiet += m.gradients(f.td, 16, seed, 4).term_loss[2];
    CHECK(quiet > 0);
    CHECK(std::string(Model::term_name(2)) == "quiet");
  } else {
    check_model<Model>();
    CHECK(Model::loss_description() != OccupancyModel<1>::loss_description());
  }
}

// The distortion regulariser (loss::Plus with loss::Distortion, a term on the samples) joins the loss of
// every pass; one-network models, where the loss is one sum (a two-network model's coarse gradient excludes
// the fine pass through its resampled depths, see above).
TEST_CASE_TEMPLATE("whole training loss with the distortion regulariser: finite differences in double", Model, TvOf<StratifiedModel<1>>,
                   TvOf<OccupancyModel<1>>, TvOf<ExpRadianceModel<3>>) {
  check_model<Model>(0.05);
}

// The total-variation regulariser (loss::Plus with loss::TotalVariation): a third ray per pixel (a neighbour
// from the window's first pose), its term in every pass; with the distortion term too, on the end rays.
TEST_CASE_TEMPLATE("whole training loss with the total-variation regulariser: finite differences in double", Model,
                   TvOf<StratifiedModel<1>>, TvOf<OccupancyModel<1>>, TvOf<ExpRadianceModel<3>>) {
  SUBCASE("alone") { check_model<Model>(0, 0.3); }
  SUBCASE("with the distortion term") { check_model<Model>(0.05, 0.3); }
  SUBCASE("vertical neighbours") { check_model<Model>(0, 0.3, false, loss::TvNeighbours::Vertical); }
  SUBCASE("neighbours across the image motion") { check_model<Model>(0, 0.3, false, loss::TvNeighbours::Across); }
  SUBCASE("half the pixels, with the distortion term") { check_model<Model>(0.05, 0.3, false, loss::TvNeighbours::Vertical, 0.5); }
}

/// Two fresh models of the tiny fixture with the total-variation term at weight 0.2: `a` keeps the term's
/// other settings at their defaults, `b` is the one a test changes.
struct TvModels {
  const evtest::Fixture f;
  TvOf<OccupancyModel<1>> a{f.td.slices.size(), train::scene_box(f.td, f.cfg), 5}, b{f.td.slices.size(), train::scene_box(f.td, f.cfg), 5};
  loss::TvTerm &ta = *a.term<loss::TvTerm>(), &tb = *b.term<loss::TvTerm>();
  TvModels() {
    ta.set_weight(0.2);
    tb.set_weight(0.2);
  }
};

TEST_CASE("total-variation share: 1 is the default's step, a share draws pixels per step, keeps the term's scale, ignores the tiling") {
  TvModels t;
  const evtest::Fixture& f = t.f;
  auto &a = t.a, &b = t.b;
  a.term<loss::DistortionTerm>()->set_weight(0.05);
  b.term<loss::DistortionTerm>()->set_weight(0.05);
  CHECK(t.ta.share == 1.0);
  const auto sa = a.gradients(f.td, 16, 3, 4);
  const std::vector<double> ga = a.params().grads;
  t.tb.set_share(1.0);
  b.gradients(f.td, 16, 3, 4);
  CHECK(ga == b.params().grads);
  CHECK(sa.rays == 3 * 16);
  // Half the pixels: the pairs are the same rays, fewer neighbours are rendered, the gradient differs.
  t.tb.set_share(0.5);
  const auto sh = b.gradients(f.td, 16, 3, 4);
  CHECK(sh.event_loss == sa.event_loss);
  CHECK(sh.rays > 2 * 16);
  CHECK(sh.rays < 3 * 16);
  const std::vector<double> gh = b.params().grads;
  CHECK(gh != ga);
  const auto s1 = b.gradients(f.td, 16, 3, 1);  // one pixel per tile: the same draw, summed in another order
  CHECK(s1.rays == sh.rays);
  double worst = 0;
  for (std::size_t i = 0; i < gh.size(); ++i)
    worst = std::max(worst, std::abs(b.params().grads[i] - gh[i]) / std::max(1e-12, std::abs(gh[i])));
  CHECK(worst < 1e-9);
  // The weight is divided by the share: over many steps the term's mean is the whole term's. Each draw
  // keeps about half the pixels, so a term that forgot the division would come out near half.
  double whole = 0, half = 0;
  std::size_t drawn = 0;
  for (std::uint64_t seed = 1; seed <= 48; ++seed) {
    whole += a.gradients(f.td, 32, seed, 8).term_loss[1];
    const auto st = b.gradients(f.td, 32, seed, 8);
    half += st.term_loss[1];
    drawn += st.rays - 2 * 32;
  }
  CHECK(drawn > 48 * 32 * 4 / 10);
  CHECK(drawn < 48 * 32 * 6 / 10);
  CHECK(half / whole > 0.8);
  CHECK(half / whole < 1.25);
  CHECK_THROWS_AS(t.tb.set_share(0), Error);
  CHECK_THROWS_AS(t.tb.set_share(1.5), Error);
  CHECK_THROWS_AS(t.tb.set_share(std::nan("")), Error);
  CHECK(t.tb.share == 0.5);
}

TEST_CASE("total-variation neighbours: any draws right or below, vertical and horizontal fix one, borders turn back") {
  using loss::TvNeighbours;
  using P = std::pair<int, int>;
  // Any: the draw's lowest bit picks right (odd) or below (even); the last column (row) looks back.
  CHECK(loss::tv_neighbour(3, 4, 10, 8, 7, TvNeighbours::Any) == P{4, 4});
  CHECK(loss::tv_neighbour(3, 4, 10, 8, 6, TvNeighbours::Any) == P{3, 5});
  CHECK(loss::tv_neighbour(9, 4, 10, 8, 1, TvNeighbours::Any) == P{8, 4});
  CHECK(loss::tv_neighbour(3, 7, 10, 8, 0, TvNeighbours::Any) == P{3, 6});
  // Vertical and Horizontal ignore the draw.
  for (std::uint64_t draw : {0u, 1u, 2u, 3u}) {
    CHECK(loss::tv_neighbour(3, 4, 10, 8, draw, TvNeighbours::Vertical) == P{3, 5});
    CHECK(loss::tv_neighbour(3, 7, 10, 8, draw, TvNeighbours::Vertical) == P{3, 6});
    CHECK(loss::tv_neighbour(3, 4, 10, 8, draw, TvNeighbours::Horizontal) == P{4, 4});
    CHECK(loss::tv_neighbour(9, 4, 10, 8, draw, TvNeighbours::Horizontal) == P{8, 4});
  }
  // A sensor one pixel high (wide) has no vertical (horizontal) neighbour: the pixel itself, no cost.
  CHECK(loss::tv_neighbour(3, 0, 10, 1, 0, TvNeighbours::Vertical) == P{3, 0});
  CHECK(loss::tv_neighbour(0, 4, 1, 8, 1, TvNeighbours::Horizontal) == P{0, 4});
  CHECK(std::string(loss::tv_neighbours_name(TvNeighbours::Vertical)) == "vertical");
  // Across: the pixel axis nearest the perpendicular of the motion axis, whichever its sign.
  for (double s : {1.0, -1.0}) {
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 1, TvNeighbours::Across, s, 0.0) == P{3, 5});              // along x: below
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 0, TvNeighbours::Across, 0.0, s) == P{4, 4});              // along y: right
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 0, TvNeighbours::Across, s, s) == P{2, 5});                // diagonal: below-left
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 0, TvNeighbours::Across, s, -s) == P{4, 5});               // the other: below-right
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 0, TvNeighbours::Across, s * 0.95, s * 0.31) == P{3, 5});  // 18° from x: below
    CHECK(loss::tv_neighbour(3, 4, 10, 8, 0, TvNeighbours::Across, s * 0.9, s * 0.44) == P{2, 5});   // 26°: below-left
  }
  CHECK(loss::tv_neighbour(0, 4, 10, 8, 0, TvNeighbours::Across, 1.0, 1.0) == P{1, 3});   // the first column turns back
  CHECK(loss::tv_neighbour(3, 7, 10, 8, 0, TvNeighbours::Across, 1.0, -1.0) == P{2, 6});  // the last row turns back
  CHECK(loss::tv_neighbour(0, 0, 1, 1, 0, TvNeighbours::Across, 1.0, 1.0) == P{0, 0});    // nowhere to go
  // No motion: Any's draw.
  CHECK(loss::tv_neighbour(3, 4, 10, 8, 7, TvNeighbours::Across) == P{4, 4});
  CHECK(loss::tv_neighbour(3, 4, 10, 8, 6, TvNeighbours::Across) == P{3, 5});
  CHECK(std::string(loss::tv_neighbours_name(TvNeighbours::Across)) == "across");
}

TEST_CASE("total-variation neighbours: any is the default's step, vertical changes the term alone, whatever the tiling") {
  TvModels t;
  const evtest::Fixture& f = t.f;
  auto &a = t.a, &b = t.b;
  CHECK(t.ta.neighbours == loss::TvNeighbours::Any);
  const auto sa = a.gradients(f.td, 16, 3, 4);
  const std::vector<double> ga = a.params().grads;
  t.tb.neighbours = loss::TvNeighbours::Any;
  b.gradients(f.td, 16, 3, 4);
  CHECK(ga == b.params().grads);
  t.tb.neighbours = loss::TvNeighbours::Vertical;
  const auto sv = b.gradients(f.td, 16, 3, 4);
  CHECK(sv.event_loss == sa.event_loss);  // the pairs' rays are the same; only the neighbours move
  CHECK(sv.term_loss[1] > 0);
  CHECK(sv.term_loss[1] != sa.term_loss[1]);
  CHECK(sv.rays == sa.rays);
  const std::vector<double> gv = b.params().grads;
  CHECK(gv != ga);
  b.gradients(f.td, 16, 3, 1);  // one pixel per tile: the same draw, summed in another order
  double worst = 0;
  for (std::size_t i = 0; i < gv.size(); ++i)
    worst = std::max(worst, std::abs(b.params().grads[i] - gv[i]) / std::max(1e-12, std::abs(gv[i])));
  CHECK(worst < 1e-9);
}

TEST_CASE("total-variation neighbours: across is vertical's step on a slider along x, horizontal's along y") {
  TvModels t;
  const evtest::Fixture& f = t.f;
  auto &a = t.a, &b = t.b;
  t.ta.neighbours = loss::TvNeighbours::Vertical;
  t.tb.neighbours = loss::TvNeighbours::Across;
  const auto sa = a.gradients(f.td, 16, 3, 4);
  const auto sb = b.gradients(f.td, 16, 3, 4);
  CHECK(sb.term_loss[1] == sa.term_loss[1]);
  CHECK(b.params().grads == a.params().grads);
  // The same scene's slider turned to run along y (every pose's x and y swapped, so the camera moves along
  // its own y axis): across now picks the pixel to the right, Horizontal's.
  TrainingData ty = f.td;
  for (auto& p : ty.boundary_poses) std::swap(p.t.x(), p.t.y());
  t.ta.neighbours = loss::TvNeighbours::Horizontal;
  const auto sh = a.gradients(ty, 16, 3, 4);
  const std::vector<double> gh = a.params().grads;
  const auto sy = b.gradients(ty, 16, 3, 4);
  CHECK(sy.term_loss[1] == sh.term_loss[1]);
  CHECK(b.params().grads == gh);
  t.ta.neighbours = loss::TvNeighbours::Vertical;
  CHECK(a.gradients(ty, 16, 3, 4).term_loss[1] != sh.term_loss[1]);  // the choice matters on this data
}

TEST_CASE("distortion regulariser: weight 0 leaves the step bit-identical, on it adds its term and renders nothing more") {
  const evtest::Fixture f;
  using M = OccupancyModel<1>;
  M a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  TvOf<M> b(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  CHECK(a.term<loss::DistortionTerm>() == nullptr);
  loss::DistortionTerm& db = *b.term<loss::DistortionTerm>();
  CHECK(std::string(TvOf<M>::term_name(2)) == "distortion");
  const auto sa = a.gradients(f.td, 16, 3, 4);
  const std::vector<double> ga = a.params().grads;
  db.set_weight(0.05);
  const auto sb = b.gradients(f.td, 16, 3, 4);
  CHECK(sb.event_loss == sa.event_loss);
  CHECK(sb.rays == sa.rays);
  CHECK(sb.term_loss[2] > 0);
  CHECK(sb.loss == doctest::Approx(sa.loss + sb.term_loss[2]).epsilon(1e-12));
  CHECK(b.params().grads != ga);
  db.set_weight(0);
  b.gradients(f.td, 16, 3, 4);
  CHECK(b.params().grads == ga);
  CHECK_THROWS_WITH_AS(db.set_weight(std::nan("")), doctest::Contains("distortion weight"), Error);
}

TEST_CASE("total-variation regulariser: weight 0 leaves the step bit-identical, its draw ignores tiling and threads") {
  const evtest::Fixture f;
  using M = OccupancyModel<1>;
  M a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  TvOf<M> b(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  loss::TvTerm& tb = *b.term<loss::TvTerm>();
  CHECK(a.term<loss::TvTerm>() == nullptr);  // an objective without the term has none to find
  const auto sa = a.gradients(f.td, 16, 3, 4);
  const std::vector<double> ga = a.params().grads;
  b.gradients(f.td, 16, 3, 4);
  CHECK(ga == b.params().grads);
  tb.set_weight(0.2);
  const auto sb = b.gradients(f.td, 16, 3, 4);
  CHECK(sb.event_loss == sa.event_loss);  // the pairs' rays and their random streams are the same
  CHECK(sb.term_loss[1] > 0);
  CHECK(sb.loss == doctest::Approx(sa.loss + sb.term_loss[1]).epsilon(1e-12));
  CHECK(b.params().grads != ga);
  const std::vector<double> gb = b.params().grads;
  b.gradients(f.td, 16, 3, 1);  // one pixel per tile
  double worst = 0;             // summed in another order only
  for (std::size_t i = 0; i < gb.size(); ++i)
    worst = std::max(worst, std::abs(b.params().grads[i] - gb[i]) / std::max(1e-12, std::abs(gb[i])));
  CHECK(worst < 1e-9);
  CHECK_THROWS_WITH_AS(tb.set_weight(-1), doctest::Contains("total-variation weight"), Error);
  CHECK(std::string(TvOf<M>::term_name(1)) == "tv");
  // A term on by default (loss::TotalVariation<250>): a new model starts at its weight, which a run may
  // change, and checkpoints record the objective's loss alone (the weight is a training setting).
  using T = EvNerf<HashTiny<1>, render::OccupancySkipping<8, 8, 1, 0>, loss::ProjectedThresholds, loss::DefaultNoise,
                   loss::Plus<Window, loss::TotalVariation<250>>, double>;
  T t(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  CHECK(t.term<loss::TvTerm>()->weight == 0.25);
  CHECK(t.term<loss::TvTerm>()->neighbours == loss::TvNeighbours::Any);
  CHECK(t.term<loss::TvTerm>()->share == 1.0);
  CHECK(T::loss_description() == M::loss_description());
  const auto st = t.gradients(f.td, 16, 3, 4);
  CHECK(st.term_loss[1] > 0);
  CHECK(st.rays == 48u);
  t.term<loss::TvTerm>()->set_weight(0);
  CHECK(t.gradients(f.td, 16, 3, 4).term_loss[1] == 0);
  // Neighbours and a share named by the term's type: a new model starts at them, and its steps are those of
  // a model given the same settings by hand.
  using U = EvNerf<HashTiny<1>, render::OccupancySkipping<8, 8, 1, 0>, loss::ProjectedThresholds, loss::DefaultNoise,
                   loss::Plus<Window, loss::TotalVariation<250, loss::TvNeighbours::Vertical, 500>>, double>;
  U u(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  CHECK(u.term<loss::TvTerm>()->share == 0.5);
  CHECK(u.term<loss::TvTerm>()->neighbours == loss::TvNeighbours::Vertical);
  T byhand(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  byhand.term<loss::TvTerm>()->neighbours = loss::TvNeighbours::Vertical;
  byhand.term<loss::TvTerm>()->set_share(0.5);
  const auto su = u.gradients(f.td, 16, 3, 4);
  const auto sh = byhand.gradients(f.td, 16, 3, 4);
  CHECK(su.term_loss[1] > 0);
  CHECK(su.term_loss[1] == sh.term_loss[1]);
  CHECK(su.rays < 48u);  // half the pixels get the neighbour ray
  CHECK(su.rays == sh.rays);
  CHECK(u.params().grads == byhand.params().grads);
  // Fast's: the term at 0.1, across the motion, half the pixels; FastNoTv is the event objective alone.
  const presets::FastTv fast_tv;
  CHECK(fast_tv.weight == 0.1);
  CHECK(fast_tv.share == 0.5);
  CHECK(fast_tv.neighbours == loss::TvNeighbours::Across);
  static_assert(presets::Fast::n_terms == 2 && presets::FastNoTv::n_terms == 1);
  CHECK(presets::Fast::loss_description() == presets::FastNoTv::loss_description());
}

TEST_CASE("examples' parts: inverse-depth samples, the triangle-wave encoding's input gradient, the shot-noise interval") {
  // Depths increase from near to far, denser near; bin centres without a generator.
  static_assert(render::Sampler<mylab::InverseDepth<16>>);
  std::vector<double> t(16);
  Rng rng(3);
  mylab::InverseDepth<16>{}.coarse_depths(16, 0.5, 4.0, &rng, t.data());
  for (int k = 0; k < 16; ++k) {
    CHECK(t[k] >= 0.5);
    CHECK(t[k] <= 4.0);
    if (k > 0) CHECK(t[k] > t[k - 1]);
  }
  mylab::InverseDepth<16>{}.coarse_depths(16, 0.5, 4.0, static_cast<Rng*>(nullptr), t.data());
  CHECK(t[1] - t[0] < t[15] - t[14]);
  // The encoding's gradient w.r.t. its input against finite differences (away from the kinks).
  using Tri = mylab::TriangleWave<3>;
  const std::vector<double> x{0.137, -0.421, 0.293};
  std::vector<double> w(Tri::out_dims);
  for (int i = 0; i < Tri::out_dims; ++i) w[i] = std::sin(1.0 + i);
  auto f = [&](const std::vector<double>& p) {
    std::vector<double> y(Tri::out_dims);
    Tri::forward(static_cast<const double*>(nullptr), p.data(), y.data());
    double v = 0;
    for (int i = 0; i < Tri::out_dims; ++i) v += w[i] * y[i];
    return v;
  };
  std::vector<double> dx(3, 0.0);
  Tri::backward(static_cast<const double*>(nullptr), x.data(), w.data(), static_cast<double*>(nullptr), dx.data());
  CHECK(evtest::max_fd_error(f, x, dx) < 1e-7);
  // The interval widens with the count: ±½ threshold plus ¼√N.
  const auto b = mylab::ShotNoiseCounts::make(12, 4);
  CHECK(b.k_pos == doctest::Approx(1.5));
  CHECK(mylab::ShotNoiseCounts::make(0, 0).k_neg == 1.0);
}

TEST_CASE("colour models: each pixel's channel follows the recording's Bayer pattern") {
  // Under BGGR the loss must see with the R and B outputs swapped what it sees under RGGB: a model whose
  // colour head has its R and B output rows swapped, trained on a BGGR recording, has the same loss and
  // the same gradients, with those rows swapped. A model that ignored the pattern would not.
  using M = StratifiedModel<3>;
  using Net = M::field_type::color_net;
  const evtest::Fixture f;
  CHECK(f.td.bayer.name() == "rggb");  // a recording that names no mosaic: the Color-DAVIS346's
  M a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5);
  Rng rng(3);
  for (auto& v : a.params().values) v += 0.1 * (rng.uniform() - 0.5);
  M b = a;
  const std::size_t last = M::field_type::color_offset + Net::weight_offset(Net::n_layers - 1);
  const int in = Net::layer_in(Net::n_layers - 1);
  auto row = [&](int o, int i) { return i < in ? last + static_cast<std::size_t>(o + 3 * i) : last + 3 * in + o; };
  for (int i = 0; i <= in; ++i) std::swap(b.params().values[row(0, i)], b.params().values[row(2, i)]);
  REQUIRE(a.renderer().learns_backdrop());  // the backdrop's R and B swap too
  std::swap(b.params().values[M::backdrop_offset()], b.params().values[M::backdrop_offset() + 2]);
  evnerf::TrainingData bggr = f.td;
  REQUIRE(geometry::BayerPattern::parse("bggr", bggr.bayer));
  const auto sa = a.gradients(f.td, 64, 7, 2), sb = b.gradients(bggr, 64, 7, 2);
  CHECK(sb.loss == doctest::Approx(sa.loss).epsilon(1e-12));
  std::vector<double> ga = a.params().grads;
  for (int i = 0; i <= in; ++i) std::swap(ga[row(0, i)], ga[row(2, i)]);
  std::swap(ga[M::backdrop_offset()], ga[M::backdrop_offset() + 2]);
  double worst = 0;
  for (std::size_t i = 0; i < ga.size(); ++i) worst = std::max(worst, std::abs(ga[i] - b.params().grads[i]));
  CHECK(worst < 1e-12);
  // and the same model on the RGGB recording sees another loss (the test can fail)
  CHECK(std::abs(b.gradients(f.td, 64, 7, 2).loss - sa.loss) > 1e-9);
}

// Training rays that stop where their transmittance falls below the backward pass's cut (set_ray_termination,
// samplers that skip): the loss is then a function of the samples evaluated before each ray's stop, and its
// gradient still matches finite differences.
TEST_CASE_TEMPLATE("whole training loss with training rays that stop early: finite differences in double", Model, LongOccupancyModel<1>,
                   LongOccupancyModel<3>) {
  check_model<Model>(0, 0, true);
}

// A background of known luminance behind the samples (train::Config::background): the rays' leftover
// transmittance weighs it in every pass, and the whole loss still matches finite differences, with rays that
// stop early too.
TEST_CASE_TEMPLATE("whole training loss before a known background: finite differences in double", Model, StratifiedModel<1>,
                   HierarchicalModel<3>, OccupancyModel<1>, LongOccupancyModel<3>) {
  const bool terminate = std::is_same_v<Model, LongOccupancyModel<3>>;
  check_model<Model>(0, 0, terminate, loss::TvNeighbours::Any, 1, false, 0.4);
  // The background is part of the loss: the same step without it differs.
  evtest::Fixture f;
  train::Config plain = f.cfg;
  f.cfg.background = 0.4;
  Model with(f.td.slices.size(), train::scene_box(f.td, f.cfg), 5), without(f.td.slices.size(), train::scene_box(f.td, plain), 5);
  without.set_ray_termination(terminate);
  with.set_ray_termination(terminate);
  REQUIRE(with.box().background == 0.4);
  CHECK(with.gradients(f.td, 16, 1, 4).loss != without.gradients(f.td, 16, 1, 4).loss);
}
// A learned backdrop (train::Config::learn_background): the rays' leftover transmittance weighs a luminance
// per channel that is a parameter, shared by every pass; the whole loss matches finite differences in its
// raw values as in the field's, grey and colour, with rays that stop early (which show no backdrop) too.
TEST_CASE_TEMPLATE("whole training loss before a learned backdrop: finite differences in double", Model, StratifiedModel<1>,
                   HierarchicalModel<3>, LongOccupancyModel<3>) {
  const bool terminate = std::is_same_v<Model, LongOccupancyModel<3>>;
  check_model<Model>(0, 0, terminate, loss::TvNeighbours::Any, 1, false, std::nullopt, true);
}
