// train/trainer.hpp — turning a recording into training data (prepare), the training loop (run: progress bar,
// JSON-lines log, settings.json, atomic checksummed checkpoints, exact resume, divergence and collapse
// stops) and Trainer, a run as one object. The settings are train/settings.hpp's. Depends on model/model.hpp,
// io/dataset.hpp and train/.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <optional>
#include <string>
#include <string_view>

#include "../core/fileio.hpp"
#include "../core/progress.hpp"
#include "../io/dataset.hpp"
#include "../loss/total_variation.hpp"
#include "../model/model.hpp"
#include "data.hpp"
#include "group.hpp"
#include "settings.hpp"

#include <nlohmann/json.hpp>

namespace evnerf::train {

namespace fs = std::filesystem;

/// What a collapse check saw. A run has collapsed when its renders are almost constant (the spread of
/// log luminance over the pixels of a few low-resolution views below kMinLogSpread) or when its event loss
/// has not fallen below kMinLossImprovement of where it started (the mean of the first kLogEvery steps).
struct CollapseCheck {
  static constexpr double kMinLogSpread = 0.05;       ///< nats: a standard deviation of 5 % brightness
  static constexpr double kMinLossImprovement = 0.9;  ///< the loss must reach 90 % of its start
  long step = 0;
  double log_spread = 0, start_loss = 0, recent_loss = 0;
  bool flat_renders = false, loss_stuck = false;
  bool collapsed() const { return flat_renders || loss_stuck; }
  std::string describe() const {
    std::string d = "at step " + std::to_string(step) + ": ";
    if (flat_renders)
      d += "the renders are almost constant (log-luminance spread " + short_number(log_spread, 4) + " nats < " +
           short_number(kMinLogSpread, 4) + ")";
    if (flat_renders && loss_stuck) d += "; ";
    if (loss_stuck)
      d += "the event loss is not improving (" + short_number(recent_loss, 4) + " now, " + short_number(start_loss, 4) +
           " over the first steps)";
    if (!collapsed()) d += "healthy (log-luminance spread " + short_number(log_spread, 4) + " nats)";
    return d;
  }
};

/// What renders at quarter resolution from three boundary poses (first, middle, last) show: the spread
/// (standard deviation over all pixels) of log(ℓ + 1e-3), near 0 for a field that renders a constant image,
/// and the backdrop's share, the mean over the pixels of the transmittance a ray leaves behind its samples
/// (1 − opacity): what of the views a backdrop shows through.
struct ViewStatistics {
  double log_spread = 0, backdrop_share = 0;
};
template <class Model>
ViewStatistics view_statistics(const Model& model, const TrainingData& td) {
  const auto cam = td.camera.resized(std::max(8, td.camera.width() / 4), std::max(8, td.camera.height() / 4));
  const auto dirs = render::pixel_directions(cam);
  const std::size_t n = td.boundary_poses.size();
  double s = 0, ss = 0, count = 0, open = 0, pixels = 0;
  for (std::size_t i : {std::size_t{0}, n / 2, n - 1}) {
    const auto r = model.render(cam, dirs, td.boundary_poses[i]);
    for (float v : r.luminance.data) {
      const double l = std::log(std::max(0.0, double(v)) + 1e-3);
      s += l;
      ss += l * l;
      count += 1;
    }
    for (float o : r.opacity.data) open += std::clamp(1.0 - double(o), 0.0, 1.0);
    pixels += static_cast<double>(r.opacity.data.size());
  }
  const double mean = s / count;
  return {std::sqrt(std::max(0.0, ss / count - mean * mean)), open / pixels};
}

/// Pose refinement's settings a Config gives.
inline PoseRefinementSettings pose_settings(const Config& cfg) {
  PoseRefinementSettings s;
  s.poses = cfg.refine_poses;
  s.offset = cfg.learn_time_offset;
  s.lr_rotation = cfg.pose_lr_rotation;
  s.lr_translation = cfg.pose_lr_translation;
  s.lr_offset = cfg.time_offset_lr;
  s.decay_steps = cfg.pose_lr_decay_steps;
  s.levels = cfg.pose_levels;
  s.start = cfg.pose_start;
  s.prior_rotation = cfg.pose_prior_rotation;
  s.prior_translation = cfg.pose_prior_translation;
  return s;
}

/// Where a learned refractory period starts and the most it reaches: the recording's bound
/// (TrainingData::refractory_bound), within RefractoryState::kMax; where the bound was not read, kMax's
/// range from 0.
inline double refractory_start(const TrainingData& td) {
  return td.refractory_bound < 0 ? 0.0 : std::min(td.refractory_bound, RefractoryState::kMax);
}

/// A fresh model for the training data under `cfg` (scene box from near/far, Adam from lr/decay, seed).
template <class Model>
Model make_model(const TrainingData& td, const Config& cfg) {
  Model m(td, scene_box(td, cfg), cfg.seed, adam_config(cfg));
  // The refractory period: given, fixed (0 reads the counts as they are); unset, learned downward from the
  // bound the recording's intervals set (TrainingData::refractory_bound), and never above it.
  if (cfg.refractory) {
    if (*cfg.refractory > 0) m.set_refractory(*cfg.refractory, false);
  } else {
    const double bound = refractory_start(td);
    m.set_refractory(bound, true, bound);
  }
  if (cfg.refine_poses || cfg.learn_time_offset) m.set_pose_refinement(td, pose_settings(cfg));
  return m;
}

template <class Model>
void save_checkpoint(const fs::path& path, const Model& m, const std::string& name, const io::CheckpointRun& run) {
  write_file_atomic(path, m.serialize(name, run));
}
/// Loads `m` from the checkpoint at `path`; returns its record of the run.
template <class Model>
io::CheckpointRun load_checkpoint(const fs::path& path, Model& m) {
  return m.deserialize(read_file(path), path.string());
}

struct RunResult {
  long steps = 0;
  double final_loss = 0, seconds = 0, rays_per_second = 0;
  bool diverged = false, stopped = false;  ///< stopped: the callback asked to stop
  bool collapsed = false;                  ///< a collapse check fired (the run stopped unless allow_collapse)
  std::vector<CollapseCheck> checks;       ///< every collapse check of this run, in order
};

/// What the per-step callback sees: the step just taken, its statistics, the period's means (over the
/// steps since the last log line) when `logged` is true, and the wall time so far.
struct StepReport {
  long step = 0;
  StepStats stats;
  bool logged = false;
  double mean_loss = 0, mean_event_loss = 0, mean_threshold_loss = 0;
  double seconds = 0;
};

/// Writes `out/settings.json`, what trained the run in `out`: {"variant": name, "runs": [...]}, one entry per
/// call of train::run (settings_json and "from_step", the step it started from). A fresh run starts the list
/// afresh; a resumed one keeps the entries that started before its checkpoint's step (a call that died
/// before its first checkpoint left no steps) and appends its own. Written atomically; a file that is not
/// this object is refused, naming it, rather than overwritten.
inline void record_settings(const fs::path& out, const Config& c, const std::string& name, long from_step) {
  const fs::path file = out / "settings.json";
  nlohmann::json runs = nlohmann::json::array();
  if (from_step > 0 && fs::exists(file)) {
    const auto old = nlohmann::json::parse(read_file(file), nullptr, false);
    if (old.is_discarded() || !old.is_object() || !old.contains("runs") || !old["runs"].is_array())
      throw Error(file.string(), 0, "not the settings record train writes (a JSON object with a \"runs\" array); move it away to resume");
    for (const auto& r : old["runs"])
      if (r.is_object() && r.contains("from_step") && r["from_step"].is_number_integer() && r["from_step"].get<long>() < from_step)
        runs.push_back(r);
  }
  auto entry = settings_json(c);
  entry["from_step"] = from_step;
  runs.push_back(std::move(entry));
  write_file_atomic(file, nlohmann::json{{"variant", name}, {"runs", std::move(runs)}}.dump(2) + "\n");
}

/// Steps between two lines of log.jsonl (each line holds the means over them).
inline constexpr long kLogEvery = 50;
/// The transmittance behind which a training ray stops where the sampler skips samples
/// (EvNerf::set_ray_termination): a step evaluates 21–32 % fewer samples than at the backward pass's own
/// cut of 1e-4, at the same quality.
inline constexpr double kRayCut = 1e-2;

namespace detail {

/// The sums over the steps since the last log line, whose means the line reports.
struct LogPeriod {
  double loss = 0, event = 0, threshold = 0, samples = 0, backward = 0;
  std::array<double, StepStats::kMaxTerms> terms{};
  long steps = 0;
  void add(const StepStats& st, int n_terms) {
    loss += st.loss;
    event += st.event_loss;
    threshold += st.threshold_loss;
    for (int k = 1; k < n_terms; ++k) terms[k] += st.term_loss[k];
    samples += static_cast<double>(st.samples) / std::max<std::size_t>(1, st.rays);
    backward += static_cast<double>(st.backward_samples) / std::max<std::size_t>(1, st.rays);
    ++steps;
  }
};

/// out/log.jsonl opened for a run at `step`: started afresh at step 0; on a resume, first rid of the lines
/// past the checkpoint's step (written before the process died), then appended to.
inline std::ofstream open_log(const fs::path& out, long step) {
  const fs::path file = out / "log.jsonl";
  if (step > 0 && fs::exists(file)) {
    std::string kept, line;
    std::istringstream in(read_file(file));
    while (std::getline(in, line)) {
      const auto j = nlohmann::json::parse(line, nullptr, false);
      if (!j.is_discarded() && j.contains("step") && j["step"].is_number() && j["step"].get<long>() <= step) kept += line + "\n";
    }
    write_file_atomic(file, kept);
  }
  std::ofstream log(file, step == 0 ? std::ios::trunc : std::ios::app);
  if (!log) throw Error(file.string(), 0, "cannot open the training log for writing");
  return log;
}

/// A log line: the period's means, the learning rate, the speed, the model's learned refractory period,
/// backdrop and pose corrections (their mean size, the clock offset), and each regulariser that is on (as <name>_loss).
template <class Model>
nlohmann::ordered_json log_line(const Model& model, const LogPeriod& p, long step, std::size_t rays, double seconds) {
  const double n = static_cast<double>(p.steps);
  nlohmann::ordered_json j = {{"step", step},
                              {"loss", p.loss / n},
                              {"event_loss", p.event / n},
                              {"threshold_loss", p.threshold / n},
                              {"steps_in_mean", p.steps},
                              {"samples_per_ray", p.samples / n},
                              {"backward_samples_per_ray", p.backward / n},
                              {"lr", model.optimizer().learning_rate()},
                              {"rays_per_s", rays / std::max(seconds, 1e-9)},
                              {"seconds", seconds}};
  if (model.refractory().active()) j["refractory"] = model.refractory().seconds;
  if (const auto& pr = model.pose_refinement(); pr.active()) {
    double t = 0, r = 0;  // the corrections' mean size
    for (const auto& c : pr.correction) {
      t += c.t.norm() / pr.correction.size();
      r += Eigen::AngleAxisd(c.q).angle() * (180.0 / 3.14159265358979323846) / pr.correction.size();
    }
    j["pose_correction_translation"] = t;
    j["pose_correction_rotation_deg"] = r;
    if (pr.settings.offset) j["time_offset"] = pr.offset;
  }
  if (model.renderer().learns_backdrop()) {  // the learned backdrop's luminance per channel
    const auto b = *model.renderer().backdrop(model.params().values.data());
    j["background"] = std::vector<double>(b.begin(), b.end());
  }
  for (int k = 1; k < Model::n_terms; ++k)
    if (model.objective().active(k)) j[std::string(Model::term_name(k)) + "_loss"] = p.terms[k] / n;
  return j;
}

/// A log line's figures of a sharded step: the shards, and with processes their exchange since the last
/// line. The processes hold the same parameters (each applies the same summed gradients); a difference would
/// mean the sums differ between them, and the runs would drift apart silently: an Error.
template <class Model>
void log_shards(nlohmann::ordered_json& j, const Model& model, int shard_count, Group* group, GradientExchange& exchange, Exchange mode,
                long step) {
  j["shards"] = shard_count;
  if (!group) return;
  j["ranks"] = group->size();
  j["exchange_bytes_per_step"] = exchange.bytes() / std::max(1L, exchange.steps());
  j["exchange_seconds_per_step"] = exchange.seconds() / std::max(1L, exchange.steps());
  j["sparse_steps"] = exchange.sparse_steps();
  if (mode != Exchange::Dense) j["touched_blocks"] = exchange.last_fraction();  // dense never looks
  exchange.reset();
  const auto& v = model.params().values;
  if (!group->same(fnv1a64(std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0])))))
    throw Error("train: at step " + std::to_string(step) + " the processes' parameters differ (rank " + std::to_string(group->rank()) +
                " sees another checksum); the group's sums are not the same on every process");
}

}  // namespace detail

/// A collapse check at `step` of a model whose renders show `views` (view_statistics): their log spread,
/// and (where `start_steps` > 0) the event loss of the last log period against the mean of the run's first
/// steps (`start_sum` over `start_steps`).
inline CollapseCheck collapse_check(const ViewStatistics& views, long step, double start_sum, long start_steps, double recent) {
  CollapseCheck c;
  c.step = step;
  c.log_spread = views.log_spread;
  c.flat_renders = c.log_spread < CollapseCheck::kMinLogSpread;
  if (start_steps > 0) {  // a resumed run has no start of its own to compare with
    c.start_loss = start_sum / static_cast<double>(start_steps);
    c.recent_loss = recent;
    c.loss_stuck = c.recent_loss > CollapseCheck::kMinLossImprovement * c.start_loss;
  }
  return c;
}

/// Trains `model` for cfg.iterations steps in total (a resumed model continues from its step). Writes
/// `out/settings.json` (record_settings: the settings of every call that trained the run), `out/log.jsonl`
/// (started afresh when the model is at step 0, appended to on a resume: one line every `kLogEvery` steps,
/// every figure a mean over the steps since the previous line) and `out/model.ckpt` every checkpoint_every
/// steps and at the end; an empty `out` writes nothing (the model stays in memory, as the Python module's
/// `train` without `out` has it). On a NaN/Inf loss, or a NaN/Inf parameter when a checkpoint
/// is due, it stops with a message (RunResult::diverged) and leaves the last good checkpoint in place. A
/// resumed run first drops the log's lines past the checkpoint's step (written before the process died),
/// so the log reads as one run. `on_step`, when given, is called after every step and may return false to
/// stop the run (a checkpoint is written first). The caller's thread count is restored on return.
template <class Model, class OnStep = bool (*)(const StepReport&)>
RunResult run(Model& model, const TrainingData& td, const Config& cfg, const fs::path& out, const std::string& name,
              const io::CheckpointRun& described, OnStep&& on_step = nullptr) {
  check(cfg);
  auto* tv_term = model.template term<loss::TvTerm>();
  // A weight for a term the variant does not have would be silently ignored: refuse it.
  require(!cfg.tv || *cfg.tv == 0 || tv_term, "train: a total-variation weight of " + short_number(cfg.tv.value_or(0)) +
                                                  " for a variant without the term (use fast, or add "
                                                  "loss::TotalVariation to the variant's objective)");
  require(cfg.collapse_check_every % kLogEvery == 0 && cfg.collapse_check_from % kLogEvery == 0,
          "train: collapse checks run at log steps: their period and first step must be multiples of " + std::to_string(kLogEvery));
  Group* group = cfg.processes();
  const int rank = group ? group->rank() : 0, shard_count = cfg.shard_count();
  const StepShards shards{shard_count, rank, group ? group->size() : 1};
  GradientExchange exchange(group, cfg.exchange);
  const bool files = !out.empty() && rank == 0;  // rank 0 writes; the others only train
  io::CheckpointRun saved_run = described;       // what each checkpoint records of this run
  saved_run.shards = static_cast<std::uint64_t>(shard_count);
  if (files) {
    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) throw Error(out.string(), 0, "cannot create the output folder: " + ec.message());
  }
  const ScopedThreadCount threads(cfg.threads);
  model.set_ray_termination(true, kRayCut);
  if (cfg.tv && tv_term) tv_term->set_weight(*cfg.tv);
  model.set_average(cfg.average);  // a resumed model keeps the average its checkpoint holds
  // The settings first: a record it cannot read refuses the call before the log is touched. The term's
  // weight as the model now has it, its variant's where cfg leaves it unset: what trains the run.
  if (files) {
    Config used = cfg;
    if (tv_term) used.tv = tv_term->weight;
    record_settings(out, used, name, model.step());
  }
  std::ofstream log;
  if (files) log = detail::open_log(out, model.step());
  Progress bar(cfg.iterations, "train", cfg.progress && rank == 0);
  RunResult r;
  const double t_start = bar.elapsed();
  detail::LogPeriod period;
  double start_event = 0;  // the event loss summed over the first kLogEvery steps
  long start_steps = 0;
  std::size_t rays = 0;
  const fs::path ckpt = out / "model.ckpt";
  auto diverged = [&](const std::string& what) {
    r.diverged = true;
    if (rank != 0) return;
    std::error_code ec;
    std::fprintf(stderr, "\ntraining diverged at step %ld (%s); %s\n", model.step(), what.c_str(),
                 !files                 ? "nothing was written (no output folder)"
                 : fs::exists(ckpt, ec) ? ("the last good checkpoint is " + ckpt.string() + ", unchanged").c_str()
                                        : "no checkpoint was written");
  };
  // A checkpoint is written only of finite parameters: a NaN or Inf in them stops the run as a divergence
  // and leaves the previous checkpoint as it was.
  auto save = [&] {
    const auto& v = model.params().values;
    const auto bad = std::find_if(v.begin(), v.end(), [](auto x) { return !std::isfinite(static_cast<double>(x)); });
    if (bad != v.end()) {
      diverged("parameter " + std::to_string(bad - v.begin()) + " of " + std::to_string(v.size()) + " is " +
               short_number(static_cast<double>(*bad)));
      return false;
    }
    if (files) save_checkpoint(ckpt, model, name, saved_run);
    return true;
  };
  while (model.step() < cfg.iterations) {
    const auto st =
        shard_count == 1 ? model.train_step(td, cfg.pixels, cfg.seed) : model.train_step(td, cfg.pixels, cfg.seed, 0, shards, exchange);
    if (!std::isfinite(st.loss)) {
      diverged("loss " + short_number(st.loss));
      break;
    }
    rays += st.rays;
    period.add(st, Model::n_terms);
    r.final_loss = st.loss;
    const long s = model.step();
    if (s <= kLogEvery) {
      start_event += st.event_loss;
      ++start_steps;
    }
    const double el = bar.elapsed() - t_start;
    char extra[160];
    const double n = static_cast<double>(period.steps);
    std::snprintf(extra, sizeof extra, "loss %.4f  rays/s %.0f", period.loss / n, rays / std::max(el, 1e-9));
    bar.update(s, extra);
    StepReport rep{s, st, false, period.loss / n, period.event / n, period.threshold / n, el};
    if (s % kLogEvery == 0 || s == cfg.iterations) {
      rep.logged = true;
      auto j = detail::log_line(model, period, s, rays, el);
      if (shard_count > 1) detail::log_shards(j, model, shard_count, group, exchange, cfg.exchange, s);
      if constexpr (requires { requires Model::sampler_type::skips_samples; }) {
        j["occupied"] = model.sampler().occupied_fraction();
        if constexpr (requires { model.sampler().grid().seen_fraction(); })
          j["occupied_of_seen"] = model.sampler().occupied_fraction() / std::max(1e-12, model.sampler().grid().seen_fraction());
      }
      const bool check = cfg.collapse_check_every > 0 && cfg.collapse_check_from > 0 && s >= cfg.collapse_check_from &&
                         (s - cfg.collapse_check_from) % cfg.collapse_check_every == 0;
      if (check) {
        const ViewStatistics views = view_statistics(model, td);
        const CollapseCheck c = collapse_check(views, s, start_event, start_steps, rep.mean_event_loss);
        j["collapse_check"] = {{"log_spread", c.log_spread}, {"backdrop_share", views.backdrop_share}, {"collapsed", c.collapsed()}};
        r.checks.push_back(c);
        if (c.collapsed()) {
          r.collapsed = true;
          if (rank == 0)
            std::fprintf(stderr, "\ntraining has collapsed %s%s\n", c.describe().c_str(),
                         cfg.allow_collapse ? "; going on (allow_collapse)" : "; stopping (pass --allow-collapse to go on)");
        }
      }
      if (files) {
        log << j.dump() << "\n";
        log.flush();
      }
      period = {};
      if (r.collapsed && !cfg.allow_collapse) {
        ++r.steps;
        save();
        break;
      }
    }
    bool go_on = true;
    if constexpr (!std::is_same_v<std::decay_t<OnStep>, bool (*)(const StepReport&)>) {
      go_on = on_step(rep);
    } else {
      if (on_step) go_on = on_step(rep);
    }
    if (group) {  // a stop anywhere stops every process at this step
      double stop = go_on ? 0.0 : 1.0;
      group->sum(&stop, 1);
      go_on = stop == 0.0;
    }
    ++r.steps;
    if ((cfg.checkpoint_every > 0 && s % cfg.checkpoint_every == 0) || s == cfg.iterations || !go_on)
      if (!save()) break;
    if (!go_on) {
      r.stopped = true;
      break;
    }
  }
  r.seconds = bar.elapsed() - t_start;
  r.rays_per_second = rays / std::max(r.seconds, 1e-9);
  return r;
}

/// A training run of `Model` as one object: the Config is its only source of settings (scene box from
/// near/far, density_per_box and background, Adam from lr and its decay, seed, threads, steps, checkpoint period), the
/// output folder holds log.jsonl and model.ckpt. The training data must outlive the trainer.
template <class Model>
class Trainer {
 public:
  Trainer(const TrainingData& td, Config cfg, fs::path out, std::string name, io::CheckpointRun run)
      : td_(td), cfg_(cfg), out_(std::move(out)), name_(std::move(name)), run_(std::move(run)), model_(make_model<Model>(td, cfg_)) {}

  /// Continues from out/model.ckpt when there is one (same architecture and loss; the Config's learning
  /// rate applies from here on). Returns whether it did.
  /// In a group, rank 0 reads the file and every process gets its bytes (no shared file system needed).
  /// A checkpoint of another shard count is refused: its run would go on drawing other rays.
  bool resume() {
    Group* g = cfg_.processes();
    const fs::path file = out_ / "model.ckpt";
    std::string bytes;  // "" when there is no checkpoint, else "c" and the file's bytes (an empty file is damaged)
    if ((!g || g->rank() == 0) && !out_.empty() && fs::exists(file)) bytes = "c" + read_file(file);
    if (g) g->broadcast(bytes);
    if (bytes.empty()) return false;
    const io::CheckpointRun run = model_.deserialize(bytes.substr(1), file.string());
    const auto shards = static_cast<std::uint64_t>(cfg_.shard_count());
    if (run.shards != shards)
      throw Error(file.string(), 0,
                  "the checkpoint was trained with " + std::to_string(run.shards) + " shard(s) per step, this run has " +
                      std::to_string(shards) + " (processes × shards): resume with --shards " + std::to_string(run.shards) +
                      " (any number of processes that divides it)");
    model_.optimizer().set_config(adam_config(cfg_));
    if (model_.refractory().learned && td_.refractory_bound >= 0) model_.set_refractory_bound(refractory_start(td_));
    follow_box();
    model_.set_pose_rates(td_, pose_settings(cfg_));
    return true;
  }
  /// Trains up to cfg.iterations steps in total (see train::run); `on_step` may stop early.
  template <class OnStep = bool (*)(const StepReport&)>
  RunResult run(OnStep&& on_step = nullptr) {
    return train::run(model_, td_, cfg_, out_, name_, run_, std::forward<OnStep>(on_step));
  }
  Model& model() { return model_; }
  const Model& model() const { return model_; }
  const Config& config() const { return cfg_; }
  const fs::path& out() const { return out_; }

 private:
  /// A resumed model keeps its checkpoint's scene box (near, far, its density unit and backdrop), its
  /// refractory period and what it refines of the poses, whatever this call's Config says; the Config takes them over, so that settings.json
  /// records what the run uses.
  void follow_box() {
    const auto& b = model_.box();
    cfg_.near = b.near;
    cfg_.far = b.far;
    cfg_.density_per_box = b.density_length != 1.0;
    cfg_.background = b.background;
    cfg_.learn_background = b.background_learned;  // a known background (above) is never learned
    const auto& r = model_.refractory();
    if (r.learned) cfg_.refractory.reset();
    else cfg_.refractory = r.active() ? r.seconds : 0.0;
    cfg_.refine_poses = model_.pose_refinement().settings.poses;  // what the checkpoint learns, it goes on learning
    cfg_.learn_time_offset = model_.pose_refinement().settings.offset;
  }

  const TrainingData& td_;
  Config cfg_;
  fs::path out_;
  std::string name_;
  io::CheckpointRun run_;
  Model model_;
};

}  // namespace evnerf::train
