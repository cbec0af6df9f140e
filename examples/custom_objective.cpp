// A new objective is one type (examples/parts/shot_noise_counts.hpp: a bound policy, windows of up to 32
// slices, event-weighted pixels); the Fast preset with it gets the whole command line.
// `custom_objective train <recording> --out DIR`, then render and eval.
#include <evnerf/cli/cli.hpp>

#include "parts/shot_noise_counts.hpp"

using namespace evnerf;
using FastShotNoise = presets::FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, mylab::ShotNoiseWindows>;

int main(int argc, char** argv) {
  return cli::main<cli::Variant<FastShotNoise, "fast-shot-noise">>(argc, argv, "evnerf with a count-dependent interval");
}
