// eval/mesh.hpp — a field's surface as a triangle mesh (`evnerf export`'s mesh.ply): the density sampled on
// a regular lattice over a region, its level set cut out by marching tetrahedra (each lattice cell split into
// the six tetrahedra of its main diagonal, the split every neighbour shares, so the surface is closed and
// has no ambiguous cell), vertices shared between the cells that meet at an edge, each triangle facing the
// lower density, and vertex luminance from the field seen from the nearest recorded camera. Depends on
// core/ only; the field comes in as a function (FieldProbe), eval/export.hpp writes the PLY.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"

namespace evnerf::evaluation {

/// Scalar values on a regular lattice: n[0] × n[1] × n[2] points at origin + (i, j, k) · spacing, x fastest.
struct Lattice {
  std::array<int, 3> n{0, 0, 0};
  Vec3 origin = Vec3::Zero();
  double spacing = 1;
  std::vector<float> value;  ///< n[0] · n[1] · n[2], index i + n[0] · (j + n[1] · k)
  std::size_t index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(n[0]) * (static_cast<std::size_t>(j) + static_cast<std::size_t>(n[1]) * k);
  }
  Vec3 point(int i, int j, int k) const { return origin + spacing * Vec3(i, j, k); }
  std::size_t size() const { return static_cast<std::size_t>(n[0]) * n[1] * n[2]; }
};

/// A lattice over the axis-aligned box [lo, hi] with `cells` cells along its longest side (and as many of
/// the same size along the others, at least one), its values from `f` (called with every point, x fastest).
inline Lattice lattice_over(const Vec3& lo, const Vec3& hi, int cells,
                            const std::function<void(const std::vector<Vec3>&, std::vector<float>&)>& f) {
  require(cells >= 1 && cells <= 1024, "mesh: the lattice's resolution must be between 1 and 1024 cells, got " + std::to_string(cells));
  require(lo.allFinite() && hi.allFinite() && (hi - lo).minCoeff() >= 0 && (hi - lo).maxCoeff() > 0,
          "mesh: the region to mesh spans no volume");
  Lattice L;
  L.spacing = (hi - lo).maxCoeff() / cells;
  for (int a = 0; a < 3; ++a) L.n[a] = std::max(2, static_cast<int>(std::ceil((hi[a] - lo[a]) / L.spacing - 1e-9)) + 1);
  L.origin = lo;
  std::vector<Vec3> pts;
  pts.reserve(static_cast<std::size_t>(L.n[0]) * L.n[1]);
  L.value.resize(L.size());
  std::vector<float> v;
  for (int k = 0; k < L.n[2]; ++k) {  // a plane at a time: memory for one plane's points
    pts.clear();
    for (int j = 0; j < L.n[1]; ++j)
      for (int i = 0; i < L.n[0]; ++i) pts.push_back(L.point(i, j, k));
    f(pts, v);
    require(v.size() == pts.size(),
            "mesh: the field gave " + std::to_string(v.size()) + " values for " + std::to_string(pts.size()) + " points");
    std::copy(v.begin(), v.end(), L.value.begin() + static_cast<std::ptrdiff_t>(L.index(0, 0, k)));
  }
  return L;
}

/// A triangle mesh: positions, and triangles as three vertex indices each (counter-clockwise seen from
/// the side the normal points to).
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

namespace detail {
/// The vertex on the lattice edge between points a and b (either order): made once, placed linearly where
/// the value crosses `level`, and found again by every cell around that edge.
inline std::uint32_t edge_vertex(std::unordered_map<std::uint64_t, std::uint32_t>& at_edge, TriangleMesh& m, const Lattice& L, double level,
                                 std::size_t a, std::size_t b, Vec3 pa, Vec3 pb) {
  if (a > b) {
    std::swap(a, b);
    std::swap(pa, pb);
  }
  const std::uint64_t key = static_cast<std::uint64_t>(a) * static_cast<std::uint64_t>(L.size()) + b;
  const auto it = at_edge.find(key);
  if (it != at_edge.end()) return it->second;
  const double va = L.value[a], vb = L.value[b];
  const double t = std::isfinite(va) && std::isfinite(vb) && va != vb ? std::clamp((level - va) / (vb - va), 0.0, 1.0) : 0.5;
  const auto id = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.push_back(pa + t * (pb - pa));
  at_edge.emplace(key, id);
  return id;
}
}  // namespace detail

/// The level set {value = level} of `L` as triangles, each facing the side of lower value (outward for a
/// density). A point with value > level is inside; a lattice edge from inside to outside holds one vertex,
/// placed linearly between its ends and shared by every cell around that edge. Non-finite values count as
/// outside. Deterministic.
inline TriangleMesh marching_tetrahedra(const Lattice& L, double level) {
  require(std::isfinite(level), "mesh: the level must be finite");
  TriangleMesh m;
  if (L.n[0] < 2 || L.n[1] < 2 || L.n[2] < 2) return m;
  // Corner c of a cell is at offset (c & 1, c >> 1 & 1, c >> 2 & 1); the six tetrahedra of the diagonal
  // 0–7 are the paths from corner 0 to 7 along the axes in each order.
  static constexpr int kTets[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};
  std::unordered_map<std::uint64_t, std::uint32_t> at_edge;
  auto inside = [&](std::size_t g) { return static_cast<double>(L.value[g]) > level; };  // NaN: outside
  std::array<std::size_t, 8> g{};
  std::array<Vec3, 8> p;
  for (int k = 0; k + 1 < L.n[2]; ++k)
    for (int j = 0; j + 1 < L.n[1]; ++j)
      for (int i = 0; i + 1 < L.n[0]; ++i) {
        int in_count = 0;
        for (int c = 0; c < 8; ++c) {
          g[c] = L.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1));
          in_count += inside(g[c]);
        }
        if (in_count == 0 || in_count == 8) continue;
        for (int c = 0; c < 8; ++c) p[c] = L.point(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1));
        for (const auto& tet : kTets) {
          int in[4], out[4], ni = 0, no = 0;
          for (int v : tet) (inside(g[v]) ? in[ni++] : out[no++]) = v;
          if (ni == 0 || no == 0) continue;
          auto edge = [&](int a, int b) { return detail::edge_vertex(at_edge, m, L, level, g[a], g[b], p[a], p[b]); };
          // Each triangle faces from the inside corners to the outside ones. Its side is read off the
          // midpoints of its three lattice edges, which depend on the corners alone: its own vertices may
          // coincide (a value exactly at the level) and leave it no direction of its own.
          Vec3 ci = Vec3::Zero(), co = Vec3::Zero();
          for (int q = 0; q < ni; ++q) ci += p[in[q]] / ni;
          for (int q = 0; q < no; ++q) co += p[out[q]] / no;
          const Vec3 outward = co - ci;
          auto emit = [&](std::array<int, 2> e0, std::array<int, 2> e1, std::array<int, 2> e2) {
            auto mid = [&](const std::array<int, 2>& e) -> Vec3 { return 0.5 * (p[e[0]] + p[e[1]]); };
            if ((mid(e1) - mid(e0)).cross(mid(e2) - mid(e0)).dot(outward) < 0) std::swap(e1, e2);
            m.triangles.push_back({edge(e0[0], e0[1]), edge(e1[0], e1[1]), edge(e2[0], e2[1])});
          };
          if (ni == 1) {
            emit({in[0], out[0]}, {in[0], out[1]}, {in[0], out[2]});
          } else if (no == 1) {
            emit({in[0], out[0]}, {in[1], out[0]}, {in[2], out[0]});
          } else {  // two and two: a quad around the tetrahedron, cut in two along a–c
            const std::array<int, 2> a{in[0], out[0]}, b{in[0], out[1]}, c{in[1], out[1]}, d{in[1], out[0]};
            emit(a, b, c);
            emit(a, c, d);
          }
        }
      }
  return m;
}

/// The field as exports read it (evaluation::Renderable::field): at world points seen along unit
/// directions, the density as α reads it (per `density_length` world units) and `channels` luminance values.
struct FieldProbe {
  int channels = 1;
  double density_length = 1;
  std::function<void(const std::vector<Vec3>& points, const std::vector<Vec3>& dirs, std::vector<float>& sigma, std::vector<float>& lum)>
      at;
  explicit operator bool() const { return static_cast<bool>(at); }
};

/// The cells of the survey lattice that finds where a surface is (field_mesh).
inline constexpr int kMeshSurvey = 64;

/// The box that holds a cloud's points but its stray ones: per axis from the `q` to the 1 − q quantile,
/// grown by `pad` of the box's largest side on every side.
inline std::pair<Vec3, Vec3> robust_bounds(const std::vector<Vec3>& pts, double q = 0.005, double pad = 0.05) {
  require(!pts.empty(), "mesh: no points to bound (no pixel of the recorded poses is opaque)");
  Vec3 lo, hi;
  std::vector<double> v(pts.size());
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < pts.size(); ++i) v[i] = pts[i][a];
    std::sort(v.begin(), v.end());
    lo[a] = v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
    hi[a] = v[static_cast<std::size_t>((1 - q) * static_cast<double>(v.size() - 1))];
  }
  const double grow = pad * std::max((hi - lo).maxCoeff(), 1e-9);
  return {lo - Vec3::Constant(grow), hi + Vec3::Constant(grow)};
}

/// A field's surface where its `points` lie (expected depths of opaque pixels, export's points.ply): inside the
/// box that holds them (robust_bounds), at the level of the field's density that is the `quantile` of its
/// density at the points (the rays' expected depths: on a surface they sit where it turns opaque). First a
/// lattice of kMeshSurvey cells finds the points above the level, then `cells` lattice cells along the
/// longest side of the box that holds those (but their outer 0.5 % per axis, grown by 5 %) cut the surface,
/// so the resolution goes where the surface is. Each vertex's luminance is the field's as the nearest of
/// `cameras` (centres) sees it; `lum` gets channels per vertex.
inline TriangleMesh field_mesh(const FieldProbe& f, const std::vector<Vec3>& points, const std::vector<Vec3>& cameras, int cells,
                               double quantile, std::vector<float>& lum) {
  require(static_cast<bool>(f), "mesh: the model is not a field (a Gaussian scene exports its Gaussians)");
  require(quantile >= 0 && quantile <= 1, "mesh: the level's quantile must be in [0, 1], got " + std::to_string(quantile));
  require(!cameras.empty(), "mesh: no camera to see the vertices from");
  std::vector<Vec3> dirs;
  std::vector<float> unused;
  auto density = [&](const std::vector<Vec3>& pts, std::vector<float>& sigma) {
    dirs.assign(pts.size(), Vec3(0, 0, 1));  // density does not depend on the direction
    f.at(pts, dirs, sigma, unused);
  };
  const auto [lo, hi] = robust_bounds(points);
  std::vector<float> at_points;
  density(points, at_points);
  const std::size_t qk = static_cast<std::size_t>(quantile * static_cast<double>(at_points.size() - 1));
  std::nth_element(at_points.begin(), at_points.begin() + static_cast<std::ptrdiff_t>(qk), at_points.end());
  const double level = at_points[qk];
  const Lattice survey = lattice_over(lo, hi, std::min(cells, kMeshSurvey), density);
  std::vector<Vec3> above;
  for (int k = 0; k < survey.n[2]; ++k)
    for (int j = 0; j < survey.n[1]; ++j)
      for (int i = 0; i < survey.n[0]; ++i)
        if (static_cast<double>(survey.value[survey.index(i, j, k)]) > level) above.push_back(survey.point(i, j, k));
  if (above.empty()) {
    lum.clear();
    return {};
  }
  auto [flo, fhi] = robust_bounds(above);
  const Vec3 grow = Vec3::Constant(survey.spacing);  // a survey cell: the surface lies within one of the points above
  flo = (flo - grow).cwiseMax(lo);
  fhi = (fhi + grow).cwiseMin(hi);
  TriangleMesh m = marching_tetrahedra(lattice_over(flo, fhi, cells, density), level);
  dirs.resize(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Vec3& v = m.vertices[i];
    std::size_t best = 0;
    for (std::size_t c = 1; c < cameras.size(); ++c)
      if ((cameras[c] - v).squaredNorm() < (cameras[best] - v).squaredNorm()) best = c;
    const Vec3 d = v - cameras[best];
    dirs[i] = d.norm() > 0 ? Vec3(d.normalized()) : Vec3(0, 0, 1);
  }
  std::vector<float> sigma;
  if (!m.vertices.empty()) f.at(m.vertices, dirs, sigma, lum);
  else lum.clear();
  return m;
}

}  // namespace evnerf::evaluation
