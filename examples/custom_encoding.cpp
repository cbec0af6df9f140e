// A new encoding is one type (examples/parts/triangle_wave.hpp); FieldOf derives the networks' widths
// from it. `custom_encoding train <recording> --out DIR`, then render and eval.
#include <evnerf/cli/cli.hpp>

#include "parts/triangle_wave.hpp"

using namespace evnerf;
using TriangleField = field::FieldOf<mylab::TriangleWave<8>, nn::SphericalHarmonics<3>, nn::MlpShape{.width = 128, .hidden_layers = 4}, 16,
                                     nn::MlpShape{.width = 64, .hidden_layers = 1}>;
using Triangles = EvNerf<TriangleField, render::Stratified<64>, loss::ProjectedThresholds, loss::DefaultNoise, presets::FastObjective>;

int main(int argc, char** argv) {
  return cli::main<cli::Variant<Triangles, "triangles">>(argc, argv, "evnerf with a triangle-wave encoding");
}
