// cli/run.hpp — the command line's body, which does not depend on a model type: the verbs, their flags,
// and what each does, over a table of the program's variants (the per-model parts cli::main instantiates:
// train one model, open a checkpoint). Defined in cli/run_impl.hpp, included here unless the program
// compiles it once (core/compiled.hpp). Depends on eval/evaluate.hpp and train/.
#pragma once
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "../core/compiled.hpp"
#include "../eval/evaluate.hpp"
#include "../train/group.hpp"
#include "../train/settings.hpp"

namespace evnerf::cli {

/// What `train` gives a variant's training function besides the data: the settings, the recording's path
/// (the checkpoint names it), whether to resume, whether this process prints (rank 0), its group, and the
/// model a new scene starts from.
struct TrainJob {
  const train::Config* cfg = nullptr;
  std::string recording;
  bool resume = false;
  bool lead = true;
  train::Group* group = nullptr;
  /// A trained model the scene starts from (train --start-from: Gaussians from a field's surfaces; null: the
  /// variant's own start).
  const evaluation::Renderable* teacher = nullptr;
};

/// Trains one model of a variant on `td` into `dir` (the model type is the function's); returns the exit
/// code (cli::main's list).
using TrainFunction = int (*)(const TrainJob& job, const std::string& name, const TrainingData& td, const std::filesystem::path& dir,
                              std::size_t n_events);

/// One variant of a program's command line: its name, how many channels it renders, and its training.
struct VariantEntry {
  std::string name;
  int channels = 1;
  TrainFunction train = nullptr;
  bool starts_from_scene = false;  ///< whether it can start from another model's scene (train --start-from: Gaussians)
};

/// A program's command line: its description (the first line of --help), its variants (the first is
/// train's default), and the opening of a model.ckpt written by any of them.
struct Programme {
  std::string description;
  std::vector<VariantEntry> variants;
  evaluation::Renderable (*open)(const std::filesystem::path& checkpoint) = nullptr;
};

/// The command line of `programme` over argv; returns the process exit code (cli::main documents them).
EVNERF_COMPILED int run(int argc, char** argv, const Programme& programme, train::Group* group);

}  // namespace evnerf::cli

#ifndef EVNERF_SEPARATE_COMPILATION
#include "run_impl.hpp"
#endif
