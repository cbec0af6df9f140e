// New parts, each one type in a header under examples/parts/, each in its own variant, all in one
// program with the whole command line:
//   fast-inverse-depth  a sampler: the Fast preset with 64 samples stratified in disparity instead of the
//                       occupancy grid (parts/inverse_depth.hpp);
//   triangles           an encoding: triangle waves, FieldOf deriving the networks' widths from it
//                       (parts/triangle_wave.hpp);
//   fast-shot-noise     an objective: an interval whose slack grows with √N, windows of up to 32 slices at
//                       event-weighted pixels (parts/shot_noise_counts.hpp);
//   fast-eventnerf      an objective: EventNeRF's squared event loss, normalised by the thresholds
//                       (parts/eventnerf_mse.hpp);
//   fast-quiet          a regulariser: Fast's objective plus a pull to no change where a window has no event
//                       (parts/quiet_pixels.hpp);
// and a file format, registered for every command: events as CSV (parts/csv_events.hpp; `custom_parts
// convert rec out/events.csv`, then `custom_parts train out/events.csv …`).
// `custom_parts train <recording> --out DIR --variant triangles`, then render and eval (the first variant is
// the default). One program rather than three: the command line's own code compiles once.
#include <evnerf/cli/cli.hpp>

#include "parts/csv_events.hpp"
#include "parts/eventnerf_mse.hpp"
#include "parts/inverse_depth.hpp"
#include "parts/quiet_pixels.hpp"
#include "parts/shot_noise_counts.hpp"
#include "parts/triangle_wave.hpp"

using namespace evnerf;
using FastInverseDepth =
    EvNerf<presets::FastField<>, mylab::InverseDepth<64>, loss::ProjectedThresholds, loss::DefaultNoise, presets::FastObjective>;
using TriangleField = field::FieldOf<mylab::TriangleWave<8>, nn::SphericalHarmonics<3>, nn::MlpShape{.width = 128, .hidden_layers = 4}, 16,
                                     nn::MlpShape{.width = 64, .hidden_layers = 1}>;
using Triangles = EvNerf<TriangleField, render::Stratified<64>, loss::ProjectedThresholds, loss::DefaultNoise, presets::FastObjective>;
using FastShotNoise = presets::FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, mylab::ShotNoiseWindows>;
using FastEventNerf = presets::FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, mylab::EventNerfMse<>>;
using FastQuiet = presets::FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1,
                                     loss::Plus<presets::FastEventObjective, presets::FastTv, mylab::QuietPixels<300>>>;

int main(int argc, char** argv) {
  io::register_format(mylab::csv_format());
  return cli::main<cli::Variant<FastInverseDepth, "fast-inverse-depth">, cli::Variant<Triangles, "triangles">,
                   cli::Variant<FastShotNoise, "fast-shot-noise">, cli::Variant<FastEventNerf, "fast-eventnerf">,
                   cli::Variant<FastQuiet, "fast-quiet">>(argc, argv, "evnerf with new samplers, encodings, objectives and regularisers");
}
