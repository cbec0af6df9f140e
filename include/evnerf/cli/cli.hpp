// cli/cli.hpp — the whole command line (inspect, simulate, baselines, train, render, eval) for any list of
// variants, so that a researcher's own variant gets it from a program of a few lines:
//
//   #include <evnerf/cli/cli.hpp>
//   using Mine = evnerf::EvNerf<...>;
//   int main(int argc, char** argv) {
//     return evnerf::cli::main<evnerf::cli::Variant<Mine, "mine">, evnerf::cli::Variant<evnerf::presets::Fast, "fast">>(argc, argv);
//   }
//
// The first variant is `train`'s default. Built on CLI11 (flags, --help, number validation), nlohmann::json
// (metrics) and fmt (messages). Not included by the umbrella header: only programs that want the command
// line pay for CLI11. Depends on everything.
#pragma once
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "../evnerf.hpp"

namespace evnerf::cli {

namespace fs = std::filesystem;

/// A string usable as a template argument (a variant's name).
template <std::size_t N>
struct Name {
  char s[N]{};
  constexpr Name(const char (&a)[N]) { std::copy_n(a, N, s); }
};

/// A model type and the name the command line knows it by.
template <class Model, Name N>
struct Variant {
  using model = Model;
  static constexpr const char* name = N.s;
};

/// Calls fn.template operator()<Model>(name) for the variant called `name`.
template <class... V, class Fn>
int with_variant(const std::string& name, Fn&& fn) {
  int result = 0;
  const bool found = ((name == V::name ? (result = fn.template operator()<typename V::model>(std::string(V::name)), true) : false) || ...);
  if (!found) {
    std::string known;
    ((known += (known.empty() ? "" : ", ") + std::string(V::name)), ...);
    throw Error("unknown variant '" + name + "' (this program has: " + known + ")");
  }
  return result;
}

/// The variant that can load a checkpoint: of those whose architecture (version 5 on), loss (version 4
/// on) and parameter count match the file, the one named in the file, else the first (a file written
/// under another name, or by another program with the same model).
template <class... V>
std::string checkpoint_variant(const fs::path& path) {
  const auto h = io::peek_checkpoint(path);
  auto fits = [&]<class Model>() {
    const bool params = h.n_params == Model::n_fields * Model::field_params + 2 * h.n_slices;
    return params && (h.version < 4 || h.loss == Model::loss_description()) &&
           (h.version < 5 || h.architecture == Model::architecture());
  };
  std::string pick;
  ((pick.empty() && h.name == V::name && fits.template operator()<typename V::model>() ? (pick = V::name, 0) : 0), ...);
  ((pick.empty() && fits.template operator()<typename V::model>() ? (pick = V::name, 0) : 0), ...);
  if (pick.empty())
    throw Error(path.string(), 0, "written by variant '" + h.name + "' with the loss '" + h.loss + "'" +
                                      (h.architecture.empty() ? "" : " and the architecture '" + h.architecture + "'") +
                                      ", which no variant of this program matches");
  return pick;
}

namespace detail {

/// While alive, SIGINT and SIGTERM only record that a stop was asked for (the first one; the handler then
/// restores the default action, so a second signal ends the process at once). The previous handlers come
/// back on destruction.
class StopOnSignal {
 public:
  StopOnSignal() {
    received() = 0;
    old_int_ = std::signal(SIGINT, &StopOnSignal::handle);
    old_term_ = std::signal(SIGTERM, &StopOnSignal::handle);
  }
  ~StopOnSignal() {
    std::signal(SIGINT, old_int_ == SIG_ERR ? SIG_DFL : old_int_);
    std::signal(SIGTERM, old_term_ == SIG_ERR ? SIG_DFL : old_term_);
  }
  StopOnSignal(const StopOnSignal&) = delete;
  StopOnSignal& operator=(const StopOnSignal&) = delete;
  bool requested() const { return received() != 0; }
  int signal_number() const { return static_cast<int>(received()); }
  const char* signal_name() const { return received() == SIGTERM ? "SIGTERM" : "SIGINT"; }

 private:
  static volatile std::sig_atomic_t& received() {
    static volatile std::sig_atomic_t s = 0;
    return s;
  }
  static void handle(int sig) {
    received() = sig;
    std::signal(sig, SIG_DFL);
  }
  void (*old_int_)(int) = SIG_DFL;
  void (*old_term_)(int) = SIG_DFL;
};

/// Frames of a recording that lie strictly inside (lo, hi] (where event methods can work).
inline std::vector<std::size_t> frames_inside(const io::Dataset& d, double lo, double hi) {
  std::vector<std::size_t> ids;
  for (std::size_t i = 0; i < d.frames.size(); ++i)
    if (d.frames.t[i] > lo + 1e-9 && d.frames.t[i] <= hi + 1e-9) ids.push_back(i);
  return ids;
}

inline void print_table(const eval::AlignedScores& a, const std::vector<std::size_t>& subset = {}) {
  fmt::print("{:<22} {:>10} {:>10} {:>10}   (alignment: {})\n", "method", "MSE", "PSNR", "SSIM", eval::to_string(a.alignment));
  for (std::size_t m = 0; m < a.names.size(); ++m) {
    std::vector<eval::Scores> s;
    if (subset.empty()) {
      s = a.per_frame[m];
    } else {
      for (auto q : subset) s.push_back(a.per_frame[m][q]);
    }
    const auto mean = eval::mean(s);
    fmt::print("{:<22} {:>10.5f} {:>10.3f} {:>10.4f}\n", a.names[m], mean.mse, mean.psnr, mean.ssim);
  }
}

/// The requested alignment first, then the others of global-log-affine, log-affine, min-max and eventnerf.
inline std::vector<eval::Alignment> alignments_from(const std::string& flag) {
  const auto first = eval::parse_alignment(flag);
  std::vector<eval::Alignment> all{first};
  for (auto al : {eval::Alignment::GlobalLogAffine, eval::Alignment::LogAffine, eval::Alignment::MinMax, eval::Alignment::EventNerf})
    if (al != first) all.push_back(al);
  return all;
}

/// Whether a recording is scored in colour: its frames are RGB.
inline bool colour_frames(const io::Dataset& d, const std::vector<std::size_t>& ids) {
  return !ids.empty() && io::frame_image(d.frames, ids.front()).channels == 3;
}

/// The baselines' reconstructions at the given frames. In colour, each pixel integrates its own events
/// (its channel of the mosaic), and the mosaic is then demosaiced.
inline std::vector<eval::Method> baseline_methods(const io::Dataset& d, const std::vector<std::size_t>& ids, double contrast, bool colour = false) {
  std::vector<double> times;
  for (auto i : ids) times.push_back(d.frames.t[i]);
  std::vector<eval::Method> m{{"direct_integration", eval::direct_integration(d.events, times, contrast)},
                              {"high_pass_filter", eval::high_pass_filter(d.events, times, contrast)}};
  if (colour) {
    const auto p = io::bayer_of(d);
    for (auto& method : m)
      for (auto& img : method.images) img = geometry::demosaic(img, p);
  }
  return m;
}

/// The ground truth of the frames `ids` (grey): the frames, or the simulator's unclipped linear radiance where
/// the recording has it, then with the tone map that scores in the log space (`hdr` set).
struct Truth {
  std::vector<Image> images;
  std::optional<eval::HdrTone> hdr;
  /// What the montage shows of the truth.
  Image shown(std::size_t k) const { return hdr ? hdr->apply(images[k]) : images[k]; }
};
inline Truth load_truth(const io::Dataset& d, const std::vector<std::size_t>& ids, bool colour = false) {
  Truth t;
  const bool linear = d.linear.size() == d.frames.size() && !d.linear.empty();
  auto keep = [&](const Image& img) { return colour && img.channels == 3 ? img : eval::to_grey(img); };
  for (auto i : ids) {
    if (!linear) {
      t.images.push_back(keep(io::frame_image(d.frames, i)));
      continue;
    }
    const auto a = io::load_npy<float>(d.linear[i]);
    const int C = a.shape.size() == 3 ? static_cast<int>(a.shape[2]) : 1;
    if (a.shape.size() < 2 || a.shape.size() > 3 || a.shape[0] != static_cast<std::size_t>(d.camera.height()) ||
        a.shape[1] != static_cast<std::size_t>(d.camera.width()) || (C != 1 && C != 3))
      throw Error(d.linear[i].string(), 0, "linear truth: expected a float32 array of H×W or H×W×3 with the sensor's size");
    Image img(d.camera.width(), d.camera.height(), C);
    img.data = a.data;
    t.images.push_back(keep(img));
  }
  if (linear) t.hdr = eval::HdrTone::of(t.images, d.linear_log_offset);
  return t;
}

/// Scores under every alignment (the first is the primary), prints the tables and returns metrics.json.
inline nlohmann::json score_and_report(const std::vector<eval::Method>& methods, const Truth& truth,
                                       const std::vector<eval::Alignment>& als, const std::vector<std::size_t>& ids,
                                       eval::AlignedScores& primary) {
  const eval::HdrTone* hdr = truth.hdr ? &*truth.hdr : nullptr;
  primary = eval::score_methods(methods, truth.images, als.front(), true, hdr);
  std::vector<eval::AlignedScores> others;
  for (std::size_t k = 1; k < als.size(); ++k) others.push_back(eval::score_methods(methods, truth.images, als[k], false, hdr));
  if (hdr)
    fmt::print("scored against the linear (HDR) truth in log(x + {}), its range over the sequence on [0, 1]\n", short_number(hdr->offset));
  print_table(primary);
  for (const auto& o : others) print_table(o);
  auto j = eval::metrics_json(primary, others, ids);
  j["truth"] = hdr ? nlohmann::json{{"kind", "linear-hdr"}, {"log_offset", hdr->offset}, {"log_range", {hdr->lo, hdr->hi}}}
                   : nlohmann::json{{"kind", "frames"}};
  const int channels = truth.images.empty() ? 1 : truth.images.front().channels;
  j["channels"] = channels;
  if (channels == 3) {  // colour: the same methods in grey (Rec. 601 luminance), as secondary scores
    Truth grey;
    for (const auto& im : truth.images) grey.images.push_back(eval::to_grey(im));
    if (hdr) grey.hdr = eval::HdrTone::of(grey.images, hdr->offset);
    std::vector<eval::Method> gm = methods;
    for (auto& m : gm)
      for (auto& im : m.images) im = eval::to_grey(im);
    fmt::print("in grey (luminance of every method and of the truth):\n");
    const auto g = eval::score_methods(gm, grey.images, als.front(), false, grey.hdr ? &*grey.hdr : nullptr);
    print_table(g);
    j["grey"] = eval::metrics_json(g, {}, ids);
  }
  return j;
}

/// Intensity and depth of one view. Luminance beyond 1 (a field of unbounded radiance) is written as its log
/// put on [0, 1] (PNG) and as linear float32 (`<stem>.npy`).
inline void write_rendering(const fs::path& out, const std::string& stem, const Rendering& r, float dlo, float dhi) {
  const auto& l = r.luminance;
  if (!l.data.empty() && *std::max_element(l.data.begin(), l.data.end()) > 1.0f) {
    std::vector<std::size_t> shape{static_cast<std::size_t>(l.height), static_cast<std::size_t>(l.width)};
    if (l.channels > 1) shape.push_back(static_cast<std::size_t>(l.channels));
    io::save_npy(out / (stem + ".npy"), l.data.data(), shape);
    io::write_png(out / (stem + ".png"), eval::HdrTone{eval::kLogEps}.log_min_max(l));
  } else {
    io::write_png(out / (stem + ".png"), l);
  }
  io::write_png(out / (stem + "_depth.png"), io::colorize(r.depth, dlo, dhi));
  io::save_npy(out / (stem + "_depth.npy"), r.depth.data.data(),
               {static_cast<std::size_t>(r.depth.height), static_cast<std::size_t>(r.depth.width)});
}

/// The paper's colour model (train --per-channel): a grey model per colour channel, each trained on its
/// channel's quarter-resolution sites (io::channel_dataset), in these subfolders of the run.
inline constexpr const char* kChannelDirs[3] = {"r", "g", "b"};

/// channels.json: the full sensor's camera, the mosaic, and each channel's checkpoint (relative paths).
inline nlohmann::json per_channel_manifest(const geometry::Camera& c, const geometry::BayerPattern& p) {
  nlohmann::json j = {{"kind", "evnerf per-channel colour"},
                      {"pattern", p.name()},
                      {"camera", {{"width", c.width()}, {"height", c.height()}, {"fx", c.fx()}, {"fy", c.fy()}, {"cx", c.cx()},
                                  {"cy", c.cy()}, {"distortion", c.distortion()}}},
                      {"channels", nlohmann::json::array()}};
  for (int k = 0; k < 3; ++k) j["channels"].push_back(std::string(kChannelDirs[k]) + "/model.ckpt");
  return j;
}

/// What render and eval need of a trained model: its name, the training description (boundary times and
/// poses; the camera is the recording's sensor), near and far for the depth maps, and a render at any pose.
struct Renderable {
  std::string name;
  train::Described desc;
  double near = 0, far = 1;
  std::function<Rendering(const geometry::Pose&)> render;
};

/// One checkpoint, by the variant of V... that can load it.
template <class... V>
Renderable load_model(const fs::path& ckpt) {
  Renderable r;
  with_variant<V...>(checkpoint_variant<V...>(ckpt), [&]<class Model>(const std::string& name) {
    auto model = std::make_shared<Model>();
    r.desc = train::parse_description(train::load_checkpoint(ckpt, *model, ""), ckpt.string());
    r.name = name;
    r.near = model->box().near;
    r.far = model->box().far;
    auto dirs = std::make_shared<const std::vector<Vec3f>>(render::pixel_directions(r.desc.camera));
    r.render = [model, dirs, cam = r.desc.camera](const geometry::Pose& pose) { return model->render(cam, *dirs, pose); };
    return 0;
  });
  return r;
}

/// A model.ckpt, or the channels.json of train --per-channel: each channel's model renders its quarter-
/// resolution sites, geometry::upsample_sites brings them to the full sensor, and the three make one RGB
/// image (depth and opacity: the green model's, upsampled). Boundary times: those all three channels share.
template <class... V>
Renderable load_renderable(const fs::path& ckpt) {
  if (ckpt.extension() != ".json") return load_model<V...>(ckpt);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file(ckpt));
  } catch (const nlohmann::json::exception& e) {
    throw Error(ckpt.string(), 0, std::string("not a channels.json of train --per-channel: ") + e.what());
  }
  geometry::Camera cam;
  geometry::BayerPattern pattern;
  std::vector<fs::path> files;
  try {
    if (j.value("kind", "") != "evnerf per-channel colour") throw Error("its \"kind\" is not \"evnerf per-channel colour\"");
    if (!geometry::BayerPattern::parse(j.at("pattern").get<std::string>(), pattern))
      throw Error("unknown Bayer pattern '" + j.at("pattern").get<std::string>() + "'");
    const auto& c = j.at("camera");
    cam = geometry::Camera(c.at("width").get<int>(), c.at("height").get<int>(), c.at("fx").get<double>(), c.at("fy").get<double>(),
                           c.at("cx").get<double>(), c.at("cy").get<double>(), c.at("distortion").get<std::array<double, 5>>());
    if (!j.at("channels").is_array() || j.at("channels").size() != 3) throw Error("\"channels\" must list three checkpoints (R, G, B)");
    for (const auto& f : j.at("channels")) files.push_back(ckpt.parent_path() / f.get<std::string>());
  } catch (const nlohmann::json::exception& e) {
    throw Error(ckpt.string(), 0, std::string("channels.json: ") + e.what());
  } catch (const Error& e) {
    throw Error(ckpt.string(), 0, std::string("channels.json: ") + e.what());
  }
  std::array<Renderable, 3> ch;
  std::array<geometry::Site, 3> sites;
  double lo = -1e300, hi = 1e300;
  for (int k = 0; k < 3; ++k) {
    ch[k] = load_model<V...>(files[k]);
    sites[k] = geometry::site_of(pattern, k);
    const auto expect = geometry::site_camera(cam, sites[k]);
    if (ch[k].desc.camera.width() != expect.width() || ch[k].desc.camera.height() != expect.height())
      throw Error(files[k].string(), 0, "its camera is not the " + std::string(1, "RGB"[k]) + " sites of the sensor in " + ckpt.string());
    if (ch[k].desc.times.empty()) throw Error(files[k].string(), 0, "no slice boundaries");
    lo = std::max(lo, ch[k].desc.times.front());
    hi = std::min(hi, ch[k].desc.times.back());
  }
  Renderable r;
  r.name = ch[1].name + "_per_channel";
  r.near = ch[1].near;
  r.far = ch[1].far;
  r.desc = ch[1].desc;
  r.desc.camera = cam;
  r.desc.times.clear();
  r.desc.poses.clear();
  for (std::size_t i = 0; i < ch[1].desc.times.size(); ++i)
    if (ch[1].desc.times[i] >= lo - 1e-9 && ch[1].desc.times[i] <= hi + 1e-9) {
      r.desc.times.push_back(ch[1].desc.times[i]);
      r.desc.poses.push_back(ch[1].desc.poses[i]);
    }
  r.render = [ch, sites, W = cam.width(), H = cam.height()](const geometry::Pose& pose) {
    Rendering out;
    out.luminance = Image(W, H, 3);
    for (int k = 0; k < 3; ++k) {
      const auto rk = ch[k].render(pose);
      const auto up = geometry::upsample_sites(rk.luminance, sites[k], W, H);
      for (std::size_t i = 0; i < up.pixels(); ++i) out.luminance.data[3 * i + k] = up.data[i];
      if (k == 1) {
        out.depth = geometry::upsample_sites(rk.depth, sites[k], W, H);
        out.opacity = geometry::upsample_sites(rk.opacity, sites[k], W, H);
      }
    }
    return out;
  };
  return r;
}

const char* const kAlignHelp = "alignment of the primary scores: global-log-affine (one log-affine map per channel over the "
                               "sequence), log-affine (per image), eventnerf (EventNeRF's: per channel over the sequence in log(x^2.2 + 0.1)), "
                               "min-max, none";

}  // namespace detail

/// The command line over the variants V... (the first is train's default). Returns the process exit code:
/// 0 success, 1 an error (printed), 2 a usage error (printed with the command's flags), 3 training diverged,
/// 4 training collapsed (train::CollapseCheck; --allow-collapse goes on and returns 0).
template <class... V>
int main(int argc, char** argv, const std::string& description = "evnerf: neural radiance fields from event cameras") {
  static_assert(sizeof...(V) >= 1, "cli::main needs at least one variant");
  using namespace detail;
  std::string variant_list;
  ((variant_list += (variant_list.empty() ? "" : ", ") + std::string(V::name)), ...);
  const std::string default_variant = std::get<0>(std::tuple<V...>{}).name;

  CLI::App app{description};
  app.require_subcommand(1);
  app.fallthrough(false);

  // The recording every verb reads, and how to read it (any format io::load reads).
  std::string folder;
  io::LoadOptions load_opt;
  std::vector<double> time_window;
  auto add_recording = [&](CLI::App* sub, const std::string& help) {
    sub->add_option("recording", folder, help)->required();
    sub->add_option("--calib", load_opt.calib,
                    "calibration instead of the recording's own: a calib.txt file (fx fy cx cy [k1 k2 p1 p2 [k3]]) or COLMAP's cameras.txt");
    sub->add_option("--poses", load_opt.poses,
                    "poses instead of the recording's own: a pose file (t px py pz qx qy qz qw, camera to world; for a bag in its clock), or a "
                    "COLMAP text model (folder or images.txt), each image at the time of the recording's frame of its file name");
    sub->add_option("--time-window", time_window,
                    "only the events from T0 to T1 (seconds on the recording's clock as inspect shows it; DSEC HDF5 files are read "
                    "through ms_to_idx, only the window)")
        ->expected(2);
    sub->add_option("--format", load_opt.format,
                    "the reader, where the content does not decide it (a folder holding two layouts): ijrr, eventnerf, robust-e-nerf, hdf5, rosbag")
        ->check(CLI::IsMember(io::load_formats()));
    sub->add_option("--events-topic", load_opt.events_topic, "ROS bag: the event topic (default: the one topic of event arrays)");
    sub->add_option("--images-topic", load_opt.images_topic, "ROS bag: the frames' topic, or 'none' (default: the one sensor_msgs/Image topic)");
    sub->add_option("--camera-info-topic", load_opt.camera_info_topic, "ROS bag: the sensor_msgs/CameraInfo topic, or 'none' (default: the one such topic)");
    sub->add_option("--poses-topic", load_opt.poses_topic,
                    "ROS bag: the pose topic (PoseStamped, Odometry, TransformStamped), or 'none' (default: the one such topic)");
  };
  const std::string rec_help =
      "recording: an IJRR-layout folder, an EventNeRF scene or Robust e-NeRF sequence folder, an event HDF5 file or a ROS bag (calib.txt, groundtruth.txt beside a "
      "file when it lacks them)";

  // inspect
  auto* inspect = app.add_subcommand("inspect", "summary of a recording: sensor, events, frames, poses, warnings");
  add_recording(inspect, rec_help);

  // convert
  fs::path convert_out;
  auto* convert = app.add_subcommand("convert", "write a recording in another format: an IJRR-layout folder, HDF5 (event_utils/HQF layout) "
                                                "when the output ends in .h5 or .hdf5, a ROS bag when it ends in .bag");
  add_recording(convert, "recording to read (any format evnerf reads)");
  convert->add_option("output", convert_out,
                      "output folder (IJRR layout), file.h5 (calib.txt, groundtruth.txt written beside it) or file.bag (ROS bag, DAVIS topics)")
      ->required();
  std::string bag_compression = "lz4";
  convert->add_option("--compression", bag_compression, "ROS bag output: chunk compression")
      ->check(CLI::IsMember({"none", "bz2", "lz4"}))
      ->capture_default_str();

  // simulate
  std::string scene;
  fs::path out;
  sim::SensorConfig sc;
  bool realistic = false, bayer = false, hdr = false;
  std::uint64_t sim_seed = 1;
  int width = sc.width, height = sc.height;
  double focal = 0;
  fs::path textures;
  auto* simulate = app.add_subcommand("simulate", "simulate events, 24 Hz frames, depth, poses and calibration (IJRR layout)");
  simulate->add_option("scene", scene,
                       "built-in scene (planes, object, room; blocks, the colour scene, always through an RGGB mosaic), 'random' (a procedural scene from --seed, saved as <out>/scene.txt) "
                       "or a scene description file")
      ->required();
  simulate->add_option("--out", out, "output folder")->required();
  simulate->add_flag("--realistic", realistic, "sensor effects: threshold mismatch, refractory period, leak and shot noise");
  simulate->add_flag("--bayer", bayer, "colour sensor: RGGB mosaic in front of the event pixels");
  simulate->add_flag("--hdr", hdr,
                     "high dynamic range lighting (ambient ×0.05, directional light ×4: deep shadows, highlights that clip the "
                     "frames); writes the unclipped linear truth that eval scores against");
  simulate->add_option("--seed", sim_seed, "random seed (sensor noise; with 'random', also the scene)")->capture_default_str();
  simulate->add_option("--textures", textures, "with 'random': photos (.png) to texture some surfaces with");
  simulate->add_option("--log-offset", sc.log_offset, "the sensor's dark end: pixels see log(I + offset)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  simulate->add_option("--noise-rate", sc.noise_rate, "background events per pixel per second")->capture_default_str()->check(CLI::NonNegativeNumber);
  simulate->add_option("--noise-ratio", sc.noise_ratio, "uniform random events added, as a fraction of the signal events")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  simulate->add_option("--width", width, "sensor width (pixels)")->capture_default_str()->check(CLI::Range(8, 8192));
  simulate->add_option("--height", height, "sensor height (pixels)")->capture_default_str()->check(CLI::Range(8, 8192));
  simulate->add_option("--focal", focal, "focal length in pixels (default: scaled with the width, 200 at 240)")->check(CLI::PositiveNumber);

  // baselines
  std::string align = "global-log-affine";
  double contrast = 0.2;
  fs::path baselines_out;
  auto* baselines = app.add_subcommand("baselines", "direct integration and the high-pass filter, scored against the frames");
  add_recording(baselines, rec_help);
  baselines->add_option("--out", baselines_out, "output folder (default: <folder>/baselines)");
  baselines->add_option("--align", align, kAlignHelp)->capture_default_str();
  baselines->add_option("--contrast", contrast, "contrast threshold the baselines integrate with (log units)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);

  // train
  train::Config cfg;
  std::string variant = default_variant;
  bool resume = false, quiet = false;
  auto* trainc = app.add_subcommand("train", "train a variant on a recording; writes model.ckpt and log.jsonl to --out");
  add_recording(trainc, rec_help);
  trainc->add_option("--out", out, "output folder")->required();
  trainc->add_option("--preset,--variant", variant, "variant: " + variant_list)->capture_default_str();
  trainc->add_option("--iters", cfg.iterations, "training steps in total")->capture_default_str()->check(CLI::PositiveNumber);
  trainc->add_option("--pixels", cfg.pixels_per_step, "pixels per step (each rendered at both poses)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1 << 22));
  trainc->add_option("--seed", cfg.seed, "random seed")->capture_default_str();
  trainc->add_option("--threads", cfg.threads, "threads (0 = all)")->capture_default_str()->check(CLI::Range(0, 4096));
  trainc->add_option("--near", cfg.near, "nearest sample depth (world units)")->capture_default_str()->check(CLI::PositiveNumber);
  trainc->add_option("--far", cfg.far, "farthest sample depth (world units)")->capture_default_str()->check(CLI::PositiveNumber);
  trainc->add_option("--lr", cfg.lr, "Adam learning rate")->capture_default_str()->check(CLI::PositiveNumber);
  trainc->add_option("--lr-decay-steps", cfg.lr_decay_steps, "steps over which the learning rate decays by 10×")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  trainc->add_option("--checkpoint-every", cfg.checkpoint_every, "steps between checkpoints (0: only at the end)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  trainc->add_option("--subslices", cfg.subslices, "slices per frame interval (boundaries between frames, poses interpolated)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  trainc->add_option("--holdout", cfg.holdout_every, "hold out every K-th slice boundary (novel views; 0 = none)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  trainc->add_flag("--clamp-poses", cfg.clamp_poses, "slice boundaries outside the poses take the nearest pose");
  trainc->add_flag("--density-per-box", cfg.density_per_box, "density per unit of the normalised scene box, not per world unit");
  trainc->add_flag("--allow-collapse", cfg.allow_collapse,
                   "go on when a collapse check fires (renders almost constant, or the event loss not improving)");
  std::string box_fit = cfg.box == train::Config::BoxFit::Frusta ? "frusta" : "cameras";
  trainc->add_option("--box", box_fit, "scene box: cameras (centres plus far in every direction) or frusta (tight around the views)")
      ->check(CLI::IsMember({"cameras", "frusta"}))
      ->capture_default_str();
  bool per_channel = false;
  trainc->add_flag("--per-channel", per_channel,
                   "colour recording, the paper's way: a grey model per colour channel on that channel's quarter-resolution sites "
                   "(<out>/r, g, b), listed in <out>/channels.json, which render and eval take as the checkpoint");
  trainc->add_flag("--resume", resume, "continue from <out>/model.ckpt when it exists");
  trainc->add_flag("--quiet", quiet, "no progress bar");

  // render
  fs::path ckpt;
  int novel = 8;
  auto* renderc = app.add_subcommand("render", "intensity and depth at every slice boundary and along a novel path");
  renderc->add_option("checkpoint", ckpt, "model.ckpt, or channels.json of train --per-channel")->required();
  renderc->add_option("--out", out, "output folder")->required();
  renderc->add_option("--novel", novel, "views along the novel path")->capture_default_str()->check(CLI::Range(0, 100000));

  // eval
  int holdout = 0;
  auto* evalc = app.add_subcommand("eval", "render at the frames; metrics.json (ours and both baselines) and a montage");
  evalc->add_option("checkpoint", ckpt, "model.ckpt, or channels.json of train --per-channel")->required();
  add_recording(evalc, rec_help);
  evalc->add_option("--out", out, "output folder")->required();
  evalc->add_option("--align", align, kAlignHelp)->capture_default_str();
  evalc->add_option("--holdout", holdout, "as given to train: also score the never-trained frames on their own")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints the help, or the message and a pointer to --help
    return code == 0 ? 0 : 2;
  }
  const std::string cmd = app.get_subcommands().front()->get_name();
  if (time_window.size() == 2) {
    load_opt.t_begin = time_window[0];
    load_opt.t_end = time_window[1];
  }
  try {
    if (*inspect) {
#ifdef EVNERF_HAVE_ROSBAG
      if (fs::is_regular_file(folder) && io::is_rosbag(folder)) {
        fmt::print("ROS bag topics (messages, type):\n");
        for (const auto& t : io::rosbag_topics(folder)) fmt::print("  {:<32} {:>9}  {}\n", t.topic, t.messages, t.type);
      }
#endif
      auto d = io::load(folder, load_opt);
      fmt::print("recording     {}{}\n", folder, d.from_cache ? " (events from cache)" : "");
      if (d.time_origin != 0) fmt::print("time origin   {} s (the recording's clock at t = 0)\n", d.time_origin);
      if (!d.bayer_pattern.empty()) fmt::print("colour filter {} (events through a Bayer mosaic)\n", d.bayer_pattern);
      std::fputs(io::format_summary(io::summarize(d)).c_str(), stdout);
      return 0;
    }
    if (*convert) {
      const auto d = io::load(folder, load_opt);
      const std::string ext = convert_out.extension().string();
      if (ext == ".h5" || ext == ".hdf5") {
#ifdef EVNERF_HAVE_HDF5
        io::write_hdf5_recording(convert_out, d);
#else
        throw Error(convert_out.string(), 0, "this build of evnerf has no HDF5 support (install libhdf5-dev and rebuild)");
#endif
      } else if (ext == ".bag") {
#ifdef EVNERF_HAVE_ROSBAG
        io::write_rosbag_recording(convert_out, d, bag_compression);
#else
        throw Error(convert_out.string(), 0, "this build of evnerf has no ROS bag support (install libbz2-dev and liblz4-dev and rebuild)");
#endif
      } else {
        io::write_ijrr(convert_out, d);
      }
      fmt::print("wrote {} events, {} frames, {} poses → {}\n", d.events.size(), d.frames.size(), d.trajectory.size(), convert_out.string());
      return 0;
    }
    if (*simulate) {
      std::string scene_text;
      require(textures.empty() || scene == "random", "simulate: --textures goes with the 'random' scene");
      auto spec = scene == "random" ? sim::random_scene(sim_seed, sim::texture_pictures(textures), &scene_text) : sim::load_scene(scene);
      sim::SensorConfig cfg_s = realistic ? sim::SensorConfig::realistic() : sim::SensorConfig{};
      cfg_s.noise_rate = sc.noise_rate;
      cfg_s.noise_ratio = sc.noise_ratio;
      cfg_s.log_offset = sc.log_offset;
      cfg_s.bayer = bayer || scene == "blocks";  // the built-in colour scene is seen through an RGGB mosaic
      if (hdr) {
        cfg_s.hdr = true;
        sim::hdr_lighting(spec.scene);
      }
      cfg_s.seed = sim_seed;
      cfg_s.fx = cfg_s.fy = focal > 0 ? focal : cfg_s.fx * width / 240.0;
      cfg_s.width = width;
      cfg_s.height = height;
      cfg_s.cx = cfg_s.cy = -1;
      const auto t0 = std::chrono::steady_clock::now();
      auto rec = sim::Simulator(spec, cfg_s).run(true);
      sim::write_recording(out, rec);
      if (!scene_text.empty()) write_file_atomic(out / "scene.txt", scene_text);
      if (!rec.linear.empty())
        fmt::print("{}: wrote the unclipped linear truth (linear/){}; eval scores against it\n", out.string(),
                   rec.clipped ? ", as highlights clip the frames" : "");
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      fmt::print("scene {}: {} events ({} ON) over {:.2f} s, {} frames, {} renders, {:.1f} s wall → {}\n", spec.scene.name,
                 rec.events.size(), rec.events.count_positive(), spec.path.duration, rec.frames.size(), rec.renders, secs,
                 out.string());
      return 0;
    }
    if (*baselines) {
      const auto d = io::load(folder, load_opt);
      const auto als = alignments_from(align);
      const auto ids = frames_inside(d, d.events.t_begin(), d.events.t_end());
      require(!ids.empty(), folder + ": no frames inside the events' time span");
      const bool colour = colour_frames(d, ids);
      const Truth truth = load_truth(d, ids, colour);
      eval::AlignedScores primary;
      const auto j = score_and_report(baseline_methods(d, ids, contrast, colour), truth, als, ids, primary);
      const fs::path rec_path(folder);  // a folder gets baselines/ inside, a file <name>_baselines/ beside it
      const fs::path bo = !baselines_out.empty()          ? baselines_out
                          : fs::is_directory(rec_path) ? rec_path / "baselines"
                                                       : rec_path.parent_path() / (rec_path.stem().string() + "_baselines");
      write_file_atomic(bo / "baselines.json", j.dump(2) + "\n");
      const std::size_t mid = ids.size() / 2;
      io::write_png(bo / "montage.png", io::montage({truth.shown(mid), primary.aligned[0][mid], primary.aligned[1][mid]}, colour ? 3 : 1));
      fmt::print("wrote {}/baselines.json and montage.png (ground truth | direct integration | high-pass filter)\n", bo.string());
      return 0;
    }
    if (*trainc) {
      cfg.progress = !quiet;
      cfg.box = box_fit == "frusta" ? train::Config::BoxFit::Frusta : train::Config::BoxFit::Cameras;
      require(cfg.far > cfg.near, "train: --far must be greater than --near");
      const auto d = io::load(folder, load_opt);
      // One run: a model trained on `td` into `dir`; returns the exit code.
      auto train_one = [&]<class Model>(const std::string& name, const TrainingData& td, const fs::path& dir, std::size_t n_events) -> int {
        const std::string meta = train::describe(td, fs::absolute(folder).string());
        train::Trainer<Model> trainer(td, cfg, dir, name, meta);
        std::string note;
        if (resume && trainer.resume(&note)) {
          if (!note.empty()) fmt::print(stderr, "warning: {}\n", note);
          fmt::print(stderr, "resuming {} at step {}\n", name, trainer.model().step());
        }
        fmt::print(stderr, "training {} on {} slices, {} events, {} threads\n", name, td.slices.size(), n_events,
                   cfg.threads > 0 ? cfg.threads : thread_count());
        // SIGINT (Ctrl-C) and SIGTERM (a batch system's stop) end the run after the current step with a
        // checkpoint; a second signal kills at once (the handler restores the default action).
        const StopOnSignal stop_request;
        const auto r = trainer.run([&](const train::StepReport&) { return !stop_request.requested(); });
        fmt::print("trained {}: {} steps in {:.1f} s ({:.0f} rays/s), final loss {:.5f}{} → {}\n", name, r.steps, r.seconds,
                   r.rays_per_second, r.final_loss, r.diverged ? " (DIVERGED)" : "", (dir / "model.ckpt").string());
        if (r.diverged) return 3;
        if (r.stopped) {
          fmt::print(stderr, "train: stopped by {} at step {}; the checkpoint is written, continue with --resume\n",
                     stop_request.signal_name(), trainer.model().step());
          return 128 + stop_request.signal_number();
        }
        if (r.collapsed && !cfg.allow_collapse) {
          fmt::print(stderr, "train: the run collapsed ({}); the checkpoint is kept, but this is not a usable model\n",
                     r.checks.back().describe());
          return 4;
        }
        return 0;
      };
      return with_variant<V...>(variant, [&]<class Model>(const std::string& name) -> int {
        if (!per_channel) return train_one.template operator()<Model>(name, train::prepare(d, cfg), out, d.events.size());
        if constexpr (Model::channels != 1) {
          throw Error("train --per-channel: the variant '" + name + "' renders colour; name a grey one (each channel gets a grey model)");
        } else {
          const auto pattern = io::bayer_of(d);
          for (int c = 0; c < 3; ++c) {
            const auto sub = io::channel_dataset(d, pattern, c);
            fmt::print(stderr, "channel {}: {}x{} sites, {} events\n", "RGB"[c], sub.camera.width(), sub.camera.height(), sub.events.size());
            const int code = train_one.template operator()<Model>(name, train::prepare(sub, cfg), out / kChannelDirs[c], sub.events.size());
            if (code != 0) return code;
          }
          write_file_atomic(out / "channels.json", per_channel_manifest(d.camera, pattern).dump(2) + "\n");
          fmt::print("wrote {} (render and eval take it as the checkpoint)\n", (out / "channels.json").string());
          return 0;
        }
      });
    }
    if (*renderc) {
      const auto model = load_renderable<V...>(ckpt);
      const auto& desc = model.desc;
      const float dlo = float(model.near), dhi = float(model.far * 0.6);
      for (std::size_t i = 0; i < desc.poses.size(); ++i)
        write_rendering(out, fmt::format("boundary_{:04d}", i), model.render(desc.poses[i]), dlo, dhi);
      for (int k = 0; k < novel; ++k)
        write_rendering(out, fmt::format("novel_{:04d}", k), model.render(render::novel_pose(desc.poses.front(), desc.poses.back(), k, novel)),
                        dlo, dhi);
      fmt::print("rendered {} boundary views and {} novel views (intensity, depth PNG + .npy) → {}\n", desc.poses.size(), novel,
                 out.string());
      return 0;
    }
    if (*evalc) {
      const auto d = io::load(folder, load_opt);
      const auto als = alignments_from(align);
      {
        const auto model = load_renderable<V...>(ckpt);
        const auto& desc = model.desc;
        const std::string& name = model.name;
        require(desc.camera.width() == d.camera.width() && desc.camera.height() == d.camera.height(),
                "eval: the checkpoint's camera does not match the recording's sensor size");
        // Frames at the trained slice boundaries (the first boundary has no events before it: skipped).
        const auto ids = frames_inside(d, desc.times.front(), desc.times.back());
        require(!ids.empty(), "eval: no frames inside the trained time range");
        eval::Method ours{"evnerf_" + name, {}};
        std::vector<Image> depths;
        const auto t0 = std::chrono::steady_clock::now();
        for (auto i : ids) {
          const double t = d.frames.t[i];
          const auto pose = d.trajectory.covers(t) ? d.trajectory.pose_at(t) : d.trajectory.pose_at(t, geometry::OutOfRange::Clamp);
          const auto r = model.render(pose);
          ours.images.push_back(r.luminance);
          depths.push_back(r.depth);
          write_rendering(out / "renders", fmt::format("frame_{:08d}", i), r, float(model.near), float(model.far * 0.6));
        }
        const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / ids.size();
        // In colour where both the frames and the model are: RGB scores per channel, grey ones secondary.
        const bool colour = colour_frames(d, ids) && ours.images.front().channels == 3;
        if (!colour)
          for (auto& im : ours.images) im = eval::to_grey(im);
        auto methods = baseline_methods(d, ids, 0.2, colour);
        methods.insert(methods.begin(), ours);
        eval::AlignedScores primary;
        const Truth truth = load_truth(d, ids, colour);
        nlohmann::json j = score_and_report(methods, truth, als, ids, primary);
        j["seconds_per_render"] = render_s;
        // Depth against simulated ground truth, where the recording has it (median scale alignment).
        if (d.depth.size() == d.frames.size()) {
          std::vector<std::vector<float>> gtd;
          for (auto i : ids) gtd.push_back(io::load_npy<float>(d.depth[i]).data);
          const double absrel = eval::depth_absrel_median_scaled(gtd, depths, model.far);
          if (std::isfinite(absrel)) j["depth_absrel_median_scaled"] = absrel;
        }
        // Novel views: with --holdout K (as given to train), the frames at every K-th boundary were never
        // trained on (both slices touching them were held out); their scores are reported on their own.
        std::vector<std::size_t> pick;  // positions in ids
        if (holdout > 0) {
          for (std::size_t k = static_cast<std::size_t>(holdout); k + 1 < desc.times.size(); k += static_cast<std::size_t>(holdout))
            for (std::size_t q = 0; q < ids.size(); ++q)
              if (std::abs(d.frames.t[ids[q]] - desc.times[k]) < 1e-9) pick.push_back(q);
          require(!pick.empty(), "eval: --holdout " + std::to_string(holdout) + " selects no frame of this recording");
          std::vector<std::size_t> frames;
          for (auto q : pick) frames.push_back(ids[q]);
          j["heldout"] = {{"every", holdout}, {"frames", frames}, {"methods", eval::methods_json(primary, false, pick)}};
        }
        write_file_atomic(out / "metrics.json", j.dump(2) + "\n");
        const std::size_t mid = ids.size() / 2;
        io::write_png(out / "montage.png",
                      io::montage({truth.shown(mid), primary.aligned[0][mid], primary.aligned[1][mid], primary.aligned[2][mid]}, colour ? 3 : 1));
        if (!pick.empty()) {
          fmt::print("held-out frames only ({}, novel views):\n", pick.size());
          print_table(primary, pick);
        }
        fmt::print("{:.2f} s per {}x{} render; wrote {}/metrics.json, montage.png (ground truth | ours | direct integration | "
                   "high-pass filter), renders/\n",
                   render_s, d.camera.width(), d.camera.height(), out.string());
        return 0;
      }
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "evnerf {}: error: {}\n", cmd, e.what());
    return 1;
  }
  return 2;
}

}  // namespace evnerf::cli
