// model/ray_marching.hpp — the neural field seen through a ray-marcher as a model's representation
// (model/model.hpp's Model): render::Renderer (rays → samples → field → compositing, the sampler's state)
// with what a training step asks of a representation. A tile's rays start at their poses through their
// pixels' directions, each with its own random stream (the sampler's jitter, the noise of a density);
// their gradients come back to the field's parameters and, when poses are refined, to the poses' twists.
// Tiles are small and many (a few thousand samples each: a layer's activations stay in L2), and the
// trainer's threads take them in parallel. A hash grid's table gradients wait in each thread's workspace
// until the step's end (flush). EvNerf<Field, Sampler, …> is the model over this representation.
// Depends on render/renderer.hpp, geometry/ and loss/step.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../events/training_data.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../loss/step.hpp"
#include "../render/renderer.hpp"
#include "../render/sampler.hpp"
#include "../render/scene.hpp"
#include "representation.hpp"

namespace evnerf {

/// The field `FieldT` rendered by ray marching with `SamplerT`, in precision T (model/model.hpp's
/// Representation). Its parameters are the networks' (coarse, then fine for a two-network sampler) and the
/// backdrop's raw values (render::Renderer's layout).
template <class FieldT, render::Sampler SamplerT, class T = float>
class RayMarching : public render::Renderer<FieldT, SamplerT, T> {
  using Base = render::Renderer<FieldT, SamplerT, T>;

 public:
  using Base::Base;
  using Base::channels;
  using Base::networks;
  /// Value sets a tile's forward gives the objective: one per network (a two-network sampler's coarse
  /// pass is scored too, as in NeRF).
  static constexpr int passes = Base::networks;
  /// The floor under the luminance whose logarithm the objectives compare (the field's radiance's).
  static constexpr double log_eps = FieldT::radiance::log_eps;
  /// Table gradients a thread holds back until the step's end, in parts (a hash grid's levels).
  static constexpr int flush_parts = FieldT::encoding_grad_parts;

  /// The architecture as checkpoints record it: the field's (encodings, networks, activation) and the
  /// sampler's. Two variants with the same architecture and loss load each other's files.
  static std::string architecture() { return FieldT::architecture() + "; sampler " + SamplerT::name(); }

  /// Pixels a tile of a training step holds: about 1–4 k samples, so the widest layer's activations stay
  /// within L2.
  static constexpr int default_tile_pixels(int /*step_pixels*/) {
    constexpr int per_pixel = 2 * (Base::n_coarse + (networks == 2 ? Base::n_coarse + Base::n_fine : 0));
    return per_pixel >= 1024 ? 4 : std::max(1, 2048 / per_pixel);
  }

  /// A fresh model's parameters: each network from its own stream of `rng` (the backdrop's raw values stay
  /// 0, the radiance activation's middle, as an untrained field's samples).
  void init(T* params, Rng& rng, const TrainingData* /*data*/) const {
    for (int f = 0; f < networks; ++f) {
      Rng r = rng.split(static_cast<std::uint64_t>(f));
      FieldT::init(params + f * Base::field_params, r);
    }
  }

  /// A thread's scratch through a step: the renderer's workspace and the tile's rays with their streams.
  struct TileWork {
    typename Base::Workspace rw;
    std::vector<Vec3> origin, dir;
    std::vector<Rng> rng;
  };
  /// A thread's first tile of a step: counters zeroed, ray termination set, table gradients held back.
  static void begin_step(TileWork& w, const TrainSettings& s) {
    w.rw.evaluated = w.rw.backward_samples = 0;
    w.rw.training_termination = s.ray_termination;
    w.rw.training_cut = static_cast<T>(s.ray_cut);
    Base::defer_encoding_grad(w.rw);  // the thread's table gradients in one batch (bit-identical)
  }
  /// Renders the tile's rays (every pass), keeping what backward() needs.
  void forward(const T* params, const TileRays& in, TileWork& w) const {
    const int R = in.rays->size();
    w.origin.resize(R);
    w.dir.resize(R);
    w.rng.clear();
    for (int r = 0; r < R; ++r) {
      const auto a = geometry::Camera::ray_along(in.poses[in.rays->pose[r]], in.pixel_dirs[in.rays->pixel[r]].template cast<double>());
      w.origin[r] = a.origin;
      w.dir[r] = a.dir;
      w.rng.push_back(Rng(in.ray_key).split(in.rays->key[r]));
    }
    w.rw.ray_grad = in.pose_grad;  // the rays' gradients too, for their poses
    w.rw.ray_grad_levels = in.pose_levels > 0 ? in.pose_levels : 1 << 30;
    this->forward_train(params, w.origin.data(), w.dir.data(), w.rng.data(), R, w.rw);
  }
  /// Pass `pass`'s values for the objective, with the rays' samples when it reads them.
  static loss::RenderedValues<render::RayComposite<T>, T> values(TileWork& w, int pass, bool with_samples) {
    loss::RenderedValues<render::RayComposite<T>, T> v{Base::composites(w.rw, pass).data(), w.rw.pass[pass].dcolor.data(), channels};
    if (with_samples) {
      const auto s = Base::samples(w.rw, pass);
      v.samples = s.samples;
      v.depth = s.depth;
      v.weight_grad = s.weight_grad;
    }
    return v;
  }
  /// Adds the gradient the objective wrote through values() to `grads` and, with pose gradients asked for,
  /// each ray's to its pose's twist (do = R ρ, dd = R (φ × k)) in `pose_grad` (indexed by pose).
  void backward(const T* params, const TileRays& in, TileWork& w, T* grads, std::array<double, 6>* pose_grad) const {
    Base::backward(params, w.rw, grads);
    if (!pose_grad) return;
    for (int r = 0; r < in.rays->size(); ++r) {
      const std::size_t pose = in.rays->pose[r];
      const Quat qi = in.poses[pose].q.conjugate();
      const Vec3 k = in.pixel_dirs[in.rays->pixel[r]].template cast<double>();
      const Vec3 gphi = k.cross(qi * w.rw.ddir[static_cast<std::size_t>(r)]), grho = qi * w.rw.dorigin[static_cast<std::size_t>(r)];
      for (int d = 0; d < 3; ++d) {
        pose_grad[pose][d] += gphi[d];
        pose_grad[pose][3 + d] += grho[d];
      }
    }
  }
  /// Field evaluations of the thread's step so far, and those run backward.
  static std::size_t evaluated(const TileWork& w) { return w.rw.evaluated; }
  static std::size_t backward_samples(const TileWork& w) { return w.rw.backward_samples; }
  /// The held-back table gradients: part `part` applied to the thread's accumulator (its cost in samples),
  /// then dropped.
  static double flush_cost(const TileWork& w) { return static_cast<double>(Base::deferred_count(w.rw)); }
  static void flush(const TileWork& w, int part) { Base::flush_part(w.rw, part); }
  static void end_step(TileWork& w) { Base::clear_deferred(w.rw); }

  /// Before a training step: the sampler refreshed as it would be before step `step`; a world ball is
  /// seen when its centre projects (Camera::project) into the image of one of up to 64 of `knots`
  /// spread over the recording, within the ball's projected radius, between near and far.
  void prepare_step(const T* params, const TrainingData& data, const std::vector<geometry::Pose>& knots, long step, std::uint64_t seed) {
    render::SamplerUpdate u;
    u.step = step;
    u.seed = seed;
    const std::size_t np = knots.size(), every = std::max<std::size_t>(1, np / 64);
    std::vector<const geometry::Pose*> poses;
    for (std::size_t i = 0; i < np; i += every) poses.push_back(&knots[i]);
    if (np > 0) poses.push_back(&knots.back());
    const auto& cam = data.camera;
    const double near = this->box().near, far = this->box().far;
    u.seen = [&cam, poses, near, far](const Vec3& world, double radius) {
      for (const auto* pose : poses) {
        const Vec3 q = pose->q.conjugate() * (world - pose->t);
        if (q.z() < near - radius || q.z() > far + radius || q.z() <= 1e-6) continue;
        const double mx = cam.fx() * radius / q.z(), my = cam.fy() * radius / q.z();
        const Vec2 uv = cam.project(q);
        if (uv.x() >= -mx && uv.x() <= cam.width() + mx && uv.y() >= -my && uv.y() <= cam.height() + my) return true;
      }
      return false;
    };
    this->update_sampler(params, std::move(u));
  }

  /// The state a checkpoint keeps beside the parameters (the sampler's: an occupancy grid), and its restore
  /// (false when the bytes are not this sampler's).
  std::string state() const { return this->sampler().serialize(); }
  bool restore(const std::string& bytes) {
    SamplerT s;
    if (!s.deserialize(bytes)) return false;
    this->sampler() = std::move(s);
    return true;
  }
  static std::string state_name() { return "the sampler's state (occupancy grid) of " + SamplerT::name(); }
};

}  // namespace evnerf
