// Training: a short run lowers the loss, determinism and resume, the training data (slices, windows,
// subslices, held-out frames), noise injection, thresholds and Adam, the Trainer and its loop, the
// settings table, collapse detection.
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

#include <evnerf/sim/simulate.hpp>
#include <evnerf/sim/simulator.hpp>
#include <evnerf/train/trainer.hpp>
#include <evnerf/model/variants.hpp>

#include "common.hpp"
#include "tiny_models.hpp"

using namespace evnerf;
namespace fs = std::filesystem;
using evtest::Fixture;

TEST_CASE_TEMPLATE("training: a short run on a tiny simulated scene lowers the loss", Model, Tiny, TinySigned, TinyHalf, TinyBf16,
                   TinyWindow) {
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

TEST_CASE("training: fixed thresholds never move, noise-free and noisy variants differ") {
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
TEST_CASE_TEMPLATE("training: deterministic for a seed and thread count, resume equals uninterrupted, checkpoints round-trip", Model, Tiny,
                   TinyBf16, TinyWindow) {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  Model a(f.td.slices.size(), box, 7), b(f.td.slices.size(), box, 7);
  for (int s = 0; s < 6; ++s) {
    a.train_step(f.td, 128, 3);
    b.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == b.params().values);
  // Save after 6 steps, continue both the original and a restored copy.
  const std::string bytes = a.serialize("tiny", f.run());
  Model c;
  CHECK(c.deserialize(bytes, "mem").recording == "tiny");
  for (int s = 0; s < 4; ++s) {
    a.train_step(f.td, 128, 3);
    c.train_step(f.td, 128, 3);
  }
  CHECK(a.params().values == c.params().values);
  CHECK(a.step() == c.step());
  // A restored model renders bit-identically.
  Model e;
  e.deserialize(a.serialize("tiny", {}), "mem");
  const auto dirs = render::pixel_directions(f.td.camera);
  CHECK(a.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data ==
        e.render(f.td.camera, dirs, f.td.boundary_poses[0]).luminance.data);
}

TEST_CASE("training data: poses that do not cover the events are an error, clamping is explicit") {
  Fixture f;
  io::Dataset d = f.d;
  d.frames = {};
  std::vector<double> t{10.0, 11.0};
  d.trajectory = geometry::Trajectory(t, {geometry::Pose{}, geometry::Pose{}});
  CHECK_THROWS_WITH(train::prepare(d, f.cfg), doctest::Contains("do not cover the events"));
}

TEST_CASE("training data: suspected hot pixels are never drawn, keep_hot_pixels draws them, a clean recording keeps every pixel") {
  sim::SimulateOptions so;
  so.width = 64;
  so.height = 48;
  so.progress = false;
  train::Config cfg;
  const auto clean = train::prepare(sim::to_dataset(sim::simulate("planes", so)), cfg);
  CHECK(clean.masked.empty());
  CHECK(clean.sites.all());
  so.sensor.hot_pixels = 3;
  so.sensor.hot_rate = 150;
  const auto d = sim::to_dataset(sim::simulate("planes", so));
  const auto td = train::prepare(d, cfg);
  REQUIRE(td.masked.size() == 3);
  REQUIRE(td.sites.list.size() == static_cast<std::size_t>(64 * 48 - 3));
  for (const auto& h : td.masked) CHECK(td.sites.mask[static_cast<std::size_t>(h.y) * 64 + h.x] == 0);
  // The pixels of many steps' draws: never a masked one.
  Rng rng(4);
  loss::StepDraw draw;
  std::set<std::uint32_t> drawn;
  for (int step = 0; step < 50; ++step) {
    loss::draw_step<loss::WindowInterval<24>>(td.slices, td.slice_enabled, td.prefix, 0.05, 512, rng, draw, &td.sites);
    for (auto p : draw.pixels) drawn.insert(p);
  }
  for (const auto& h : td.masked) CHECK(drawn.count(static_cast<std::uint32_t>(h.y * 64 + h.x)) == 0);
  CHECK(drawn.size() > 1000);
  cfg.keep_hot_pixels = true;
  const auto kept = train::prepare(d, cfg);
  CHECK(kept.masked.empty());
  CHECK(kept.sites.all());
}

TEST_CASE("training data: the slices keep their events' intervals unless the period is 0, and a step weighs its counts by them") {
  sim::SimulateOptions so;
  so.width = 64;
  so.height = 48;
  so.progress = false;
  so.sensor.refractory = 2e-3;
  const auto d = sim::to_dataset(sim::simulate("planes", so));
  train::Config cfg;
  cfg.refractory = 0.0;
  const auto plain = train::prepare(d, cfg);
  for (const auto& s : plain.slices.slices) CHECK(!s.has_intervals());
  cfg.refractory.reset();  // learned: the intervals are kept
  const auto td = train::prepare(d, cfg);
  for (const auto& s : td.slices.slices) CHECK(s.gap.size() == s.total);
  Rng rng(3);
  loss::StepDraw draw;
  std::size_t saturated = 0, counted = 0;
  for (int step = 0; step < 20; ++step) {
    const double tau = step % 3 == 0 ? 0.0 : step % 3 == 1 ? 4e-3 : 5e-3;  // the sensor's 2 ms leaves intervals of 4.5 ms and more
    loss::draw_step<loss::WindowInterval<24>>(td.slices, td.slice_enabled, td.prefix, 0.0, 256, rng, draw, &td.sites, 1, tau);
    REQUIRE(draw.wpos.size() == draw.pixels.size() * draw.len);
    for (std::size_t i = 0; i < draw.pixels.size(); ++i)
      for (std::size_t k = 0; k < draw.len; ++k) {
        // The plain sum over the pixel's events, by polarity.
        const auto& c = td.slices.slices[draw.first + k];
        double w[2] = {0, 0}, dw[2] = {0, 0};
        std::uint8_t bits = 0;
        for (std::size_t e = 0; e < c.gap.size(); ++e) {
          const auto a = static_cast<std::size_t>(std::upper_bound(c.gap_start.begin(), c.gap_start.end(), e) - c.gap_start.begin()) - 1;
          if (c.active[a] != draw.pixels[i]) continue;
          const int on = c.gap[e] > 0 ? 0 : 1;
          const auto dt = events::dead_time_weight(std::abs(static_cast<double>(c.gap[e])), tau);
          w[on] += dt.weight;
          dw[on] += dt.dweight;
          if (dt.saturated) bits |= on == 0 ? 1 : 2;
        }
        const std::size_t o = i * draw.len + k;
        CHECK(draw.wpos[o] == doctest::Approx(w[0]));
        CHECK(draw.wneg[o] == doctest::Approx(w[1]));
        CHECK(draw.dwpos[o] == doctest::Approx(dw[0]));
        CHECK(draw.dwneg[o] == doctest::Approx(dw[1]));
        CHECK(draw.limited[o] == bits);
        CHECK(draw.wpos[o] >= draw.npos[o]);  // a period only ever adds crossings
        if (tau == 0) CHECK(draw.wpos[o] == draw.npos[o]);
        saturated += bits != 0;
        counted += draw.npos[o] + draw.nneg[o] > 0;
      }
  }
  CHECK(saturated > 0);  // the sensor's 2 ms period leaves saturated counts, but not everywhere
  CHECK(saturated < counted);
  // Plain counts draw no weights; slices without intervals refuse a period.
  loss::draw_step<loss::WindowInterval<24>>(plain.slices, plain.slice_enabled, plain.prefix, 0.0, 256, rng, draw, &plain.sites);
  CHECK(draw.wpos.empty());
  CHECK(draw.limited.empty());
  CHECK_THROWS_WITH(loss::draw_step<loss::WindowInterval<24>>(plain.slices, plain.slice_enabled, plain.prefix, 0.0, 256, rng, draw,
                                                              &plain.sites, 1, 1e-3),
                    doctest::Contains("needs the slices' event intervals"));
}

TEST_CASE("training data: a learned refractory period starts at the recording's bound (hot pixels left out) and stays below it") {
  // A fine checker swept fast, so that the period binds (as in test_sim.cpp's bound).
  const fs::path scene = fs::temp_directory_path() / ("evnerf_sweep_" + std::to_string(::getpid()) + ".txt");
  write_file_atomic(scene, "plane 0 0 1 0 0 -1 1 0 0 0 0 checker 8\npath slider -0.6 0 0 0.6 0 0 0 0 1 0.3\n");
  sim::SimulateOptions so;
  so.width = 64;
  so.height = 48;
  so.progress = false;
  so.sensor.refractory = 1e-3;
  so.sensor.hot_pixels = 3;  // firing far faster than the period allows: their intervals would set the quantile
  so.sensor.hot_rate = 20000;
  const auto d = sim::to_dataset(sim::simulate(scene.string(), so));
  fs::remove(scene);
  train::Config cfg;
  const auto td = train::prepare(d, cfg);
  REQUIRE(td.masked.size() == 3);
  CAPTURE(td.refractory_bound);
  CHECK(td.refractory_bound >= 1e-3);  // an upper bound of the true period, within twice it
  CHECK(td.refractory_bound <= 2e-3);
  cfg.keep_hot_pixels = true;
  CHECK(train::prepare(d, cfg).refractory_bound < 1e-3);  // the hot pixels' own intervals
  cfg.keep_hot_pixels = false;
  cfg.refractory = 5e-4;  // a given period reads no bound
  CHECK(train::prepare(d, cfg).refractory_bound < 0);
  cfg.refractory.reset();
  // The model starts there, learns downward and never above it; a resumed run reads the bound again.
  cfg.iterations = 40;
  cfg.pixels = 64;
  cfg.threads = 1;
  cfg.progress = false;
  cfg.checkpoint_every = 0;
  const fs::path base = fs::temp_directory_path() / ("evnerf_refractory_" + std::to_string(::getpid()));
  fs::remove_all(base);
  io::CheckpointRun run = train::describe(td, "planes");
  train::Trainer<Tiny> whole(td, cfg, base / "whole", "tiny", run);
  CHECK(whole.model().refractory().learned);
  CHECK(whole.model().refractory().seconds == td.refractory_bound);
  CHECK(whole.model().refractory().max == td.refractory_bound);
  double highest = 0;
  whole.run([&](const train::StepReport&) {
    highest = std::max(highest, whole.model().refractory().seconds);
    return true;
  });
  CHECK(highest <= td.refractory_bound);
  {
    train::Trainer<Tiny> first(td, cfg, base / "split", "tiny", run);
    first.run([](const train::StepReport& rep) { return rep.step < 15; });
  }
  train::Trainer<Tiny> second(td, cfg, base / "split", "tiny", run);
  REQUIRE(second.resume());
  CHECK(second.model().refractory().max == td.refractory_bound);
  second.run();
  CHECK(second.model().refractory().seconds == whole.model().refractory().seconds);
  CHECK(second.model().params().values == whole.model().params().values);
  fs::remove_all(base);
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
  const std::string bytes = m.serialize("tiny", {});
  // The same recording cut into fewer slices.
  train::Config cfg = f.cfg;
  io::Dataset d = f.d;
  d.frames.t.resize(d.frames.t.size() / 2);
  d.frames.paths.resize(d.frames.t.size());
  const auto td2 = train::prepare(d, cfg);
  REQUIRE(td2.slices.size() != f.td.slices.size());
  Tiny r;
  r.deserialize(bytes, "mem");
  try {
    r.train_step(td2, 64, 3);
    FAIL("a model trained on other slices was not refused");
  } catch (const Error& e) {
    CHECK_CONTAINS(e.what(), "slices");
    CHECK_CONTAINS(e.what(), std::to_string(f.td.slices.size()));
    CHECK_CONTAINS(e.what(), std::to_string(td2.slices.size()));
  }
}

TEST_CASE("training loop: a fresh run starts a fresh log of period means, the callback can stop it, the thread count is restored") {
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
  auto r = train::run(m, f.td, cfg, out, "tiny", f.run(), [&](const train::StepReport& rep) {
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
  train::run(m, f.td, cfg, out, "tiny", f.run());
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
  CHECK_THROWS_WITH_AS(train::run(m, f.td, cfg, out, "tiny", f.run()), doctest::Contains("settings.json"), Error);
  CHECK(read_file(out / "settings.json") == "{\"runs\": 3}");
  CHECK(read_file(out / "log.jsonl") == log_before);  // refused before the log was touched
  nlohmann::json later = both;
  later["runs"].push_back(both["runs"][1]);
  later["runs"][2]["from_step"] = 500;
  write_file_atomic(out / "settings.json", later.dump());
  train::run(m, f.td, cfg, out, "tiny", f.run());
  auto kept = settings();
  REQUIRE(kept["runs"].size() == 3);
  CHECK(kept["runs"][1] == both["runs"][1]);
  CHECK(kept["runs"][2]["from_step"] == 100);
  CHECK(kept["runs"][2]["iterations"] == 110);
  fs::remove_all(out);
}

TEST_CASE("training loop: without an output folder nothing is written and the model trains the same, bad settings are refused") {
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
  const auto r = train::run(a, f.td, cfg, fs::path(), "tiny", f.run());
  fs::current_path(cwd);
  CHECK(r.steps == 20);
  CHECK(fs::is_empty(here));
  train::run(b, f.td, cfg, here / "run", "tiny", f.run());
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
  refused([](train::Config& c) { c.tv = std::numeric_limits<double>::infinity(); }, "tv must be >= 0, got inf");
  refused([](train::Config& c) { c.average = 1.0; }, "average must be in [0, 1), got 1");
  Tiny m(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  train::Config bad = cfg;
  bad.threads = -1;
  CHECK_THROWS_WITH_AS(train::run(m, f.td, bad, fs::path(), "tiny", f.run()), doctest::Contains("threads must be in [0, 4096], got -1"),
                       Error);
  CHECK(m.step() == 0);
  // The total-variation weight: unset, the model keeps its own; set, the Config's replaces it; a variant
  // without the term refuses a weight (it would do nothing) but takes 0.
  using TinyTv = EvNerf<TinyField, render::Stratified<16>, loss::JointThresholds, loss::DefaultNoise,
                        loss::Plus<loss::SliceInterval<>, loss::TotalVariation<125>>>;
  TinyTv t(f.td.slices.size(), train::scene_box(f.td, f.cfg), 7);
  train::Config two = cfg;
  two.iterations = 2;
  train::run(t, f.td, two, fs::path(), "tiny", f.run());
  CHECK(t.term<loss::TvTerm>()->weight == 0.125);
  two.tv = 0.0;
  train::run(t, f.td, two, fs::path(), "tiny", f.run());
  CHECK(t.term<loss::TvTerm>()->weight == 0.0);
  two.tv = 0.25;
  const long at = m.step();
  CHECK_THROWS_WITH_AS(train::run(m, f.td, two, fs::path(), "tiny", f.run()),
                       doctest::Contains("weight of 0.25 for a variant without the term"), Error);
  CHECK(m.step() == at);
  two.tv = 0.0;
  CHECK_NOTHROW(train::run(m, f.td, two, fs::path(), "tiny", f.run()));
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

TEST_CASE("train::Trainer: the Config decides box and Adam, a stopped run resumed ends where an uninterrupted one does, in its own box") {
  Fixture f;
  train::Config cfg = f.run_config(30, 64);
  cfg.threads = 2;
  cfg.near = 0.6;
  cfg.far = 2.5;
  cfg.lr = 2e-3;
  cfg.checkpoint_every = 0;
  const fs::path base = fs::temp_directory_path() / ("evnerf_trainer_" + std::to_string(::getpid()));
  train::Trainer<Tiny> whole(f.td, cfg, base / "whole", "tiny", f.run());
  CHECK(whole.model().box().near == 0.6);
  CHECK(whole.model().box().far == 2.5);
  CHECK(whole.model().optimizer().config().lr == 2e-3);
  CHECK_FALSE(whole.resume());  // nothing to resume from
  whole.run();
  CHECK(whole.model().step() == 30);
  {
    train::Trainer<Tiny> first(f.td, cfg, base / "split", "tiny", f.run());
    const auto r = first.run([](const train::StepReport& rep) { return rep.step < 12; });
    CHECK(r.stopped);
  }
  train::Trainer<Tiny> second(f.td, cfg, base / "split", "tiny", f.run());
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
  train::Trainer<Tiny> third(f.td, other, base / "split", "tiny", f.run());
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
    CHECK(s.flag() == "--" + [&] {
      std::string n = s.name;
      std::replace(n.begin(), n.end(), '_', '-');
      return n;
    }());
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
        CHECK_THROWS_WITH_AS(train::config_from_json(k, "test"), doctest::Contains((std::string(s.name) + " must be an integer").c_str()),
                             Error);
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
      CHECK_THROWS_WITH_AS(train::check(d), doctest::Contains(("train: " + std::string(s.name) + " must be " + s.range_text()).c_str()),
                           Error);
    }
  }
  CHECK_THROWS_WITH_AS(train::setting("iters", "train"), doctest::Contains("unknown setting 'iters' (known: iterations, pixels"), Error);
  CHECK_THROWS_WITH_AS(train::config_from_json(nlohmann::json{{"pixels", "many"}}, "settings.json"),
                       doctest::Contains("settings.json: pixels must be an integer, got \"many\""), Error);
}

TEST_CASE("collapse detection: a forced collapse stops the run with what it saw, a healthy run is not stopped") {
  Fixture f;
  train::Config cfg = f.run_config(300, 128);
  cfg.collapse_check_from = 100;
  cfg.collapse_check_every = 100;
  const fs::path base = fs::temp_directory_path() / ("evnerf_collapse_" + std::to_string(::getpid()));
  {
    // Forced: every parameter zero and no learning rate. No density, so every render is black and the
    // loss never moves.
    cfg.lr = 1e-30;
    train::Trainer<Tiny> t(f.td, cfg, base / "dead", "tiny", f.run());
    std::fill(t.model().params().values.begin(), t.model().params().values.end(), 0.f);
    const auto r = t.run();
    CHECK(r.collapsed);
    CHECK(t.model().step() == 100);  // stopped at the first check
    REQUIRE(r.checks.size() == 1);
    CHECK(r.checks[0].flat_renders);
    CHECK(r.checks[0].log_spread < 1e-6);
    CHECK(r.checks[0].loss_stuck);
    CHECK_CONTAINS(r.checks[0].describe(), "at step 100: the renders are almost constant");
    // No density: every ray passes all its samples and shows the (learned) backdrop whole.
    REQUIRE(t.model().renderer().learns_backdrop());
    const auto views = train::view_statistics(t.model(), f.td);
    CHECK(views.log_spread == r.checks[0].log_spread);
    CHECK(views.backdrop_share == doctest::Approx(1.0));
    CHECK(fs::exists(base / "dead" / "model.ckpt"));
    // Asked to go on, it does, and still reports it.
    cfg.allow_collapse = true;
    train::Trainer<Tiny> u(f.td, cfg, base / "dead2", "tiny", f.run());
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
    train::Trainer<Healthy> t(f.td, cfg, base / "healthy", "tiny", f.run());
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
    // The plane that fills the views holds density: most of every view is opaque.
    const double share = train::view_statistics(t.model(), f.td).backdrop_share;
    CHECK(share >= 0);
    CHECK(share < 0.5);
  }
  cfg.collapse_check_every = 75;  // not a multiple of the log period
  train::Trainer<Tiny> bad(f.td, cfg, base / "bad", "tiny", f.run());
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

TEST_CASE("pose refinement: off, a step is the one without it, a resumed run equals an uninterrupted one, a rolled pose comes back") {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  // Off (the default settings) is the model without the setting, bit for bit.
  {
    TinyWindow a(f.td.slices.size(), box, 7), b(f.td.slices.size(), box, 7);
    b.set_pose_refinement(f.td, PoseRefinementSettings{});
    for (int s = 0; s < 5; ++s) {
      a.train_step(f.td, 128, 3);
      b.train_step(f.td, 128, 3);
    }
    CHECK(a.params().values == b.params().values);
    CHECK(b.refined_poses().empty());
  }
  // A stopped run resumed ends where an uninterrupted one does, corrections and offset included, and the
  // resumed Config learns what the checkpoint learns.
  {
    train::Config cfg = f.run_config(24, 64);
    cfg.threads = 2;
    cfg.checkpoint_every = 0;
    cfg.refine_poses = cfg.learn_time_offset = true;
    cfg.pose_start = 4;
    const fs::path base = fs::temp_directory_path() / ("evnerf_pose_trainer_" + std::to_string(::getpid()));
    train::Trainer<TinyWindow> whole(f.td, cfg, base / "whole", "tiny", f.run());
    whole.run();
    {
      train::Trainer<TinyWindow> first(f.td, cfg, base / "split", "tiny", f.run());
      first.run([](const train::StepReport& rep) { return rep.step < 10; });
    }
    train::Config plain = cfg;
    plain.refine_poses = plain.learn_time_offset = false;
    train::Trainer<TinyWindow> second(f.td, plain, base / "split", "tiny", f.run());
    REQUIRE(second.resume());
    CHECK(second.config().refine_poses);
    CHECK(second.config().learn_time_offset);
    second.run();
    CHECK(second.model().params().values == whole.model().params().values);
    CHECK(second.model().pose_refinement().offset == whole.model().pose_refinement().offset);
    CHECK(whole.model().pose_refinement().offset != 0);
    for (std::size_t i = 0; i < f.td.boundary_poses.size(); ++i)
      CHECK(second.model().refined_poses()[i].t == whole.model().refined_poses()[i].t);
    const auto log = read_file(base / "whole" / "log.jsonl");
    CHECK(log.find("\"time_offset\"") != std::string::npos);
    CHECK(log.find("\"pose_correction_rotation_deg\"") != std::string::npos);
    fs::remove_all(base);
  }
  // A recording whose poses at two boundaries are rolled by 3° about the optical axis (which no
  // translation can mimic): the refined poses there come back to within half of it (0.47° and 0.97° here),
  // and the knots that were right stay within a degree.
  {
    TrainingData rough = f.td;
    const double roll = 3 * 3.14159265358979323846 / 180;
    const std::vector<std::size_t> knots = {2, 4};
    for (const std::size_t k : knots) rough.boundary_poses[k] = rough.boundary_poses[k] * twist_exp(Vec3(0, 0, roll), Vec3::Zero());
    TinyWindow m(rough.slices.size(), box, 7);
    PoseRefinementSettings s;
    s.poses = true;
    s.lr_rotation = 4e-3;
    s.lr_translation = 0;  // the roll alone
    s.start = 50;
    s.decay_steps = 600;
    m.set_pose_refinement(rough, s);
    for (int step = 0; step < 600; ++step) REQUIRE(std::isfinite(m.train_step(rough, 256, 3).loss));
    for (const std::size_t k : knots) {
      const double left = geometry::pose_error({m.refined_poses()[k]}, {f.td.boundary_poses[k]}).rotation_mean_deg;
      CAPTURE(k);
      CHECK(left < 1.5);
    }
    for (const std::size_t k : {std::size_t{1}, std::size_t{3}})
      CHECK(geometry::pose_error({m.refined_poses()[k]}, {f.td.boundary_poses[k]}).rotation_mean_deg < 1.0);
  }
}
