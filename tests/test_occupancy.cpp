// The occupancy grid and occupancy skipping: what is marked, rendering like full sampling, resume.
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
  c.deserialize(a.serialize("tinyocc", {}), "mem");
  for (int s = 0; s < 9; ++s) {
    a.train_step(f.td, 128, 3);
    c.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == c.params().values);
  CHECK(a.sampler().serialize() == c.sampler().serialize());
  // A grid-less model refuses a checkpoint with a grid: another sampler is another architecture.
  Tiny t;
  CHECK_THROWS_WITH(t.deserialize(a.serialize("tiny", {}), "x.ckpt"),
                    doctest::Contains("sampler occupancy 16 grid 16 every 4 after 8'; this model is"));
}

// Two variants of one field whose occupancy grids differ (occupied alpha 1 % and 30 %): a file written as
// "fast" by the first must go to the variant that has its grid, and a file of the second to its own name.
