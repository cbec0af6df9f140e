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
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "../core/error.hpp"
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
/// scene box's scale, log-scales 5e-3, rotations 1e-3, opacity logits 2.5e-2, colour coefficients 2.5e-3;
/// and a learned backdrop's raw value 1e-4, slow: seen through every Gaussian that is not yet opaque, a
/// backdrop that moves as fast as the colours takes the brightness the Gaussians should carry.
struct Steps3dgs {
  static constexpr double mean = 1.6e-4 / 5e-3, log_scale = 1.0, rotation = 1e-3 / 5e-3, opacity = 2.5e-2 / 5e-3, colour = 2.5e-3 / 5e-3,
                          backdrop = 1e-4 / 5e-3;
};

/// A scene that keeps the Gaussians it starts with: no densification, no pruning.
struct FixedGaussians {
  static constexpr bool active = false;
  static std::string name() { return "fixed"; }
};

/// Adaptive density control after 3DGS. Every `Every` steps from `From` to `Until` (the steps taken):
/// - the Gaussians in use whose mean positional gradient since the last control ranks in the top
///   `TopPermille` ‰ grow: one wider than `SplitPermille` ‰ of the box's scale splits into two, drawn from
///   itself with scales / 1.6 (3DGS's), a smaller one is cloned;
/// - a Gaussian whose opacity fell under `PrunePer10k` / 10⁴, or wider than a tenth of the box's scale,
///   is dropped (its slot freed).
/// The gradient ranked is the image-space one a Gaussian's centre gets, estimated from the world-space
/// gradient times the distance to the nearest camera of the recording: moving a centre by a pixel moves it
/// by its depth over the focal length, so the world-space gradient alone favours the nearest surfaces.
/// It is taken from the step's exchanged gradient, so every process of a data-parallel run decides alike.
/// New and changed slots start Adam's moments at zero and the parameter average at their values.
template <int Every = 250, int From = 500, int Until = 4000, int TopPermille = 100, int SplitPermille = 10, int PrunePer10k = 50>
struct Densify {
  static_assert(Every > 0 && From >= 0 && Until >= From && TopPermille > 0 && TopPermille <= 1000, "Densify: bad schedule");
  static constexpr bool active = true;
  static constexpr long every = Every, from = From, until = Until;
  static constexpr double top = TopPermille / 1000.0, split = SplitPermille / 1000.0, prune = PrunePer10k / 1e4, too_wide = 0.1;
  static std::string name() {
    return "densify every " + std::to_string(Every) + " in [" + std::to_string(From) + ", " + std::to_string(Until) + "], top " +
           std::to_string(TopPermille) + " per mille, split above " + std::to_string(SplitPermille) + " per mille, prune under " +
           std::to_string(PrunePer10k) + " per 10k";
  }
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
/// `Steps` gives each group's step size (splat::Steps3dgs), `Density` whether and how the scene grows and
/// shrinks (splat::FixedGaussians, splat::Densify). Parameters: Capacity blocks of L::size values
/// (in units of their group's step), then the backdrop's raw values (C).
template <class L, class Act = nn::Softplus, std::size_t Capacity = 65536, std::size_t Initial = Capacity, class Steps = splat::Steps3dgs,
          class Density = splat::FixedGaussians, class T = float>
class Splatting {
  static_assert(Initial >= 1 && Initial <= Capacity, "Splatting: a fresh scene uses between 1 and Capacity Gaussians");

 public:
  using scalar = T;
  using layout = L;
  using activation = Act;  ///< the colours' (a Gaussian's luminance is Act of its harmonics' sum)
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
           " channels x degree-" + std::to_string(L::degree) + " harmonics); colour " + Act::name + "; steps " + short_steps() + "; " +
           Density::name();
  }
  /// One tile is the step's pixels: the rasterizer spreads them over the threads.
  static constexpr int default_tile_pixels(int step_pixels) { return std::max(1, step_pixels); }

  /// The size of a stored unit of a learned backdrop's raw value.
  static constexpr T backdrop_unit() { return static_cast<T>(Steps::backdrop); }
  /// The size of a stored unit of slot `s` of a Gaussian's block, in the scene's units.
  T unit(int s) const {
    if (s < L::log_scale) return static_cast<T>(Steps::mean * box_.scale);
    if (s < L::rotation) return static_cast<T>(Steps::log_scale);
    if (s < L::opacity) return static_cast<T>(Steps::rotation);
    if (s < L::colour) return static_cast<T>(Steps::opacity);
    return static_cast<T>(Steps::colour);
  }
  /// Every slot's unit(s), in slot order.
  std::array<T, L::size> units() const {
    std::array<T, L::size> u;
    for (int s = 0; s < L::size; ++s) u[s] = unit(s);
    return u;
  }
  /// The Gaussians of `params` in the scene's units (Capacity · L::size values), as splat/ reads them.
  void to_scene(const T* params, std::vector<T>& out) const {
    const auto u = units();
    out.resize(backdrop_offset);
    for (std::size_t i = 0; i < Capacity; ++i)
      for (int s = 0; s < L::size; ++s) out[i * L::size + s] = params[i * L::size + s] * u[s];
  }

  /// A fresh scene: Initial Gaussians, each where a random pixel of a random boundary pose looks, at a
  /// log-uniform depth between near and far (the frusta, as E-3DGS starts without points), or without data
  /// uniform in the box; the other slots unused. A learned backdrop starts at the same luminance.
  void init(T* params, Rng& rng, const TrainingData* data) const {
    const double raw = splat::activation_inverse<Act>(kInitialLuminance), dc = raw / 0.28209479177387814;
    for (int c = 0; c < channels; ++c) params[backdrop_offset + c] = static_cast<T>(raw / backdrop_unit());
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

  /// A scene started from what a teacher knows (splat::Seeds): the first min(seeds, Capacity) slots hold
  /// one isotropic Gaussian per seed (its point, width, luminance and the seeds' opacity; a grey seed
  /// gives every channel its luminance, a colour seed a grey scene its channels' mean), the other slots
  /// are unused; a learned backdrop takes the teacher's luminance where it has one. Replaces init's scene.
  void start_from(T* params, const splat::Seeds& seeds) const {
    require(seeds.channels >= 1 && seeds.luminance.size() == seeds.size() * static_cast<std::size_t>(seeds.channels) &&
                seeds.width.size() == seeds.size(),
            "Gaussians' seeds: a luminance per channel and a width for every point");
    require(seeds.opacity > 0 && seeds.opacity < 1, "Gaussians' seeds: the opacity must lie in (0, 1)");
    require(seeds.size() > 0, "Gaussians' seeds: none (the teacher is opaque nowhere it was seen from; a field trained longer is)");
    auto luminance = [&](std::size_t i, int c) {
      const float* l = &seeds.luminance[i * static_cast<std::size_t>(seeds.channels)];
      if (seeds.channels == channels) return double(l[c]);
      if (seeds.channels == 1) return double(l[0]);
      double m = 0;
      for (int k = 0; k < seeds.channels; ++k) m += l[k];
      return m / seeds.channels;
    };
    // Act's inverse at the luminance (bounded below: softplus reaches 0 only at −∞).
    auto raw = [](double lum) { return splat::activation_inverse<Act>(std::max(lum, 1e-4)); };
    for (std::size_t i = 0; i < Capacity; ++i) {
      std::array<double, L::size> g{};
      g[L::rotation] = 1;
      g[L::opacity] = kDeadLogit;
      if (i < seeds.size()) {
        const double width = seeds.width[i];
        require(seeds.position[i].allFinite() && std::isfinite(width) && width > 0,
                "Gaussians' seeds: point " + std::to_string(i) + " has a non-finite position or no width");
        for (int a = 0; a < 3; ++a) g[L::mean + a] = seeds.position[i][a], g[L::log_scale + a] = std::log(width);
        g[L::opacity] = std::log(seeds.opacity / (1 - seeds.opacity));
        for (int c = 0; c < channels; ++c) g[L::colour + c * L::sh] = raw(luminance(i, c)) / 0.28209479177387814;
      }
      for (int s = 0; s < L::size; ++s) params[i * L::size + s] = static_cast<T>(g[s] / unit(s));
    }
    if (learns_backdrop() && !seeds.backdrop.empty())
      for (int c = 0; c < channels; ++c) {
        const double b =
            seeds.backdrop.size() == static_cast<std::size_t>(channels) ? seeds.backdrop[static_cast<std::size_t>(c)] : seeds.backdrop[0];
        params[backdrop_offset + c] = static_cast<T>(raw(b) / backdrop_unit());
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
    const auto u = units();
    for (std::size_t i = 0; i < Capacity; ++i)
      for (int s = 0; s < L::size; ++s) grads[i * L::size + s] += w.dscene[i * L::size + s] * u[s];
    if (learns_backdrop()) {
      T b[channels], db[channels];
      backdrop_values(params, b, db);
      for (int c = 0; c < channels; ++c) grads[backdrop_offset + c] += dbg[c] * db[c] * backdrop_unit();
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

  /// After each optimiser step (`step` the steps taken before it): densification's statistics gathered
  /// from the step's gradient, and at its schedule's steps the scene grown and pruned, the optimiser's
  /// moments and the parameter average of every changed slot reset (splat::Densify). Nothing without one.
  template <class Adam, class Average>
  void after_step(std::vector<T>& params, const std::vector<T>& grads, Adam& adam, Average& average, const TrainingData& data, long step,
                  std::uint64_t seed) {
    if constexpr (Density::active) {
      if (step + 1 > Density::until) return;
      grad_sum_.resize(Capacity, 0.0f);
      grad_count_.resize(Capacity, 0);
      const T um = unit(L::mean);
      for (std::size_t i = 0; i < Capacity; ++i) {
        const T* g = grads.data() + i * L::size + L::mean;
        const double n = std::sqrt(static_cast<double>(g[0]) * g[0] + static_cast<double>(g[1]) * g[1] + static_cast<double>(g[2]) * g[2]);
        if (n > 0) {
          grad_sum_[i] += static_cast<float>(n / um);
          ++grad_count_[i];
        }
      }
      const long done = step + 1;
      if (done >= Density::from && done % Density::every == 0)
        control(params, adam, average, data, Rng(seed).split(0xD3A5u).split(static_cast<std::uint64_t>(done)));
    }
  }

  /// The state a checkpoint keeps beside the parameters: densification's statistics since its last control
  /// (none for a scene that does not grow), and its restore (false when the bytes are not such statistics).
  std::string state() const {
    if (grad_sum_.empty()) return {};
    std::string b(Capacity * 8, '\0');
    std::memcpy(b.data(), grad_sum_.data(), Capacity * 4);
    std::memcpy(b.data() + Capacity * 4, grad_count_.data(), Capacity * 4);
    return b;
  }
  bool restore(const std::string& bytes) {
    grad_sum_.clear();
    grad_count_.clear();
    if (bytes.empty()) return true;
    if (!Density::active || bytes.size() != Capacity * 8) return false;
    grad_sum_.resize(Capacity);
    grad_count_.resize(Capacity);
    std::memcpy(grad_sum_.data(), bytes.data(), Capacity * 4);
    std::memcpy(grad_count_.data(), bytes.data() + Capacity * 4, Capacity * 4);
    for (const float v : grad_sum_)
      if (!std::isfinite(v) || v < 0) return false;
    return true;
  }
  static std::string state_name() { return "densification's statistics of " + std::to_string(Capacity) + " Gaussians"; }

  /// Gaussians in use (opacity above the unused slots').
  std::size_t in_use(const T* params) const {
    std::size_t n = 0;
    for (std::size_t i = 0; i < Capacity; ++i) n += alive(params, i);
    return n;
  }

 private:
  static std::string short_steps() {
    char b[128];
    std::snprintf(b, sizeof b, "%g/%g/%g/%g/%g/%g", Steps::mean, Steps::log_scale, Steps::rotation, Steps::opacity, Steps::colour,
                  Steps::backdrop);
    return b;
  }
  void backdrop_values(const T* params, T* b, T* db) const {
    for (int c = 0; c < channels; ++c) {
      if (box_.background) b[c] = static_cast<T>(*box_.background), db[c] = 0;
      else if (box_.background_learned) b[c] = Act::f(params[backdrop_offset + c] * backdrop_unit()), db[c] = Act::df_from_y(b[c]);
      else b[c] = 0, db[c] = 0;
    }
  }

  bool alive(const T* params, std::size_t i) const {
    return static_cast<double>(params[i * L::size + L::opacity]) * unit(L::opacity) > kDeadLogit + 1;
  }
  /// One control of splat::Densify: prune, then grow the top share (split or clone) into free slots.
  template <class Adam, class Average>
  void control(std::vector<T>& params, Adam& adam, Average& average, const TrainingData& data, Rng rng) {
    std::vector<std::size_t> changed, free_slots;
    auto real = [&](std::size_t i, int s) { return static_cast<double>(params[i * L::size + s]) * unit(s); };
    auto set = [&](std::size_t i, int s, double v) { params[i * L::size + s] = static_cast<T>(v / unit(s)); };
    auto kill = [&](std::size_t i) {
      for (int s = 0; s < L::size; ++s) set(i, s, s == L::rotation ? 1.0 : s == L::opacity ? kDeadLogit : 0.0);
      changed.push_back(i);
    };
    std::vector<Vec3> centres;
    for (const auto& p : data.boundary_poses) centres.push_back(p.t);
    // Scores: mean gradient times the distance to the nearest camera; prune first.
    std::vector<std::pair<double, std::size_t>> score;
    std::size_t alive_n = 0;  // in use after pruning
    for (std::size_t i = 0; i < Capacity; ++i) {
      if (!alive(params.data(), i)) {
        free_slots.push_back(i);
        continue;
      }
      const double opacity = 1 / (1 + std::exp(-real(i, L::opacity)));
      double widest = 0;
      for (int a = 0; a < 3; ++a) widest = std::max(widest, std::exp(real(i, L::log_scale + a)));
      if (opacity < Density::prune || widest > Density::too_wide * box_.scale) {
        kill(i);
        free_slots.push_back(i);
        continue;
      }
      ++alive_n;
      if (grad_count_[i] == 0) continue;
      const Vec3 mu(real(i, 0), real(i, 1), real(i, 2));
      double d = 1e300;
      for (const auto& c : centres) d = std::min(d, (mu - c).norm());
      score.push_back({static_cast<double>(grad_sum_[i]) / grad_count_[i] * (centres.empty() ? 1.0 : d), i});
    }
    const std::size_t want = std::min(score.size(), static_cast<std::size_t>(Density::top * static_cast<double>(alive_n)));
    std::partial_sort(score.begin(), score.begin() + static_cast<std::ptrdiff_t>(want), score.end(),
                      [](const auto& a, const auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
    std::sort(score.begin(), score.begin() + static_cast<std::ptrdiff_t>(want),
              [](const auto& a, const auto& b) { return a.second < b.second; });
    std::size_t next_free = 0;
    for (std::size_t k = 0; k < want && next_free < free_slots.size(); ++k) {
      const std::size_t i = score[k].second, j = free_slots[next_free++];
      double widest = 0;
      for (int a = 0; a < 3; ++a) widest = std::max(widest, std::exp(real(i, L::log_scale + a)));
      for (int s = 0; s < L::size; ++s) params[j * L::size + s] = params[i * L::size + s];
      if (widest > Density::split * box_.scale) {  // split: two children drawn from the parent, narrower
        double q[4], r[9];
        double qn = 0;
        for (int a = 0; a < 4; ++a) q[a] = real(i, L::rotation + a), qn += q[a] * q[a];
        qn = std::sqrt(std::max(qn, 1e-30));
        for (double& v : q) v /= qn;
        splat::quat_to_matrix(q, r);
        const double sc[3] = {std::exp(real(i, L::log_scale)), std::exp(real(i, L::log_scale + 1)), std::exp(real(i, L::log_scale + 2))};
        const double centre[3] = {real(i, L::mean), real(i, L::mean + 1), real(i, L::mean + 2)};  // both children draw around it
        for (const std::size_t child : {i, j}) {
          double e[3];
          for (double& v : e) v = rng.normal();
          for (int a = 0; a < 3; ++a) {
            double off = 0;
            for (int b = 0; b < 3; ++b) off += r[3 * a + b] * sc[b] * e[b];
            set(child, L::mean + a, centre[a] + off);
          }
        }
        for (const std::size_t child : {i, j})
          for (int a = 0; a < 3; ++a) set(child, L::log_scale + a, std::log(sc[a] / 1.6));
        changed.push_back(i);
      }
      changed.push_back(j);
    }
    std::fill(grad_sum_.begin(), grad_sum_.end(), 0.0f);
    std::fill(grad_count_.begin(), grad_count_.end(), 0u);
    for (const std::size_t i : changed)
      for (int s = 0; s < L::size; ++s) {
        const std::size_t k = i * L::size + s;
        adam.m()[k] = adam.v()[k] = T(0);
        if (average.active()) average.values()[k] = params[k];
      }
  }

  render::SceneBox box_;
  std::vector<float> grad_sum_;            ///< densification: Σ |∂L/∂centre| per Gaussian since the last control
  std::vector<std::uint32_t> grad_count_;  ///< and the steps that gave it one
};

}  // namespace evnerf
