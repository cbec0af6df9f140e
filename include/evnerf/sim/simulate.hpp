// sim/simulate.hpp — a scene simulated from a few options, as `evnerf simulate` and the Python module's
// `simulate` take them, and a simulated recording as an in-memory io::Dataset. Depends on sim/ and io/.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

#include "../io/dataset.hpp"
#include "random_scene.hpp"
#include "scene.hpp"
#include "simulator.hpp"

namespace evnerf::sim {

/// What `evnerf simulate` asks of a simulation besides the scene.
struct SimulateOptions {
  bool realistic = false;  ///< sensor effects (SensorConfig::realistic)
  bool bayer = false;      ///< RGGB mosaic (always on for the built-in colour scene, blocks)
  bool hdr = false;        ///< high dynamic range lighting and the linear truth (sim::hdr_lighting)
  std::uint64_t seed = 1;  ///< sensor noise; with the scene 'random', also the scene
  std::filesystem::path textures;  ///< with 'random': photos (.png) to texture surfaces with
  double log_offset = SensorConfig{}.log_offset;
  double noise_rate = 0, noise_ratio = 0;
  int width = SensorConfig{}.width, height = SensorConfig{}.height;
  double focal = 0;  ///< pixels; 0 = scaled with the width (200 at 240)
  bool progress = true;  ///< a progress bar on stderr
};

/// Simulates a built-in scene, 'random' (a procedural scene from the seed; its text goes to `scene_text`)
/// or a scene description file.
inline Recording simulate(const std::string& scene, const SimulateOptions& o, std::string* scene_text = nullptr) {
  require(o.textures.empty() || scene == "random", "simulate: --textures goes with the 'random' scene");
  require(o.width >= 8 && o.width <= 8192 && o.height >= 8 && o.height <= 8192,
          "simulate: the sensor's width and height must be between 8 and 8192 pixels");
  require(o.focal >= 0 && std::isfinite(o.focal), "simulate: the focal length must be positive (or 0 for the default)");
  require(o.noise_rate >= 0 && o.noise_ratio >= 0, "simulate: noise rates must not be negative");
  auto spec = scene == "random" ? random_scene(o.seed, texture_pictures(o.textures), scene_text) : load_scene(scene);
  SensorConfig c = o.realistic ? SensorConfig::realistic() : SensorConfig{};
  c.noise_rate = o.noise_rate;
  c.noise_ratio = o.noise_ratio;
  c.log_offset = o.log_offset;
  c.bayer = o.bayer || scene == "blocks";  // the built-in colour scene is seen through an RGGB mosaic
  if (o.hdr) {
    c.hdr = true;
    hdr_lighting(spec.scene);
  }
  c.seed = o.seed;
  c.fx = c.fy = o.focal > 0 ? o.focal : c.fx * o.width / 240.0;
  c.width = o.width;
  c.height = o.height;
  c.cx = c.cy = -1;
  return Simulator(spec, c).run(o.progress);
}

/// A simulated recording as a Dataset in memory: camera, events, poses and frames (the mosaic named when
/// there is one). Depth and the linear truth live in files only: write_recording, then io::load, keeps them.
inline io::Dataset to_dataset(Recording rec, const std::string& name = "simulated") {
  io::Dataset d;
  d.folder = name;
  d.camera = rec.camera;
  d.events = std::move(rec.events);
  d.trajectory = std::move(rec.trajectory);
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  if (!d.frames.images.empty() && d.frames.images.front().channels == 3) d.bayer_pattern = "rggb";
  return d;
}

}  // namespace evnerf::sim
