// Checkpoints: the variant a file goes to, refusal of corrupt, truncated, mismatched or non-finite
// files, the parameter average they keep, and the faults a long run meets writing them (the process-level
// ones, SIGKILL and SIGINT, are in tests/faults.sh).
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
  const auto old_fast = write(Dense(f.td.slices.size(), box, 7).serialize("fast", {}), "old.ckpt");
  const auto new_fast = write(Pruned(f.td.slices.size(), box, 7).serialize("fast-prune", {}), "new.ckpt");
  using List = std::tuple<Variant<Pruned, "fast">, Variant<Dense, "dense">, Variant<Pruned, "fast-prune">>;
  auto pick = [](const std::filesystem::path& p) {
    return [&]<class... V>(std::tuple<V...>*) { return checkpoint_variant<V...>(p); }(static_cast<List*>(nullptr));
  };
  CHECK(pick(old_fast) == "dense");       // its name is a label; its grid decides
  CHECK(pick(new_fast) == "fast-prune");  // two names of one type: the file's own name
  // Without a variant of the old grid, the old file is refused with what it was written by.
  using OnlyNew = Variant<Pruned, "fast">;
  CHECK_THROWS_WITH(checkpoint_variant<OnlyNew>(old_fast), doctest::Contains("written by variant 'fast'"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("checkpoints: corrupt, truncated or mismatched files are refused with a clear error") {
  Fixture f;
  Tiny a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  std::string bytes = a.serialize("tiny", {});
  Tiny b;
  std::string bad = bytes;
  bad[bad.size() / 2] ^= 0x55;
  CHECK_THROWS_WITH(b.deserialize(bad, "x.ckpt"), doctest::Contains("x.ckpt:0: corrupt or mismatched checkpoint: checksum mismatch"));
  CHECK_THROWS_WITH(b.deserialize(bytes.substr(0, 100), "x.ckpt"), doctest::Contains("checksum mismatch"));
  // The architecture decides, not the name: a file of this model under another name loads, a model of
  // another architecture refuses it with both descriptions.
  CHECK_NOTHROW(b.deserialize(bytes, "x.ckpt"));
  using Wider = EvNerf<
      field::FieldOf<nn::HashGrid<6, 2, 12, 4, 64>, nn::SphericalHarmonics<2>, nn::MlpShape{.width = 32}, 4, nn::MlpShape{.width = 16}>,
      render::Stratified<16>>;
  static_assert(Wider::field_params != Tiny::field_params);
  Wider wider;
  CHECK_THROWS_WITH(wider.deserialize(bytes, "x.ckpt"),
                    doctest::Contains("written by a model of another architecture ('position hash grid 6x2 2^12 4..64, direction "
                                      "spherical harmonics 2, density mlp 12>16x1>5 relu/identity, colour mlp 8>16x1>1 "
                                      "relu/identity, density activation relu; sampler stratified 16'; this model is"));
  using OtherSampler = EvNerf<TinyField, render::Stratified<24>>;
  OtherSampler other;
  CHECK_THROWS_WITH(other.deserialize(bytes, "x.ckpt"), doctest::Contains("sampler stratified 24"));
  CHECK_THROWS_WITH(b.deserialize("hello", "x.ckpt"), doctest::Contains("not an evnerf checkpoint"));
  // Found by tests/fuzz (fuzz_checkpoint): a header whose slice and parameter counts agree with each other
  // but not with the file's size made the loader allocate 64 GB. Now refused before allocating.
  {
    std::string huge = bytes.substr(0, bytes.size() - 8);
    const std::uint64_t slices = std::uint64_t{1} << 33, n = Tiny::renderer_type::n_params + 2 * slices;
    const std::size_t at = 16 + 8 + 4;  // after the magic, the version and the name "tiny" (length, bytes)
    std::memcpy(huge.data() + at, &n, 8);
    std::memcpy(huge.data() + at + 8, &slices, 8);
    const std::uint64_t sum = fnv1a64(huge);
    huge.append(reinterpret_cast<const char*>(&sum), 8);
    CHECK_THROWS_WITH(b.deserialize(huge, "x.ckpt"), doctest::Contains("x.ckpt:0: corrupt or mismatched checkpoint: truncated: 171799"));
  }
  // The trainer's file path: atomic write and load.
  const fs::path dir = fs::temp_directory_path() / ("evnerf_ck_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  train::save_checkpoint(dir / "m.ckpt", a, "tiny", f.run());
  Tiny c;
  CHECK(train::load_checkpoint(dir / "m.ckpt", c).recording == "tiny");
  fs::remove_all(dir);
}

TEST_CASE("checkpoints: a NaN or infinite value (or a negative second moment) behind a valid checksum is refused, naming it") {
  Fixture f;
  Tiny a(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  a.set_average(0.99);
  for (int s = 0; s < 2; ++s) a.train_step(f.td, 128, 3);
  const std::string good = a.serialize("tiny", f.run());
  const std::size_t n = a.params().size();
  const std::size_t header =
      8 + 8 + (8 + 4) + 8 + 8 + 8 + 6 * 8 + 8 + 8 + 8 + 4 * 8 + (8 + Tiny::loss_description().size()) + (8 + Tiny::architecture().size());
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
    REQUIRE_NOTHROW(t.deserialize(with(header + 4 * 5, static_cast<float>(a.params().values[5])), "x.ckpt"));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  Tiny t;
  CHECK_THROWS_WITH(
      t.deserialize(with(header + 4 * 5, nan), "x.ckpt"),
      doctest::Contains(("x.ckpt:0: corrupt or mismatched checkpoint: parameter 5 of " + std::to_string(n) + " is NaN").c_str()));
  CHECK_THROWS_WITH(t.deserialize(with(header + 4 * (n + 2), -inf), "x.ckpt"),
                    doctest::Contains(("Adam's first moment of parameter 2 of " + std::to_string(n) + " is infinite").c_str()));
  CHECK_THROWS_WITH(t.deserialize(with(header + 4 * (2 * n + 7), -1.0f), "x.ckpt"),
                    doctest::Contains(("Adam's second moment of parameter 7 of " + std::to_string(n) + " is negative").c_str()));
  CHECK_THROWS_WITH(
      t.deserialize(with(header + 12 * n + 16 + 4 * (n - 1), nan), "x.ckpt"),
      doctest::Contains(("the parameter average's value " + std::to_string(n - 1) + " of " + std::to_string(n) + " is NaN").c_str()));
  // The refused loads left the model as it was (a default model: no parameters).
  CHECK(t.params().size() == 0);
}

TEST_CASE("checkpoints: the run's record round-trips as typed fields, another format version and bad fields are refused") {
  Fixture f;
  f.cfg.density_per_box = true;
  const auto box = train::scene_box(f.td, f.cfg);
  REQUIRE(box.scale > 1.5);
  CHECK(box.density_length == box.scale);
  Tiny a(f.td.slices.size(), box, 7);
  for (int s = 0; s < 4; ++s) a.train_step(f.td, 128, 3);
  REQUIRE_FALSE(a.average().active());
  io::CheckpointRun run = f.run();
  run.shards = 3;
  const std::string good = a.serialize("tiny", run);
  // Everything the run holds comes back, exactly.
  Tiny t;
  const auto back = t.deserialize(good, "m.ckpt");
  CHECK(back.recording == "tiny");
  CHECK(back.shards == 3);
  CHECK(back.camera.width() == f.td.camera.width());
  CHECK(back.camera.height() == f.td.camera.height());
  CHECK(back.camera.fx() == f.td.camera.fx());
  CHECK(back.camera.cy() == f.td.camera.cy());
  CHECK(back.camera.distortion() == f.td.camera.distortion());
  REQUIRE(back.times.size() == f.td.slices.size() + 1);
  for (std::size_t i = 0; i < back.times.size(); ++i) {
    CHECK(back.times[i] == f.td.slices.boundaries[i]);
    CHECK(back.poses[i].t == f.td.boundary_poses[i].t);
    CHECK(back.poses[i].q.coeffs() == f.td.boundary_poses[i].q.normalized().coeffs());
  }
  CHECK(t.params().values == a.params().values);
  CHECK(t.box().density_length == box.scale);
  CHECK_FALSE(t.box().background.has_value());
  // A background comes back too, and renders are the same.
  {
    train::Config cb = f.cfg;
    cb.background = 0.37;
    Tiny with(f.td.slices.size(), train::scene_box(f.td, cb), 7), back_bg;
    with.train_step(f.td, 128, 3);
    back_bg.deserialize(with.serialize("tiny", run), "b.ckpt");
    REQUIRE(back_bg.box().background.has_value());
    CHECK(*back_bg.box().background == 0.37);
    CHECK_FALSE(back_bg.box().background_learned);  // a known backdrop is not learned
    const auto dirs = render::pixel_directions(f.td.camera);
    CHECK(back_bg.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data ==
          with.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data);
  }
  // A learned backdrop comes back with its values, and renders are the same.
  {
    train::Config cb = f.cfg;
    REQUIRE(cb.learn_background);  // the default
    Tiny with(f.td.slices.size(), train::scene_box(f.td, cb), 7), back_bg;
    for (int s = 0; s < 3; ++s) with.train_step(f.td, 128, 3);
    REQUIRE(with.params().values[Tiny::backdrop_offset()] != 0.f);  // it moved
    back_bg.deserialize(with.serialize("tiny", run), "b.ckpt");
    CHECK(back_bg.box().background_learned);
    CHECK_FALSE(back_bg.box().background.has_value());
    CHECK(back_bg.params().values == with.params().values);
    const auto dirs = render::pixel_directions(f.td.camera);
    CHECK(back_bg.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data ==
          with.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data);
    CHECK(t.box().background_learned);  // the default Config learns it
  }
  // A refractory period comes back with its optimiser state, and a resumed step is the uninterrupted one's.
  CHECK_FALSE(t.refractory().active());
  {
    Tiny learn(f.td.slices.size(), box, 7), back_r;
    learn.set_refractory(1e-4, true);
    for (int s = 0; s < 3; ++s) learn.train_step(f.td, 128, 3);
    REQUIRE(learn.refractory().seconds != 1e-4);  // it moved
    back_r.deserialize(learn.serialize("tiny", run), "r.ckpt");
    CHECK(back_r.refractory().seconds == learn.refractory().seconds);
    CHECK(back_r.refractory().m == learn.refractory().m);
    CHECK(back_r.refractory().v == learn.refractory().v);
    CHECK(back_r.refractory().learned);
    learn.train_step(f.td, 128, 3);
    back_r.train_step(f.td, 128, 3);
    CHECK(back_r.refractory().seconds == learn.refractory().seconds);
    CHECK(back_r.params().values == learn.params().values);
    Tiny fixed(f.td.slices.size(), box, 7), back_f;
    fixed.set_refractory(2e-4, false);
    fixed.train_step(f.td, 128, 3);
    CHECK(fixed.refractory().seconds == 2e-4);  // a given period stays
    back_f.deserialize(fixed.serialize("tiny", run), "f.ckpt");
    CHECK(back_f.refractory().seconds == 2e-4);
    CHECK_FALSE(back_f.refractory().learned);
  }
  // Pose refinement comes back with its corrections, offset, moments and refined poses, and a resumed step is
  // the uninterrupted one's; a damaged record is refused, naming it.
  CHECK_FALSE(t.pose_refinement().active());
  {
    Tiny learn(f.td.slices.size(), box, 7), back_p;
    PoseRefinementSettings ps;
    ps.poses = ps.offset = true;
    ps.start = 0;
    learn.set_pose_refinement(f.td, ps);
    for (int s = 0; s < 3; ++s) learn.train_step(f.td, 128, 3);
    REQUIRE(learn.pose_refinement().offset != 0);  // they moved
    REQUIRE(learn.pose_refinement().correction[1].t != Vec3::Zero());
    CHECK(learn.pose_refinement().correction[0].t == Vec3::Zero());  // the gauge
    const std::string saved = learn.serialize("tiny", run);
    back_p.deserialize(saved, "p.ckpt");
    back_p.set_pose_rates(f.td, ps);  // step sizes and schedule are training settings, like the learning rate
    const auto& a0 = learn.pose_refinement();
    const auto& b0 = back_p.pose_refinement();
    CHECK(b0.settings.poses);
    CHECK(b0.settings.offset);
    CHECK(b0.offset == a0.offset);
    CHECK(b0.offset_v == a0.offset_v);
    REQUIRE(b0.correction.size() == a0.correction.size());
    for (std::size_t i = 0; i < a0.correction.size(); ++i) {
      CHECK(b0.correction[i].t == a0.correction[i].t);
      CHECK(b0.correction[i].q.coeffs() == a0.correction[i].q.coeffs());
      CHECK(b0.m[i] == a0.m[i]);
      CHECK(b0.v[i] == a0.v[i]);
      CHECK(back_p.refined_poses()[i].t == learn.refined_poses()[i].t);
    }
    learn.train_step(f.td, 128, 3);
    back_p.train_step(f.td, 128, 3);
    CHECK(back_p.params().values == learn.params().values);
    CHECK(back_p.pose_refinement().offset == learn.pose_refinement().offset);
    CHECK(back_p.refined_poses()[2].t == learn.refined_poses()[2].t);
    // The record sits before the run: its knot count (after what it learns and the offset's three values) is
    // that of the boundaries, and a rotation of norm 0 is refused.
    const std::size_t run_bytes = 8 + run.recording.size() + 8 + 16 + 72 + 8 + 64 * run.times.size() + 8;
    const std::size_t knots = f.td.slices.size() + 1, record = 8 + 24 + 8 + 26 * 8 * knots;
    const std::size_t at = saved.size() - run_bytes - record;
    std::uint64_t what = 0, count = 0;
    std::memcpy(&what, saved.data() + at, 8);
    std::memcpy(&count, saved.data() + at + 32, 8);
    REQUIRE(what == 3);
    REQUIRE(count == knots);
    auto damaged = [&](std::size_t offset, const void* bytes, std::size_t n) {
      std::string b = saved.substr(0, saved.size() - 8);
      std::memcpy(b.data() + offset, bytes, n);
      const std::uint64_t sum = fnv1a64(b);
      b.append(reinterpret_cast<const char*>(&sum), 8);
      return b;
    };
    const std::uint64_t bad_what = 4, bad_count = knots + 1;
    CHECK_THROWS_WITH(back_p.deserialize(damaged(at, &bad_what, 8), "p.ckpt"),
                      doctest::Contains("pose refinement's record says it learns 4"));
    CHECK_THROWS_WITH(back_p.deserialize(damaged(at + 32, &bad_count, 8), "p.ckpt"), doctest::Contains("pose refinement has"));
    const double zero_q[4] = {0, 0, 0, 0};
    CHECK_THROWS_WITH(back_p.deserialize(damaged(at + 40 + 26 * 8 + 3 * 8, zero_q, sizeof zero_q), "p.ckpt"),
                      doctest::Contains("pose refinement's correction at knot 1 has a rotation quaternion of norm 0"));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(back_p.deserialize(damaged(at + 8, &nan, 8), "p.ckpt"), doctest::Contains("pose refinement's clock offset"));
    // The model refused every one and kept what it had.
    CHECK(back_p.pose_refinement().offset == learn.pose_refinement().offset);
  }
  CHECK(Tiny::loss_description() == "bounds split 1, thresholds joint, noise 50 per mille");
  // A model saved outside a run records none; it loads, and render and eval refuse it (evaluation::load_model).
  CHECK(t.deserialize(a.serialize("tiny", {}), "m.ckpt").times.empty());
  auto with_sum = [](std::string b) {
    const std::uint64_t sum = fnv1a64(b);
    b.append(reinterpret_cast<const char*>(&sum), 8);
    return b;
  };
  const std::string body = good.substr(0, good.size() - 8);
  // Another format version, older or newer, is refused with the one this build reads.
  for (std::uint64_t version : {io::kCheckpointVersion - 1, io::kCheckpointVersion + 1}) {
    std::string other = body;
    std::memcpy(other.data() + 8, &version, 8);
    CHECK_THROWS_WITH(t.deserialize(with_sum(other), "x.ckpt"),
                      doctest::Contains(("x.ckpt:0: corrupt or mismatched checkpoint: format version " + std::to_string(version) +
                                         "; this build reads version " + std::to_string(io::kCheckpointVersion) + " only")
                                            .c_str()));
  }
  // A nonsensical density length.
  const std::size_t at = 8 + 8 + (8 + 4) + 8 + 8 + 8 + 6 * 8;
  std::string bad = body;
  const double zero = 0.0;
  std::memcpy(bad.data() + at, &zero, 8);
  CHECK_THROWS_WITH(t.deserialize(with_sum(bad), "x.ckpt"), doctest::Contains("density length is not a positive number"));
  // A background that is no luminance (NaN stands for none).
  for (const double v : {-1.0, -std::numeric_limits<double>::min(), std::numeric_limits<double>::infinity()}) {
    bad = body;
    std::memcpy(bad.data() + at + 8, &v, 8);
    CHECK_THROWS_WITH(
        t.deserialize(with_sum(bad), "x.ckpt"),
        doctest::Contains(("x.ckpt:0: corrupt or mismatched checkpoint: the background luminance is " + short_number(v)).c_str()));
  }
  // A backdrop flag other than 0 or 1.
  bad = body;
  const std::uint64_t two = 2;
  std::memcpy(bad.data() + at + 16, &two, 8);
  CHECK_THROWS_WITH(t.deserialize(with_sum(bad), "x.ckpt"), doctest::Contains("the backdrop's flag is 2"));
  // A refractory period's record that training never writes: a period beyond a second or not finite, a
  // moment not finite, a negative second moment, a learned flag other than 0 or 1.
  for (const auto& [offset, v] : std::vector<std::pair<std::size_t, double>>{
           {24, 2.0}, {24, std::numeric_limits<double>::quiet_NaN()}, {32, std::numeric_limits<double>::infinity()}, {40, -1.0}}) {
    bad = body;
    std::memcpy(bad.data() + at + offset, &v, 8);
    CHECK_THROWS_WITH(t.deserialize(with_sum(bad), "x.ckpt"),
                      doctest::Contains("x.ckpt:0: corrupt or mismatched checkpoint: the refractory period's record"));
  }
  bad = body;
  std::memcpy(bad.data() + at + 48, &two, 8);
  CHECK_THROWS_WITH(t.deserialize(with_sum(bad), "x.ckpt"), doctest::Contains("learned 2) is not one training writes"));
  // A model trained with other bounds refuses the file, naming both losses.
  using TinyHalfSlack = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise, loss::HalfSlackCounts>;
  TinyHalfSlack other;
  CHECK_THROWS_WITH(
      other.deserialize(good, "m.ckpt"),
      doctest::Contains(
          "m.ckpt:0: corrupt or mismatched checkpoint: trained with the loss 'bounds split 1, "
          "thresholds joint, noise 50 per mille', this model's is 'bounds half-slack, thresholds joint, noise 50 per mille'"));
  // The run's fields: offsets from the end of the body (8 boundaries' worth of f64 each, then its count, the camera).
  const std::size_t n_b = back.times.size();
  const std::size_t poses_at = body.size() - 64 * n_b, count_at = poses_at - 8, camera_at = count_at - 9 * 8, sensor_at = camera_at - 16,
                    shards_at = sensor_at - 8;
  auto patched = [&](std::size_t where, const void* value, std::size_t bytes) {
    std::string b = body;
    std::memcpy(b.data() + where, value, bytes);
    return with_sum(std::move(b));
  };
  const std::uint64_t no_shards = 0, many = std::uint64_t{1} << 40;
  CHECK_THROWS_WITH(t.deserialize(patched(shards_at, &no_shards, 8), "x.ckpt"),
                    doctest::Contains("shards per step (0) are not in 1..4096"));
  const std::int64_t huge_width = 1 << 20;
  CHECK_THROWS_WITH(t.deserialize(patched(sensor_at, &huge_width, 8), "x.ckpt"), doctest::Contains("the run's sensor is 1048576 x"));
  const double nan = std::numeric_limits<double>::quiet_NaN(), negative = -1;
  CHECK_THROWS_WITH(t.deserialize(patched(camera_at + 16, &nan, 8), "x.ckpt"), doctest::Contains("non-finite intrinsic"));
  CHECK_THROWS_WITH(t.deserialize(patched(camera_at, &negative, 8), "x.ckpt"), doctest::Contains("focal length that is not positive"));
  CHECK_THROWS_WITH(t.deserialize(patched(count_at, &many, 8), "x.ckpt"), doctest::Contains("boundaries need more bytes than remain"));
  const double zeros[4] = {0, 0, 0, 0};
  CHECK_THROWS_WITH(t.deserialize(patched(poses_at + 64 + 32, zeros, 32), "x.ckpt"),
                    doctest::Contains("boundary 1 of the run has a rotation quaternion of norm 0"));
  // Found by tests/fuzz (fuzz_checkpoint): a component near the largest double overflows the norm, and the
  // normalised quaternion was zero.
  const double vast = -8.7e307;
  CHECK_THROWS_WITH(t.deserialize(patched(poses_at + 64 + 56, &vast, 8), "x.ckpt"),
                    doctest::Contains("boundary 1 of the run has a rotation quaternion of norm inf"));
  const double early = -5;
  CHECK_THROWS_WITH(t.deserialize(patched(poses_at + 64, &early, 8), "x.ckpt"),
                    doctest::Contains("the run's boundary times do not increase at boundary 1"));
  CHECK_THROWS_WITH(t.deserialize(patched(poses_at + 64 + 8, &nan, 8), "x.ckpt"),
                    doctest::Contains("boundary 1 of the run has a non-finite time or pose"));
  // A run of another slice count than the model's.
  io::CheckpointRun fewer = run;
  fewer.times.pop_back();
  fewer.poses.pop_back();
  CHECK_THROWS_WITH(
      t.deserialize(a.serialize("tiny", fewer), "x.ckpt"),
      doctest::Contains(
          ("the run records " + std::to_string(n_b - 1) + " slice boundaries for " + std::to_string(n_b - 1) + " slices").c_str()));
  // The refused loads left the model as the good file made it.
  CHECK(t.params().values == a.params().values);
  // A file whose average does not match the model, or whose decay is out of range, is refused.
  // density length, background, the backdrop's flag, the refractory period's record
  const std::size_t header = at + 8 + 8 + 8 + 4 * 8 + (8 + Tiny::loss_description().size()) + (8 + Tiny::architecture().size());
  const std::size_t moments_end = header + 12 * a.params().size();
  Tiny avg(f.td.slices.size(), box, 7);
  avg.set_average(0.9);
  avg.train_step(f.td, 128, 3);
  const std::string with_average = avg.serialize("tiny", f.run());
  std::string wrong = with_average.substr(0, with_average.size() - 8);
  const std::uint64_t three_values = 3;
  std::memcpy(wrong.data() + moments_end, &three_values, 8);
  CHECK_THROWS_WITH(t.deserialize(with_sum(wrong), "x.ckpt"), doctest::Contains("the parameter average has 3 values"));
  wrong = with_average.substr(0, with_average.size() - 8);
  const double one = 1.0;
  std::memcpy(wrong.data() + moments_end + 8, &one, 8);
  CHECK_THROWS_WITH(t.deserialize(with_sum(wrong), "x.ckpt"), doctest::Contains("decay is not in (0, 1)"));
}

TEST_CASE("parameter average: TensorFlow's warm-up, never changes training, renders use it, checkpoints keep it") {
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
  CHECK(c.deserialize(a.serialize("tiny", f.run()), "mem").recording == "tiny");
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
  d.deserialize(b.serialize("tiny", {}), "mem");
  CHECK_FALSE(d.average().active());
  CHECK_THROWS_WITH(d.set_average(1.0), doctest::Contains("decay must be in [0, 1)"));
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
    train::Trainer<Tiny> t(f.td, cfg, out, "tiny", f.run());
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
    train::load_checkpoint(out / "model.ckpt", back);
    CHECK(back.step() == 2);
    CHECK(std::all_of(back.params().values.begin(), back.params().values.end(), [](float x) { return std::isfinite(x); }));
  }
  fs::remove_all(base);
}

TEST_CASE("faults: a full disk or an unwritable folder is a clear error, no partial file, the earlier checkpoint intact") {
  Fixture f;
  const fs::path base = fs::temp_directory_path() / ("evnerf_full_" + std::to_string(::getpid()));
  const fs::path out = base / "run";
  train::Config cfg = f.run_config(4, 64);
  cfg.threads = 1;
  cfg.checkpoint_every = 2;
  train::Trainer<Tiny>(f.td, cfg, out, "tiny", f.run()).run();
  const std::string good = read_file(out / "model.ckpt");
  REQUIRE(good.size() > 128 * 1024);

  // A disk that takes at most 64 KB per file: RLIMIT_FSIZE makes write() fail with EFBIG as a full disk
  // fails with ENOSPC (SIGXFSZ ignored), in this process only.
  cfg.iterations = 8;
  train::Trainer<Tiny> more(f.td, cfg, out, "tiny", f.run());
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
  train::Trainer<Tiny> nowhere(f.td, cfg, base / "plain" / "run", "tiny", f.run());
  const std::string nowhere_error = (base / "plain" / "run").string() + ":0: cannot create the output folder";
  CHECK_THROWS_WITH(nowhere.run(), doctest::Contains(nowhere_error.c_str()));
  fs::create_directories(base / "blocked" / "model.ckpt");
  train::Trainer<Tiny> blocked(f.td, cfg, base / "blocked", "tiny", f.run());
  CHECK_THROWS_WITH(blocked.run(), doctest::Contains("cannot rename the temporary file into place"));
  CHECK(temporaries(base / "blocked").empty());
  fs::remove_all(base);
}
