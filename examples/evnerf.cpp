// evnerf — the command-line tool (inspect, simulate, baselines, train, render, eval) over the built-in
// variants. The whole tool is evnerf::cli::main (include/evnerf/cli/cli.hpp); a program with your own
// variants is the same few lines (examples/custom_variant.cpp).
#include <evnerf/cli/cli.hpp>

int main(int argc, char** argv) {
  using namespace evnerf::presets;
  using evnerf::cli::Variant;
  return evnerf::cli::main<Variant<Fast, "fast">, Variant<FastOneSlice, "fast-slice">, Variant<FastBf16, "fast-bf16">,
                           Variant<FastNoJointThresholds, "no-joint">, Variant<FastNoNoiseInjection, "no-noise">,
                           Variant<FastColour, "colour">, Variant<FastSigmoid, "fast-sigmoid">,
                           Variant<FastColourSigmoid, "colour-sigmoid">, Variant<Paper, "paper">, Variant<PaperBf16, "paper-bf16">,
                           Variant<PaperNoJointThresholds, "paper-no-joint">, Variant<PaperNoNoiseInjection, "paper-no-noise">,
                           Variant<FastRatio, "fast-ratio">, Variant<FastWindow<8>, "fast-w8">, Variant<FastWindow<48>, "fast-w48">,
                           Variant<FastWindow<24, evnerf::events::EventPixels<100>>, "fast-events">>(argc, argv);
}
