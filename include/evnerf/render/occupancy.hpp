// render/occupancy.hpp — empty-space skipping: OccupancyGrid, a Res³ grid over the scene box [−1, 1]³
// holding a decaying maximum of the density seen in each cell (Instant-NGP's occupancy grid), and the
// sampler that owns one, OccupancySkipping. Samples in cells whose density cannot make a visible alpha are
// not evaluated: they composite as density 0 and get no gradient. Depends on core/ and render/sampler.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/parallel.hpp"
#include "../core/rng.hpp"
#include "sampler.hpp"

namespace evnerf::render {

class OccupancyGrid {
 public:
  OccupancyGrid() = default;
  explicit OccupancyGrid(int res) : res_(res), density_(static_cast<std::size_t>(res) * res * res, 0.f) {}

  int resolution() const { return res_; }
  bool active() const { return active_; }
  std::size_t cells() const { return density_.size(); }
  /// Fraction of cells marked occupied (1 before the first update).
  double occupied_fraction() const {
    if (!active_) return 1.0;
    return static_cast<double>(std::count(occupied_.begin(), occupied_.end(), std::uint8_t{1})) / static_cast<double>(cells());
  }
  /// The share of the cells some training camera sees (1 before visibility is known). Most of a box fitted
  /// around the cameras is never seen, so occupied_fraction() / seen_fraction() is what pruning kept.
  double seen_fraction() const {
    if (visible_.empty()) return 1.0;
    return static_cast<double>(std::count(visible_.begin(), visible_.end(), std::uint8_t{1})) / static_cast<double>(cells());
  }

  /// Cell of a point in [−1, 1]³, or −1 outside the box (outside counts as occupied: never skipped).
  template <class T>
  long cell_of(const T* p) const {
    long idx = 0;
    for (int d = 2; d >= 0; --d) {
      const float u = (static_cast<float>(p[d]) + 1.f) * 0.5f * static_cast<float>(res_);
      if (!(u >= 0.f && u < static_cast<float>(res_))) return -1;
      idx = idx * res_ + static_cast<long>(u);
    }
    return idx;
  }
  template <class T>
  bool occupied(const T* p) const {
    if (!active_) return true;
    const long c = cell_of(p);
    return c < 0 || occupied_[static_cast<std::size_t>(c)];
  }

  /// Centre of cell c in [−1, 1]³.
  void cell_centre(std::size_t c, float* p) const {
    const std::size_t idx[3] = {c % res_, (c / res_) % res_, c / (static_cast<std::size_t>(res_) * res_)};
    for (int d = 0; d < 3; ++d) p[d] = -1.f + 2.f * (static_cast<float>(idx[d]) + 0.5f) / static_cast<float>(res_);
  }
  /// Restricts the grid to cells some training camera sees (1 = seen): the others never get a training
  /// signal, keep whatever density the initialisation gave them, and are skipped. Empty = all seen.
  void set_visible(std::vector<std::uint8_t> visible) {
    require(visible.empty() || visible.size() == cells(), "OccupancyGrid::set_visible: wrong mask size");
    visible_ = std::move(visible);
  }
  bool has_visibility() const { return !visible_.empty(); }

  /// Refreshes the grid: `density(pts, n, out)` evaluates n points (3 floats each, [−1, 1]³) to their
  /// density after activation. One jittered point per seen cell; a cell keeps max(0.95 · old, new), and
  /// is occupied when that exceeds min(`threshold`, mean density over seen cells). Deterministic for a
  /// given rng.
  template <class DensityFn>
  void update(DensityFn&& density, Rng rng, float threshold) {
    const std::size_t n = cells();
    std::vector<std::size_t> todo;
    todo.reserve(n);
    for (std::size_t c = 0; c < n; ++c)
      if (visible_.empty() || visible_[c]) todo.push_back(c);
    std::vector<float> pts(3 * todo.size()), sigma(todo.size());
    const float h = 2.f / static_cast<float>(res_);
    for (std::size_t i = 0; i < todo.size(); ++i) {
      cell_centre(todo[i], &pts[3 * i]);
      for (int d = 0; d < 3; ++d) pts[3 * i + d] += h * (static_cast<float>(rng.uniform()) - 0.5f);
    }
    if (!todo.empty()) density(pts.data(), todo.size(), sigma.data());
    double mean = 0;
    for (std::size_t i = 0; i < todo.size(); ++i) {
      const std::size_t c = todo[i];
      const float s = std::isfinite(sigma[i]) ? sigma[i] : 0.f;
      density_[c] = std::max(active_ ? 0.95f * density_[c] : 0.f, s);
      mean += density_[c];
    }
    mean /= static_cast<double>(std::max<std::size_t>(1, todo.size()));
    const float th = std::min(threshold, static_cast<float>(mean));
    occupied_.assign(n, 0);
    for (std::size_t c : todo) occupied_[c] = density_[c] > th ? 1 : 0;
    active_ = true;
  }

  /// Bytes for checkpoints (resolution, state, densities).
  std::string serialize() const {
    std::string b;
    const std::int64_t head[2] = {res_, active_ ? 1 : 0};
    b.append(reinterpret_cast<const char*>(head), sizeof head);
    b.append(reinterpret_cast<const char*>(density_.data()), density_.size() * sizeof(float));
    b.append(reinterpret_cast<const char*>(occupied_.data()), occupied_.size());
    return b;
  }
  /// Restores serialize()'s bytes; false when they do not describe a grid of this resolution.
  bool deserialize(std::string_view b) {
    std::int64_t head[2];
    if (b.size() < sizeof head) return false;
    std::memcpy(head, b.data(), sizeof head);
    const std::size_t n = static_cast<std::size_t>(res_) * res_ * res_;
    const bool act = head[1] == 1;
    if (head[0] != res_ || b.size() != sizeof head + n * sizeof(float) + (act ? n : 0)) return false;
    active_ = act;
    std::memcpy(density_.data(), b.data() + sizeof head, n * sizeof(float));
    occupied_.assign(b.begin() + static_cast<std::ptrdiff_t>(sizeof head + n * sizeof(float)), b.end());
    return true;
  }

 private:
  int res_ = 0;
  bool active_ = false;
  std::vector<float> density_;
  std::vector<std::uint8_t> occupied_, visible_;
};

/// Sampler: N stratified samples per ray, one network, with a Res³ occupancy grid that it owns. The grid is
/// refreshed every `Interval` steps once `Warmup` steps have passed; until then every sample is evaluated.
/// A cell is occupied when its density can give a sample an alpha of kOccupiedAlpha = AlphaPerMille / 1000
/// at the mean spacing (far − near)/N (or exceeds the mean density over the seen cells, whichever is lower).
/// `Spacing` places the N bins along the ray (UniformDepth, or LogDepth; render/sampler.hpp).
template <int N, int Res = 64, int Interval = 16, int Warmup = 256, int AlphaPerMille = 10, DepthSpacing Spacing = UniformDepth>
struct OccupancySkipping {
  static_assert(N >= 2, "OccupancySkipping<N>: need at least two samples per ray.");
  static_assert(Res >= 2 && Res <= 512, "OccupancySkipping: the grid resolution must be between 2 and 512.");
  static_assert(Interval >= 1 && Warmup >= 0, "OccupancySkipping: Interval must be positive and Warmup non-negative.");
  static_assert(AlphaPerMille >= 1 && AlphaPerMille < 1000, "OccupancySkipping: the occupied alpha is in per mille (1..999).");
  static constexpr int n_coarse = N, n_fine = 0;
  static constexpr bool two_networks = false, skips_samples = true;
  static constexpr int grid_res = Res, update_interval = Interval, warmup_steps = Warmup;
  static constexpr double kOccupiedAlpha = AlphaPerMille / 1000.0;
  static std::string name() {
    return "occupancy " + std::to_string(N) + " grid " + std::to_string(Res) + " every " + std::to_string(Interval) + " after " +
           std::to_string(Warmup) + (AlphaPerMille == 10 ? "" : " alpha " + std::to_string(AlphaPerMille) + "/1000") +
           std::string(Spacing::name);
  }
  using spacing = Spacing;

  template <class T>
  void coarse_depths(int n, T near, T far, Rng* rng, T* t) const {
    Spacing::depths(n, near, far, rng, t);
  }
  bool skipping() const { return grid_.active(); }
  template <class T>
  bool evaluates(const T* p) const {
    return grid_.occupied(p);
  }
  double occupied_fraction() const { return grid_.occupied_fraction(); }
  const OccupancyGrid& grid() const { return grid_; }

  /// Before a step: from step Warmup on, every Interval steps, the grid is refreshed from the density.
  /// The first refresh also restricts the grid to the cells some training camera sees.
  void update(const SamplerUpdate& u) {
    if (u.step < Warmup || (u.step - Warmup) % Interval != 0) return;
    if (!grid_.has_visibility() && u.seen) grid_.set_visible(visible_cells(u));
    const float threshold = static_cast<float>(kOccupiedAlpha * N * u.box.density_length / (u.box.far - u.box.near));
    grid_.update(u.density, Rng(u.seed), threshold);
  }
  std::string serialize() const { return grid_.serialize(); }
  bool deserialize(std::string_view b) { return grid_.deserialize(b); }

 private:
  /// Cells whose ball (the cell's circumradius) some training camera sees.
  std::vector<std::uint8_t> visible_cells(const SamplerUpdate& u) const {
    std::vector<std::uint8_t> vis(grid_.cells(), 0);
    const double radius = std::sqrt(3.0) * u.box.scale / grid_.resolution();
    parallel_for(grid_.cells(), 4096, [&](std::size_t c) {
      float p[3];
      grid_.cell_centre(c, p);
      vis[c] = u.seen(u.box.center + u.box.scale * Vec3(p[0], p[1], p[2]), radius) ? 1 : 0;
    });
    return vis;
  }
  OccupancyGrid grid_{Res};
};

}  // namespace evnerf::render
