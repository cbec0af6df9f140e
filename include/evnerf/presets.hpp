// presets.hpp — the named variants: the paper's model (Paper), the fast hash-grid model (Fast), their
// ablations and their mixed-precision twins. Each is a type; a variant of your own is another alias of
// EvNerf in your own code (examples/custom_variant.cpp). Depends on model.hpp.
#pragma once
#include "model.hpp"

namespace evnerf {

namespace presets {
using namespace nn;

/// The paper's field: Frequency 10/4, 8×256 ReLU trunk with the skip before layer 5, a linear head giving
/// density and a 256-wide feature, a 128-wide view layer, `C` luminance outputs. `Prec` is the networks'
/// product precision (nn::Fp32, or nn::Bf16: bf16 factors with FP32 accumulation, nn/bf16.hpp).
template <int C = 1, int W = 256, class Prec = Fp32>
using PaperField = field::FieldOf<Frequency<10>, Frequency<4>, MlpShape{.width = W, .hidden_layers = 8, .skip = 4}, W,
                                  MlpShape{.width = W / 2, .hidden_layers = 1}, C, ReLU, Prec>;
/// The fast field: hash grid (16 levels × 2 features, 2^15 entries, resolutions 16..1024) and degree-4
/// spherical harmonics into two 64-wide networks.
/// `Radiance`: radiance of any range (field::ExpRadiance, the Fast presets' since session 9) or the paper's
/// sigmoid (field::SigmoidRadiance). `Dir`: the view-direction encoding; SphericalHarmonics<1> is a constant,
/// so the radiance depends on the position alone (a diffuse, view-independent scene: FastDiffuse).
template <int C = 1, class Prec = Fp32, class Radiance = field::ExpRadiance, class Dir = SphericalHarmonics<4>>
using FastField = field::FieldOf<HashGrid<16, 2, 15, 16, 1024>, Dir, MlpShape{.width = 64, .hidden_layers = 1}, 15,
                                 MlpShape{.width = 64, .hidden_layers = 2}, C, ReLU, Prec, ReLU, Radiance>;
static_assert(std::is_same_v<FastField<1, Fp32, field::SigmoidRadiance>,
                             field::Field<HashGrid<16, 2, 15, 16, 1024>, SphericalHarmonics<4>, Mlp<32, 64, 1, 16>, Mlp<15 + 16, 64, 2, 1>>>,
              "FastField: the derived widths are the ones written out");
static_assert(std::is_same_v<PaperField<>, field::Field<Frequency<10>, Frequency<4>, Mlp<63, 256, 8, 257, ReLU, Identity, 4>,
                                                        Mlp<256 + 27, 128, 1, 1>>>,
              "PaperField: the derived widths are the ones written out");

template <class Th = loss::JointThresholds, class No = loss::DefaultNoise, int C = 1, class Prec = Fp32>
using PaperModel = EvNerf<PaperField<C, 256, Prec>, render::Hierarchical<64, 128>, Th, No>;
/// The Fast presets' event objective: poses 1..24 slices apart (loss::WindowInterval), the half-slack
/// interval (with split counts and k = 1 a constant image costs nothing on pixels with one event, and on
/// sparse or noisy recordings the hash-grid field never leaves it), pixels uniform over the sensor. Chosen
/// by measurement (bench/README.md).
using FastEventObjective = loss::WindowInterval<24, loss::HalfSlackCounts>;
/// Fast's objective (since session 50): the event objective plus the total-variation regulariser
/// (loss::LogTv) at weight 0.1, each pixel compared with its neighbour across the image motion of the
/// window's poses (loss::TvNeighbours::Across), for half the step's pixels (2.5 rays per pixel instead of
/// 2; the weight divided by the share). Over sessions 47–50 against the event objective alone: `planes`
/// +0.51 dB over three seeds, the real slider chunk +0.37 (every seed), random scenes 1–10 pass 9 of 10
/// (8), the unseen 11–16 +0.24 dB; `object`, `room`, the noisy and HDR scenes within their seed spread;
/// 1.14 times the time of a whole 6000-step run (1.30 over the first 1000 steps; bench/README.md, sessions
/// 47–50). Its checkpoints record FastEventObjective's loss text (the term is a training setting), so a run
/// from before session 50, resumed as `fast`, goes on with the term unless given --tv 0.
using FastObjective = loss::WithTv<FastEventObjective, 100, loss::TvNeighbours::Across, 500>;
static_assert(FastObjective::tv_weight == 0.1 && FastObjective::tv_share == 0.5 &&
                  FastObjective::tv_neighbours == loss::TvNeighbours::Across && std::is_base_of_v<FastEventObjective, FastObjective>,
              "FastObjective: the event objective (its loss text) plus the total-variation term at 0.1, across, half the pixels");
/// The event objective plus the total-variation regulariser at weight 0.3 (loss::LogTv, Cauchy δ = 0.1: it
/// smooths the grain a hash grid leaves where few events constrain the scene and leaves edges their
/// height). Random scenes 1–10: +0.4 dB mean, 9 of 10 pass (8 without); `planes` +0.1–0.25 dB, but
/// `object` −0.03 to −1.6 dB over three seeds: not a clean gain, so not Fast's default (bench/README.md,
/// session 21). A third ray per pixel. Its checkpoints record FastEventObjective's loss text.
using FastTvObjective = loss::WithTv<FastEventObjective, 300>;
static_assert(FastTvObjective::tv_weight == 0.3 && std::is_base_of_v<FastEventObjective, FastTvObjective>,
              "FastTvObjective: the event objective (its loss text) plus the total-variation term at 0.3");
/// Fast's sampler: 64 stratified samples per ray, skipping cells of a 64³ occupancy grid (updated every 16
/// steps after the first 256) whose density cannot give a sample an alpha of 30 %. With the 1 % of sessions
/// 9–19 (FastDenseGrid) the grid kept 84–99 % of the cells the cameras see; at 30 % a training step takes
/// 18–31 % less time and the scores at equal steps stay within the seed spread (bench/README.md, session 19).
using FastSampler = render::OccupancySkipping<64, 64, 16, 256, 300>;
/// FastLog's sampler (session 28): 128 samples per ray spaced evenly in log depth (render::LogDepth), the
/// same 64³ grid and the same density threshold as Fast's (an alpha of 15 % at 128 samples' mean spacing is
/// 30 % at 64's). Its bins are shorter than Fast's out to 4.3 m (4 times at 1 m) and longer beyond. With the
/// grid skipping empty space a step evaluates about Fast's forward samples on `object` and `room`, 1.3–1.5
/// times on `planes`. Not Fast's default: `planes` +0.63 dB over three seeds (the fine part up at every
/// seed), `object` level with seed 2 −2.0 dB, random seed 1 −1.0 dB (bench/README.md, session 28).
using LogSampler = render::OccupancySkipping<128, 64, 16, 256, 150, render::LogDepth>;
/// FastLogOffset's sampler (session 29): 128 samples per ray spaced evenly in log(z + 1 m)
/// (render::OffsetLogDepth<100>), otherwise LogSampler. Its bins are 2.8 cm long at 1 m (LogDepth's 2.5) and
/// 11.4 cm at 7 m (LogDepth's 17): nowhere much longer than Fast's 10.5 cm, where LogDepth's bins pass them
/// beyond 4.3 m and cost `object` (median depth 3.6 m) its fine part at 64 bins (session 28).
using LogOffsetSampler = render::OccupancySkipping<128, 64, 16, 256, 150, render::OffsetLogDepth<100>>;
/// The grid of sessions 9–19: a cell kept while its density gives a sample an alpha of 1 %.
using DenseGridSampler = render::OccupancySkipping<64>;
/// Fast learns its thresholds jointly, kept beyond the floor by projection (loss::ProjectedThresholds): the
/// λ = 1000 floor loss fought the event loss for the first few hundred steps of every run. Its radiance is
/// exp(raw) (field::ExpRadiance): the sigmoid's log spans at most 6.9 nats, scenes of high dynamic range ask
/// for more; on random scenes exp radiance scored 0.6–0.9 dB higher, on the built-in ones the same
/// (bench/README.md).
template <class Th = loss::ProjectedThresholds, class No = loss::DefaultNoise, int C = 1, class Obj = FastObjective,
          class Prec = Fp32, class Radiance = field::ExpRadiance, class Sampler = FastSampler, class Dir = SphericalHarmonics<4>>
using FastModel = EvNerf<FastField<C, Prec, Radiance, Dir>, Sampler, Th, No, Obj>;
/// Fast with windows of 1..W frame intervals (W slices at train's --subslices 1; measurement presets; no
/// total-variation term).
template <int W, class Pixels = events::UniformPixels, class Th = loss::ProjectedThresholds>
using FastWindow = FastModel<Th, loss::DefaultNoise, 1, loss::WindowInterval<W, loss::HalfSlackCounts, Pixels>>;

using Paper = PaperModel<>;
using PaperNoJointThresholds = PaperModel<loss::FixedThresholds>;
using PaperNoNoiseInjection = PaperModel<loss::JointThresholds, loss::NoNoise>;
using Fast = FastModel<>;
/// Fast without the total-variation term: its event objective alone, Fast as it was in sessions 20–49 (the
/// same checkpoints; `train --preset fast-no-tv` gives session 43's bits). The ablation of the term.
using FastNoTv = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective>;
/// Fast without view dependence: radiance from the position alone (the direction encoding is the constant
/// SphericalHarmonics<1>), the right model of a diffuse scene such as the simulator's. Session 23: `planes`
/// +0.40, +0.66, +0.88 dB at seeds 1–3 (all in the coarse part), `object` −1.88, +0.64, +1.23 (level on
/// average), `room` +0.70, the real slider chunk −0.72, random scenes 1–10 −0.53 dB on average and 7 of 10
/// passing (Fast 8). The brightness steps that no event constrains (along a horizon the camera moves
/// along) come out differently, better on some scenes and worse on others. Not Fast's default
/// (bench/README.md, session 23). On the event objective alone (FastNoTv's), as measured.
using FastDiffuse = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective, Fp32, field::ExpRadiance, FastSampler,
                              SphericalHarmonics<1>>;
/// Fast with LogSampler: samples spaced in log depth (session 28, `fast-log`), on the event objective alone.
using FastLog = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective, Fp32, field::ExpRadiance, LogSampler>;
/// Fast with LogOffsetSampler: samples spaced in log(z + 1 m) (sessions 29–30, `fast-log-offset`). `planes`
/// +0.96 dB over five seeds (a gain at every one) and `object --hdr` +1.1, the fine part up on every built-in
/// scene; but `object` −0.25 dB over five seeds, the real slider chunk −0.44, the noisy `planes` −0.013 SSIM
/// over three, the unseen random seeds 12 and 16 about 2 dB of their fine part, and a step takes 1.76 times
/// as long. Not Fast's default (bench/README.md, session 30). On the event objective alone, as measured.
using FastLogOffset =
    FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective, Fp32, field::ExpRadiance, LogOffsetSampler>;
/// Fast rendering each pixel at three poses of its window: the ends and one inner boundary drawn per pixel,
/// each of the three pairs a term (loss::WindowInterval's Poses = 3; session 33). Three rays per pixel: at
/// `train --pixels 683` a step renders as many rays as Fast's 1024 pixels at two poses.
using FastThreePoses = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1,
                                 loss::WindowInterval<24, loss::HalfSlackCounts, events::UniformPixels, 3>>;
/// Fast with the total-variation term at weight 0.3 (session 21's measurements; the same checkpoints as Fast).
using FastTv = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastTvObjective>;
/// Fast as it was in sessions 9–19, with the dense occupancy grid (its checkpoints load as this).
using FastDenseGrid =
    FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective, Fp32, field::ExpRadiance, DenseGridSampler>;
/// Fast with the paper's sigmoid radiance (the Fast preset of sessions 7–8, with their sampler; their
/// checkpoints load as this).
using FastSigmoid =
    FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastEventObjective, Fp32, field::SigmoidRadiance, DenseGridSampler>;
/// Fast with the paper's one-slice objective and sigmoid (the Fast preset before windows, with its sampler;
/// an ablation).
using FastOneSlice = FastModel<loss::JointThresholds, loss::DefaultNoise, 1, loss::HalfSlackCounts, Fp32,
                               field::SigmoidRadiance, DenseGridSampler>;
using FastNoJointThresholds = FastModel<loss::FixedThresholds>;
using FastNoNoiseInjection = FastModel<loss::ProjectedThresholds, loss::NoNoise>;
/// Fast learning only each slice's threshold ratio, the scale shared and fixed (loss::RatioThresholds).
using FastRatio = FastModel<loss::RatioThresholds>;
/// Session 19's `fast-prune`, Fast's sampler since session 20: the same type as Fast (its checkpoints load
/// under either name).
using FastPrune = Fast;
using FastColour = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 3, FastEventObjective>;
/// The colour preset as it was in sessions 9–19, with the dense occupancy grid (its checkpoints load as this).
using FastColourDenseGrid =
    FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 3, FastEventObjective, Fp32, field::ExpRadiance, DenseGridSampler>;
/// The colour preset with the sigmoid (sessions 7–8's `colour`, with their sampler; their checkpoints load as this).
using FastColourSigmoid =
    FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 3, FastEventObjective, Fp32, field::SigmoidRadiance, DenseGridSampler>;
/// The same models with mixed-precision networks (bf16 factors, FP32 accumulation, parameters and
/// gradients); checkpoints are interchangeable with the FP32 presets'.
using PaperBf16 = PaperModel<loss::JointThresholds, loss::DefaultNoise, 1, Bf16>;
using FastBf16 = FastModel<loss::ProjectedThresholds, loss::DefaultNoise, 1, FastObjective, Bf16>;
}  // namespace presets

}  // namespace evnerf
