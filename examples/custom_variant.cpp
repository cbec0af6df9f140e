// A user's own Ev-NeRF variant with the whole command line: another encoding (Frequency<6> instead of a
// hash grid), another activation (Softplus), other widths, 48 stratified samples, and the windowed
// objective. `custom_variant train <recording> --out DIR`, then `render` and `eval`, as with `evnerf`.
#include <evnerf/cli/cli.hpp>

using namespace evnerf;
// γ(x) with 6 frequencies → 3 × 96 Softplus → density + 8 features; features + SH degree 3 → 48 → luminance.
// FieldOf derives the networks' input and output widths from the encodings and the feature count.
using MyField = field::FieldOf<nn::Frequency<6>, nn::SphericalHarmonics<3>, nn::MlpShape{.width = 96, .hidden_layers = 3}, 8,
                               nn::MlpShape{.width = 48, .hidden_layers = 1}, 1, nn::Softplus>;
using Mine = EvNerf<MyField, render::Stratified<48>, loss::ProjectedThresholds, loss::DefaultNoise, loss::WindowInterval<16>>;

int main(int argc, char** argv) {
  return cli::main<cli::Variant<Mine, "mine">, cli::Variant<presets::Fast, "fast">>(argc, argv, "evnerf with my own variant");
}
