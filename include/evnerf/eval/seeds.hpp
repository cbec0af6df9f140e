// eval/seeds.hpp — where Gaussians start when a field trained on the same recording already knows the
// scene (train --start-from): the field is rendered at the recording's poses at a reduced resolution, and
// every pixel whose opacity reaches one half gives a point at its expected depth with its luminance. The
// points are merged on lattices whose spacing is a number of pixels at the point (finer near the cameras),
// the smallest that leaves at most the scene's capacity (the mean of the points in a cell, as wide as the
// cell). Rays that never become opaque seed nothing,
// so empty space starts empty, and the interiors no event observes start at the brightness the field
// interpolated there. Depends on splat/gaussians.hpp, render/scene.hpp and geometry/.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "../core/error.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../render/scene.hpp"
#include "../splat/gaussians.hpp"

namespace evnerf::evaluation {

/// How gaussian_seeds samples the teacher: every `stride`-th pixel in x and y (the camera resized by it),
/// a point where the opacity reaches `min_opacity`, the Gaussians' starting opacity.
struct SeedOptions {
  int stride = 4;
  double min_opacity = 0.5;
  double opacity = 0.5;
};

namespace detail {
/// The lattice cell of p at spacing 2^level as one key (the level in 8 bits, 18 bits an axis, wrapping:
/// cells 2^18 apart share a key only beyond any scene's extent in cells).
inline std::uint64_t cell_key(const Vec3& p, int level) {
  std::uint64_t k = static_cast<std::uint64_t>(level + 128) & 0xff;
  for (int a = 0; a < 3; ++a) {
    const double c = std::clamp(std::floor(std::ldexp(p[a], -level)), -9e15, 9e15);
    k = (k << 18) | (static_cast<std::uint64_t>(static_cast<std::int64_t>(c)) & 0x3ffff);
  }
  return k;
}
/// The cells of `points` (point i's at spacing 2^level[i]), each numbered in the order a point first falls in it.
inline std::vector<std::uint32_t> cells_of(const std::vector<Vec3>& points, const std::vector<int>& level, std::size_t& n_cells) {
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  index.reserve(points.size());
  std::vector<std::uint32_t> cell(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    cell[i] = index.try_emplace(cell_key(points[i], level[i]), static_cast<std::uint32_t>(index.size())).first->second;
  n_cells = index.size();
  return cell;
}
}  // namespace detail

/// Seeds for at most `capacity` Gaussians from a teacher that renders any camera at any pose (`render`),
/// seen at `poses` through `cam` resized by the stride (SeedOptions). Thresholds and backdrop are left
/// empty (the caller adds what the teacher learned). No pixel reaches the opacity: no seeds.
inline splat::Seeds gaussian_seeds(const std::function<Rendering(const geometry::Camera&, const geometry::Pose&)>& render,
                                   const geometry::Camera& cam, const std::vector<geometry::Pose>& poses, std::size_t capacity,
                                   const SeedOptions& o = {}) {
  require(o.stride >= 1 && o.min_opacity > 0 && o.min_opacity <= 1 && o.opacity > 0 && o.opacity < 1 && capacity >= 1,
          "Gaussians' seeds: the stride must be at least 1, the opacities in (0, 1] and (0, 1), the capacity at least 1");
  const geometry::Camera small = cam.resized(std::max(1, cam.width() / o.stride), std::max(1, cam.height() / o.stride));
  const auto dirs = render::pixel_directions(small);
  std::vector<Vec3> points;
  std::vector<float> lum;
  std::vector<double> footprint;
  int C = 0;
  for (const auto& pose : poses) {
    const Rendering r = render(small, pose);
    C = r.luminance.channels;
    for (int y = 0; y < small.height(); ++y)
      for (int x = 0; x < small.width(); ++x) {
        const double a = r.opacity.at(x, y);
        if (!(a >= o.min_opacity)) continue;
        const double z = r.depth.at(x, y) / a;
        const Vec3f& d = dirs[static_cast<std::size_t>(y) * small.width() + x];
        const Vec3 p = pose.t + pose.q * (d.cast<double>() * z);
        if (!p.allFinite() || !(z > 0)) continue;
        points.push_back(p);
        for (int c = 0; c < C; ++c) lum.push_back(r.luminance.at(x, y, c));
        footprint.push_back(z * d.norm() / small.fx());  // a pixel's width at the point
      }
  }
  splat::Seeds s;
  s.channels = std::max(C, 1);
  s.opacity = o.opacity;
  if (points.size() <= capacity) {
    s.position = std::move(points);
    s.luminance = std::move(lum);
    s.width = std::move(footprint);
    return s;
  }
  // Cells as wide as k pixels at the point (its footprint times k, rounded to a power of two so that the
  // points of one surface seen from nearby poses share a lattice): the smallest k (to 1 %) whose cells
  // number at most `capacity`, by bisection in log k. Near surfaces, which fill more of the images, get
  // finer cells than far ones, as they would in pixels.
  std::vector<int> level(points.size());
  auto cells = [&](double k, std::size_t& n) {
    for (std::size_t i = 0; i < points.size(); ++i) level[i] = static_cast<int>(std::lround(std::log2(k * footprint[i])));
    return detail::cells_of(points, level, n);
  };
  double fine = 1e-3, coarse = 1e6;
  std::size_t n = 0;
  while (coarse / fine > 1.01) {
    const double mid = std::sqrt(fine * coarse);
    cells(mid, n);
    (n > capacity ? fine : coarse) = mid;
  }
  const auto cell = cells(coarse, n);
  std::vector<Vec3> sum(n, Vec3::Zero());
  std::vector<double> lsum(n * static_cast<std::size_t>(s.channels), 0.0);
  std::vector<std::size_t> count(n, 0);
  std::vector<int> cell_level(n, 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    sum[cell[i]] += points[i];
    for (int c = 0; c < s.channels; ++c) lsum[cell[i] * s.channels + c] += lum[i * s.channels + c];
    ++count[cell[i]];
    cell_level[cell[i]] = level[i];
  }
  for (std::size_t k = 0; k < n; ++k) {
    s.position.push_back(sum[k] / double(count[k]));
    for (int c = 0; c < s.channels; ++c) s.luminance.push_back(static_cast<float>(lsum[k * s.channels + c] / double(count[k])));
    s.width.push_back(std::ldexp(1.0, cell_level[k]));
  }
  return s;
}

/// A teacher's images for loss::Teacher (TrainingData::teacher): its luminance at every pose of `poses` seen
/// through `cam`, pose-major, then pixel and channel, in the student's `channels` (a grey teacher's value in
/// each, a colour teacher's mean for a grey student).
inline std::vector<float> teacher_images(const std::function<Rendering(const geometry::Camera&, const geometry::Pose&)>& render,
                                         const geometry::Camera& cam, const std::vector<geometry::Pose>& poses, int channels) {
  require(channels == 1 || channels == 3, "a teacher's images have 1 or 3 channels");
  const std::size_t hw = static_cast<std::size_t>(cam.width()) * cam.height();
  std::vector<float> out;
  out.reserve(poses.size() * hw * channels);
  for (const auto& pose : poses) {
    const Rendering r = render(cam, pose);
    const int C = r.luminance.channels;
    require(r.luminance.width == cam.width() && r.luminance.height == cam.height(), "a teacher rendered another image size");
    for (std::size_t p = 0; p < hw; ++p) {
      const float* v = &r.luminance.data[p * C];
      for (int c = 0; c < channels; ++c) {
        if (C == channels) out.push_back(v[c]);
        else if (C == 1) out.push_back(v[0]);
        else out.push_back((v[0] + v[1] + v[2]) / 3.0f);
      }
    }
  }
  return out;
}

}  // namespace evnerf::evaluation
