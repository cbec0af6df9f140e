// model/presets.hpp — the named variants: the paper's model (Paper), the fast hash-grid model (Fast), their
// ablations, the colour model, the mixed-precision twins and the Gaussian scenes (Splat, SplatColour). Each is a type; a variant of your own is
// another alias of EvNerf in your own code (examples/custom_variant.cpp). Depends on model/model.hpp and
// loss/total_variation.hpp.
#pragma once
#include "../loss/teacher.hpp"
#include "../loss/total_variation.hpp"
#include "model.hpp"
#include "splatting.hpp"

namespace evnerf {

namespace presets {
using namespace nn;

/// The paper's field: Frequency 10/4, 8×256 ReLU trunk with the skip before layer 5, a linear head giving
/// density and a 256-wide feature, a 128-wide view layer, `C` luminance outputs. `Prec` is the networks'
/// product precision (nn::Fp32, or nn::Bf16: bf16 factors with FP32 accumulation, nn/detail/bf16.hpp).
template <int C = 1, int W = 256, class Prec = Fp32>
using PaperField = field::FieldOf<Frequency<10>, Frequency<4>, MlpShape{.width = W, .hidden_layers = 8, .skip = 4}, W,
                                  MlpShape{.width = W / 2, .hidden_layers = 1}, C, ReLU, Prec>;
/// The fast field: hash grid (16 levels × 2 features, 2^15 entries, resolutions 16..1024) and degree-4
/// spherical harmonics into two 64-wide networks. `Radiance`: radiance of any range (field::ExpRadiance,
/// Fast's: scenes of high dynamic range need more than the sigmoid's 6.9 nats) or the paper's sigmoid
/// (field::SigmoidRadiance).
template <int C = 1, class Prec = Fp32, class Radiance = field::ExpRadiance>
using FastField = field::FieldOf<HashGrid<16, 2, 15, 16, 1024>, SphericalHarmonics<4>, MlpShape{.width = 64, .hidden_layers = 1}, 15,
                                 MlpShape{.width = 64, .hidden_layers = 2}, C, ReLU, Prec, ReLU, Radiance>;
static_assert(
    std::is_same_v<FastField<1, Fp32, field::SigmoidRadiance>,
                   field::Field<HashGrid<16, 2, 15, 16, 1024>, SphericalHarmonics<4>, Mlp<32, 64, 1, 16>, Mlp<15 + 16, 64, 2, 1>>>,
    "FastField: the derived widths are the ones written out");
static_assert(std::is_same_v<PaperField<>,
                             field::Field<Frequency<10>, Frequency<4>, Mlp<63, 256, 8, 257, ReLU, Identity, 4>, Mlp<256 + 27, 128, 1, 1>>>,
              "PaperField: the derived widths are the ones written out");

/// The paper's model: its field, 64 + 128 hierarchical samples, the one-slice interval of split counts
/// (spec §2), thresholds learned jointly with the λ = 1000 floor, 5 % noise injection.
template <class Th = loss::JointThresholds, class No = loss::DefaultNoise, int C = 1, class Prec = Fp32>
using PaperModel = EvNerf<PaperField<C, 256, Prec>, render::Hierarchical<64, 128>, Th, No>;

/// Fast's event objective: poses 1..24 slices apart (loss::WindowInterval), the half-slack interval (with
/// split counts and k = 1 a constant image costs nothing on pixels with one event, and on sparse or noisy
/// recordings the hash-grid field never leaves it), pixels uniform over the sensor.
using FastEventObjective = loss::WindowInterval<24, loss::HalfSlackCounts>;
/// Fast's regulariser: total variation of the rendered log-luminance (loss::LogTv) at weight 0.1, each pixel
/// compared with its neighbour across the image motion of the window's poses (loss::TvNeighbours::Across),
/// for half the step's pixels (2.5 rays per pixel instead of 2). It ties together the image rows (or
/// columns) whose relative brightness a straight camera motion never shows the events.
using FastTv = loss::TotalVariation<100, loss::TvNeighbours::Across, 500>;
/// Fast's objective: the event objective plus the total-variation term. Its checkpoints record the event
/// objective's loss text (the term's weight is a training setting, train --tv).
using FastObjective = loss::Plus<FastEventObjective, FastTv>;
/// Fast's sampler: 64 stratified samples per ray, skipping cells of a 64³ occupancy grid (updated every 16
/// steps after the first 256) whose density cannot give a sample an alpha of 30 %.
using FastSampler = render::OccupancySkipping<64, 64, 16, 256, 300>;
/// Fast learns its thresholds jointly, kept beyond the floor by projection (loss::ProjectedThresholds: the
/// λ = 1000 floor loss fights the event loss for the first few hundred steps of a run). Its radiance is
/// exp(raw) (field::ExpRadiance).
template <class Th = loss::ProjectedThresholds, class No = loss::DefaultNoise, int C = 1, class Obj = FastObjective, class Prec = Fp32,
          class Radiance = field::ExpRadiance, class Sampler = FastSampler>
using FastModel = EvNerf<FastField<C, Prec, Radiance>, Sampler, Th, No, Obj>;

using Paper = PaperModel<>;
/// The paper's ablations: thresholds fixed at ±0.3, and no noise injection.
using PaperNoJointThresholds = PaperModel<loss::FixedThresholds>;
using PaperNoNoiseInjection = PaperModel<loss::JointThresholds, loss::NoNoise>;
using Fast = FastModel<>;
/// Fast's ablations: thresholds fixed, no noise injection, no total-variation term (its event objective alone,
/// the same checkpoints as Fast's), and the paper's one-slice objective with the sigmoid radiance and a grid
/// that keeps every cell a sample could see through at 1 % alpha.
using FastNoJointThresholds = FastModel<loss::FixedThresholds>;
using FastNoNoiseInjection = FastModel<loss::ProjectedThresholds, loss::NoNoise>;
using FastNoTv = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective>;
using FastOneSlice = FastModel<loss::JointThresholds, loss::DefaultNoise, 1, loss::HalfSlackCounts, Fp32, field::SigmoidRadiance,
                               render::OccupancySkipping<64>>;
/// The colour model: three channels behind the recording's Bayer mosaic, each pixel's events scored on its
/// own channel; Fast's event objective alone.
using FastColour = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 3, FastEventObjective>;
/// The same models with mixed-precision networks (bf16 factors, FP32 accumulation, parameters and
/// gradients); checkpoints are interchangeable with the FP32 presets'.
using PaperBf16 = PaperModel<loss::JointThresholds, loss::DefaultNoise, 1, Bf16>;
using FastBf16 = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastObjective, Bf16>;

/// Gaussians trained from events (model/splatting.hpp): up to N Gaussians of C channels (degree-0
/// harmonics: one luminance from every side, softplus), all placed at the start in the cameras' frusta, each
/// group moved by 3DGS's step size; Fast's event objective and thresholds. `splat` is grey, `splat-colour`
/// three channels behind the recording's Bayer mosaic.
template <int C = 1, std::size_t N = 20000>
using SplatScene = Splatting<splat::Layout<C, 0>, nn::Softplus, N, N>;
/// Fast's event objective and the teacher term (loss::Teacher): it pulls toward a field's images where the
/// events are silent when train --start-from gives one, and adds nothing otherwise.
using SplatObjective = loss::Plus<FastEventObjective, loss::Teacher<>>;
using Splat = Model<SplatScene<1>, loss::ProjectedThresholds, loss::DefaultNoise, SplatObjective>;
using SplatColour = Model<SplatScene<3>, loss::ProjectedThresholds, loss::DefaultNoise, SplatObjective>;
}  // namespace presets

}  // namespace evnerf
