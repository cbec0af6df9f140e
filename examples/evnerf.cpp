// evnerf — the command-line tool: inspect, simulate, baselines, train, render, eval.
#include <evnerf/evnerf.hpp>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

using namespace evnerf;
namespace fs = std::filesystem;

namespace {

const char* kUsage =
    "usage: evnerf <command> [args]\n"
    "  inspect <folder>                          summary of an IJRR-layout recording\n"
    "  simulate <scene|file> --out DIR [--realistic] [--bayer] [--hdr] [--seed N] [--noise-rate R]\n"
    "        [--noise-ratio F] [--width W] [--height H] [--focal F]\n"
    "                                            simulate events (scenes: planes, object, room); R: background\n"
    "                                            events per pixel per second; F: uniform random events added\n"
    "                                            as a fraction of the signal events\n"
    "  baselines <folder> [--out DIR] [--align global-log-affine|log-affine|min-max|none] [--contrast C]\n"
    "                                            direct integration and high-pass filter vs the frames\n"
    "  train <folder> --out DIR [--preset P] [--iters N] [--pixels N] [--seed N] [--threads N]\n"
    "        [--near M] [--far M] [--lr X] [--lr-decay-steps S] [--checkpoint-every N] [--resume]\n"
    "        [--clamp-poses] [--holdout K] [--density-per-box] [--quiet]\n"
    "                                            presets: fast (default), paper, no-joint, no-noise,\n"
    "                                            paper-no-joint, paper-no-noise, colour, fast-bf16,\n"
    "                                            paper-bf16 (mixed-precision networks); defaults: 3000\n"
    "                                            steps, lr 5e-3 decaying 0.1^(s/S), S = 250000 (spec)\n"
    "  render <checkpoint> --out DIR [--novel N]  intensity + depth at the slice boundaries and a novel path\n"
    "  eval <checkpoint> <folder> --out DIR [--align global-log-affine|log-affine|min-max|none] [--holdout K]\n"
    "                                            metrics JSON + montage (ground truth | ours | baselines)\n";

int usage() {
  std::fputs(kUsage, stderr);
  return 2;
}

/// Flags of the form --name value (or --name alone for booleans).
struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> flags;
  /// `booleans` are flags without a value, `values` flags with one; anything else is an error (a
  /// mistyped flag must not be silently ignored).
  Args(const std::vector<std::string>& a, const std::vector<std::string>& booleans, const std::vector<std::string>& values) {
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].rfind("--", 0) == 0) {
        const std::string k = a[i].substr(2);
        if (std::find(values.begin(), values.end(), k) == values.end() &&
            std::find(booleans.begin(), booleans.end(), k) == booleans.end()) {
          std::string known;
          for (const auto* list : {&values, &booleans})
            for (const auto& v : *list) known += " --" + v;
          throw Error("unknown flag --" + k + " (this command takes:" + known + ")");
        }
        if (std::find(booleans.begin(), booleans.end(), k) != booleans.end()) {
          flags[k] = "1";
        } else {
          if (i + 1 >= a.size()) throw Error("flag --" + k + " needs a value");
          flags[k] = a[++i];
        }
      } else {
        positional.push_back(a[i]);
      }
    }
  }
  bool has(const std::string& k) const { return flags.count(k) > 0; }
  std::string str(const std::string& k, const std::string& def) const { return has(k) ? flags.at(k) : def; }
  double num(const std::string& k, double def) const {
    if (!has(k)) return def;
    try {
      std::size_t used = 0;
      const double v = std::stod(flags.at(k), &used);
      if (used != flags.at(k).size() || !std::isfinite(v)) throw std::invalid_argument("x");
      return v;
    } catch (const std::exception&) {
      throw Error("flag --" + k + ": '" + flags.at(k) + "' is not a number");
    }
  }
};

int cmd_inspect(const std::vector<std::string>& a) {
  if (a.size() != 1) return usage();
  auto d = io::load_ijrr(a[0]);
  std::printf("recording     %s%s\n", a[0].c_str(), d.from_cache ? " (events from cache)" : "");
  std::fputs(io::format_summary(io::summarize(d)).c_str(), stdout);
  return 0;
}

int cmd_simulate(const std::vector<std::string>& raw) {
  Args a(raw, {"realistic", "bayer", "hdr"}, {"out", "focal", "width", "height", "noise-rate", "noise-ratio", "seed"});
  if (a.positional.size() != 1 || !a.has("out")) return usage();
  auto spec = sim::load_scene(a.positional[0]);
  sim::SensorConfig cfg = a.has("realistic") ? sim::SensorConfig::realistic() : sim::SensorConfig{};
  cfg.bayer = a.has("bayer");
  if (a.has("hdr")) {
    cfg.hdr = true;
    cfg.exposure = 3.0;
  }
  cfg.seed = static_cast<std::uint64_t>(a.num("seed", 1));
  cfg.noise_rate = a.num("noise-rate", cfg.noise_rate);
  cfg.noise_ratio = a.num("noise-ratio", cfg.noise_ratio);
  if (!(cfg.noise_ratio >= 0)) throw Error("simulate: --noise-ratio must be a non-negative number");
  cfg.width = static_cast<int>(a.num("width", cfg.width));
  cfg.height = static_cast<int>(a.num("height", cfg.height));
  cfg.fx = cfg.fy = a.num("focal", cfg.fx * cfg.width / 240.0);
  cfg.cx = cfg.cy = -1;
  const auto t0 = std::chrono::steady_clock::now();
  sim::Simulator s(spec, cfg);
  auto rec = s.run(true);
  sim::write_recording(a.str("out", ""), rec);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("scene %s: %zu events (%zu ON) over %.2f s, %zu frames, %zu renders, %.1f s wall → %s\n", spec.scene.name.c_str(),
              rec.events.size(), rec.events.count_positive(), spec.path.duration, rec.frames.size(), rec.renders, secs,
              a.str("out", "").c_str());
  return 0;
}

/// Frames of a recording that lie strictly inside the events' span (where event methods can work).
std::vector<std::size_t> frames_inside(const io::Dataset& d, double lo, double hi) {
  std::vector<std::size_t> ids;
  for (std::size_t i = 0; i < d.frames.size(); ++i)
    if (d.frames.t[i] > lo && d.frames.t[i] <= hi) ids.push_back(i);
  return ids;
}

void print_table(const eval::AlignedScores& a, const std::vector<std::size_t>& subset = {}) {
  std::printf("%-22s %10s %10s %10s   (alignment: %s)\n", "method", "MSE", "PSNR", "SSIM", eval::to_string(a.alignment));
  for (std::size_t m = 0; m < a.names.size(); ++m) {
    std::vector<eval::Scores> s;
    if (subset.empty()) {
      s = a.per_frame[m];
    } else {
      for (auto q : subset) s.push_back(a.per_frame[m][q]);
    }
    const auto mean = eval::mean(s);
    std::printf("%-22s %10.5f %10.3f %10.4f\n", a.names[m].c_str(), mean.mse, mean.psnr, mean.ssim);
  }
}

/// The requested alignment first, then the others of global-log-affine, log-affine and min-max.
std::vector<eval::Alignment> alignments_from(const std::string& flag) {
  const auto first = eval::parse_alignment(flag);
  std::vector<eval::Alignment> all{first};
  for (auto al : {eval::Alignment::GlobalLogAffine, eval::Alignment::LogAffine, eval::Alignment::MinMax})
    if (al != first) all.push_back(al);
  return all;
}

/// The baselines' reconstructions at the given frames.
std::vector<eval::Method> baseline_methods(const io::Dataset& d, const std::vector<std::size_t>& ids, double contrast) {
  std::vector<double> times;
  for (auto i : ids) times.push_back(d.frames.t[i]);
  return {{"direct_integration", eval::direct_integration(d.events, times, contrast)},
          {"high_pass_filter", eval::high_pass_filter(d.events, times, contrast)}};
}

/// Scores under every alignment (the first is the primary), prints the tables and returns metrics.json.
nlohmann::json score_and_report(const std::vector<eval::Method>& methods, const std::vector<Image>& gts,
                                const std::vector<eval::Alignment>& als, const std::vector<std::size_t>& ids,
                                eval::AlignedScores& primary) {
  primary = eval::score_methods(methods, gts, als.front(), true);
  std::vector<eval::AlignedScores> others;
  for (std::size_t k = 1; k < als.size(); ++k) others.push_back(eval::score_methods(methods, gts, als[k]));
  print_table(primary);
  for (const auto& o : others) print_table(o);
  return eval::metrics_json(primary, others, ids);
}

int cmd_baselines(const std::vector<std::string>& raw) {
  Args a(raw, {}, {"out", "align", "contrast"});
  if (a.positional.size() != 1) return usage();
  const auto d = io::load_ijrr(a.positional[0]);
  const auto als = alignments_from(a.str("align", "global-log-affine"));
  const auto ids = frames_inside(d, d.events.t_begin(), d.events.t_end());
  require(!ids.empty(), a.positional[0] + ": no frames inside the events' time span");
  std::vector<Image> gts;
  for (auto i : ids) gts.push_back(eval::to_grey(io::read_png(d.frames.paths[i])));
  eval::AlignedScores primary;
  const auto j = score_and_report(baseline_methods(d, ids, a.num("contrast", 0.2)), gts, als, ids, primary);
  const fs::path out = a.str("out", (fs::path(a.positional[0]) / "baselines").string());
  write_file_atomic(out / "baselines.json", j.dump(2) + "\n");
  const std::size_t mid = ids.size() / 2;
  io::write_png(out / "montage.png", io::montage({gts[mid], primary.aligned[0][mid], primary.aligned[1][mid]}));
  std::printf("wrote %s/baselines.json and montage.png (ground truth | direct integration | high-pass filter)\n", out.c_str());
  return 0;
}

constexpr const char* kPresets[] = {"fast", "fast-slice", "fast-bf16", "no-joint", "no-noise", "colour", "paper", "paper-bf16",
                                    "paper-no-joint", "paper-no-noise", "fast-w8", "fast-w48", "fast-events"};

/// Runs `fn.template operator()<Model>(name)` for a preset name.
template <class Fn>
int with_preset(const std::string& preset, Fn&& fn) {
  using namespace presets;
  if (preset == "fast") return fn.template operator()<Fast>("fast");
  if (preset == "fast-slice") return fn.template operator()<FastOneSlice>("fast-slice");
  if (preset == "fast-bf16") return fn.template operator()<FastBf16>("fast-bf16");
  if (preset == "no-joint") return fn.template operator()<FastNoJointThresholds>("no-joint");
  if (preset == "no-noise") return fn.template operator()<FastNoNoiseInjection>("no-noise");
  if (preset == "colour") return fn.template operator()<FastColour>("colour");
  if (preset == "fast-w8") return fn.template operator()<FastWindow<8>>("fast-w8");
  if (preset == "fast-w48") return fn.template operator()<FastWindow<48>>("fast-w48");
  if (preset == "fast-events") return fn.template operator()<FastWindow<24, events::EventPixels<100>>>("fast-events");
  if (preset == "paper") return fn.template operator()<Paper>("paper");
  if (preset == "paper-bf16") return fn.template operator()<PaperBf16>("paper-bf16");
  if (preset == "paper-no-joint") return fn.template operator()<PaperNoJointThresholds>("paper-no-joint");
  if (preset == "paper-no-noise") return fn.template operator()<PaperNoNoiseInjection>("paper-no-noise");
  throw Error("unknown preset '" + preset + "' (fast, fast-bf16, paper, paper-bf16, no-joint, no-noise, paper-no-joint, paper-no-noise, colour)");
}

/// The compiled variant that can load a checkpoint: the one named in the file when its parameter count and
/// loss match, else the one whose parameter count and loss match (a file written under an older name).
std::string checkpoint_preset(const fs::path& path) {
  const auto h = io::peek_checkpoint(path);
  auto fits = [&](const std::string& preset) {
    return with_preset(preset, [&]<class Model>(const std::string&) {
      const bool params = h.n_params == Model::n_fields * Model::field_params + 2 * h.n_slices;
      return params && (h.version < 4 || h.loss == Model::loss_description()) ? 1 : 0;
    }) == 1;
  };
  try {
    if (fits(h.name)) return h.name;
  } catch (const Error&) {  // a name this program does not know
  }
  for (const char* p : kPresets)
    if (fits(p)) return p;
  throw Error(path.string(), 0, "written by variant '" + h.name + "' with the loss '" + h.loss +
                                    "', which no variant of this program matches");
}

int cmd_train(const std::vector<std::string>& raw) {
  Args a(raw, {"resume", "clamp-poses", "quiet", "density-per-box"},
         {"out", "checkpoint-every", "far", "near", "holdout", "iters", "lr", "lr-decay-steps", "pixels", "seed", "threads", "preset"});
  if (a.positional.size() != 1 || !a.has("out")) return usage();
  train::Config cfg;
  cfg.iterations = static_cast<long>(a.num("iters", 3000));
  cfg.pixels_per_step = static_cast<int>(a.num("pixels", 1024));
  cfg.seed = static_cast<std::uint64_t>(a.num("seed", 1));
  cfg.threads = static_cast<int>(a.num("threads", 0));
  cfg.near = a.num("near", 0.3);
  cfg.far = a.num("far", 7.0);
  cfg.lr = a.num("lr", 5e-3);
  cfg.lr_decay_steps = a.num("lr-decay-steps", 250000);
  cfg.checkpoint_every = static_cast<long>(a.num("checkpoint-every", 500));
  cfg.clamp_poses = a.has("clamp-poses");
  cfg.density_per_box = a.has("density-per-box");
  cfg.holdout_every = static_cast<int>(a.num("holdout", 0));
  cfg.progress = !a.has("quiet");
  const fs::path out = a.str("out", "");
  const auto d = io::load_ijrr(a.positional[0]);
  const auto td = train::prepare(d, cfg);
  const std::string meta = train::describe(td, fs::absolute(a.positional[0]).string());
  return with_preset(a.str("preset", "fast"), [&]<class Model>(const std::string& name) {
    nn::AdamConfig ac;
    ac.lr = cfg.lr;
    ac.decay = cfg.lr_decay;
    ac.decay_steps = cfg.lr_decay_steps;
    Model model(td.slices.size(), train::scene_box(td, cfg), cfg.seed, ac);
    if (a.has("resume") && fs::exists(out / "model.ckpt")) {
      train::load_checkpoint(out / "model.ckpt", model, name);
      if (!model.load_note().empty()) std::fprintf(stderr, "warning: %s\n", model.load_note().c_str());
      model.optimizer().set_config(ac);
      std::fprintf(stderr, "resuming %s at step %ld\n", name.c_str(), model.step());
    }
    std::fprintf(stderr, "training %s on %zu slices, %zu events, %d threads\n", name.c_str(), td.slices.size(), d.events.size(),
                 cfg.threads > 0 ? cfg.threads : thread_count());
    auto r = train::run(model, td, cfg, out, name, meta);
    std::printf("trained %s: %ld steps in %.1f s (%.0f rays/s), final loss %.5f%s → %s\n", name.c_str(), r.steps, r.seconds,
                r.rays_per_second, r.final_loss, r.diverged ? " (DIVERGED)" : "", (out / "model.ckpt").c_str());
    return r.diverged ? 3 : 0;
  });
}

template <class Model>
void write_rendering(const fs::path& out, const std::string& stem, const Rendering& r, float dlo, float dhi) {
  io::write_png(out / (stem + ".png"), r.luminance);
  io::write_png(out / (stem + "_depth.png"), io::colorize(r.depth, dlo, dhi));
  io::save_npy(out / (stem + "_depth.npy"), r.depth.data.data(), {static_cast<std::size_t>(r.depth.height), static_cast<std::size_t>(r.depth.width)});
}

int cmd_render(const std::vector<std::string>& raw) {
  Args a(raw, {}, {"out", "novel"});
  if (a.positional.size() != 1 || !a.has("out")) return usage();
  const fs::path ckpt = a.positional[0], out = a.str("out", "");
  return with_preset(checkpoint_preset(ckpt), [&]<class Model>(const std::string&) {
    Model model;
    const auto desc = train::parse_description(train::load_checkpoint(ckpt, model, ""), ckpt.string());
    const auto dirs = render::pixel_directions(desc.camera);
    const float dlo = float(model.box().near), dhi = float(model.box().far * 0.6);
    for (std::size_t i = 0; i < desc.poses.size(); ++i) {
      char stem[64];
      std::snprintf(stem, sizeof stem, "boundary_%04zu", i);
      write_rendering<Model>(out, stem, model.render(desc.camera, dirs, desc.poses[i]), dlo, dhi);
    }
    // Novel path: beyond the recorded poses, sideways and rotated, from the first to the last boundary.
    const int novel = static_cast<int>(a.num("novel", 8));
    for (int k = 0; k < novel; ++k) {
      const double s = novel > 1 ? double(k) / (novel - 1) : 0.5;
      geometry::Pose p = geometry::Pose::interpolate(desc.poses.front(), desc.poses.back(), s);
      const double ang = 0.06 * std::sin(6.283185307179586 * s);
      p.q = (p.q * Quat(Eigen::AngleAxisd(ang, Vec3::UnitY()))).normalized();
      p.t += p.q * Vec3(0, 0.05 * std::sin(3.14159 * s), 0);
      char stem[64];
      std::snprintf(stem, sizeof stem, "novel_%04d", k);
      write_rendering<Model>(out, stem, model.render(desc.camera, dirs, p), dlo, dhi);
    }
    std::printf("rendered %zu boundary views and %d novel views (intensity, depth PNG + .npy) → %s\n", desc.poses.size(), novel,
                out.c_str());
    return 0;
  });
}

int cmd_eval(const std::vector<std::string>& raw) {
  Args a(raw, {}, {"out", "align", "holdout"});
  if (a.positional.size() != 2 || !a.has("out")) return usage();
  const fs::path ckpt = a.positional[0], out = a.str("out", "");
  const auto d = io::load_ijrr(a.positional[1]);
  // Primary: one log-affine map over the whole sequence (eval::Alignment::GlobalLogAffine); per-image
  // log-affine and min-max follow as secondary scores.
  const auto als = alignments_from(a.str("align", "global-log-affine"));
  return with_preset(checkpoint_preset(ckpt), [&]<class Model>(const std::string& name) {
    Model model;
    const auto desc = train::parse_description(train::load_checkpoint(ckpt, model, ""), ckpt.string());
    require(desc.camera.width() == d.camera.width() && desc.camera.height() == d.camera.height(),
            "eval: the checkpoint's camera does not match the recording's sensor size");
    // Frames at the trained slice boundaries (the first boundary has no events before it: skipped).
    std::vector<std::size_t> ids;
    for (std::size_t i = 0; i < d.frames.size(); ++i)
      if (d.frames.t[i] > desc.times.front() + 1e-9 && d.frames.t[i] <= desc.times.back() + 1e-9) ids.push_back(i);
    require(!ids.empty(), "eval: no frames inside the trained time range");
    const auto dirs = render::pixel_directions(d.camera);
    eval::Method ours{"evnerf_" + name, {}};
    std::vector<Image> gts, depths;
    const auto t0 = std::chrono::steady_clock::now();
    for (auto i : ids) {
      const double t = d.frames.t[i];
      const auto pose = d.trajectory.covers(t) ? d.trajectory.pose_at(t) : d.trajectory.pose_at(t, geometry::OutOfRange::Clamp);
      const auto r = model.render(d.camera, dirs, pose);
      ours.images.push_back(eval::to_grey(r.luminance));
      gts.push_back(eval::to_grey(io::read_png(d.frames.paths[i])));
      depths.push_back(r.depth);
      char stem[64];
      std::snprintf(stem, sizeof stem, "frame_%08zu", i);
      write_rendering<Model>(out / "renders", stem, r, float(model.box().near), float(model.box().far * 0.6));
    }
    const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / ids.size();
    auto methods = baseline_methods(d, ids, 0.2);
    methods.insert(methods.begin(), ours);
    eval::AlignedScores primary;
    nlohmann::json j = score_and_report(methods, gts, als, ids, primary);
    j["seconds_per_render"] = render_s;
    // Depth against simulated ground truth, where the recording has it (median scale alignment).
    if (d.depth.size() == d.frames.size()) {
      std::vector<std::vector<float>> gtd;
      for (auto i : ids) gtd.push_back(io::load_npy<float>(d.depth[i]).data);
      const double absrel = eval::depth_absrel_median_scaled(gtd, depths, model.box().far);
      if (std::isfinite(absrel)) j["depth_absrel_median_scaled"] = absrel;
    }
    // Novel views: with --holdout K (as given to train), the frames at every K-th boundary were never
    // trained on (both slices touching them were held out); their scores are reported on their own.
    const int holdout = static_cast<int>(a.num("holdout", 0));
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
    io::write_png(out / "montage.png", io::montage({gts[mid], primary.aligned[0][mid], primary.aligned[1][mid], primary.aligned[2][mid]}));
    if (!pick.empty()) {
      std::printf("held-out frames only (%zu, novel views):\n", pick.size());
      print_table(primary, pick);
    }
    std::printf("%.2f s per %dx%d render; wrote %s/metrics.json, montage.png (ground truth | ours | direct integration | "
                "high-pass filter), renders/\n",
                render_s, d.camera.width(), d.camera.height(), out.c_str());
    return 0;
  });
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  std::vector<std::string> args(argv + 2, argv + argc);
  try {
    if (cmd == "inspect") return cmd_inspect(args);
    if (cmd == "simulate") return cmd_simulate(args);
    if (cmd == "baselines") return cmd_baselines(args);
    if (cmd == "train") return cmd_train(args);
    if (cmd == "render") return cmd_render(args);
    if (cmd == "eval") return cmd_eval(args);
    if (cmd == "help" || cmd == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    return usage();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evnerf %s: error: %s\n", cmd.c_str(), e.what());
    return 1;
  }
}
