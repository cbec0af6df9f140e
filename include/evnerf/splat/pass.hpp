// splat/pass.hpp — a training step drawn by Gaussians. An objective names the (pose, pixel) pairs it needs
// (loss::RayList); the pass groups them by pose, projects the Gaussians once per pose, rasterizes just those
// pixels, and hands the objective their values through the interface a ray-marcher's values have (at, add:
// loss::RenderedValues). The objective's gradients for the values then go back through each pose's
// rasterizer and projection to every Gaussian's parameters and the backdrop. So an objective, its
// thresholds and its noise score Gaussians unchanged. A pixel is its undistorted centre (the camera's
// pixel direction (x, y, 1) through the pinhole), so a distorted sensor's pixel lands where it looks.
// Objectives that read samples along a ray (the distortion regulariser) have none here. Depends on
// geometry/, loss/step.hpp and splat/rasterizer.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <cstddef>
#include <vector>

#include "../core/types.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../loss/step.hpp"
#include "rasterizer.hpp"

namespace evnerf::splat {

/// A pass's rendered values as an objective reads them: ray r's channel c and where its gradient goes.
/// There are no samples along a ray (samples 0, depth and weight_grad null).
template <class T>
struct PassValues {
  const T* colour = nullptr;
  T* grad = nullptr;
  int channels = 1;
  int samples = 0;
  const T* depth = nullptr;
  T* weight_grad = nullptr;
  double at(int ray, int c) const { return static_cast<double>(colour[static_cast<std::size_t>(ray) * channels + c]); }
  void add(int ray, int c, double g) const { grad[static_cast<std::size_t>(ray) * channels + c] += static_cast<T>(g); }
};

/// The view of `camera` at `pose` (its pinhole; the image's extent is the sensor's).
inline View view_of(const geometry::Camera& camera, const geometry::Pose& pose, double near) {
  View v;
  v.pose = pose;
  v.fx = camera.fx(), v.fy = camera.fy(), v.cx = camera.cx(), v.cy = camera.cy();
  v.width = camera.width(), v.height = camera.height();
  v.near = near;
  return v;
}

/// One training step's rendering by the Gaussians of layout L (colour activation Act) in precision T:
/// forward() renders the rays of a RayList, values() gives them to the objective, backward() adds the
/// gradient the objective wrote to the parameters and the backdrop. Reused step after step (its buffers
/// only grow). Deterministic at a given thread count (the rasterizer's).
template <class L, class Act, class T>
class TrainingPass {
 public:
  static constexpr int C = L::channels;

  /// Renders ray r of `rays` (pose rays.pose[r] of `poses`, the pixel whose camera-frame direction is
  /// pixel_dirs[rays.pixel[r]]) from the n Gaussians of `params` over the backdrop `bg` (C values).
  /// Poses are rendered in the order their first ray comes, one projection and one rasterization each.
  void forward(const T* params, std::size_t n, const geometry::Camera& camera, const geometry::Pose* poses, const loss::RayList& rays,
               const Vec3f* pixel_dirs, const T* bg, double near = 0.01) {
    const std::size_t R = static_cast<std::size_t>(rays.size());
    n_ = n;
    colour_.assign(C * R, T(0));
    depth_.assign(R, T(0));
    alpha_.assign(R, T(0));
    grad_.assign(C * R, T(0));
    for (int c = 0; c < C; ++c) bg_[c] = bg[c];
    // Group the rays by pose, each group in ray order.
    groups_ = 0;
    slot_.clear();
    for (std::size_t r = 0; r < R; ++r) {
      const std::size_t pose = rays.pose[r];
      auto it = std::find(slot_.begin(), slot_.end(), pose);
      std::size_t g = static_cast<std::size_t>(it - slot_.begin());
      if (it == slot_.end()) {
        slot_.push_back(pose);
        g = groups_++;
        if (group_.size() < groups_) group_.emplace_back();
        group_[g].rays.clear();
        group_[g].px.clear();
      }
      const Vec3f& d = pixel_dirs[rays.pixel[r]];
      group_[g].rays.push_back(r);
      group_[g].px.push_back(static_cast<T>(camera.fx() * d.x() / d.z() + camera.cx()));
      group_[g].px.push_back(static_cast<T>(camera.fy() * d.y() / d.z() + camera.cy()));
    }
    for (std::size_t g = 0; g < groups_; ++g) {
      Group& gr = group_[g];
      gr.view = view_of(camera, poses[slot_[g]], near);
      project<L, Act>(params, n, gr.view, gr.proj);
      const std::size_t P = gr.rays.size();
      gr.colour.resize(C * P);
      gr.depth.resize(P);
      gr.alpha.resize(P);
      gr.raster.forward(gr.proj, gr.view, gr.px.data(), P, bg_, gr.colour.data(), gr.depth.data(), gr.alpha.data(), true);
      for (std::size_t k = 0; k < P; ++k) {
        const std::size_t r = gr.rays[k];
        for (int c = 0; c < C; ++c) colour_[C * r + c] = gr.colour[C * k + c];
        depth_[r] = gr.depth[k];
        alpha_[r] = gr.alpha[k];
      }
    }
  }

  /// The last forward's values for the objective (its gradients start at zero).
  PassValues<T> values() { return {colour_.data(), grad_.data(), C}; }
  /// Ray r's expected depth and opacity (the backdrop counting 0).
  T depth(std::size_t r) const { return depth_[r]; }
  T opacity(std::size_t r) const { return alpha_[r]; }

  /// Adds the gradient of the loss whose gradient for the values is what the objective added through
  /// values() to `dparams` (n · L::size) and, where not null, to `dbg` (C values) and to `dpose`: indexed
  /// by pose (the RayList's), the gradient for each rendered pose's twist ε = (φ, ρ) of pose ∘ Exp(ε)
  /// (splat::project_backward), what pose refinement learns from.
  void backward(const T* params, T* dparams, T* dbg = nullptr, std::array<double, 6>* dpose = nullptr) {
    T dbg_local[C] = {};
    for (std::size_t g = 0; g < groups_; ++g) {
      Group& gr = group_[g];
      const std::size_t P = gr.rays.size();
      gr.dcolour.resize(C * P);
      for (std::size_t k = 0; k < P; ++k)
        for (int c = 0; c < C; ++c) gr.dcolour[C * k + c] = grad_[C * gr.rays[k] + c];
      gr.raster.backward(gr.proj, gr.px.data(), gr.dcolour.data(), bg_, gr.pgrad, dbg_local);
      project_backward<L, Act>(params, n_, gr.view, gr.proj, gr.pgrad, dparams, dpose ? &dpose[slot_[g]] : nullptr);
    }
    if (dbg)
      for (int c = 0; c < C; ++c) dbg[c] += dbg_local[c];
  }

  /// Pairs (Gaussian, pixel) the last forward evaluated, over all its poses.
  std::size_t evaluated() const {
    std::size_t e = 0;
    for (std::size_t g = 0; g < groups_; ++g) e += group_[g].raster.evaluated();
    return e;
  }
  /// Poses the last forward rendered.
  std::size_t poses() const { return groups_; }

 private:
  struct Group {
    View view;
    std::vector<std::size_t> rays;
    std::vector<T> px, colour, depth, alpha, dcolour;
    Projection<T, C> proj;
    ProjectionGrad<T, C> pgrad;
    Rasterizer<T, C> raster;
  };
  std::size_t n_ = 0, groups_ = 0;
  std::vector<std::size_t> slot_;  ///< group g's pose index
  std::vector<Group> group_;
  std::vector<T> colour_, depth_, alpha_, grad_;
  T bg_[C] = {};
};

}  // namespace evnerf::splat
