// A Python module with a variant of one's own: the type, then one line. Python then trains it by name:
//   import my_evnerf; model = my_evnerf.train(my_evnerf.simulate("planes"), preset="mine", iterations=100)
// (the module's name must be the file's: build it as my_evnerf, as examples/python/CMakeLists.txt does).
#include <evnerf/python/module.hpp>

using namespace evnerf;
// γ(x) with 6 frequencies → 2 × 64 ReLU → density + 8 features; features + SH degree 2 → 32 → luminance;
// 32 stratified samples; poses up to 16 slices apart.
using MyField = field::FieldOf<nn::Frequency<6>, nn::SphericalHarmonics<2>, nn::MlpShape{.width = 64, .hidden_layers = 2}, 8,
                               nn::MlpShape{.width = 32, .hidden_layers = 1}, 1>;
using Mine = EvNerf<MyField, render::Stratified<32>, loss::ProjectedThresholds, loss::DefaultNoise, loss::WindowInterval<16>>;

EVNERF_PYTHON_MODULE(my_evnerf, Variant<Mine, "mine">, Variant<presets::Fast, "fast">)
