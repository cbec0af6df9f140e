// evnerf — the command-line tool (inspect, simulate, baselines, train, render, eval) over the built-in
// variants. The whole tool is evnerf::cli::main (include/evnerf/cli/cli.hpp); a program with your own
// variants is the same few lines (examples/custom_variant.cpp). Built with EVNERF_MPI=ON, `mpirun -np N
// evnerf train …` trains data-parallel (dist/mpi.hpp); run on its own it starts no MPI runtime.
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
  return evnerf::cli::main<Variant<Fast, "fast">, Variant<FastOneSlice, "fast-slice">, Variant<FastBf16, "fast-bf16">,
                           Variant<FastNoJointThresholds, "no-joint">, Variant<FastNoNoiseInjection, "no-noise">,
                           Variant<FastColour, "colour">, Variant<FastDenseGrid, "fast-dense-grid">,
                           Variant<FastColourDenseGrid, "colour-dense-grid">, Variant<FastSigmoid, "fast-sigmoid">,
                           Variant<FastColourSigmoid, "colour-sigmoid">, Variant<Paper, "paper">, Variant<PaperBf16, "paper-bf16">,
                           Variant<PaperNoJointThresholds, "paper-no-joint">, Variant<PaperNoNoiseInjection, "paper-no-noise">,
                           Variant<FastRatio, "fast-ratio">, Variant<FastPrune, "fast-prune">, Variant<FastTv, "fast-tv">, Variant<FastNoTv, "fast-no-tv">, Variant<FastDiffuse, "fast-diffuse">, Variant<FastLog, "fast-log">, Variant<FastLogOffset, "fast-log-offset">, Variant<FastThreePoses, "fast-3poses">, Variant<FastWindow<8>, "fast-w8">, Variant<FastWindow<48>, "fast-w48">,
                           Variant<FastWindow<24, evnerf::events::EventPixels<100>>, "fast-events">>(argc, argv, "evnerf: neural radiance fields from event cameras", group);
}
