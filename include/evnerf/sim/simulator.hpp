// sim/simulator.hpp — an ESIM-style event simulator: renders log intensity at adaptive time steps (fine
// enough that no pixel moves by more than a fraction of the threshold between steps, down to a minimum
// step), interpolates each pixel linearly between renders and emits an event at every threshold
// crossing with its interpolated time; sensor effects as parameters; writes the IJRR folder layout plus
// ground-truth depth. Depends on core/, geometry/, events/, io/ and sim/scene.hpp only.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "../core/parallel.hpp"
#include "../core/progress.hpp"
#include "../events/event_stream.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/trajectory.hpp"
#include "../io/ijrr.hpp"
#include "../io/image_io.hpp"
#include "../io/npy.hpp"
#include "scene.hpp"

namespace evnerf::sim {

struct SensorConfig {
  int width = 240, height = 180;
  double fx = 200, fy = 200, cx = 120, cy = 90;       ///< cx, cy < 0 → image centre
  double threshold_pos = 0.25, threshold_neg = 0.25;  ///< contrast thresholds (log units, both > 0)
  double mismatch = 0.0;                              ///< per-pixel threshold deviation: relative standard deviation
  double refractory = 0.0;                            ///< seconds
  double noise_rate = 0.0;                            ///< background activity, events per pixel per second
  double noise_ratio = 0.0;                           ///< extra uniform random events, as a fraction of the signal events
                                                      ///< (Ev-NeRF's noise-robustness experiment: 0.5 adds half as many)
  int hot_pixels = 0;                                 ///< pixels firing at `hot_rate`
  double hot_rate = 200.0;
  double jitter = 0.0;                      ///< timestamp jitter standard deviation, seconds
  double frame_rate = 24.0;                 ///< APS frames per second
  double exposure = 1.0;                    ///< frame gain (events see every level; frames clip at 1)
  double log_offset = 1e-4;                 ///< the dark end: pixels respond to log(I + log_offset), I the linear
                                            ///< radiance (a photoreceptor's dark current, not a hard clamp)
  bool hdr = false;                         ///< always write linear/ ground truth (also written when a frame clips)
  bool bayer = false;                       ///< RGGB colour filter: each pixel sees one channel
  double max_step_fraction = 0.4;           ///< max log change per step, as a fraction of the threshold
  double min_step = 5e-4, max_step = 5e-3;  ///< seconds
  std::uint64_t seed = 1;

  /// A sensor with a short dead time: asymmetric thresholds with 3 % mismatch, 0.1 ms refractory period,
  /// 0.1 Hz background activity, three hot pixels, 20 µs timestamp jitter (`simulate --sensor realistic`).
  static SensorConfig realistic() {
    SensorConfig c;
    c.threshold_pos = 0.22;
    c.threshold_neg = 0.28;
    c.mismatch = 0.03;
    c.refractory = 1e-4;
    c.noise_rate = 0.1;
    c.hot_pixels = 3;
    c.jitter = 2e-5;
    return c;
  }
  /// The DAVIS240C of the IJRR recordings (Ev-NeRF's real datasets): the realistic sensor with a 1.5 ms
  /// refractory period (`simulate --sensor davis`). In the real recordings no pixel fires twice within
  /// 1.3 ms; pooled over the 12 event windows of ../shared/data their per-pixel intervals have the 0.1, 0.5
  /// and 1 % quantiles 1.54, 1.69 and 1.78 ms, and a simulated fast sweep recorded with this sensor has them
  /// within 15 % (tests/test_sim.cpp).
  static SensorConfig davis() {
    SensorConfig c = realistic();
    c.refractory = 1.5e-3;
    return c;
  }
};

struct Recording {
  geometry::Camera camera;
  events::EventStream events;
  std::vector<double> frame_times;
  std::vector<Image> frames;  ///< grey (or RGB with bayer), in [0, 1]
  std::vector<Image> depth;   ///< z-depth per frame (inf where nothing is hit)
  std::vector<Image> linear;  ///< linear radiance per frame, unclipped (grey, or RGB with bayer): HDR truth
  bool clipped = false;       ///< some frame pixel exceeded 1 (frames lost highlights)
  double log_offset = 0;      ///< the sensor's, to score HDR renders in the space the events see
  geometry::Trajectory trajectory;
  /// The true poses when `trajectory` was perturbed (simulate's --pose-noise, --time-offset), else empty:
  /// write_recording keeps them as groundtruth_true.txt, and eval measures the pose error against them.
  geometry::Trajectory true_trajectory;
  std::size_t renders = 0;
  std::string scene_name;  ///< the scene's own name
  double duration = 0;     ///< the camera path's length in time, seconds
  SensorConfig sensor;     ///< the sensor that recorded it (write_recording writes its model to sensor_model.txt)
  /// Held-out views (the scene's `novel` path): poses never on the training path, with their frames and depth.
  struct Views {
    std::vector<geometry::Pose> poses;
    std::vector<Image> frames, depth;
  } novel;
};

/// The sensor `simulate` records with: a named model and any of its parameters set one by one (each unset one
/// keeps the model's value). The parameters are those of sensor_params().
struct SensorOptions {
  /// ideal (thresholds 0.25 / 0.25, no mismatch, refractory period or noise), realistic
  /// (SensorConfig::realistic), davis (SensorConfig::davis) or random (every parameter drawn from what real
  /// cameras span, from the seed).
  std::string model = "ideal";
  std::optional<double> threshold_pos, threshold_neg;  ///< C⁺, C⁻ (log units)
  std::optional<double> mismatch;                      ///< per-pixel threshold deviation, relative σ
  std::optional<double> refractory;                    ///< seconds a pixel is blind after it fires
  std::optional<double> noise_rate;                    ///< background activity, events per pixel per second
  std::optional<int> hot_pixels;                       ///< pixels that fire on their own
  std::optional<double> hot_rate;                      ///< their events per second
  std::optional<double> jitter;                        ///< timestamp noise, standard deviation in seconds
};

/// One parameter of the simulated sensor, as every interface names it: `name` is the Python keyword, the key
/// in sensor_model.txt and (with '-' for '_') `simulate`'s flag; `given` its field in SensorOptions, `value`
/// in SensorConfig; the values a sensor can have, [lo, hi] ((lo, hi] when lo_open); what it is.
template <class T>
struct SensorParam {
  const char* name;
  std::optional<T> SensorOptions::*given;
  T SensorConfig::*value;
  double lo, hi;
  bool lo_open;
  const char* help;
  std::string flag() const {
    std::string f = std::string("--") + name;
    std::replace(f.begin(), f.end(), '_', '-');
    return f;
  }
};

/// The sensor's parameters, one table: `simulate`'s flags, Python's keywords (simulate, sensor_model),
/// sensor_model.txt and the check of a given value come from it. Calls f(SensorParam<double or int>) for
/// each, in one order.
template <class F>
void sensor_params(F&& f) {
  using O = SensorOptions;
  using C = SensorConfig;
  f(SensorParam<double>{"threshold_pos", &O::threshold_pos, &C::threshold_pos, 0, 5, true, "C+: the log-intensity rise of an ON event"});
  f(SensorParam<double>{"threshold_neg", &O::threshold_neg, &C::threshold_neg, 0, 5, true,
                        "C-: the log-intensity fall of an OFF event (positive)"});
  f(SensorParam<double>{"mismatch", &O::mismatch, &C::mismatch, 0, 0.5, false,
                        "per-pixel threshold deviation: relative standard deviation (0.03 = 3 %)"});
  f(SensorParam<double>{"refractory", &O::refractory, &C::refractory, 0, 1, false, "seconds a pixel is blind after it fires"});
  f(SensorParam<double>{"noise_rate", &O::noise_rate, &C::noise_rate, 0, 1e4, false, "background activity: events per pixel per second"});
  f(SensorParam<int>{"hot_pixels", &O::hot_pixels, &C::hot_pixels, 0, 1e6, false, "pixels that fire on their own, at --hot-rate"});
  f(SensorParam<double>{"hot_rate", &O::hot_rate, &C::hot_rate, 0, 1e6, false, "a hot pixel's events per second (200 unless given)"});
  f(SensorParam<double>{"jitter", &O::jitter, &C::jitter, 0, 0.1, false, "timestamp noise: standard deviation in seconds"});
}

/// The parameters' names, joined by ", " (the messages that list them).
inline std::string sensor_param_names() {
  std::string s;
  sensor_params([&](const auto& p) { s.append(s.empty() ? "" : ", ").append(p.name); });
  return s;
}

/// The sensor's model as `name value` lines (sensor_model.txt): every parameter of sensor_params(), the
/// uniform noise's ratio and the seed of its noise.
inline std::string sensor_model_text(const SensorConfig& c) {
  std::string out;
  char buf[96];
  sensor_params([&](const auto& p) {
    std::snprintf(buf, sizeof buf, "%s %.9g\n", p.name, static_cast<double>(c.*p.value));
    out += buf;
  });
  std::snprintf(buf, sizeof buf, "noise_ratio %.9g\nseed %llu\n", c.noise_ratio, static_cast<unsigned long long>(c.seed));
  return out + buf;
}

class Simulator {
 public:
  Simulator(const SceneSpec& spec, SensorConfig cfg) : spec_(spec), cfg_(cfg) {
    if (cfg_.cx < 0) cfg_.cx = cfg_.width * 0.5;
    if (cfg_.cy < 0) cfg_.cy = cfg_.height * 0.5;
    cam_ = geometry::Camera(cfg_.width, cfg_.height, cfg_.fx, cfg_.fy, cfg_.cx, cfg_.cy);
    require(cfg_.threshold_pos > 0 && cfg_.threshold_neg > 0, "simulator: thresholds must be positive");
    require(cfg_.log_offset > 0 && std::isfinite(cfg_.log_offset), "simulator: the log offset must be positive");
  }
  const geometry::Camera& camera() const { return cam_; }

  /// Linear intensity (per pixel, RGB) and z-depth at time t of the path.
  void render(double t, std::vector<Vec3>& rgb, std::vector<float>* depth = nullptr) const { render_at(spec_.path.pose(t), rgb, depth); }
  /// Linear intensity (per pixel, RGB) and z-depth seen from a pose.
  void render_at(const geometry::Pose& pose, std::vector<Vec3>& rgb, std::vector<float>* depth = nullptr) const {
    const int W = cfg_.width, H = cfg_.height;
    rgb.resize(static_cast<std::size_t>(W) * H);
    if (depth) depth->resize(rgb.size());
    const double pix_angle = 1.0 / cfg_.fx;
    parallel_blocks(static_cast<std::size_t>(H), 8, [&](std::size_t b, std::size_t e, int) {
      thread_local std::vector<Vec3> dirs;
      thread_local std::vector<double> tt;
      dirs.resize(static_cast<std::size_t>(W));
      tt.resize(static_cast<std::size_t>(W));
      for (std::size_t y = b; y < e; ++y) {  // a row at a time: one stream of rays for the meshes
        for (int x = 0; x < W; ++x)
          dirs[static_cast<std::size_t>(x)] = pose.q * Vec3((x + 0.5 - cfg_.cx) / cfg_.fx, (double(y) + 0.5 - cfg_.cy) / cfg_.fy, 1.0);
        spec_.scene.shade(pose.t, dirs, pix_angle, std::span<Vec3>(rgb.data() + y * W, static_cast<std::size_t>(W)), tt);
        if (depth)
          for (int x = 0; x < W; ++x)
            (*depth)[y * W + x] = static_cast<float>(tt[static_cast<std::size_t>(x)]);  // d has unit camera z: t is z-depth
      }
    });
  }
  /// Log intensity seen by each pixel (its Bayer channel, or luminance).
  void log_intensity(const std::vector<Vec3>& rgb, std::vector<double>& L) const {
    L.resize(rgb.size());
    const int W = cfg_.width;
    for (std::size_t i = 0; i < rgb.size(); ++i) {
      const double v = cfg_.bayer ? rgb[i][geometry::rggb_channel(static_cast<int>(i % W), static_cast<int>(i / W))]
                                  : 0.299 * rgb[i][0] + 0.587 * rgb[i][1] + 0.114 * rgb[i][2];
      L[i] = std::log(std::max(v, 0.0) + cfg_.log_offset);
    }
  }

  Recording run(bool progress = false) const {
    Recording rec;
    rec.camera = cam_;
    rec.sensor = cfg_;
    rec.scene_name = spec_.scene.name;
    rec.duration = spec_.path.duration;
    const int W = cfg_.width, H = cfg_.height;
    const std::size_t n = static_cast<std::size_t>(W) * H;
    const double T = spec_.path.duration;
    Rng rng(cfg_.seed);
    // Per-pixel thresholds (mismatch) and state.
    std::vector<double> cpos(n, cfg_.threshold_pos), cneg(n, cfg_.threshold_neg);
    if (cfg_.mismatch > 0)
      for (std::size_t i = 0; i < n; ++i) {
        cpos[i] = std::max(0.01, cfg_.threshold_pos * (1 + cfg_.mismatch * rng.normal()));
        cneg[i] = std::max(0.01, cfg_.threshold_neg * (1 + cfg_.mismatch * rng.normal()));
      }
    std::vector<Vec3> rgb;
    std::vector<double> L0, L1, ref;
    const bool refractory = cfg_.refractory > 0;
    std::vector<double> release(n, -1e9);  // the end of each pixel's refractory period
    render(0.0, rgb);
    log_intensity(rgb, L0);
    ref = L0;
    struct Ev {
      double t;
      std::uint32_t pix;
      std::int8_t p;
    };
    std::vector<Ev> evs;
    double t = 0, dt = cfg_.max_step;
    const double cmin = std::min(cfg_.threshold_pos, cfg_.threshold_neg);
    Progress bar(static_cast<long>(T * 1000), "simulate", progress);
    while (t < T - 1e-12) {
      dt = std::min(dt, T - t);
      render(t + dt, rgb);
      log_intensity(rgb, L1);
      ++rec.renders;
      double worst = 0;
      for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(L1[i] - L0[i]));
      if (worst > cfg_.max_step_fraction * cmin && dt > cfg_.min_step * 1.0001) {
        dt = std::max(cfg_.min_step, dt * 0.5);
        continue;
      }
      // Emit events at the crossings of the linear interpolation in (t, t + dt]. A pixel that fired is held in
      // reset for the refractory period: it sees nothing until `release`, and then memorises the level it sees
      // (the DVS pixel's differencing amplifier is balanced again when its reset switch opens), so the change
      // during the period is lost, not carried over.
      const double t1 = t + dt;
      for (std::size_t i = 0; i < n; ++i) {
        const double a = L0[i], b = L1[i];
        if (refractory && release[i] > t) {
          if (release[i] >= t1) continue;  // blind for the whole step
          ref[i] = a + (b - a) * ((release[i] - t) / dt);
        }
        if (a == b) continue;
        while (true) {
          const bool up = b > ref[i];
          const double level = up ? ref[i] + cpos[i] : ref[i] - cneg[i];
          if ((up && b < level) || (!up && b > level)) break;
          const double te = t + dt * std::clamp((level - a) / (b - a), 0.0, 1.0);
          ref[i] = level;
          evs.push_back({te, static_cast<std::uint32_t>(i), static_cast<std::int8_t>(up ? 1 : -1)});
          if (refractory) {
            release[i] = te + cfg_.refractory;
            if (release[i] >= t1) break;
            ref[i] = a + (b - a) * ((release[i] - t) / dt);
          }
        }
      }
      L0.swap(L1);
      t += dt;
      if (worst < 0.25 * cfg_.max_step_fraction * cmin) dt = std::min(cfg_.max_step, dt * 2);
      bar.update(static_cast<long>(t * 1000));
    }
    // Background activity and hot pixels: Poisson counts, uniform times, random polarity.
    auto poisson = [&](double mean) {
      if (mean > 50) return static_cast<std::size_t>(std::max(0.0, std::round(mean + std::sqrt(mean) * rng.normal())));
      std::size_t k = 0;
      double p = std::exp(-mean), s = p, u = rng.uniform();
      while (u > s && k < 1000) {
        ++k;
        p *= mean / k;
        s += p;
      }
      return k;
    };
    // Noise at a ratio of the signal (drawn before the sensor's own noise, so the signal is unchanged).
    const auto n_ratio = static_cast<std::size_t>(std::llround(cfg_.noise_ratio * static_cast<double>(evs.size())));
    for (std::size_t k = 0; k < n_ratio; ++k)
      evs.push_back({rng.uniform(0, T), static_cast<std::uint32_t>(rng.below(n)), static_cast<std::int8_t>(rng.below(2) ? 1 : -1)});
    const std::size_t n_noise = poisson(cfg_.noise_rate * n * T);
    for (std::size_t k = 0; k < n_noise; ++k)
      evs.push_back({rng.uniform(0, T), static_cast<std::uint32_t>(rng.below(n)), static_cast<std::int8_t>(rng.below(2) ? 1 : -1)});
    for (int h = 0; h < cfg_.hot_pixels; ++h) {
      const auto pix = static_cast<std::uint32_t>(rng.below(n));
      const std::size_t m = poisson(cfg_.hot_rate * T);
      for (std::size_t k = 0; k < m; ++k) evs.push_back({rng.uniform(0, T), pix, static_cast<std::int8_t>(rng.below(2) ? 1 : -1)});
    }
    if (cfg_.jitter > 0)
      for (auto& e : evs) e.t = std::clamp(e.t + cfg_.jitter * rng.normal(), 0.0, T);
    std::stable_sort(evs.begin(), evs.end(), [](const Ev& a, const Ev& b) { return a.t < b.t; });
    rec.events.width = W;
    rec.events.height = H;
    rec.events.reserve(evs.size());
    for (const auto& e : evs) rec.events.push_back(e.t, static_cast<int>(e.pix % W), static_cast<int>(e.pix / W), e.p);
    // Frames and depth at the frame rate (along the held-out path too), and poses at 200 Hz.
    auto frame_at = [&](const geometry::Pose& pose, std::vector<Image>& frames, std::vector<Image>& depths, std::vector<Image>* linears) {
      std::vector<float> dep;
      render_at(pose, rgb, &dep);
      const int C = cfg_.bayer ? 3 : 1;
      Image frame(W, H, C), depth(W, H, 1), linear(W, H, C);
      for (std::size_t i = 0; i < n; ++i) {
        for (int c = 0; c < C; ++c) {
          const double v = C == 3 ? rgb[i][c] : 0.299 * rgb[i][0] + 0.587 * rgb[i][1] + 0.114 * rgb[i][2];
          linear.data[C * i + c] = static_cast<float>(v);
          frame.data[C * i + c] = static_cast<float>(std::clamp(v * cfg_.exposure, 0.0, 1.0));
          if (linears) rec.clipped = rec.clipped || v * cfg_.exposure > 1.0;
        }
        depth.data[i] = dep[i];
      }
      frames.push_back(std::move(frame));
      depths.push_back(std::move(depth));
      if (linears) linears->push_back(std::move(linear));
    };
    for (double ft = 0; ft <= T + 1e-9; ft += 1.0 / cfg_.frame_rate) {
      frame_at(spec_.path.pose(ft), rec.frames, rec.depth, &rec.linear);
      rec.frame_times.push_back(ft);
    }
    if (spec_.novel) {
      // Held-out views: evenly spaced along the novel path, never between the frames of the training path.
      const double nt = spec_.novel->duration;
      const int count = std::max(1, static_cast<int>(std::lround(nt * cfg_.frame_rate)));
      for (int k = 0; k < count; ++k) {
        const geometry::Pose pose = spec_.novel->pose(nt * k / count);
        frame_at(pose, rec.novel.frames, rec.novel.depth, nullptr);
        rec.novel.poses.push_back(pose);
      }
    }
    std::vector<double> pt;
    std::vector<geometry::Pose> poses;
    for (double pt_ = 0; pt_ <= T + 1e-9; pt_ += 0.005) {
      pt.push_back(pt_);
      poses.push_back(spec_.path.pose(pt_));
    }
    rec.trajectory = geometry::Trajectory(pt, poses, "simulated trajectory");
    rec.log_offset = cfg_.log_offset;
    if (!cfg_.hdr && !rec.clipped) rec.linear.clear();  // the frames are the whole truth
    return rec;
  }

 private:
  SceneSpec spec_;
  SensorConfig cfg_;
  geometry::Camera cam_;
};

/// Writes held-out views as a folder: poses.txt (one `index tx ty tz qx qy qz qw` line per view, the camera-to-world
/// pose of groundtruth.txt), images/view_XXXXXXXX.png and depth/view_XXXXXXXX.npy. Every file is written atomically.
inline void write_views(const std::filesystem::path& dir, const Recording::Views& v) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "images");
  fs::create_directories(dir / "depth");
  std::string poses = "# index tx ty tz qx qy qz qw: held-out views, never trained on\n";
  char buf[256];
  for (std::size_t k = 0; k < v.poses.size(); ++k) {
    const auto& p = v.poses[k];
    std::snprintf(buf, sizeof buf, "%zu %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", k, p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(),
                  p.q.w());
    poses += buf;
    char name[64];
    std::snprintf(name, sizeof name, "images/view_%08zu.png", k);
    io::write_png(dir / name, v.frames[k]);
    std::snprintf(name, sizeof name, "depth/view_%08zu.npy", k);
    io::save_npy(dir / name, v.depth[k].data.data(),
                 {static_cast<std::size_t>(v.depth[k].height), static_cast<std::size_t>(v.depth[k].width)});
  }
  write_file_atomic(dir / "poses.txt", poses);
}

/// Writes a recording in the IJRR layout (events.txt, images.txt, images/, groundtruth.txt, calib.txt) plus
/// groundtruth_true.txt (the true poses of a perturbed trajectory),
/// sensor.txt, sensor_model.txt (sensor_model_text) and depth/frame_XXXXXXXX.npy; with HDR truth also
/// linear/frame_XXXXXXXX.npy (float32, H×W or H×W×3) and linear/log_offset.txt; with held-out views novel/
/// (write_views). Every file is written atomically.
inline void write_recording(const std::filesystem::path& dir, const Recording& rec) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "images");
  fs::create_directories(dir / "depth");
  if (!rec.linear.empty()) fs::create_directories(dir / "linear");
  std::string ev;
  ev.reserve(rec.events.size() * 24);
  char buf[128];
  for (std::size_t i = 0; i < rec.events.size(); ++i) {
    const int k = std::snprintf(buf, sizeof buf, "%.9f %d %d %d\n", rec.events.t[i], rec.events.x[i], rec.events.y[i],
                                rec.events.polarity[i] > 0 ? 1 : 0);
    ev.append(buf, static_cast<std::size_t>(k));
  }
  write_file_atomic(dir / "events.txt", ev);
  std::string images;
  for (std::size_t f = 0; f < rec.frames.size(); ++f) {
    char name[64];
    std::snprintf(name, sizeof name, "images/frame_%08zu.png", f);
    io::write_png(dir / name, rec.frames[f]);
    std::snprintf(buf, sizeof buf, "%.9f %s\n", rec.frame_times[f], name);
    images += buf;
    std::snprintf(name, sizeof name, "depth/frame_%08zu.npy", f);
    io::save_npy(dir / name, rec.depth[f].data.data(),
                 {static_cast<std::size_t>(rec.depth[f].height), static_cast<std::size_t>(rec.depth[f].width)});
    if (f < rec.linear.size()) {
      const Image& l = rec.linear[f];
      std::snprintf(name, sizeof name, "linear/frame_%08zu.npy", f);
      std::vector<std::size_t> shape{static_cast<std::size_t>(l.height), static_cast<std::size_t>(l.width)};
      if (l.channels > 1) shape.push_back(static_cast<std::size_t>(l.channels));
      io::save_npy(dir / name, l.data.data(), shape);
    }
  }
  if (!rec.linear.empty()) {
    std::snprintf(buf, sizeof buf, "%.9g\n", rec.log_offset);
    write_file_atomic(dir / "linear" / "log_offset.txt", buf);
  }
  write_file_atomic(dir / "images.txt", images);
  io::write_poses_txt(dir / "groundtruth.txt", rec.trajectory);
  if (!rec.true_trajectory.empty()) io::write_poses_txt(dir / "groundtruth_true.txt", rec.true_trajectory);
  const auto& c = rec.camera;
  std::snprintf(buf, sizeof buf, "%.9f %.9f %.9f %.9f 0 0 0 0 0\n", c.fx(), c.fy(), c.cx(), c.cy());
  write_file_atomic(dir / "calib.txt", buf);
  write_file_atomic(dir / "sensor.txt", std::to_string(c.width()) + " " + std::to_string(c.height()) + "\n");
  write_file_atomic(dir / "sensor_model.txt", sensor_model_text(rec.sensor));
  if (!rec.novel.poses.empty()) write_views(dir / "novel", rec.novel);
}

}  // namespace evnerf::sim
