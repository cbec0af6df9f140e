// The model whose checkpoints the checkpoint harness reads: a tiny hash-grid field with the occupancy
// sampler (so the grid's state is parsed too) and the Fast presets' objective. Shared with make_seeds.cpp.
#pragma once
#include <evnerf/evnerf.hpp>

namespace evfuzz {
namespace en = evnerf;
using FuzzField =
    en::field::Field<en::nn::HashGrid<2, 2, 5, 2, 4>, en::nn::SphericalHarmonics<2>,
                     en::nn::Mlp<4, 8, 1, 4, en::nn::ReLU, en::nn::Identity>, en::nn::Mlp<3 + 4, 8, 1, 1, en::nn::ReLU, en::nn::Identity>>;
using FuzzModel = en::EvNerf<FuzzField, en::render::OccupancySkipping<8, 8, 1, 0>, en::loss::ProjectedThresholds, en::loss::DefaultNoise,
                             en::loss::WindowInterval<4, en::loss::HalfSlackCounts>>;
}  // namespace evfuzz
