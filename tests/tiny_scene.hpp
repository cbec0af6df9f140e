// The tiny simulated recording that training tests share: a checkered plane seen by a 32×24 camera on a
// short slider path, 12 Hz frames, near 0.5 and far 3.
#pragma once
#include <evnerf/sim/simulator.hpp>
#include <evnerf/train/trainer.hpp>

namespace evtest {

struct Fixture {
  evnerf::io::Dataset d;
  evnerf::TrainingData td;
  evnerf::train::Config cfg;
  /// `threshold`: the sensor's contrast threshold (a finer one fires more events, closer together).
  explicit Fixture(double threshold = 0.25) {
    auto spec = evnerf::sim::parse_scene("plane 0 0 1.5 0 0 -1 1 0 0 0 0 checker 2\npath slider -0.1 0 0 0.1 0 0 0 0 1 0.5\n", "tiny.txt");
    evnerf::sim::SensorConfig sc;
    sc.width = 32;
    sc.height = 24;
    sc.fx = sc.fy = 30;
    sc.cx = sc.cy = -1;
    sc.frame_rate = 12;
    sc.threshold_pos = sc.threshold_neg = threshold;
    auto rec = evnerf::sim::Simulator(spec, sc).run();
    d.camera = rec.camera;
    d.events = rec.events;
    d.trajectory = rec.trajectory;
    d.frames.t = rec.frame_times;
    d.frames.paths.resize(rec.frame_times.size());
    cfg.near = 0.5;
    cfg.far = 3.0;
    cfg.pixels = 256;
    td = evnerf::train::prepare(d, cfg);
  }
  /// What a checkpoint of a run on the fixture records (train::describe), the recording named "tiny".
  evnerf::io::CheckpointRun run() const { return evnerf::train::describe(td, "tiny"); }
  /// The fixture's Config for a quiet run of `iterations` steps at `pixels` pixels per step.
  evnerf::train::Config run_config(long iterations, int pixels) const {
    evnerf::train::Config c = cfg;
    c.iterations = iterations;
    c.pixels = pixels;
    c.progress = false;
    return c;
  }
};
}  // namespace evtest
