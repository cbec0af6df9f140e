// cli/run_impl.hpp — the definition of cli::run (cli/run.hpp): every verb's flags and what it does, for
// any table of variants. Included by cli/run.hpp, or compiled once by a program that defines
// EVNERF_SEPARATE_COMPILATION (core/compiled.hpp). Built on CLI11 (flags, --help, number validation),
// nlohmann::json (metrics) and fmt (messages). Depends on everything but the model types.
#pragma once
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "../core/progress.hpp"
#include "../eval/evaluate.hpp"
#include "../io/dataset.hpp"
#include "../io/inspect.hpp"
#include "../io/video.hpp"
#include "../render/novel.hpp"
#include "../sim/simulate.hpp"
#include "../view/session.hpp"
#include "run.hpp"
#ifdef EVNERF_HAVE_VIEW
#include <evnerf_view_page.hpp>  // the page's files as bytes (cmake/embed_page.cmake)

#include "../view/server.hpp"
#endif

namespace evnerf::cli {

namespace fs = std::filesystem;

namespace detail {

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

using namespace evaluation;

/// Prints the scores of evaluation::score_all: the primary table; `verbose` adds the error by scale, the offset
/// oracle, the other alignments and, in colour, the grey scores.
inline void print_scores(const Scored& s, const Truth& truth, bool verbose) {
  if (truth.hdr)
    fmt::print("scored against the linear (HDR) truth in log(x + {}), its range over the sequence on [0, 1]\n",
               short_number(truth.hdr->offset));
  print_table(s.primary);
  if (!verbose) return;
  if (s.json.contains("error_scales")) {
    const auto& es = s.json.at("error_scales");
    fmt::print(
        "error by scale (primary alignment; coarse = the error blurred by a {} px Gaussian, fine = the rest; row, column = "
        "each row's, column's mean error):\n",
        short_number(es.at("sigma_px").get<double>()));
    // A method's figure in dB ("inf" for no error, "-" where an older file lacks it).
    auto db = [&es](const std::string& name, const char* key) {
      const auto& v = es.at("methods").at(name);
      if (!v.contains(key)) return std::string("-");
      const auto& x = v.at(key);
      return x.is_number() ? fmt::format("{:.3f}", x.get<double>()) : std::string("inf");
    };
    for (const auto& name : s.primary.names)
      fmt::print("{:<22} coarse PSNR {:>8}   fine PSNR {:>8}   row PSNR {:>8}   column PSNR {:>8}\n", name, db(name, "coarse_psnr"),
                 db(name, "fine_psnr"), db(name, "row_psnr"), db(name, "column_psnr"));
    fmt::print(
        "PSNR with log offsets per image row, per column and both fitted to the truth over the sequence (what a "
        "straight motion never shows the events; a diagnosis, never a score):\n");
    for (const auto& name : s.primary.names)
      fmt::print("{:<22} rows {:>8}   columns {:>8}   both {:>8}\n", name, db(name, "oracle_rows_psnr"), db(name, "oracle_columns_psnr"),
                 db(name, "oracle_both_psnr"));
  }
  for (const auto& o : s.others) print_table(o);
  if (s.grey) {
    fmt::print("in grey (luminance of every method and of the truth):\n");
    print_table(*s.grey);
  }
}

/// Intensity and depth of one view: the intensity as linear float32 (`<stem>.npy`, H × W or H × W × C) and
/// as a PNG, on [0, 1] as it is or, where the luminance passes 1 (a field of unbounded radiance), its log put
/// on [0, 1]; the depth as float32 (`<stem>_depth.npy`) and a colour-mapped PNG. The .npy is written for
/// every view, so a script reading renders/*.npy finds one beside each PNG.
inline void write_rendering(const fs::path& out, const std::string& stem, const Rendering& r, float dlo, float dhi) {
  const auto& l = r.luminance;
  std::vector<std::size_t> shape{static_cast<std::size_t>(l.height), static_cast<std::size_t>(l.width)};
  if (l.channels > 1) shape.push_back(static_cast<std::size_t>(l.channels));
  io::save_npy(out / (stem + ".npy"), l.data.data(), shape);
  if (!l.data.empty() && *std::max_element(l.data.begin(), l.data.end()) > 1.0f)
    io::write_png(out / (stem + ".png"), eval::HdrTone{eval::kLogEps}.log_min_max(l));
  else io::write_png(out / (stem + ".png"), l);
  io::write_png(out / (stem + "_depth.png"), io::colorize(r.depth, dlo, dhi));
  io::save_npy(out / (stem + "_depth.npy"), r.depth.data.data(),
               {static_cast<std::size_t>(r.depth.height), static_cast<std::size_t>(r.depth.width)});
}

/// The training settings (train::settings()) as flags of `sub`, each writing its member of `cfg`: a number
/// is checked against its row's interval (a message naming the flag), a flag is a switch (one that is on by
/// default is turned off by --no-<name>), the exchange one of its names. --help shows each with its default.
inline void add_settings(CLI::App* sub, train::Config& cfg) {
  for (const auto& s : train::settings()) {
    const train::Setting* row = &s;
    std::visit(
        [&](auto m) {
          auto& v = cfg.*m;
          using V = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<V, bool>) {
            sub->add_flag(v ? s.flag() + ",!--no-" + s.flag().substr(2) : s.flag(), v, s.help);
          } else if constexpr (std::is_same_v<V, train::Exchange>) {
            sub->add_option_function<std::string>(
                   s.flag(), [&v, flag = s.flag()](const std::string& x) { v = train::parse_exchange(x, "train " + flag); }, s.help)
                ->check(CLI::IsMember({"auto", "dense", "sparse"}))
                ->default_str(train::exchange_name(v));
          } else {
            std::string range = row->range_text();
            std::erase(range, ' ');
            if (range.rfind("in", 0) == 0) range.erase(0, 2);
            auto* o = sub->add_option(s.flag(), v, s.help);
            if constexpr (!std::is_same_v<V, std::optional<double>>) o->capture_default_str();
            o->check(CLI::Validator(
                [row](std::string& x) -> std::string {
                  double d = 0;
                  std::size_t used = 0;
                  try {
                    d = std::stod(x, &used);
                  } catch (const std::exception&) {
                    return "";  // not a number: CLI11's conversion says so
                  }
                  if (used != x.size()) return "";
                  return row->allows(d) ? "" : "must be " + row->range_text() + ", got " + x;
                },
                range));
          }
        },
        s.member);
  }
}

const char* const kAlignHelp =
    "alignment of the primary scores: global-log-affine (one log-affine map per channel over the "
    "sequence), log-affine (per image), eventnerf (EventNeRF's: per channel over the sequence in log(x^2.2 + 0.1)), "
    "global-log-offset (E-3DGS's: one log offset per channel over the sequence, gain 1), min-max, none";

/// The recording a verb reads and how to read it (any format io::load reads): its flags, and the options
/// they fill.
struct RecordingArgs {
  std::string folder;
  io::LoadOptions load;
  std::vector<double> time_window;

  void add(CLI::App* sub, const std::string& help) {
    sub->add_option("recording", folder, help)->required();
    sub->add_option(
        "--calib", load.calib,
        "calibration instead of the recording's own: a calib.txt file (fx fy cx cy [k1 k2 p1 p2 [k3]]) or COLMAP's cameras.txt");
    sub->add_option(
        "--poses", load.poses,
        "poses instead of the recording's own: a pose file (t px py pz qx qy qz qw, camera to world; for a bag in its clock), or a "
        "COLMAP text model (folder or images.txt), each image at the time of the recording's frame of its file name");
    sub->add_option("--time-window", time_window,
                    "only the events from T0 to T1 (seconds on the recording's clock as inspect shows it; DSEC HDF5 files are read "
                    "through ms_to_idx, only the window)")
        ->expected(2);
    sub->add_option_function<std::string>(
           "--sensor-size",
           [this](const std::string& v) {
             int w = 0, h = 0;
             char end = 0;
             if (std::sscanf(v.c_str(), "%dx%d%c", &w, &h, &end) != 2 || w <= 0 || h <= 0 || w > 65535 || h > 65535)
               throw CLI::ValidationError("--sensor-size", "expected WxH (for example 1280x720), got '" + v + "'");
             load.width = w, load.height = h;
           },
           "the sensor's size WxH, where the recording does not give it (a Prophesee file whose header names no geometry)")
        ->type_name("WxH");
    sub->add_option("--format", load.format,
                    "the reader, where the content does not decide it (a folder holding two layouts): " + io::format_list())
        ->check(CLI::IsMember(io::format_names()));
    sub->add_option("--events-topic", load.events_topic, "ROS bag: the event topic (default: the one topic of event arrays)");
    sub->add_option("--images-topic", load.images_topic,
                    "ROS bag: the frames' topic, or 'none' (default: the one sensor_msgs/Image topic)");
    sub->add_option("--camera-info-topic", load.camera_info_topic,
                    "ROS bag: the sensor_msgs/CameraInfo topic, or 'none' (default: the one such topic)");
    sub->add_option("--poses-topic", load.poses_topic,
                    "ROS bag: the pose topic (PoseStamped, Odometry, TransformStamped), or 'none' (default: the one such topic)");
  }
  /// The options a read takes once the flags are parsed: the time window, and a progress line that shows a
  /// read longer than a second, unless `quiet`.
  io::LoadOptions options(bool quiet = false) const {
    io::LoadOptions o = load;
    if (time_window.size() == 2) o.t_begin = time_window[0], o.t_end = time_window[1];
    if (!quiet) o.progress = ReadProgressLine(folder);
    return o;
  }
};

/// The help of a verb's recording: every format's description.
inline std::string recording_help() {
  std::string h = "recording: ";
  for (const auto& f : io::formats()) h += std::string(f.description) + "; ";
  return h + "calib.txt and groundtruth.txt beside a file that lacks them";
}

/// `inspect`: a summary of a recording.
struct InspectVerb {
  RecordingArgs rec;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("inspect", "summary of a recording: sensor, events, frames, poses, warnings");
    rec.add(sub, recording_help());
    return sub;
  }
  int run() const {
    io::LoadOptions opt = rec.options();
    const io::Format& format = io::detect_format(rec.folder, opt.format);
    if (format.inspect) std::fputs(format.inspect(rec.folder).c_str(), stdout);
    opt.calibration_optional = true;  // inspect describes a file without calibration; training will ask for it
    auto d = io::load(rec.folder, opt);
    fmt::print("recording     {}{}\n", rec.folder, d.from_cache ? " (events from cache)" : "");
    fmt::print("format        {}\n", format.name);
    for (const auto& note : d.notes) fmt::print("{}\n", note);
    if (d.time_origin != 0) fmt::print("time origin   {} s (the recording's clock at t = 0)\n", d.time_origin);
    if (!d.bayer_pattern.empty()) fmt::print("colour filter {} (events through a Bayer mosaic)\n", d.bayer_pattern);
    std::fputs(io::format_summary(io::summarize(d)).c_str(), stdout);
    return 0;
  }
};

/// `convert`: a recording written in another format, chosen by the output's name.
struct ConvertVerb {
  RecordingArgs rec;
  fs::path output;
  std::string compression = "lz4";
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("convert", [] {
      std::string h = "write a recording in another format, chosen by the output's name:";
      for (const auto& f : io::formats())
        if (!f.extensions.empty()) {
          h += std::string(" ") + f.name + " (";
          for (std::size_t k = 0; k < f.extensions.size(); ++k) h += (k ? ", " : "") + f.extensions[k];
          h += "),";
        }
      return h + " else an IJRR-layout folder";
    }());
    rec.add(sub, "recording to read (any format evnerf reads)");
    sub->add_option("output", output,
                    "output: a folder (IJRR layout) or a file whose extension names its format (calib.txt and groundtruth.txt are written "
                    "beside a file that has no place for them)")
        ->required();
    sub->add_option("--compression", compression,
                    "ROS bag output: chunk compression (none, bz2, lz4); AEDAT4 output: packet compression (none, lz4, zstd)")
        ->check(CLI::IsMember({"none", "bz2", "lz4", "zstd"}))
        ->capture_default_str();
    return sub;
  }
  int run() const {
    auto opt = rec.options();
    opt.calibration_optional = true;  // converting events needs no calibration: one not known is not written
    const auto d = io::load(rec.folder, opt);
    if (d.uncalibrated)
      fmt::print(stderr, "note: {} has no calibration (no calib.txt beside it, no --calib): the output has none either\n", rec.folder);
    io::WriteOptions wo;
    wo.compression = compression;
    io::convert(output, d, wo);
    fmt::print("wrote {} events, {} frames, {} poses → {}\n", d.events.size(), d.frames.size(), d.trajectory.size(), output.string());
    return 0;
  }
};

/// `simulate`: a recording of a built-in, random, mesh or described scene (IJRR layout).
struct SimulateVerb {
  std::vector<std::string> scene_args;
  fs::path out;
  sim::SimulateOptions so;         // the flags fill it in
  std::vector<double> pose_noise;  ///< --pose-noise T,R
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("simulate", "simulate events, 24 Hz frames, depth, poses and calibration (IJRR layout)");
    sub->add_option("scene", scene_args,
                    "built-in scene (planes, object, room; blocks, the colour scene, always through an RGGB mosaic), 'random' (a "
                    "procedural scene from --seed, saved as <out>/scene.txt), "
                    "'mesh FILE' (any 3-D file assimp reads, seen along an orbit; saved as <out>/scene.txt) or a scene description file")
        ->required()
        ->expected(1, 2);
    sub->add_option("--out", out, "output folder")->required();
    sub->add_option("--sensor", so.sensor.model,
                    "the sensor: ideal (thresholds 0.25 / 0.25, nothing else), realistic (C+ 0.22, C- 0.28, 3 % mismatch, 0.1 ms "
                    "refractory, 0.1 Hz background, 3 hot pixels, 20 us jitter), davis (realistic with the 1.5 ms refractory period of "
                    "the IJRR recordings' DAVIS240C) or random (each parameter drawn from what cameras span, from --seed); the flags "
                    "below set single parameters; written to <out>/sensor_model.txt")
        ->check(CLI::IsMember({"ideal", "realistic", "davis", "random"}))
        ->capture_default_str();
    sim::sensor_params([&](const auto& p) { sub->add_option(p.flag(), so.sensor.*p.given, p.help); });
    sub->add_flag("--bayer", so.bayer, "colour sensor: RGGB mosaic in front of the event pixels");
    sub->add_flag("--hdr", so.hdr,
                  "high dynamic range lighting (ambient ×0.05, directional light ×4: deep shadows, highlights that clip the "
                  "frames); writes the unclipped linear truth that eval scores against");
    sub->add_option("--seed", so.seed, "random seed (sensor noise; with 'random', also the scene)")->capture_default_str();
    sub->add_option("--textures", so.textures, "with 'random': photos (.png) to texture some surfaces with");
    sub->add_option("--log-offset", so.log_offset, "the sensor's dark end: pixels see log(I + offset)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    sub->add_option("--noise-ratio", so.noise_ratio, "uniform random events added, as a fraction of the signal events")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--pose-noise", pose_noise,
                    "poses only roughly known: the recorded poses' RMS error in translation (world units) and rotation "
                    "(degrees), as T,R; half independent per pose, half a slow drift (the first pose exact); the true poses "
                    "go to groundtruth_true.txt, where eval measures the pose error")
        ->expected(2)
        ->delimiter(',');
    sub->add_option("--time-offset", so.time_offset,
                    "seconds the poses' clock runs ahead of the events' (kept beside as with --pose-noise)")
        ->capture_default_str();
    sub->add_option("--width", so.width, "sensor width (pixels; 240, or 346 for a mesh)")->check(CLI::Range(8, 8192));
    sub->add_option("--height", so.height, "sensor height (pixels; 180, or 260 for a mesh)")->check(CLI::Range(8, 8192));
    sub->add_option("--focal", so.focal, "focal length in pixels (default: scaled with the width, 200 at 240)")->check(CLI::PositiveNumber);
    const std::string mesh_group = "Mesh capture (simulate mesh FILE)";
    sub->add_option("--up", so.mesh.up, "the mesh file's up axis")
        ->check(CLI::IsMember({"+y", "+z", "-y"}))
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--path", so.mesh.path,
                    "orbit (one revolution a second at --elevation) or spiral (5 to 75 degrees, one revolution a second)")
        ->check(CLI::IsMember({"orbit", "spiral"}))
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--orbit-radius", so.mesh.radius, "camera distance from the object's centre (the object fills the unit sphere)")
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--elevation", so.mesh.elevation, "orbit elevation above the horizon, degrees")
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--wobble", so.mesh.wobble, "degrees the orbit's elevation swings, once over the path")
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--duration", so.mesh.duration, "seconds of capture")->capture_default_str()->group(mesh_group);
    sub->add_option("--novel-elevation", so.mesh.novel_elevation,
                    "elevation of the held-out orbit whose views (novel/: frames and depth, never trained on) eval scores apart")
        ->capture_default_str()
        ->group(mesh_group);
    sub->add_option("--background", so.mesh.background,
                    "behind the object: black, white, grey or an equirectangular environment (.png, taken as linear)")
        ->capture_default_str()
        ->group(mesh_group);
    return sub;
  }
  int run() {
    std::string scene_text;
    const auto t0 = std::chrono::steady_clock::now();
    const std::string& scene = scene_args.front();
    if (scene == "mesh") {
      if (scene_args.size() != 2) throw Error("simulate mesh: the mesh file is missing (simulate mesh FILE --out DIR)");
      so.mesh.file = scene_args[1];
    } else if (scene_args.size() != 1) {
      throw Error("simulate: one scene expected, got '" + scene_args[0] + "' and '" + scene_args[1] + "' (a mesh file goes after 'mesh')");
    }
    if (!pose_noise.empty()) {
      so.pose_noise_translation = pose_noise[0];
      so.pose_noise_rotation = pose_noise[1];
    }
    auto rec = sim::simulate(scene, so, &scene_text);
    sim::write_recording(out, rec);
    if (!scene_text.empty()) write_file_atomic(out / "scene.txt", scene_text);
    if (!rec.linear.empty())
      fmt::print("{}: wrote the unclipped linear truth (linear/){}; eval scores against it\n", out.string(),
                 rec.clipped ? ", as highlights clip the frames" : "");
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    fmt::print("scene {}: {} events ({} ON) over {:.2f} s, {} frames, {} renders, {:.1f} s wall → {}\n", rec.scene_name, rec.events.size(),
               rec.events.count_positive(), rec.duration, rec.frames.size(), rec.renders, secs, out.string());
    if (!rec.novel.poses.empty())
      fmt::print("{} held-out views off the training path → {}/novel (eval scores them apart)\n", rec.novel.poses.size(), out.string());
    return 0;
  }
};

/// `baselines`: direct integration and the high-pass filter of the recording's events, scored against its
/// frames.
struct BaselinesVerb {
  RecordingArgs rec;
  fs::path out;
  std::string align = "global-log-affine";
  double contrast = 0.2;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("baselines", "direct integration and the high-pass filter, scored against the frames");
    rec.add(sub, recording_help());
    sub->add_option("--out", out, "output folder (default: <folder>/baselines)");
    sub->add_option("--align", align, kAlignHelp)->capture_default_str();
    sub->add_option("--contrast", contrast, "contrast threshold the baselines integrate with (log units)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    return sub;
  }
  int run() const {
    const auto d = io::load(rec.folder, rec.options());
    const auto b = run_baselines(d, alignments_from(align), contrast);
    print_scores(b.scored, b.truth, true);
    const fs::path rec_path(rec.folder);  // a folder gets baselines/ inside, a file <name>_baselines/ beside it
    const fs::path bo = !out.empty()                 ? out
                        : fs::is_directory(rec_path) ? rec_path / "baselines"
                                                     : rec_path.parent_path() / (rec_path.stem().string() + "_baselines");
    write_file_atomic(bo / "baselines.json", b.scored.json.dump(2) + "\n");
    const std::size_t mid = b.ids.size() / 2;
    const auto& aligned = b.scored.primary.aligned;
    io::write_png(bo / "montage.png", io::montage({b.truth.shown(mid), aligned[0][mid], aligned[1][mid]}, b.colour ? 3 : 1));
    fmt::print("wrote {}/baselines.json and montage.png (ground truth | direct integration | high-pass filter)\n", bo.string());
    return 0;
  }
};

/// `train`: a variant of the program trained on a recording (one model, or one per colour channel).
struct TrainVerb {
  RecordingArgs rec;
  fs::path out;
  train::Config cfg;
  std::string variant;
  bool resume = false, quiet = false, per_channel = false;
  std::string green_sites = "first";
  fs::path start_from;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app, const Programme& programme) {
    variant = programme.variants.front().name;
    sub = app.add_subcommand("train", "train a variant on a recording; writes model.ckpt and log.jsonl to --out");
    rec.add(sub, recording_help());
    sub->add_option("--out", out, "output folder")->required();
    sub->add_option("--preset,--variant", variant, "variant: " + variant_list(programme))->capture_default_str();
    add_settings(sub, cfg);
    sub->add_flag("--per-channel", per_channel,
                  "colour recording, the paper's way: a grey model per colour channel on that channel's quarter-resolution sites "
                  "(<out>/r, g, b), listed in <out>/channels.json, which render and eval take as the checkpoint");
    sub->add_option("--green-sites", green_sites,
                    "--per-channel: green's model trains on the first of its two sites per 2x2 block, a quarter-resolution sensor "
                    "like red's and blue's (first), or on both at the full sensor, with twice the events (both)")
        ->check(CLI::IsMember({"first", "both"}))
        ->capture_default_str();
    sub->add_option("--start-from", start_from,
                    "Gaussians: start from a field trained on the same recording (its model.ckpt): a Gaussian wherever the field's "
                    "opacity reaches one half at the recorded poses, with its luminance, and the field's thresholds and backdrop")
        ->check(CLI::ExistingFile);
    sub->add_flag("--resume", resume,
                  "continue from <out>/model.ckpt when it exists (a resumed run keeps its checkpoint's near, far and background)");
    sub->add_flag("--quiet", quiet, "no progress bar, and no progress line for a recording that takes more than a second to read");
    return sub;
  }
  /// The variants' names, for --help and the message on an unknown one.
  static std::string variant_list(const Programme& programme) {
    std::string list;
    for (const auto& v : programme.variants) list += (list.empty() ? "" : ", ") + v.name;
    return list;
  }
  int run(const Programme& programme, train::Group* group, bool lead) {
    cfg.progress = !quiet;
    if (group) {
      cfg.group = group;
      // The processes on one machine share its cores: each takes its part unless --threads says.
      if (cfg.threads == 0) cfg.threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / group->local_size());
    }
    require(cfg.far > cfg.near, "train: --far must be greater than --near");
    const auto d = io::load(rec.folder, rec.options(quiet));
    // The variant named by --preset, as with_variant finds it.
    const VariantEntry* entry = nullptr;
    for (const auto& v : programme.variants)
      if (v.name == variant) entry = &v;
    if (!entry) throw Error("unknown variant '" + variant + "' (this program has: " + variant_list(programme) + ")");
    TrainJob job;
    job.cfg = &cfg;
    job.recording = fs::absolute(rec.folder).string();
    job.resume = resume;
    job.lead = lead;
    job.group = group;
    evaluation::Renderable teacher;
    if (!start_from.empty()) {
      require(!per_channel, "train --start-from: one model starts from another, not the channels of --per-channel");
      require(entry->starts_from_scene,
              "train --start-from: the variant '" + variant + "' does not start from another model's scene (the Gaussians' presets do)");
      teacher = programme.open(start_from);
      require(static_cast<bool>(teacher.render_with), "train --start-from: " + start_from.string() + " renders no other camera");
      job.teacher = &teacher;
    }
    if (!per_channel) {
      TrainingData td = train::prepare(d, cfg);
      if (job.teacher) {
        const auto t0 = std::chrono::steady_clock::now();
        td.teacher = evaluation::teacher_images(teacher.render_with, td.camera, td.boundary_poses, entry->channels);
        if (lead)
          fmt::print(stderr, "rendered {} at the {} boundary poses as the teacher ({:.1f} s)\n", start_from.string(),
                     td.boundary_poses.size(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      }
      return entry->train(job, entry->name, td, out, d.events.size());
    }
    if (entry->channels != 1)
      throw Error("train --per-channel: the variant '" + entry->name +
                  "' renders colour; name a grey one (each channel gets a grey model)");
    const auto pattern = io::bayer_of(d);
    for (int c = 0; c < 3; ++c) {
      const auto channel = io::channel_dataset(d, pattern, c, io::parse_green_sites(green_sites));
      if (lead)
        fmt::print(stderr, "channel {}: {}x{} {}, {} events\n", "RGB"[c], channel.camera.width(), channel.camera.height(),
                   channel.sites.empty() ? "sites" : "sensor, both green sites", channel.events.size());
      const int code = entry->train(job, entry->name, train::prepare(channel, cfg), out / kChannelDirs[c], channel.events.size());
      if (code != 0) return code;
    }
    if (!lead) return 0;
    write_file_atomic(out / "channels.json", per_channel_manifest(d.camera, pattern, io::parse_green_sites(green_sites)).dump(2) + "\n");
    fmt::print("wrote {} (render and eval take it as the checkpoint)\n", (out / "channels.json").string());
    return 0;
  }
};

const char* const kUpsamplingHelp =
    "with channels.json: each channel's volume rendered at every pixel of the sensor (volume), or at its own "
    "quarter-resolution sites and interpolated bilinearly (sites)";

/// `render`: a checkpoint's intensity and depth at every slice boundary and along a novel path.
struct RenderVerb {
  fs::path checkpoint, out;
  int novel = 8;
  std::string channel_up = "volume";
  bool video = false;
  double fps = 24;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("render", "intensity and depth at every slice boundary and along a novel path");
    sub->add_option("checkpoint", checkpoint, "model.ckpt, or channels.json of train --per-channel")->required();
    sub->add_option("--out", out, "output folder")->required();
    sub->add_option("--novel", novel, "views along the novel path")->capture_default_str()->check(CLI::Range(0, 100000));
    sub->add_option("--channel-upsampling", channel_up, kUpsamplingHelp)->check(CLI::IsMember({"volume", "sites"}))->capture_default_str();
    sub->add_flag("--video", video,
                  "also recorded.mp4 (the slice boundaries) and novel.mp4 (the novel path): intensity beside depth, H.264 through "
                  "ffmpeg (without it, the PNG frames only)");
    sub->add_option("--fps", fps, "the videos' frames per second")->capture_default_str()->check(CLI::Range(1.0, 240.0));
    return sub;
  }
  int run(const Programme& programme) const {
    const auto model = load_renderable(checkpoint, parse_channel_upsampling(channel_up), programme.open);
    const auto& desc = model.desc;
    const float dlo = float(model.near), dhi = float(model.far * 0.6);
    const bool mp4 = video && io::ffmpeg_available();
    if (video && !mp4)
      fmt::print(stderr, "render --video needs ffmpeg (Debian's ffmpeg package), which is not on the PATH: the PNG frames only\n");
    if (model.poses_refined)
      fmt::print("the boundary views are rendered at the model's refined poses (clock offset {:.2f} ms)\n", model.time_offset * 1e3);
    std::vector<Rendering> recorded, path;
    for (std::size_t i = 0; i < desc.poses.size(); ++i) {
      auto r = model.render(desc.poses[i]);
      write_rendering(out, fmt::format("boundary_{:04d}", i), r, dlo, dhi);
      if (mp4) recorded.push_back(std::move(r));
    }
    for (int k = 0; k < novel; ++k) {
      auto r = model.render(render::novel_pose(desc.poses.front(), desc.poses.back(), k, novel));
      write_rendering(out, fmt::format("novel_{:04d}", k), r, dlo, dhi);
      if (mp4) path.push_back(std::move(r));
    }
    fmt::print("rendered {} boundary views and {} novel views (intensity, depth PNG + .npy) → {}\n", desc.poses.size(), novel,
               out.string());
    if (mp4) {
      write_video(out / "recorded.mp4", recorded, dlo, dhi);
      if (!path.empty()) write_video(out / "novel.mp4", path, dlo, dhi);
      fmt::print("videos at {} frames a second (intensity beside depth): recorded.mp4 ({} frames){}\n", fps, recorded.size(),
                 path.empty() ? std::string() : fmt::format(", novel.mp4 ({} frames)", path.size()));
    }
    return 0;
  }
  /// The views as an MP4 of intensity beside depth, the intensity toned alike in every frame: clamped to
  /// [0, 1] as the PNGs are, or where a luminance passes 1 its log over the views' 0.1–99.9 % range.
  void write_video(const fs::path& file, const std::vector<Rendering>& views, float dlo, float dhi) const {
    if (views.empty()) return;
    std::vector<Image> lum;
    float top = 0;
    for (const auto& v : views) {
      lum.push_back(v.luminance);
      for (float x : v.luminance.data) top = std::max(top, x);
    }
    std::optional<eval::HdrTone> tone;
    if (top > 1.0f) {
      try {
        tone = eval::HdrTone::of(lum, eval::kLogEps);
      } catch (const Error&) {  // every view one brightness: nothing to spread
      }
    }
    const auto frame = [&](const Rendering& v) {
      return io::montage({tone ? tone->apply(v.luminance) : v.luminance, io::colorize(v.depth, dlo, dhi)}, 3);
    };
    const Image first = frame(views.front());
    io::Mp4Writer w(file, first.width, first.height, fps);
    w.frame(first);
    for (std::size_t i = 1; i < views.size(); ++i) w.frame(frame(views[i]));
    w.finish();
  }
};

/// `export`: a trained scene in the files other tools open (eval/export.hpp): transforms.json (the cameras),
/// points.ply (a point cloud from the depth at the recorded poses), for a field mesh.ply (its surface, by
/// marching tetrahedra over the point cloud's extent), and for a Gaussian scene gaussians.ply (3D Gaussian
/// splatting's layout).
struct ExportVerb {
  fs::path checkpoint, out;
  int stride = 4, pose_stride = 1, mesh_resolution = 192;
  double min_opacity = 0.9, mesh_level = 0.9;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("export",
                             "the cameras (transforms.json), a point cloud (points.ply), a field's surface (mesh.ply) and a "
                             "Gaussian scene's Gaussians (gaussians.ply, 3D Gaussian splatting's layout) for other tools");
    sub->add_option("checkpoint", checkpoint, "model.ckpt")->required();
    sub->add_option("--out", out, "output folder")->required();
    sub->add_option("--stride", stride, "points.ply: every n-th pixel in x and y")->capture_default_str()->check(CLI::Range(1, 4096));
    sub->add_option("--pose-stride", pose_stride, "points.ply: every n-th recorded pose")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    sub->add_option("--min-opacity", min_opacity, "points.ply: a pixel's point where the rendered opacity reaches this")
        ->capture_default_str()
        ->check(CLI::Range(1e-6, 1.0));
    sub->add_option("--mesh-resolution", mesh_resolution,
                    "mesh.ply: lattice cells along the longest side of the box that holds the point cloud (but its outer 0.5 % "
                    "per axis, grown by 5 %)")
        ->capture_default_str()
        ->check(CLI::Range(2, 1024));
    sub->add_option("--mesh-level", mesh_level,
                    "mesh.ply: the surface's density, as this quantile of the field's density at the points of points.ply")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1.0));
    return sub;
  }
  int run(const Programme& programme) const {
    const auto model = programme.open(checkpoint);
    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) throw Error(out.string(), 0, "cannot create the output folder: " + ec.message());
    write_file_atomic(out / "transforms.json", evaluation::transforms_json(model.desc).dump(2) + "\n");
    const auto points = evaluation::point_cloud(model.desc, model.render, stride, pose_stride, min_opacity);
    io::write_ply(out / "points.ply", points, {"evnerf export: points at the expected depth of the recorded poses"});
    std::string what = fmt::format("transforms.json ({} cameras), points.ply ({} points)", model.desc.poses.size(), points.size());
    if (model.field && points.size() > 0) {
      std::vector<Vec3> xyz(points.size()), cameras;
      const std::size_t F = points.names.size();
      for (std::size_t i = 0; i < xyz.size(); ++i) xyz[i] = Vec3(points.floats[i * F], points.floats[i * F + 1], points.floats[i * F + 2]);
      for (const auto& p : model.desc.poses) cameras.push_back(p.t);
      std::vector<float> lum;
      const auto mesh = evaluation::field_mesh(model.field, xyz, cameras, mesh_resolution, mesh_level, lum);
      io::write_ply(out / "mesh.ply", evaluation::mesh_ply(mesh, lum, model.field.channels),
                    {"evnerf export: the field's surface, marching tetrahedra"});
      what += fmt::format(", mesh.ply ({} vertices, {} triangles)", mesh.vertices.size(), mesh.triangles.size());
    } else if (model.field) {
      fmt::print(stderr, "no mesh.ply: no pixel of the recorded poses reaches --min-opacity {}, so there is no surface to bound\n",
                 min_opacity);
    }
    if (model.gaussians) {
      const auto g = model.gaussians();
      io::write_ply(out / "gaussians.ply", evaluation::gaussians_ply(g), {"evnerf export: 3D Gaussian splatting layout, degree 0"});
      what += fmt::format(", gaussians.ply ({} Gaussians)", g.size());
    }
    fmt::print("wrote {} → {}\n", what, out.string());
    return 0;
  }
};

/// `view`: a trained scene in the browser (view/session.hpp, view/server.hpp): a page on 127.0.0.1 whose
/// camera the mouse moves, each frame rendered by this process.
struct ViewVerb {
  fs::path checkpoint;
  int port = 7007;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("view",
                             "a trained scene in the browser: a page on 127.0.0.1 (orbit, pan and zoom with the mouse; the "
                             "recorded and a novel path; intensity or depth), each frame rendered by this process");
    sub->add_option("checkpoint", checkpoint, "model.ckpt")->required();
    sub->add_option("--port", port, "the loopback port the page is served on (0: a free one, printed)")
        ->capture_default_str()
        ->check(CLI::Range(0, 65535));
    return sub;
  }
  int run(const Programme& programme) const {
#ifdef EVNERF_HAVE_VIEW
    const view::Session session(programme.open(checkpoint));
    std::vector<view::PageFile> page;
    for (const auto& f : view::page::files)
      page.push_back({f.path, f.type, std::string_view(reinterpret_cast<const char*>(f.data), f.size)});
    view::serve(session, page, port, [&](int bound) {
      const auto& m = session.model();
      fmt::print("serving {} ({}, {}, {}x{}) at http://127.0.0.1:{}/ until this process ends (Ctrl-C)\n", checkpoint.string(), m.name,
                 m.gaussians ? "Gaussians" : "a field", m.desc.camera.width(), m.desc.camera.height(), bound);
      std::fflush(stdout);
    });
    return 0;
#else
    (void)programme;
    throw Error(
        "view: this evnerf was built without cpp-httplib (Debian's libcpp-httplib-dev), which serves the page; install it "
        "and build again");
#endif
  }
};

/// The fine error by true depth of metrics.json, as eval --verbose prints it: a band reads "lo-hi m", or
/// "at z m" where its edges meet (a depth that a third of the pixels share, such as a back wall).
inline void print_fine_by_depth(const nlohmann::json& fd) {
  const auto z = fd.at("edges_m").template get<std::vector<double>>();
  const auto p = fd.at("pixel_share").template get<std::vector<double>>();
  std::string bands;
  for (std::size_t b = 0; b + 1 < z.size() && b < p.size(); ++b) {
    const std::string lo = fmt::format("{:.2f}", z[b]), hi = fmt::format("{:.2f}", z[b + 1]);
    bands += fmt::format("{}{} ({:.0f} %{})", b ? ", " : "", lo == hi ? "at " + lo + " m" : lo + "-" + hi + " m", 100 * p[b],
                         b ? "" : " of pixels");
  }
  fmt::print("fine error (MSE x 1e3) by true depth, cut at its thirds: {}\n", bands);
  for (const auto& [name, v] : fd.at("methods").items()) {
    std::string row = fmt::format("{:<22}", name);
    for (const double f : v.at("fine_mse").template get<std::vector<double>>()) row += fmt::format(" {:>8.3f}", f * 1e3);
    fmt::print("{}\n", row);
  }
}

/// `eval`: a checkpoint rendered at the recording's frames (and its held-out views), scored beside both
/// baselines; metrics.json, renders and montages.
struct EvalVerb {
  RecordingArgs rec;
  fs::path checkpoint, out;
  std::string align = "global-log-affine", channel_up = "volume";
  int holdout = 0;
  bool verbose = false;
  CLI::App* sub = nullptr;

  CLI::App* add(CLI::App& app) {
    sub = app.add_subcommand("eval", "render at the frames; metrics.json (ours and both baselines) and a montage");
    sub->add_option("checkpoint", checkpoint, "model.ckpt, or channels.json of train --per-channel")->required();
    rec.add(sub, recording_help());
    sub->add_option("--out", out, "output folder")->required();
    sub->add_option("--align", align, kAlignHelp)->capture_default_str();
    sub->add_option("--channel-upsampling", channel_up, kUpsamplingHelp)->check(CLI::IsMember({"volume", "sites"}))->capture_default_str();
    sub->add_option("--holdout", holdout, "as given to train: also score the never-trained frames on their own")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    sub->add_flag("--verbose", verbose,
                  "also print the other alignments, the error by scale, the row/column offset oracle, the grey scores of a colour "
                  "recording and the fine error by depth (metrics.json has them all)");
    return sub;
  }
  int run(const Programme& programme) const {
    const auto d = io::load(rec.folder, rec.options());
    const auto model = load_renderable(checkpoint, parse_channel_upsampling(channel_up), programme.open);
    auto e = evaluate(model, d, alignments_from(align), holdout);
    print_scores(e.scored, e.truth, verbose);
    if (verbose && e.json.contains("error_scales") && e.json.at("error_scales").contains("fine_by_depth"))
      print_fine_by_depth(e.json.at("error_scales").at("fine_by_depth"));
    const float dlo = float(model.near), dhi = float(model.far * 0.6);
    for (std::size_t q = 0; q < e.ids.size(); ++q)
      write_rendering(out / "renders", fmt::format("frame_{:08d}", e.ids[q]), e.renders[q], dlo, dhi);
    write_file_atomic(out / "metrics.json", e.json.dump(2) + "\n");
    const std::size_t mid = e.ids.size() / 2;
    const auto& al = e.scored.primary.aligned;
    io::write_png(out / "montage.png", io::montage({e.truth.shown(mid), al[0][mid], al[1][mid], al[2][mid]}, e.colour ? 3 : 1));
    if (!e.heldout.empty()) {
      fmt::print("held-out frames only ({}, novel views):\n", e.heldout.size());
      print_table(e.scored.primary, e.heldout);
    }
    if (e.novel) {
      fmt::print(
          "views off the training path ({}, the recording's novel/; ours beside a flat frame, each alignment fitted over "
          "these views):\n",
          e.novel_renders.size());
      print_table(e.novel->primary);
      if (verbose)
        for (const auto& o : e.novel->others) print_table(o);
      if (verbose && e.json.at("novel_views").contains("depth_absrel_median_scaled"))
        fmt::print("depth AbsRel (median-scaled) on them: {:.4f}\n",
                   e.json.at("novel_views").at("depth_absrel_median_scaled").template get<double>());
      for (std::size_t k = 0; k < e.novel_renders.size(); ++k)
        write_rendering(out / "renders_novel", fmt::format("view_{:08d}", k), e.novel_renders[k], dlo, dhi);
      const std::size_t m = e.novel_renders.size() / 2;
      io::write_png(out / "montage_novel.png", io::montage({e.novel_truth.shown(m), e.novel->primary.aligned[0][m]}, e.colour ? 3 : 1));
    }
    if (const auto& p = e.json.at("poses"); model.poses_refined || p.contains("error_given")) {
      if (model.poses_refined)
        fmt::print("the training path is rendered at the model's refined poses (clock offset {:.2f} ms)\n",
                   p.at("time_offset_s").template get<double>() * 1e3);
      auto show = [&](const char* key, const char* what) {
        if (!p.contains(key)) return;
        const auto& q = p.at(key);
        fmt::print("pose error of the {} against the true poses: {:.4g} (max {:.4g}) world units, {:.3g} (max {:.3g}) degrees\n", what,
                   q.at("translation_mean").template get<double>(), q.at("translation_max").template get<double>(),
                   q.at("rotation_mean_deg").template get<double>(), q.at("rotation_max_deg").template get<double>());
      };
      show("error_given", "recording's poses");
      show("error_refined", "refined poses");
    }
    fmt::print(
        "{:.2f} s per {}x{} render; wrote {}/metrics.json (every alignment, the error by scale and by depth: --verbose "
        "prints them), montage.png (ground truth | ours | direct integration | high-pass filter), renders/\n",
        e.seconds_per_render, d.camera.width(), d.camera.height(), out.string());
    return 0;
  }
};

}  // namespace detail

EVNERF_COMPILED int run(int argc, char** argv, const Programme& programme, train::Group* group) {
  using namespace detail;
  if (programme.variants.empty()) throw Error("cli::run: a program needs at least one variant");
  CLI::App app{programme.description};
  app.require_subcommand(1);
  app.fallthrough(false);
  // Every verb's flags, in the order --help lists them.
  InspectVerb inspect;
  ConvertVerb convert;
  SimulateVerb simulate;
  BaselinesVerb baselines;
  TrainVerb training;
  RenderVerb rendering;
  EvalVerb evaluating;
  ExportVerb exporting;
  ViewVerb viewing;
  inspect.add(app);
  convert.add(app);
  simulate.add(app);
  baselines.add(app);
  training.add(app, programme);
  rendering.add(app);
  evaluating.add(app);
  exporting.add(app);
  viewing.add(app);

  if (group && group->size() <= 1) group = nullptr;
  const bool lead = !group || group->rank() == 0;  // prints (every process parses the same arguments)
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (!lead) return e.get_exit_code() == 0 ? 0 : 2;
    const int code = app.exit(e);  // prints the help, or the message and a pointer to --help
    return code == 0 ? 0 : 2;
  }
  const std::string cmd = app.get_subcommands().front()->get_name();
  if (group && cmd != "train") {
    if (lead)
      fmt::print(stderr, "evnerf {}: error: only train runs in several processes ({} were started); run {} as one process\n", cmd,
                 group->size(), cmd);
    return 2;
  }
  try {
    if (*inspect.sub) return inspect.run();
    if (*convert.sub) return convert.run();
    if (*simulate.sub) return simulate.run();
    if (*baselines.sub) return baselines.run();
    if (*training.sub) return training.run(programme, group, lead);
    if (*rendering.sub) return rendering.run(programme);
    if (*evaluating.sub) return evaluating.run(programme);
    if (*exporting.sub) return exporting.run(programme);
    if (*viewing.sub) return viewing.run(programme);
  } catch (const std::exception& e) {
    // In a group the others may be waiting in a sum this process will never join: end them all.
    if (group) group->abort(fmt::format("evnerf {}: error (rank {} of {}): {}", cmd, group->rank(), group->size(), e.what()), 1);
    fmt::print(stderr, "evnerf {}: error: {}\n", cmd, e.what());
    return 1;
  }
  return 2;
}

}  // namespace evnerf::cli
