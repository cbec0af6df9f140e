// model/splatting.hpp — a scene of anisotropic 3D Gaussians as a model's representation (model/model.hpp's
// Model): splat/ projects and rasterizes it, this header gives it what a training step asks of a
// representation. A step's pixels form one tile: the rays are grouped by pose, each pose projected once,
// and the rasterizer spreads the pixels over the threads (splat::TrainingPass). The scene has a fixed
// capacity: slots beyond the Gaussians in use hold invisible ones (opacity under 1/255, no gradient), so
// that the parameter vector, Adam, checkpoints and shards are those of any model.
//
// Step sizes per group. 3DGS moves each group of a Gaussian's parameters by its own learning rate (the
// means by 1.6e-4 of the scene's extent, scales 5e-3, rotations 1e-3, opacities 2.5e-2, colours 2.5e-3).
// Adam's step is invariant to the scale of a gradient, so a parameter stored in units of u moves by u times
// the model's one learning rate: the scene stores each group in units of its step relative to the default
// learning rate (nn::AdamConfig's 5e-3), and one Adam serves every group. Changing the model's learning
// rate scales every group alike. Depends on model/representation.hpp, nn/activation.hpp and splat/.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../events/training_data.hpp"
#include "../nn/activation.hpp"
#include "../render/scene.hpp"
#include "../splat/pass.hpp"
#include "representation.hpp"

namespace evnerf {

namespace splat {

/// 3DGS's step sizes per group as multiples of Adam's default learning rate (5e-3): means 1.6e-4 × the
/// scene box's scale, log-scales 5e-3, rotations 1e-3, opacity logits 2.5e-2, colour coefficients 2.5e-3.
struct Steps3dgs {
  static constexpr double mean = 1.6e-4 / 5e-3, log_scale = 1.0, rotation = 1e-3 / 5e-3, opacity = 2.5e-2 / 5e-3, colour = 2.5e-3 / 5e-3;
};

/// The raw value x at which Act::f(x) = y (bisection; Act::f increasing), for initial colours.
template <class Act>
double activation_inverse(double y) {
  double lo = -30, hi = 30;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (Act::f(mid) < y ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace splat

/// Up to `Capacity` Gaussians of layout L (splat::Layout: colour channels and spherical-harmonic degree),
/// their colours through activation Act, stored in precision T; a fresh scene uses `Initial` of them.
/// `Steps` gives each group's step size (splat::Steps3dgs). Parameters: Capacity blocks of L::size values
/// (in units of their group's step), then the backdrop's raw values (C).
template <class L, class Act = nn::Softplus, std::size_t Capacity = 65536, std::size_t Initial = Capacity, class Steps = splat::Steps3dgs,
          class T = float>
class Splatting {
  static_assert(Initial >= 1 && Initial <= Capacity, "Splatting: a fresh scene uses between 1 and Capacity Gaussians");

 public:
  using scalar = T;
  using layout = L;
  static constexpr int channels = L::channels;
  static constexpr std::size_t capacity = Capacity, initial = Initial;
  static constexpr std::size_t backdrop_offset = Capacity * L::size;
  static constexpr std::size_t n_params = backdrop_offset + channels;
  static constexpr int passes = 1;
  static constexpr int flush_parts = 0;
  /// The floor under the luminance whose logarithm the objectives compare.
  static constexpr double log_eps = 1e-3;
  /// Unused by Gaussians (a ray-marcher's training rays stop behind it); kept for the model's default.
  static constexpr T kMinTransmittance = T(1e-4);
  static constexpr int kRenderRows = 4;
  /// A fresh Gaussian: opacity 0.1, three pixels wide where the data places it, luminance 0.5.
  static constexpr double kInitialOpacity = 0.1, kInitialPixels = 3.0, kInitialLuminance = 0.5;
  /// An unused slot's opacity logit: sigmoid(−30) ≈ 1e-13, far under the 1/255 below which a Gaussian is
  /// not drawn.
  static constexpr double kDeadLogit = -30;

  Splatting() = default;
  explicit Splatting(render::SceneBox box) : box_(box) {}
  const render::SceneBox& box() const { return box_; }
  render::SceneBox& box() { return box_; }

  static std::string architecture() {
    return "gaussians " + std::to_string(Capacity) + " x (mean, log-scale, rotation, opacity, " + std::to_string(channels) +
           " channels x degree-" + std::to_string(L::degree) + " harmonics); colour " + Act::name + "; steps " + short_steps();
  }
  /// One tile is the step's pixels: the rasterizer spreads them over the threads.
  static constexpr int default_tile_pixels(int step_pixels) { return std::max(1, step_pixels); }

  /// The size of a stored unit of slot `s` of a Gaussian's block, in the scene's units.
  T unit(int s) const {
    if (s < L::log_scale) return static_cast<T>(Steps::mean * box_.scale);
    if (s < L::rotation) return static_cast<T>(Steps::log_scale);
    if (s < L::opacity) return static_cast<T>(Steps::rotation);
    if (s < L::colour) return static_cast<T>(Steps::opacity);
    return static_cast<T>(Steps::colour);
  }
  /// The Gaussians of `params` in the scene's units (Capacity · L::size values), as splat/ reads them.
  void to_scene(const T* params, std::vector<T>& out) const {
    std::array<T, L::size> u;
    for (int s = 0; s < L::size; ++s) u[s] = unit(s);
    out.resize(backdrop_offset);
    for (std::size_t i = 0; i < Capacity; ++i)
      for (int s = 0; s < L::size; ++s) out[i * L::size + s] = params[i * L::size + s] * u[s];
  }

  /// A fresh scene: Initial Gaussians, each where a random pixel of a random boundary pose looks, at a
  /// log-uniform depth between near and far (the frusta, as E-3DGS starts without points), or without data
  /// uniform in the box; the other slots unused.
  void init(T* params, Rng& rng, const TrainingData* data) const {
    const double dc = splat::activation_inverse<Act>(kInitialLuminance) / 0.28209479177387814;
    const double near = std::max(1e-6, box_.near), far = std::max(near, box_.far);
    for (std::size_t i = 0; i < Capacity; ++i) {
      std::array<double, L::size> g{};
      g[L::rotation] = 1;
      g[L::opacity] = kDeadLogit;
      if (i < Initial) {
        Vec3 p;
        double width;
        if (data && !data->boundary_poses.empty() && !data->pixel_dirs.empty()) {
          const auto& pose = data->boundary_poses[rng.below(data->boundary_poses.size())];
          const Vec3 d = data->pixel_dirs[rng.below(data->pixel_dirs.size())].template cast<double>();
          const double z = std::exp(std::log(near) + rng.uniform() * (std::log(far) - std::log(near)));
          p = pose.t + pose.q * (d * z);
          width = kInitialPixels * z / data->camera.fx();
        } else {
          for (int a = 0; a < 3; ++a) p[a] = box_.center[a] + box_.scale * (2 * rng.uniform() - 1);
          width = 2 * box_.scale / std::cbrt(static_cast<double>(Initial));
        }
        for (int a = 0; a < 3; ++a) g[L::mean + a] = p[a], g[L::log_scale + a] = std::log(width);
        g[L::opacity] = std::log(kInitialOpacity / (1 - kInitialOpacity));
        for (int c = 0; c < channels; ++c) g[L::colour + c * L::sh] = dc;
      }
      for (int s = 0; s < L::size; ++s) params[i * L::size + s] = static_cast<T>(g[s] / unit(s));
    }
  }

  /// A thread's scratch through a step: the training pass and the scene in its own units with its gradient.
  struct TileWork {
    splat::TrainingPass<L, Act, T> pass;
    std::vector<T> scene, dscene;
    std::size_t evaluated = 0;
  };
  static void begin_step(TileWork& w, const TrainSettings&) { w.evaluated = 0; }
  /// Renders the tile's rays: each pose projected once, its pixels rasterized (a pixel is its undistorted
  /// centre).
  void forward(const T* params, const TileRays& in, TileWork& w) const {
    to_scene(params, w.scene);
    T bg[channels], dbg[channels];
    backdrop_values(params, bg, dbg);
    w.pass.forward(w.scene.data(), Capacity, *in.camera, in.poses, *in.rays, in.pixel_dirs, bg, box_.near);
    w.evaluated += w.pass.evaluated();
  }
  static splat::PassValues<T> values(TileWork& w, int /*pass*/, bool /*with_samples*/) { return w.pass.values(); }
  /// Adds the gradient the objective wrote through values() to `grads` (in the stored units) and, when
  /// asked, to each rendered pose's twist in `pose_grad` (indexed by pose).
  void backward(const T* params, const TileRays&, TileWork& w, T* grads, std::array<double, 6>* pose_grad) const {
    w.dscene.assign(backdrop_offset, T(0));
    T dbg[channels] = {};
    w.pass.backward(w.scene.data(), w.dscene.data(), dbg, pose_grad);
    std::array<T, L::size> u;
    for (int s = 0; s < L::size; ++s) u[s] = unit(s);
    for (std::size_t i = 0; i < Capacity; ++i)
      for (int s = 0; s < L::size; ++s) grads[i * L::size + s] += w.dscene[i * L::size + s] * u[s];
    if (learns_backdrop()) {
      T b[channels], db[channels];
      backdrop_values(params, b, db);
      for (int c = 0; c < channels; ++c) grads[backdrop_offset + c] += dbg[c] * db[c];
    }
  }
  /// (Gaussian, pixel) pairs the thread's step evaluated; nothing runs backward per sample.
  static std::size_t evaluated(const TileWork& w) { return w.evaluated; }
  static std::size_t backward_samples(const TileWork&) { return 0; }
  static double flush_cost(const TileWork&) { return 0; }
  static void flush(const TileWork&, int) {}
  static void end_step(TileWork&) {}

  /// Whether a backdrop lies behind the Gaussians (known or learned), and whether it is learned: its raw
  /// values in params pass through Act, as colours do.
  bool has_backdrop() const { return box_.background.has_value() || box_.background_learned; }
  bool learns_backdrop() const { return box_.background_learned && !box_.background; }
  /// The backdrop's luminance per channel under `params`, or nothing (a pixel no Gaussian covers is black).
  std::optional<std::array<T, channels>> backdrop(const T* params) const {
    if (!has_backdrop()) return std::nullopt;
    std::array<T, channels> b{}, db{};
    backdrop_values(params, b.data(), db.data());
    return b;
  }

  /// The whole image at `pose`: luminance (C channels), expected depth along the optical axis and opacity
  /// (a pixel is its undistorted centre; pixel_dirs are render::pixel_directions(cam)). The rows' and
  /// termination arguments are a ray-marcher's and ignored.
  Rendering render(const T* params, const geometry::Camera& cam, const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose,
                   bool /*early_termination*/ = true, int /*rows_per_batch*/ = kRenderRows) const {
    const int W = cam.width(), H = cam.height();
    const std::size_t P = static_cast<std::size_t>(W) * H;
    std::vector<T> scene;
    to_scene(params, scene);
    T bg[channels], dbg[channels];
    backdrop_values(params, bg, dbg);
    std::vector<T> px(2 * P), colour(channels * P), depth(P), alpha(P);
    for (std::size_t p = 0; p < P; ++p) {
      const Vec3f& d = pixel_dirs[p];
      px[2 * p] = static_cast<T>(cam.fx() * d.x() / d.z() + cam.cx());
      px[2 * p + 1] = static_cast<T>(cam.fy() * d.y() / d.z() + cam.cy());
    }
    const splat::View view = splat::view_of(cam, pose, box_.near);
    splat::Projection<T, channels> proj;
    splat::project<L, Act>(scene.data(), Capacity, view, proj);
    splat::Rasterizer<T, channels> raster;
    raster.forward(proj, view, px.data(), P, bg, colour.data(), depth.data(), alpha.data(), false);
    Rendering out{Image(W, H, channels), Image(W, H, 1), Image(W, H, 1)};
    for (std::size_t p = 0; p < P; ++p) {
      const int x = static_cast<int>(p % W), y = static_cast<int>(p / W);
      for (int c = 0; c < channels; ++c) out.luminance.at(x, y, c) = static_cast<float>(colour[channels * p + c]);
      out.depth.at(x, y) = static_cast<float>(depth[p]);
      out.opacity.at(x, y) = static_cast<float>(alpha[p]);
    }
    return out;
  }

  /// A Gaussian scene keeps no state beside its parameters.
  std::string state() const { return {}; }
  bool restore(const std::string& bytes) { return bytes.empty(); }
  static std::string state_name() { return "none (a Gaussian scene keeps no state beside its parameters)"; }

 private:
  static std::string short_steps() {
    char b[128];
    std::snprintf(b, sizeof b, "%g/%g/%g/%g/%g", Steps::mean, Steps::log_scale, Steps::rotation, Steps::opacity, Steps::colour);
    return b;
  }
  void backdrop_values(const T* params, T* b, T* db) const {
    for (int c = 0; c < channels; ++c) {
      if (box_.background) b[c] = static_cast<T>(*box_.background), db[c] = 0;
      else if (box_.background_learned) b[c] = Act::f(params[backdrop_offset + c]), db[c] = Act::df_from_y(b[c]);
      else b[c] = 0, db[c] = 0;
    }
  }

  render::SceneBox box_;
};

}  // namespace evnerf
