// A new sampler is one type (examples/parts/inverse_depth.hpp); the Fast preset with it instead of the
// occupancy grid gets the whole command line. `custom_sampler train <recording> --out DIR`, then render, eval.
#include <evnerf/cli/cli.hpp>

#include "parts/inverse_depth.hpp"

using namespace evnerf;
using FastInverseDepth = EvNerf<presets::FastField<>, mylab::InverseDepth<64>, loss::ProjectedThresholds, loss::DefaultNoise,
                                presets::FastObjective>;

int main(int argc, char** argv) {
  return cli::main<cli::Variant<FastInverseDepth, "fast-inverse-depth">>(argc, argv, "evnerf with samples spaced in disparity");
}
