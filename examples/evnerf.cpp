// evnerf — the command-line tool (inspect, simulate, baselines, train, render, eval, convert) over the
// built-in variants (model/presets.hpp). The whole tool is evnerf::cli::main (include/evnerf/cli/cli.hpp); a
// program with your own variants is the same few lines (examples/custom_variant.cpp). Built with
// EVNERF_MPI=ON, `mpirun -np N evnerf train …` trains data-parallel (dist/mpi.hpp); run on its own it starts
// no MPI runtime.
#include <evnerf/cli/cli.hpp>
#ifdef EVNERF_MPI
#include <evnerf/dist/mpi.hpp>
#endif

int main(int argc, char** argv) {
  using namespace evnerf::presets;
  using evnerf::cli::Variant;
#ifdef EVNERF_MPI
  evnerf::dist::MpiGroup world(argc, argv);
  evnerf::train::Group* group = &world;
#else
  evnerf::train::Group* group = nullptr;
#endif
  return evnerf::cli::main<Variant<Fast, "fast">, Variant<FastNoJointThresholds, "no-joint">, Variant<FastNoNoiseInjection, "no-noise">,
                           Variant<FastNoTv, "fast-no-tv">, Variant<FastOneSlice, "fast-slice">, Variant<FastColour, "colour">,
                           Variant<FastBf16, "fast-bf16">, Variant<Paper, "paper">, Variant<PaperNoJointThresholds, "paper-no-joint">,
                           Variant<PaperNoNoiseInjection, "paper-no-noise">, Variant<PaperBf16, "paper-bf16">, Variant<Splat, "splat">,
                           Variant<SplatColour, "splat-colour">>(argc, argv, "evnerf: neural radiance fields from event cameras", group);
}
