// cli/cli.hpp — the whole command line (inspect, simulate, baselines, train, render, eval, convert) for any
// list of variants, so that a researcher's own variant gets it from a program of a few lines:
//
//   #include <evnerf/cli/cli.hpp>
//   using Mine = evnerf::EvNerf<...>;
//   int main(int argc, char** argv) {
//     return evnerf::cli::main<evnerf::cli::Variant<Mine, "mine">, evnerf::cli::Variant<evnerf::presets::Fast, "fast">>(argc, argv);
//   }
//
// The first variant is `train`'s default. What depends on a model type is here (training one model, opening
// a checkpoint of the list); the verbs themselves are cli::run (cli/run.hpp). Not included by the umbrella
// header: only programs that want the command line pay for CLI11. Depends on everything.
#pragma once
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>

#include <fmt/core.h>
#include <fmt/format.h>

#include "../eval/load.hpp"
#include "../evnerf.hpp"
#include "run.hpp"

namespace evnerf::cli {

namespace fs = std::filesystem;

using evnerf::checkpoint_variant;
using evnerf::Name;
using evnerf::Variant;
using evnerf::with_variant;

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

}  // namespace detail

/// Whether a model can start from another model's scene (Gaussians: Model::start_from, train --start-from).
template <class M>
inline constexpr bool starts_from_scene = requires(M& m, const splat::Seeds& s) {
  m.start_from(s);
};

/// `train` for one model type: a Trainer over `td` writing to `dir`, resumed if asked, stopped cleanly by
/// SIGINT or SIGTERM; returns the exit code (cli::main's list).
template <class Model>
int train_model(const TrainJob& job, const std::string& name, const TrainingData& td, const fs::path& dir, std::size_t n_events) {
  using detail::StopOnSignal;
  const io::CheckpointRun described = train::describe(td, job.recording);
  const train::Config& cfg = *job.cfg;
  const bool lead = job.lead;
  train::Group* group = job.group;
  train::Trainer<Model> trainer(td, cfg, dir, name, described);
  if (job.resume && trainer.resume() && lead) {
    fmt::print(stderr, "resuming {} at step {}\n", name, trainer.model().step());
    const auto& kept = trainer.config();  // the checkpoint's scene box, whatever the options say
    if (kept.near != cfg.near || kept.far != cfg.far)
      fmt::print(stderr, "note: the checkpoint's scene box is kept (near {}, far {}); --near and --far apply to new runs\n", kept.near,
                 kept.far);
  }
  if (job.teacher && trainer.model().step() == 0) {
    if constexpr (starts_from_scene<Model>) {
      const evaluation::Renderable& t = *job.teacher;
      splat::Seeds seeds = evaluation::gaussian_seeds(t.render_with, td.camera, td.boundary_poses, Model::renderer_type::capacity);
      seeds.backdrop = t.backdrop;
      seeds.thresholds = t.thresholds;
      if (seeds.size() == 0) {  // a field that has not learned its surfaces yet: it can still teach
        if (lead)
          fmt::print(stderr,
                     "note: the teacher ({}) is opaque at no pixel of the recorded poses: the Gaussians start in the cameras' frusta, "
                     "taught by it\n",
                     t.name);
      } else {
        trainer.model().start_from(seeds);
        if (lead)
          fmt::print(stderr, "started {} Gaussians from the surfaces of the teacher ({}: {}{}{})\n",
                     std::min(seeds.size(), Model::renderer_type::capacity), t.name, seeds.channels == 1 ? "grey" : "colour",
                     seeds.thresholds.size() == 2 * td.slices.size() ? ", its thresholds" : "",
                     !seeds.backdrop.empty() && trainer.model().renderer().learns_backdrop() ? ", its backdrop" : "");
      }
    } else {
      throw Error("train --start-from: the variant '" + name + "' does not start from another model's scene (the Gaussians' presets do)");
    }
  }
  if (lead)
    fmt::print(stderr, "training {} on {} slices, {} events, {} threads{}\n", name, td.slices.size(), n_events,
               cfg.threads > 0 ? cfg.threads : thread_count(),
               group                   ? fmt::format(" in each of {} processes, {} shards per step", group->size(), cfg.shard_count())
               : cfg.shard_count() > 1 ? fmt::format(", {} shards per step", cfg.shard_count())
                                       : std::string());
  if (lead && !td.masked.empty())
    fmt::print(stderr,
               "left out {} suspected hot pixel{} (busiest at x {}, y {}: {} events against {} next to it; --keep-hot-pixels keeps them)\n",
               td.masked.size(), td.masked.size() == 1 ? "" : "s", td.masked[0].x, td.masked[0].y, td.masked[0].events,
               td.masked[0].neighbours);
  if (const auto& rp = trainer.model().refractory(); lead && rp.learned && td.refractory_bound >= 0 && trainer.model().step() == 0)
    fmt::print(stderr, "refractory period learned from {:.1f} us down (the {:g} % quantile of the pixels' intervals between events)\n",
               rp.seconds * 1e6, events::kRefractoryBoundQuantile * 100);
  // SIGINT (Ctrl-C) and SIGTERM (a batch system's stop) end the run after the current step with a
  // checkpoint; a second signal kills at once (the handler restores the default action).
  const StopOnSignal stop_request;
  const auto r = trainer.run([&](const train::StepReport&) { return !stop_request.requested(); });
  // Every process returns the same code; rank 0 alone says why.
  if (lead)
    fmt::print("trained {}: {} steps in {:.1f} s ({:.0f} rays/s), final loss {:.5f}{} → {}\n", name, r.steps, r.seconds, r.rays_per_second,
               r.final_loss, r.diverged ? " (DIVERGED)" : "", (dir / "model.ckpt").string());
  if (const auto& rp = trainer.model().refractory(); lead && rp.active())
    fmt::print("refractory period {:.1f} us ({})\n", rp.seconds * 1e6, rp.learned ? "learned" : "given");
  if (const auto& m = trainer.model(); lead && m.renderer().learns_backdrop()) {
    const auto b = *m.renderer().backdrop(m.render_params().data());
    fmt::print("backdrop luminance {:.4g} (learned{})\n", fmt::join(b, " "), b.size() > 1 ? ", per channel" : "");
  }
  if (const auto& m = trainer.model(); lead && m.pose_refinement().active()) {
    const auto& pr = m.pose_refinement();
    const auto moved = geometry::pose_error(m.refined_poses(), td.boundary_poses);
    fmt::print("poses refined: {:.3g} world units and {:.3g} degrees from the recording's on average{}\n", moved.translation_mean,
               moved.rotation_mean_deg,
               pr.settings.offset ? fmt::format(", clock offset {:.2f} ms learned", pr.offset * 1e3) : std::string());
  }
  if (r.diverged) return 3;
  if (r.stopped) {
    // In a group the signal may have reached another process only: its stop is shared (train::run).
    const int sig = stop_request.requested() ? stop_request.signal_number() : SIGTERM;
    if (lead)
      fmt::print(stderr, "train: stopped by {} at step {}; the checkpoint is written, continue with --resume\n",
                 stop_request.requested() ? stop_request.signal_name() : "a signal to another process", trainer.model().step());
    return 128 + sig;
  }
  if (r.collapsed && !cfg.allow_collapse) {
    if (lead)
      fmt::print(stderr, "train: the run collapsed ({}); the checkpoint is kept, but this is not a usable model\n",
                 r.checks.back().describe());
    return 4;
  }
  return 0;
}

/// The command line over the variants V... (the first is train's default). Returns the process exit code:
/// 0 success, 1 an error (printed), 2 a usage error (printed with the command's flags), 3 training diverged,
/// 4 training collapsed (train::CollapseCheck; --allow-collapse goes on and returns 0).
/// `group` (dist/mpi.hpp's MpiGroup under mpirun; null or one process: alone) makes `train` data-parallel:
/// every process trains its shards of each step, rank 0 alone prints and writes, and an error on any
/// process ends them all (Group::abort) rather than leaving the others waiting. The other verbs refuse
/// to run in a group of several processes.
template <class... V>
int main(int argc, char** argv, const std::string& description = "evnerf: neural radiance fields from event cameras",
         train::Group* group = nullptr) {
  static_assert(sizeof...(V) >= 1, "cli::main needs at least one variant");
  Programme p;
  p.description = description;
  p.variants = {
      VariantEntry{std::string(V::name), V::model::channels, &train_model<typename V::model>, starts_from_scene<typename V::model>}...};
  p.open = &evaluation::load_model<V...>;
  return run(argc, argv, p, group);
}

}  // namespace evnerf::cli
