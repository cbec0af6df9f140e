// evnerf — the command-line tool: inspect, simulate, baselines, train, render, eval.
#include <evnerf/evnerf.hpp>
#include <evnerf/sim/simulator.hpp>
#include <evnerf/train/trainer.hpp>

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
    "  baselines <folder> [--out DIR] [--align min-max|log-affine|none] [--contrast C]\n"
    "                                            direct integration and high-pass filter vs the frames\n"
    "  train <folder> --out DIR [--preset P] [--iters N] [--pixels N] [--seed N] [--threads N]\n"
    "        [--near M] [--far M] [--lr X] [--lr-decay-steps S] [--checkpoint-every N] [--resume]\n"
    "        [--clamp-poses] [--holdout K] [--density-per-box] [--quiet]\n"
    "                                            presets: fast (default), paper, no-joint, no-noise,\n"
    "                                            paper-no-joint, paper-no-noise, colour, fast-bf16,\n"
    "                                            paper-bf16 (mixed-precision networks); defaults: 3000\n"
    "                                            steps, lr 5e-3 decaying 0.1^(s/S), S = 250000 (spec)\n"
    "  render <checkpoint> --out DIR [--novel N]  intensity + depth at the slice boundaries and a novel path\n"
    "  eval <checkpoint> <folder> --out DIR [--align min-max|log-affine|none] [--holdout K]\n"
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

std::string json_num(double v) {
  if (!std::isfinite(v)) return "null";
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

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

struct MethodScores {
  std::string name;
  std::vector<eval::Scores> per_frame;
  eval::Scores mean() const {
    eval::Scores m;
    for (auto& s : per_frame) {
      m.mse += s.mse / per_frame.size();
      m.psnr += s.psnr / per_frame.size();
      m.ssim += s.ssim / per_frame.size();
    }
    return m;
  }
};

std::string scores_json(const std::vector<MethodScores>& methods, const std::vector<std::size_t>& frames, eval::Alignment al,
                        const std::string& extra) {
  std::string j = "{\n  \"alignment\": \"" + std::string(eval::to_string(al)) + "\",\n  \"frames\": [";
  for (std::size_t i = 0; i < frames.size(); ++i) j += (i ? "," : "") + std::to_string(frames[i]);
  j += "],\n" + extra + "  \"methods\": {\n";
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const auto mean = methods[m].mean();
    j += "    \"" + methods[m].name + "\": {\"mse\": " + json_num(mean.mse) + ", \"psnr\": " + json_num(mean.psnr) +
         ", \"ssim\": " + json_num(mean.ssim) + ", \"per_frame\": [";
    for (std::size_t i = 0; i < methods[m].per_frame.size(); ++i) {
      const auto& s = methods[m].per_frame[i];
      j += std::string(i ? ", " : "") + "{\"mse\": " + json_num(s.mse) + ", \"psnr\": " + json_num(s.psnr) + ", \"ssim\": " + json_num(s.ssim) + "}";
    }
    j += "]}" + std::string(m + 1 < methods.size() ? "," : "") + "\n";
  }
  return j + "  }\n}\n";
}

void print_table(const std::vector<MethodScores>& methods, eval::Alignment al) {
  std::printf("%-22s %10s %10s %10s   (alignment: %s)\n", "method", "MSE", "PSNR", "SSIM", eval::to_string(al));
  for (auto& m : methods) {
    const auto s = m.mean();
    std::printf("%-22s %10.5f %10.3f %10.4f\n", m.name.c_str(), s.mse, s.psnr, s.ssim);
  }
}

/// Baseline reconstructions at the given frames, scored against them.
std::vector<MethodScores> score_baselines(const io::Dataset& d, const std::vector<std::size_t>& ids, eval::Alignment al,
                                          double contrast, std::vector<Image>* di_out, std::vector<Image>* hp_out) {
  std::vector<double> times;
  for (auto i : ids) times.push_back(d.frames.t[i]);
  auto di = eval::direct_integration(d.events, times, contrast);
  auto hp = eval::high_pass_filter(d.events, times, contrast);
  MethodScores a{"direct_integration", {}}, b{"high_pass_filter", {}};
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const Image gt = eval::to_grey(io::read_png(d.frames.paths[ids[k]]));
    a.per_frame.push_back(eval::score(di[k], gt, al));
    b.per_frame.push_back(eval::score(hp[k], gt, al));
    if (di_out) di_out->push_back(eval::align(di[k], gt, al).first);
    if (hp_out) hp_out->push_back(eval::align(hp[k], gt, al).first);
  }
  return {a, b};
}

int cmd_baselines(const std::vector<std::string>& raw) {
  Args a(raw, {}, {"out", "align", "contrast"});
  if (a.positional.size() != 1) return usage();
  const auto d = io::load_ijrr(a.positional[0]);
  const auto al = eval::parse_alignment(a.str("align", "min-max"));
  const auto ids = frames_inside(d, d.events.t_begin(), d.events.t_end());
  require(!ids.empty(), a.positional[0] + ": no frames inside the events' time span");
  std::vector<Image> di, hp;
  auto methods = score_baselines(d, ids, al, a.num("contrast", 0.2), &di, &hp);
  print_table(methods, al);
  const fs::path out = a.str("out", (fs::path(a.positional[0]) / "baselines").string());
  write_file_atomic(out / "baselines.json", scores_json(methods, ids, al, ""));
  const std::size_t mid = ids.size() / 2;
  io::write_png(out / "montage.png", io::montage({eval::to_grey(io::read_png(d.frames.paths[ids[mid]])), di[mid], hp[mid]}));
  std::printf("wrote %s/baselines.json and montage.png (ground truth | direct integration | high-pass filter)\n", out.c_str());
  return 0;
}

/// Runs `fn.template operator()<Model>(name)` for a preset name.
template <class Fn>
int with_preset(const std::string& preset, Fn&& fn) {
  using namespace presets;
  if (preset == "fast") return fn.template operator()<Fast>("fast");
  if (preset == "fast-bf16") return fn.template operator()<FastBf16>("fast-bf16");
  if (preset == "no-joint") return fn.template operator()<FastNoJointThresholds>("no-joint");
  if (preset == "no-noise") return fn.template operator()<FastNoNoiseInjection>("no-noise");
  if (preset == "colour") return fn.template operator()<FastColour>("colour");
  if (preset == "paper") return fn.template operator()<Paper>("paper");
  if (preset == "paper-bf16") return fn.template operator()<PaperBf16>("paper-bf16");
  if (preset == "paper-no-joint") return fn.template operator()<PaperNoJointThresholds>("paper-no-joint");
  if (preset == "paper-no-noise") return fn.template operator()<PaperNoNoiseInjection>("paper-no-noise");
  throw Error("unknown preset '" + preset + "' (fast, fast-bf16, paper, paper-bf16, no-joint, no-noise, paper-no-joint, paper-no-noise, colour)");
}

/// The preset name stored in a checkpoint.
std::string checkpoint_preset(const fs::path& path) {
  const std::string b = read_file(path);
  if (b.size() < 32 || b.compare(0, 8, "EVNERFCK") != 0) throw Error(path.string(), 0, "not an evnerf checkpoint");
  std::uint64_t n = 0;
  std::memcpy(&n, b.data() + 16, 8);  // magic (8), version (8), name length (8), name
  if (n > 64 || 24 + n > b.size()) throw Error(path.string(), 0, "corrupt checkpoint header");
  return b.substr(24, n);
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
  return with_preset(checkpoint_preset(ckpt), [&]<class Model>(const std::string& name) {
    Model model;
    const auto desc = train::parse_description(train::load_checkpoint(ckpt, model, name), ckpt.string());
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
  // Spec §9 (#9): per-image min–max is the primary normalisation, log-affine a secondary one; both are
  // reported (the other one of the pair as "secondary" when --align picks one).
  const auto al = eval::parse_alignment(a.str("align", "min-max"));
  const auto al2 = al == eval::Alignment::MinMax ? eval::Alignment::LogAffine : eval::Alignment::MinMax;
  return with_preset(checkpoint_preset(ckpt), [&]<class Model>(const std::string& name) {
    Model model;
    const auto desc = train::parse_description(train::load_checkpoint(ckpt, model, name), ckpt.string());
    require(desc.camera.width() == d.camera.width() && desc.camera.height() == d.camera.height(),
            "eval: the checkpoint's camera does not match the recording's sensor size");
    // Frames at the trained slice boundaries (the first boundary has no events before it: skipped).
    std::vector<std::size_t> ids;
    for (std::size_t i = 0; i < d.frames.size(); ++i)
      if (d.frames.t[i] > desc.times.front() + 1e-9 && d.frames.t[i] <= desc.times.back() + 1e-9) ids.push_back(i);
    require(!ids.empty(), "eval: no frames inside the trained time range");
    const auto dirs = render::pixel_directions(d.camera);
    MethodScores ours{"evnerf_" + name, {}}, ours2{"evnerf_" + name, {}};
    std::vector<Image> mine, gts;
    std::vector<Image> depths;
    const auto t0 = std::chrono::steady_clock::now();
    for (auto i : ids) {
      const double t = d.frames.t[i];
      const auto pose = d.trajectory.covers(t) ? d.trajectory.pose_at(t) : d.trajectory.pose_at(t, geometry::OutOfRange::Clamp);
      const auto r = model.render(d.camera, dirs, pose);
      const Image gt = eval::to_grey(io::read_png(d.frames.paths[i]));
      const Image pred = eval::to_grey(r.luminance);
      ours.per_frame.push_back(eval::score(pred, gt, al));
      ours2.per_frame.push_back(eval::score(pred, gt, al2));
      mine.push_back(eval::align(pred, gt, al).first);
      gts.push_back(gt);
      depths.push_back(r.depth);
      char stem[64];
      std::snprintf(stem, sizeof stem, "frame_%08zu", i);
      write_rendering<Model>(out / "renders", stem, r, float(model.box().near), float(model.box().far * 0.6));
    }
    const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / ids.size();
    std::vector<Image> di, hp;
    auto methods = score_baselines(d, ids, al, 0.2, &di, &hp);
    methods.insert(methods.begin(), ours);
    auto methods2 = score_baselines(d, ids, al2, 0.2, nullptr, nullptr);
    methods2.insert(methods2.begin(), ours2);
    // Depth against simulated ground truth, where the recording has it (median scale alignment).
    std::string extra = "  \"seconds_per_render\": " + json_num(render_s) + ",\n";
    extra += "  \"secondary\": {\"alignment\": \"" + std::string(eval::to_string(al2)) + "\", \"methods\": {";
    for (std::size_t m = 0; m < methods2.size(); ++m) {
      const auto sc = methods2[m].mean();
      extra += (m ? ", " : "") + ("\"" + methods2[m].name + "\": {\"mse\": " + json_num(sc.mse) + ", \"psnr\": " +
                                   json_num(sc.psnr) + ", \"ssim\": " + json_num(sc.ssim) + "}");
    }
    extra += "}},\n";
    if (d.depth.size() == d.frames.size()) {
      double absrel = 0;
      std::size_t n = 0;
      for (std::size_t k = 0; k < ids.size(); ++k) {
        const auto gtd = io::load_npy<float>(d.depth[ids[k]]).data;
        std::vector<double> ratio;
        for (std::size_t p = 0; p < gtd.size(); ++p)
          if (std::isfinite(gtd[p]) && gtd[p] < model.box().far && depths[k].data[p] > 0) ratio.push_back(gtd[p] / depths[k].data[p]);
        if (ratio.empty()) continue;
        std::nth_element(ratio.begin(), ratio.begin() + ratio.size() / 2, ratio.end());
        const double sc = ratio[ratio.size() / 2];
        for (std::size_t p = 0; p < gtd.size(); ++p)
          if (std::isfinite(gtd[p]) && gtd[p] < model.box().far) {
            absrel += std::abs(depths[k].data[p] * sc - gtd[p]) / gtd[p];
            ++n;
          }
      }
      if (n) extra += "  \"depth_absrel_median_scaled\": " + json_num(absrel / n) + ",\n";
    }
    // Novel views: with --holdout K (as given to train), the frames at every K-th boundary were never
    // trained on (both slices touching them were held out); their scores are reported on their own.
    const int holdout = static_cast<int>(a.num("holdout", 0));
    std::vector<MethodScores> held;
    if (holdout > 0) {
      std::vector<std::size_t> pick;  // positions in ids
      for (std::size_t k = static_cast<std::size_t>(holdout); k + 1 < desc.times.size(); k += static_cast<std::size_t>(holdout))
        for (std::size_t q = 0; q < ids.size(); ++q)
          if (std::abs(d.frames.t[ids[q]] - desc.times[k]) < 1e-9) pick.push_back(q);
      require(!pick.empty(), "eval: --holdout " + std::to_string(holdout) + " selects no frame of this recording");
      std::string j = "  \"heldout\": {\"every\": " + std::to_string(holdout) + ", \"frames\": [";
      for (std::size_t q = 0; q < pick.size(); ++q) j += (q ? "," : "") + std::to_string(ids[pick[q]]);
      j += "], \"methods\": {";
      for (std::size_t m = 0; m < methods.size(); ++m) {
        MethodScores h{methods[m].name, {}};
        for (auto q : pick) h.per_frame.push_back(methods[m].per_frame[q]);
        const auto sc = h.mean();
        j += (m ? ", " : "") + ("\"" + h.name + "\": {\"mse\": " + json_num(sc.mse) + ", \"psnr\": " + json_num(sc.psnr) +
                                 ", \"ssim\": " + json_num(sc.ssim) + "}");
        held.push_back(std::move(h));
      }
      extra += j + "}},\n";
    }
    write_file_atomic(out / "metrics.json", scores_json(methods, ids, al, extra));
    const std::size_t mid = ids.size() / 2;
    io::write_png(out / "montage.png", io::montage({gts[mid], mine[mid], di[mid], hp[mid]}));
    print_table(methods, al);
    print_table(methods2, al2);
    if (!held.empty()) {
      std::printf("held-out frames only (%zu, novel views):\n", held.front().per_frame.size());
      print_table(held, al);
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
