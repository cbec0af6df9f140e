// model/representation.hpp — what a model (model/model.hpp) asks of the thing it trains, and what it hands
// it. A representation turns the (pose, pixel) pairs an objective lists into rendered values and carries
// the objective's gradients for those values back to its parameters (and, asked, to the poses); the model
// draws the step, cuts it into tiles, scores them with the objective, reduces, and applies Adam. Two
// families implement it: a neural field through a ray-marcher (model/ray_marching.hpp; many small tiles,
// parallel across tiles) and a scene of Gaussians through a rasterizer (model/splatting.hpp; a step's
// pixels in one tile, parallel within). Depends on core/, geometry/ and loss/step.hpp.
#pragma once
#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../events/training_data.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../loss/step.hpp"
#include "../render/scene.hpp"

namespace evnerf {

/// A tile's rays as a representation renders them: ray r is pose rays->pose[r] of `poses` through the
/// pixel whose camera-frame direction is pixel_dirs[rays->pixel[r]]; `ray_key` and rays->key[r] key its
/// random stream. `pose_grad` asks backward() for the poses' gradients (pose refinement), from the
/// encodings' first `pose_levels` levels where a representation has levels (0: all).
struct TileRays {
  const geometry::Camera* camera = nullptr;
  const geometry::Pose* poses = nullptr;
  const Vec3f* pixel_dirs = nullptr;
  const loss::RayList* rays = nullptr;
  std::uint64_t ray_key = 0;
  bool pose_grad = false;
  int pose_levels = 0;
};

/// Training settings a model hands its representation at the start of each thread's step: a ray-marcher's
/// training rays stop behind transmittance `ray_cut` when `ray_termination`.
struct TrainSettings {
  bool ray_termination = false;
  double ray_cut = 1e-4;
};

/// A model's representation (Model's first parameter). Its parameters are `n_params` values in precision
/// `scalar` (the model's thresholds follow them), `channels` luminance channels, a backdrop's raw values at
/// `backdrop_offset`; a training step goes: begin_step per thread, then per tile forward → values (passes
/// value sets, each scored by the objective) → backward, then flush (flush_parts parts per thread, cost
/// shared out), end_step. prepare_step runs before each step's draw (an occupancy grid's refresh);
/// after_update after each optimiser step (a Gaussian scene's densification), with the optimiser's state.
template <class R>
concept Representation = requires(R& r, const R& cr, typename R::TileWork& w, const typename R::scalar* p, typename R::scalar* g,
                                  const TileRays& in, Rng& rng, const TrainingData& data) {
  typename R::scalar;
  requires std::same_as<decltype(R::channels), const int>;
  requires std::same_as<decltype(R::n_params), const std::size_t>;
  requires std::same_as<decltype(R::backdrop_offset), const std::size_t>;
  requires std::same_as<decltype(R::passes), const int>;
  requires std::same_as<decltype(R::flush_parts), const int>;
  { R::architecture() } -> std::convertible_to<std::string>;
  { R::default_tile_pixels(1) } -> std::convertible_to<int>;
  { cr.box() } -> std::convertible_to<const render::SceneBox&>;
  cr.init(g, rng, &data);
  R::begin_step(w, TrainSettings{});
  cr.forward(p, in, w);
  R::values(w, 0, false);
  cr.backward(p, in, w, g, static_cast<std::array<double, 6>*>(nullptr));
  { R::evaluated(w) } -> std::convertible_to<std::size_t>;
  { cr.state() } -> std::convertible_to<std::string>;
  { r.restore(std::string()) } -> std::convertible_to<bool>;
};

}  // namespace evnerf
