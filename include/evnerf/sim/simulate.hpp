// sim/simulate.hpp — a scene simulated from a few options, as `evnerf simulate` and the Python module's
// `simulate` take them, and a simulated recording as an in-memory io::Dataset. Depends on sim/ and io/.
#pragma once
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "../io/dataset.hpp"
#include "random_scene.hpp"
#include "scene.hpp"
#include "simulator.hpp"

namespace evnerf::sim {

/// The ranges `--sensor random` draws from (uniformly; the count of hot pixels as an integer): what DAVIS
/// and Prophesee cameras span.
struct RandomSensorRanges {
  static constexpr double threshold_pos[2] = {0.15, 0.5};
  static constexpr double ratio[2] = {0.7, 1.4};  ///< C⁻ / C⁺
  static constexpr double mismatch[2] = {0.0, 0.05};
  static constexpr double refractory[2] = {0.0, 1e-3};
  static constexpr double noise_rate[2] = {0.0, 1.0};
  static constexpr int hot_pixels[2] = {0, 10};
  static constexpr double jitter[2] = {0.0, 5e-5};
};

/// The sensor's parameters for `o` and the simulation's seed: the model's (random: drawn from
/// RandomSensorRanges with a stream of its own), then each parameter given. A value no sensor has is
/// refused naming its flag.
inline SensorConfig sensor_model(const SensorOptions& o, std::uint64_t seed) {
  SensorConfig c;
  if (o.model == "realistic") {
    c = SensorConfig::realistic();
  } else if (o.model == "davis") {
    c = SensorConfig::davis();
  } else if (o.model == "random") {
    Rng rng = Rng(seed).split(0x53454E534F52ull);  // "SENSOR": independent of the scene and the noise
    using R = RandomSensorRanges;
    c.threshold_pos = rng.uniform(R::threshold_pos[0], R::threshold_pos[1]);
    c.threshold_neg = c.threshold_pos * rng.uniform(R::ratio[0], R::ratio[1]);
    c.mismatch = rng.uniform(R::mismatch[0], R::mismatch[1]);
    c.refractory = rng.uniform(R::refractory[0], R::refractory[1]);
    c.noise_rate = rng.uniform(R::noise_rate[0], R::noise_rate[1]);
    c.hot_pixels = R::hot_pixels[0] + static_cast<int>(rng.below(static_cast<std::uint64_t>(R::hot_pixels[1] - R::hot_pixels[0] + 1)));
    c.jitter = rng.uniform(R::jitter[0], R::jitter[1]);
  } else if (o.model != "ideal") {
    throw Error("simulate: --sensor '" + o.model + "': expected ideal, realistic, davis or random");
  }
  sensor_params([&](const auto& p) {
    const auto& x = o.*p.given;
    if (!x) return;
    const double v = static_cast<double>(*x);
    if (!std::isfinite(v) || (p.lo_open ? v <= p.lo : v < p.lo) || v > p.hi)
      throw Error("simulate: " + p.flag() + " must be in " + (p.lo_open ? "(" : "[") + short_number(p.lo) + ", " + short_number(p.hi) +
                  "], got " + short_number(v));
    c.*p.value = *x;
  });
  return c;
}

/// An object-centric capture of one mesh file (`evnerf simulate mesh FILE`): the object normalised into the
/// unit sphere at the origin, lit as the analytic scenes are, before a plain background, seen along EventNeRF's
/// orbit (or a hemisphere spiral) by a DAVIS346-sized sensor.
struct MeshCapture {
  std::filesystem::path file;
  std::string up = "+y";            ///< the file's up axis (+y, +z or -y)
  std::string path = "orbit";       ///< orbit (one revolution a second at `elevation`) or spiral (5° to 75°)
  double radius = 3.0;              ///< camera distance from the object's centre
  double elevation = 30.0;          ///< degrees above the horizon
  double wobble = 0.0;              ///< orbit: degrees the elevation swings once over the path
  double duration = 1.0;            ///< seconds (the orbit: one revolution each)
  double novel_elevation = 50.0;    ///< degrees: the held-out orbit scored as novel views (NaN: none)
  std::string background = "grey";  ///< black, white, grey (0.5) or an equirectangular environment (.png)
};

/// The scene description text of a mesh capture (what `simulate mesh` saves as scene.txt). Refuses
/// values no capture has, naming the flag.
inline std::string mesh_scene_text(const MeshCapture& m) {
  auto check = [](bool ok, const std::string& what) {
    if (!ok) throw Error("simulate mesh: " + what);
  };
  check(!m.file.empty(), "the mesh file is missing (simulate mesh FILE)");
  check(m.file.string().find_first_of(" \t\n#") == std::string::npos,
        "the mesh file's path must not hold spaces, tabs or '#' ('" + m.file.string() + "')");
  check(m.radius > 1.05 && m.radius <= 100, "--orbit-radius must be in (1.05, 100] (the object fills the unit sphere)");
  check(std::abs(m.elevation) + std::abs(m.wobble) < 89, "--elevation (with --wobble) must stay within ±89 degrees");
  check(m.duration > 0 && m.duration <= 60, "--duration must be in (0, 60] seconds");
  check(std::isnan(m.novel_elevation) || std::abs(m.novel_elevation) < 89, "--novel-elevation must lie within ±89 degrees");
  check(m.path == "orbit" || m.path == "spiral", "--path must be orbit or spiral, not '" + m.path + "'");
  std::string bg = m.background == "black" ? "0 0 0" : m.background == "white" ? "1 1 1" : m.background == "grey" ? "0.5 0.5 0.5" : "";
  if (bg.empty()) {  // an environment picture
    check(std::filesystem::path(m.background).extension() == ".png",
          "--background must be black, white, grey or an equirectangular .png, not '" + m.background + "'");
    const std::string env = std::filesystem::absolute(m.background).lexically_normal().string();
    check(env.find_first_of(" \t\n#") == std::string::npos, "the environment's path must not hold spaces, tabs or '#' ('" + env + "')");
    bg = "image " + env;
  }
  const std::string file = std::filesystem::absolute(m.file).lexically_normal().string();
  std::string t = "# " + std::filesystem::path(file).filename().string() + ", normalised into the unit sphere\n";
  t += "light -0.4 0.8 0.6 0.35 0.65\n";
  t += std::string("background ") + bg + "\n";
  t += "mesh " + file + " 0 0 0 1 up " + m.up + "\n";
  if (m.path == "orbit")
    t += "path orbit 0 0 0 " + short_number(m.radius) + " " + short_number(m.elevation) + " " + short_number(m.duration) + " " +
         short_number(m.wobble) + "\n";
  else t += "path spiral 0 0 0 " + short_number(m.radius) + " 5 75 " + short_number(m.duration) + " " + short_number(m.duration) + "\n";
  if (!std::isnan(m.novel_elevation)) t += "novel orbit 0 0 0 " + short_number(m.radius) + " " + short_number(m.novel_elevation) + " 1\n";
  return t;
}

/// What `evnerf simulate` asks of a simulation besides the scene.
struct SimulateOptions {
  SensorOptions sensor;            ///< the sensor's model and parameters (sensor_model)
  bool bayer = false;              ///< RGGB mosaic (always on for the built-in colour scene, blocks)
  bool hdr = false;                ///< high dynamic range lighting and the linear truth (sim::hdr_lighting)
  std::uint64_t seed = 1;          ///< sensor noise; with the scene 'random', also the scene
  std::filesystem::path textures;  ///< with 'random': photos (.png) to texture surfaces with
  double log_offset = SensorConfig{}.log_offset;
  double noise_ratio = 0;     ///< uniform random events added, as a fraction of the signal events
  int width = 0, height = 0;  ///< pixels; 0 = the scene's default (240 × 180; 346 × 260 for a mesh capture)
  double focal = 0;           ///< pixels; 0 = scaled with the width (200 at 240)
  MeshCapture mesh;           ///< with the scene 'mesh': the file and its capture
  bool progress = true;       ///< a progress bar on stderr
  /// Poses only roughly known (perturb_poses): the recorded trajectory's RMS error over its pose knots in
  /// translation (world units) and rotation (degrees), and the pose clock's offset from the events' (seconds).
  double pose_noise_translation = 0, pose_noise_rotation = 0, time_offset = 0;
};

/// The recording's trajectory made only roughly known, its true poses kept in true_trajectory. Every knot
/// but the first (which fixes the scene's frame, as pose refinement's gauge holds it) moves by a rigid error
/// in its camera's frame: an independent one per knot plus a drift that grows steadily from the first knot
/// along a slowly turning direction, half the variance each, with RMS `translation` (world units) and
/// `rotation` (degrees) over the knots. Then the pose times are shifted by `offset`: the poses' clock reads
/// t + offset at the events' time t. Deterministic in `seed`.
inline void perturb_poses(Recording& rec, double translation, double rotation_deg, double offset, std::uint64_t seed) {
  require(std::isfinite(translation) && translation >= 0 && translation <= 10, "simulate: --pose-noise's translation must be in [0, 10]");
  require(std::isfinite(rotation_deg) && rotation_deg >= 0 && rotation_deg <= 45,
          "simulate: --pose-noise's rotation must be in [0, 45] degrees");
  require(std::isfinite(offset) && std::abs(offset) <= 1, "simulate: --time-offset must be within ±1 s");
  if (translation == 0 && rotation_deg == 0 && offset == 0) return;
  const auto& tr = rec.trajectory;
  require(tr.size() >= 2, "simulate: the recording has too few poses to perturb");
  Rng rng = Rng(seed).split(0x504F5345ull);  // "POSE": independent of the scene and the sensor
  const double rot = rotation_deg * 3.14159265358979323846 / 180.0;
  auto gauss3 = [&](double sd) -> Vec3 { return Vec3(rng.normal(), rng.normal(), rng.normal()) * sd; };
  auto unit = [&]() -> Vec3 { return gauss3(1).normalized(); };
  const Vec3 dt0 = unit(), dt1 = unit(), dr0 = unit(), dr1 = unit();
  const double span = tr.back() - tr.front(), quarter = 1.5707963267948966;
  // The drift's size grows as s ∈ [0, 1] along the path (RMS 1/√3), scaled to an RMS of σ/√2; the
  // independent part has σ/√6 per axis (RMS σ/√2 over three axes).
  const double grow = std::sqrt(3.0 / 2.0);
  std::vector<geometry::Pose> poses;
  std::vector<double> times;
  for (std::size_t i = 0; i < tr.size(); ++i) {
    const double s = span > 0 ? (tr.times()[i] - tr.front()) / span : 0;
    const Vec3 drift_t = (dt0 * std::cos(s * quarter) + dt1 * std::sin(s * quarter)).normalized() * (translation * grow * s);
    const Vec3 drift_r = (dr0 * std::cos(s * quarter) + dr1 * std::sin(s * quarter)).normalized() * (rot * grow * s);
    Vec3 et = drift_t + gauss3(translation / std::sqrt(6.0)), er = drift_r + gauss3(rot / std::sqrt(6.0));
    if (i == 0) et = er = Vec3::Zero();
    geometry::Pose e;
    const double a = er.norm();
    e.q = a > 0 ? Quat(Eigen::AngleAxisd(a, er / a)) : Quat::Identity();
    e.t = et;
    poses.push_back(tr.poses()[i] * e);
    times.push_back(tr.times()[i] + offset);
  }
  rec.true_trajectory = tr;
  rec.trajectory = geometry::Trajectory(std::move(times), std::move(poses), "perturbed trajectory");
}

/// Simulates a built-in scene, 'random' (a procedural scene from the seed), 'mesh' (o.mesh's capture of a
/// mesh file) or a scene description file. The text of a generated scene goes to `scene_text`.
inline Recording simulate(const std::string& scene, SimulateOptions o, std::string* scene_text = nullptr) {
  require(o.textures.empty() || scene == "random", "simulate: --textures goes with the 'random' scene");
  const bool mesh = scene == "mesh";
  if (o.width == 0) o.width = mesh ? 346 : SensorConfig{}.width;
  if (o.height == 0) o.height = mesh ? 260 : SensorConfig{}.height;
  require(o.width >= 8 && o.width <= 8192 && o.height >= 8 && o.height <= 8192,
          "simulate: the sensor's width and height must be between 8 and 8192 pixels");
  require(o.focal >= 0 && std::isfinite(o.focal), "simulate: the focal length must be positive (or 0 for the default)");
  require(o.noise_ratio >= 0 && std::isfinite(o.noise_ratio), "simulate: --noise-ratio must not be negative");
  SceneSpec spec;
  if (scene == "random") {
    spec = random_scene(o.seed, texture_pictures(o.textures), scene_text);
  } else if (mesh) {
    const std::string text = mesh_scene_text(o.mesh);
    spec = parse_scene(text, o.mesh.file.filename().string() + " (simulate mesh)");
    spec.scene.name = o.mesh.file.stem().string();
    if (scene_text) *scene_text = text;
  } else {
    spec = load_scene(scene);
  }
  SensorConfig c = sensor_model(o.sensor, o.seed);
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
  Recording rec = Simulator(spec, c).run(o.progress);
  perturb_poses(rec, o.pose_noise_translation, o.pose_noise_rotation, o.time_offset, o.seed);
  return rec;
}

/// A simulated recording as a Dataset in memory: camera, events, poses and frames (the mosaic named when
/// there is one). Depth and the linear truth live in files only: write_recording, then io::load, keeps them.
inline io::Dataset to_dataset(Recording rec, const std::string& name = "simulated") {
  io::Dataset d;
  d.folder = name;
  d.camera = rec.camera;
  d.events = std::move(rec.events);
  d.trajectory = std::move(rec.trajectory);
  d.true_trajectory = std::move(rec.true_trajectory);
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  if (!d.frames.images.empty() && d.frames.images.front().channels == 3) d.bayer_pattern = "rggb";
  return d;
}

}  // namespace evnerf::sim
