// The tiny models the training tests share: a small hash-grid field on 16 stratified samples, with each of
// the interval objectives, in mixed precision, and with windows at event pixels.
#pragma once
#include <evnerf/model/model.hpp>

#include "tiny_scene.hpp"

// A small field and model so that training tests run in seconds.
using TinyField = evnerf::field::Field<evnerf::nn::HashGrid<6, 2, 12, 4, 64>, evnerf::nn::SphericalHarmonics<2>,
                                       evnerf::nn::Mlp<12, 16, 1, 5, evnerf::nn::ReLU, evnerf::nn::Identity>,
                                       evnerf::nn::Mlp<4 + 4, 16, 1, 1, evnerf::nn::ReLU, evnerf::nn::Identity>>;
using Tiny = evnerf::EvNerf<TinyField, evnerf::render::Stratified<16>>;
using TinySigned = evnerf::EvNerf<TinyField, evnerf::render::Stratified<16>, evnerf::loss::JointThresholds, evnerf::loss::DefaultNoise,
                                  evnerf::loss::SignedCount>;
using TinyHalf = evnerf::EvNerf<TinyField, evnerf::render::Stratified<16>, evnerf::loss::JointThresholds, evnerf::loss::DefaultNoise,
                                evnerf::loss::HalfSlackCounts>;
// The same model with mixed-precision networks (bf16 factors, FP32 accumulation).
using TinyBf16Field = evnerf::field::Field<evnerf::nn::HashGrid<6, 2, 12, 4, 64>, evnerf::nn::SphericalHarmonics<2>,
                                           evnerf::nn::Mlp<12, 16, 1, 5, evnerf::nn::ReLU, evnerf::nn::Identity, -1, evnerf::nn::Bf16>,
                                           evnerf::nn::Mlp<4 + 4, 16, 1, 1, evnerf::nn::ReLU, evnerf::nn::Identity, -1, evnerf::nn::Bf16>>;
using TinyBf16 = evnerf::EvNerf<TinyBf16Field, evnerf::render::Stratified<16>, evnerf::loss::JointThresholds, evnerf::loss::DefaultNoise,
                                evnerf::loss::HalfSlackCounts>;
// Windows of 1..4 slices at event pixels (the Fast preset's kind of objective).
using TinyWindow = evnerf::EvNerf<TinyField, evnerf::render::Stratified<16>, evnerf::loss::JointThresholds, evnerf::loss::DefaultNoise,
                                  evnerf::loss::WindowInterval<4, evnerf::loss::HalfSlackCounts, evnerf::events::EventPixels<100>>>;
