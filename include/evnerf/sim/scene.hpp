// sim/scene.hpp — procedural scenes for the event simulator: analytic primitives (planes, boxes, spheres)
// and triangle meshes (sim/mesh.hpp, where the build has assimp and Embree) with Lambertian shading under
// ambient + directional light, band-limited procedural textures (checker, stripes, fractal noise) and PNG
// textures; camera paths (slider, arc, hand-held, orbit, spiral); a text description format and the
// built-in scenes. Depends on core/, geometry/ and io/image_io.hpp (and, with EVNERF_HAVE_MESH, sim/mesh.hpp).
#pragma once
#include <numbers>
#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../geometry/pose.hpp"
#include "../io/image_io.hpp"
#include "../io/text.hpp"

namespace evnerf::sim {

/// A texture returns linear RGB albedo at texture coordinates (u, v); `fw` is the pixel footprint in
/// texture units, used to fade detail finer than a pixel (so point-sampled renders do not alias).
struct Texture {
  enum Kind { Checker, Stripes, Noise, Picture } kind = Checker;
  double scale = 1;  ///< features per unit length
  Vec3 a = Vec3(0.9, 0.9, 0.9), b = Vec3(0.1, 0.1, 0.1);
  int octaves = 5;
  std::uint64_t seed = 1;
  std::shared_ptr<Image> picture;

  static double smooth_square(double x, double fw) {
    // Square wave in [0, 1] with period 1, box-filtered over width fw (analytic integral of the wave).
    auto integral = [](double s) {
      const double f = std::floor(s);
      return f * 0.5 + std::max(0.0, s - f - 0.5);
    };
    fw = std::max(fw, 1e-6);
    return (integral(x + 0.5 * fw) - integral(x - 0.5 * fw)) / fw;
  }
  static double hash01(std::int64_t x, std::int64_t y, std::uint64_t seed) {
    return unit_double(mix64(seed ^ mix64(static_cast<std::uint64_t>(x) * 0x9E3779B1ull + static_cast<std::uint64_t>(y))));
  }
  static double value_noise(double x, double y, std::uint64_t seed) {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
    auto s = [](double t) { return t * t * (3 - 2 * t); };
    const double tx = s(x - fx), ty = s(y - fy);
    const double v00 = hash01(ix, iy, seed), v10 = hash01(ix + 1, iy, seed), v01 = hash01(ix, iy + 1, seed),
                 v11 = hash01(ix + 1, iy + 1, seed);
    return (v00 * (1 - tx) + v10 * tx) * (1 - ty) + (v01 * (1 - tx) + v11 * tx) * ty;
  }
  /// Albedo at (u, v) for a footprint of fu along u and fv along v (texture units).
  Vec3 albedo(double u, double v, double fu, double fv) const {
    const double su = u * scale, sv = v * scale, sfu = fu * scale, sfv = fv * scale, sfw = std::max(sfu, sfv);
    double m = 0;
    switch (kind) {
      case Checker: {
        const double cu = smooth_square(su, sfu), cv = smooth_square(sv, sfv);
        m = cu * cv + (1 - cu) * (1 - cv);
        break;
      }
      case Stripes:
        m = smooth_square(su, sfu);
        break;
      case Noise: {
        double amp = 0.5, freq = 1, total = 0;
        for (int o = 0; o < octaves; ++o) {
          const double fade = std::clamp(1.5 - sfw * freq * 2, 0.0, 1.0);  // drop octaves finer than a pixel
          m += amp * fade * value_noise(su * freq, sv * freq, seed + o) + amp * (1 - fade) * 0.5;
          total += amp;
          amp *= 0.5;
          freq *= 2;
        }
        m /= total;
        m = std::clamp((m - 0.5) * 2.2 + 0.5, 0.0, 1.0);
        break;
      }
      case Picture: {
        const Image& p = *picture;
        double x = (su - std::floor(su)) * p.width - 0.5, y = (1 - (sv - std::floor(sv))) * p.height - 0.5;
        const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        Vec3 c = Vec3::Zero();
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) {
            const int xx = std::clamp(x0 + dx, 0, p.width - 1), yy = std::clamp(y0 + dy, 0, p.height - 1);
            const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
            for (int k = 0; k < 3; ++k) c[k] += w * p.at(xx, yy, std::min(k, p.channels - 1));
          }
        return c;
      }
    }
    return b + m * (a - b);
  }
  Vec3 albedo(double u, double v, double fw) const { return albedo(u, v, fw, fw); }
};

/// Analytic primitives. Planes are rectangles (half sizes hu, hv along axes u, v; 0 = unbounded).
struct Primitive {
  enum Kind { Plane, Box, Sphere } kind = Plane;
  Vec3 p = Vec3::Zero();   ///< plane point / box or sphere centre
  Vec3 n = Vec3::UnitZ();  ///< plane normal
  Vec3 u = Vec3::UnitX(), v = Vec3::UnitY();
  Vec3 half = Vec3::Ones();  ///< plane: (hu, hv, -); box: half extents
  double radius = 1;
  Texture tex;
};

struct Hit {
  double t = INFINITY;
  Vec3 normal, albedo;
};

/// A surface beside the analytic primitives, intersected a stream of rays at a time: a triangle mesh
/// (sim/mesh.hpp's Mesh).
struct Surface {
  virtual ~Surface() = default;
  /// For each ray o + t·dirs[i], the nearest hit with 1e-6 < t < hits[i].t replaces hits[i]; `pix_angle`
  /// is the angular size of a pixel (the texture footprint).
  virtual void intersect(const Vec3& o, std::span<const Vec3> dirs, double pix_angle, std::span<Hit> hits) const = 0;
};

/// Where a mesh goes in a scene (the `mesh` directive): scaled and moved so that its bounding sphere (centred
/// on its bounding box) is the sphere of `radius` at `centre`, as NeRF's synthetic objects are normalised; `up`
/// is the file's up axis (+y, +z or -y), turned to the scene's up (-y, as the camera paths use it).
struct MeshPlacement {
  std::filesystem::path file;
  Vec3 centre = Vec3::Zero();
  double radius = 1;
  std::string up = "+y";
};

#ifdef EVNERF_HAVE_MESH
/// Loads a mesh file (defined in sim/mesh.hpp, which this header includes at its end).
inline std::shared_ptr<const Surface> load_mesh(const MeshPlacement& where);
#endif

/// A scene: primitives and surfaces, ambient + one directional light, a background albedo.
struct Scene {
  std::string name;
  std::vector<Primitive> prims;
  std::vector<std::shared_ptr<const Surface>> surfaces;  ///< meshes
  Vec3 light_dir = Vec3(-0.3, -0.8, -0.5).normalized();  ///< direction the light travels
  double ambient = 0.35, diffuse = 0.65;
  Vec3 background = Vec3(0.05, 0.05, 0.05);
  /// An environment seen by the rays that hit nothing, instead of `background`: an equirectangular picture
  /// (longitude along its width, +z at its centre; latitude along its height, up = −y at its top row).
  std::shared_ptr<Image> environment;

  /// Nearest hit of the ray o + t·d among the analytic primitives with 1e-6 < t < best.t (else `best`).
  /// `pix_angle` is the angular size of a pixel (footprint).
  Hit intersect(const Vec3& o, const Vec3& d, double pix_angle, Hit best = {}) const {
    const double dn = d.norm();
    for (const auto& pr : prims) {
      double t = INFINITY;
      Vec3 nrm;
      double tu = 0, tv = 0, u_stretch = 1;
      if (pr.kind == Primitive::Plane) {
        const double den = pr.n.dot(d);
        if (std::abs(den) < 1e-12) continue;
        t = pr.n.dot(pr.p - o) / den;
        if (!(t > 1e-6) || t >= best.t) continue;
        const Vec3 q = o + t * d - pr.p;
        tu = q.dot(pr.u);
        tv = q.dot(pr.v);
        if ((pr.half.x() > 0 && std::abs(tu) > pr.half.x()) || (pr.half.y() > 0 && std::abs(tv) > pr.half.y())) continue;
        nrm = den < 0 ? pr.n : Vec3(-pr.n);
      } else if (pr.kind == Primitive::Sphere) {
        const Vec3 oc = o - pr.p;
        const double a = d.squaredNorm(), b = oc.dot(d), c = oc.squaredNorm() - pr.radius * pr.radius;
        const double disc = b * b - a * c;
        if (disc < 0) continue;
        const double s = std::sqrt(disc);
        t = (-b - s) / a;
        if (!(t > 1e-6)) t = (-b + s) / a;
        if (!(t > 1e-6) || t >= best.t) continue;
        nrm = (o + t * d - pr.p).normalized();
        tu = std::atan2(nrm.y(), nrm.x()) * pr.radius;
        tv = std::asin(std::clamp(nrm.z(), -1.0, 1.0)) * pr.radius;
        // Longitude lines converge at the poles: a world length there spans 1/cos(latitude) times more u.
        u_stretch = 1.0 / std::max(std::sqrt(std::max(0.0, 1.0 - nrm.z() * nrm.z())), 1e-3);
      } else {  // axis-aligned box, slab test
        double t0 = -INFINITY, t1 = INFINITY;
        int axis0 = 0, axis1 = 0;
        for (int k = 0; k < 3; ++k) {
          if (std::abs(d[k]) < 1e-15) {
            if (std::abs(o[k] - pr.p[k]) > pr.half[k]) t0 = INFINITY;
            continue;
          }
          double a = (pr.p[k] - pr.half[k] - o[k]) / d[k], b = (pr.p[k] + pr.half[k] - o[k]) / d[k];
          if (a > b) std::swap(a, b);
          if (a > t0) {
            t0 = a;
            axis0 = k;
          }
          if (b < t1) {
            t1 = b;
            axis1 = k;
          }
        }
        if (t0 > t1) continue;
        int axis = axis0;
        t = t0;
        if (!(t > 1e-6)) {  // inside the box (a room): the far wall
          t = t1;
          axis = axis1;
        }
        if (!(t > 1e-6) || t >= best.t) continue;
        const Vec3 q = o + t * d - pr.p;
        nrm = Vec3::Zero();
        nrm[axis] = q[axis] > 0 ? 1 : -1;
        if (nrm.dot(d) > 0) nrm = -nrm;
        tu = q[(axis + 1) % 3];
        tv = q[(axis + 2) % 3];
      }
      best.t = t;
      best.normal = nrm;
      const double footprint = pix_angle * t * dn / std::max(0.05, std::abs(nrm.dot(d)) / dn);
      best.albedo = pr.tex.albedo(tu, tv, footprint * u_stretch, footprint);
    }
    return best;
  }

  /// The radiance of a ray along d that hits nothing.
  Vec3 miss(const Vec3& d) const {
    if (!environment) return background;
    const Vec3 u = d.normalized();
    Texture t;
    t.kind = Texture::Picture;
    t.picture = environment;
    const double lon = std::atan2(u.x(), u.z()), lat = std::asin(std::clamp(-u.y(), -1.0, 1.0));
    return t.albedo(lon / (2 * std::numbers::pi) + 0.5, lat / std::numbers::pi + 0.5, 0.0);
  }
  /// Linear RGB radiance of a hit (Lambertian, ambient + directional light) along d, the background for a miss.
  Vec3 radiance(const Hit& h, const Vec3& d) const {
    if (!std::isfinite(h.t)) return miss(d);
    const double lam = std::max(0.0, -h.normal.dot(light_dir));
    return h.albedo * (ambient + diffuse * lam);
  }
  /// Linear RGB radiance along a ray.
  Vec3 shade(const Vec3& o, const Vec3& d, double pix_angle, double* depth_t = nullptr) const {
    Hit h;
    for (const auto& s : surfaces) s->intersect(o, std::span<const Vec3>(&d, 1), pix_angle, std::span<Hit>(&h, 1));
    h = intersect(o, d, pix_angle, h);
    if (depth_t) *depth_t = h.t;
    return radiance(h, d);
  }
  /// Radiance (and the ray parameter t of the hit, INFINITY for a miss) of the rays o + t·dirs[i]: the surfaces
  /// take the rays as one stream, then the analytic primitives ray by ray.
  void shade(const Vec3& o, std::span<const Vec3> dirs, double pix_angle, std::span<Vec3> rgb, std::span<double> t) const {
    thread_local std::vector<Hit> hits;
    hits.assign(dirs.size(), Hit{});
    for (const auto& s : surfaces) s->intersect(o, dirs, pix_angle, hits);
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      const Hit h = prims.empty() ? hits[i] : intersect(o, dirs[i], pix_angle, hits[i]);
      rgb[i] = radiance(h, dirs[i]);
      t[i] = h.t;
    }
  }
};

/// High-dynamic-range lighting for a scene (`simulate --hdr`): ambient ×0.05 and the directional light ×4, so
/// shadowed dark albedo and lit bright albedo lie 7–8 nats apart and lit highlights exceed 1 (frames clip).
inline void hdr_lighting(Scene& s) {
  s.ambient *= 0.05;
  s.diffuse *= 4.0;
}

/// A camera path: pose at any time in [0, duration].
struct CameraPath {
  double duration = 2.0;
  std::function<geometry::Pose(double)> pose;
};

inline CameraPath slider_path(const Vec3& from, const Vec3& to, const Vec3& look, double duration) {
  return {duration, [=](double t) {
            const double s = std::clamp(t / duration, 0.0, 1.0);
            const Vec3 eye = from + s * (to - from);
            return geometry::Pose::look_at(eye, eye + look, Vec3(0, -1, 0));
          }};
}
/// Orbit arc at `radius` around `center` (angles in radians around +y), looking at the centre.
inline CameraPath arc_path(const Vec3& center, double radius, double height, double a0, double a1, double duration) {
  return {duration, [=](double t) {
            const double s = std::clamp(t / duration, 0.0, 1.0), a = a0 + s * (a1 - a0);
            const Vec3 eye = center + Vec3(radius * std::sin(a), height, -radius * std::cos(a));
            return geometry::Pose::look_at(eye, center, Vec3(0, -1, 0));
          }};
}
/// EventNeRF's object-centric capture: an orbit around `center` at `radius`, one revolution per second, at
/// `elevation` radians above the horizon (up is -y), looking at the centre; `wobble` (radians) swings the
/// elevation once over the path's duration.
inline CameraPath orbit_path(const Vec3& center, double radius, double elevation, double duration, double wobble = 0) {
  return {duration, [=](double t) {
            const double a = 2 * std::numbers::pi * t, e = elevation + wobble * std::sin(2 * std::numbers::pi * t / duration);
            const Vec3 eye = center + radius * Vec3(std::cos(e) * std::sin(a), -std::sin(e), -std::cos(e) * std::cos(a));
            return geometry::Pose::look_at(eye, center, Vec3(0, -1, 0));
          }};
}
/// A spiral over the upper hemisphere: `revolutions` turns around `center` at `radius` while the elevation
/// rises linearly from e0 to e1 (radians), looking at the centre.
inline CameraPath spiral_path(const Vec3& center, double radius, double e0, double e1, double revolutions, double duration) {
  return {duration, [=](double t) {
            const double s = std::clamp(t / duration, 0.0, 1.0), a = 2 * std::numbers::pi * revolutions * s, e = e0 + s * (e1 - e0);
            const Vec3 eye = center + radius * Vec3(std::cos(e) * std::sin(a), -std::sin(e), -std::cos(e) * std::cos(a));
            return geometry::Pose::look_at(eye, center, Vec3(0, -1, 0));
          }};
}
/// Smooth hand-held zig-zag: sideways sweeps with vertical bob and small rotations.
inline CameraPath handheld_path(const Vec3& start, const Vec3& look, double amplitude, double duration) {
  return {duration, [=](double t) {
            const double w = 2 * std::numbers::pi / duration;
            const Vec3 eye = start + Vec3(amplitude * std::sin(1.5 * w * t), 0.3 * amplitude * std::sin(3.1 * w * t),
                                          0.4 * amplitude * std::sin(0.7 * w * t));
            const Vec3 target = eye + look + Vec3(0.15 * std::sin(1.1 * w * t), 0.1 * std::cos(1.7 * w * t), 0);
            return geometry::Pose::look_at(eye, target, Vec3(0, -1, 0));
          }};
}

// ---- the text description format --------------------------------------------------------------------
// One directive per line, '#' comments:
//   light  dx dy dz ambient diffuse
//   background r g b  |  background image FILE.png   (an equirectangular environment, taken as linear)
//   plane  px py pz  nx ny nz  ux uy uz  half_u half_v  <texture>
//   box    cx cy cz  hx hy hz  <texture>
//   sphere cx cy cz  r  <texture>
//   mesh   file  cx cy cz  radius  [up +y|+z|-y]    (any file assimp reads; normalised into the sphere)
//   path   slider x0 y0 z0 x1 y1 z1 lookx looky lookz duration
//   path   arc cx cy cz radius height angle0 angle1 duration
//   path   handheld x y z lookx looky lookz amplitude duration
//   path   orbit cx cy cz radius elevation_deg duration [wobble_deg]     (one revolution per second)
//   path   spiral cx cy cz radius elevation0_deg elevation1_deg revolutions duration
//   novel  <path>    (held-out views: frames along this path are written to novel/, never trained on)
// <texture> = checker scale | stripes scale | noise scale octaves seed | image path scale
//             each optionally followed by "colors ar ag ab br bg bb".
struct SceneSpec {
  Scene scene;
  CameraPath path;
  std::optional<CameraPath> novel;  ///< held-out views: frames along it are ground truth never trained on
};

inline Texture parse_texture(io::LineScanner& s, const std::filesystem::path& folder) {
  Texture t;
  const std::string kind(s.word("texture kind"));
  if (kind == "checker") {
    t.kind = Texture::Checker;
    t.scale = s.real("scale");
  } else if (kind == "stripes") {
    t.kind = Texture::Stripes;
    t.scale = s.real("scale");
  } else if (kind == "noise") {
    t.kind = Texture::Noise;
    t.scale = s.real("scale");
    const long long octaves = s.integer("octaves"), seed = s.integer("seed");
    if (octaves < 1 || octaves > 16) s.fail("noise octaves must lie in 1 … 16");
    if (seed < 0) s.fail("noise seed must not be negative");
    t.octaves = static_cast<int>(octaves);
    t.seed = static_cast<std::uint64_t>(seed);
  } else if (kind == "image") {
    t.kind = Texture::Picture;
    const std::string path(s.word("image path"));
    std::error_code ec;
    if (!std::filesystem::is_regular_file(folder / path, ec))
      s.fail("texture image '" + io::LineScanner::shown(path) + "' is not a file in " + io::LineScanner::shown(folder.string()));
    try {
      t.picture = std::make_shared<Image>(io::read_png(folder / path, 3));
    } catch (const Error& e) {
      s.fail("cannot load texture '" + io::LineScanner::shown(path) + "': " + e.message());
    }
    t.scale = s.real("scale");
  } else {
    s.fail("unknown texture '" + io::LineScanner::shown(kind) + "' (checker, stripes, noise, image)");
  }
  if (!s.at_end_of_line()) {
    if (s.word("colors") != "colors") s.fail("expected 'colors' after the texture");
    for (int k = 0; k < 3; ++k) t.a[k] = s.real("colour a");
    for (int k = 0; k < 3; ++k) t.b[k] = s.real("colour b");
  }
  if (t.scale <= 0) s.fail("texture scale must be positive");
  return t;
}

inline SceneSpec parse_scene(std::string_view text, const std::string& file, const std::filesystem::path& folder = ".") {
  SceneSpec spec;
  spec.scene.name = std::filesystem::path(file).stem().string();
  bool have_path = false;
  io::LineScanner s(text, file);
  auto vec = [&](const char* n) {
    Vec3 v;
    v.x() = s.real(n);
    v.y() = s.real(n);
    v.z() = s.real(n);
    return v;
  };
  auto direction = [&](const char* n) {
    const Vec3 v = vec(n);
    const double len = v.norm();
    if (!(len > 1e-12) || !std::isfinite(len)) s.fail(std::string(n) + " must be a non-zero vector");
    return Vec3(v / len);
  };
  while (s.next_line()) {
    const std::string cmd(s.word("directive"));
    if (cmd == "light") {
      spec.scene.light_dir = direction("light direction");
      spec.scene.ambient = s.real("ambient");
      spec.scene.diffuse = s.real("diffuse");
      if (spec.scene.ambient < 0 || spec.scene.diffuse < 0) s.fail("ambient and diffuse light must not be negative");
    } else if (cmd == "background") {
      const std::string_view first = s.peek_word();
      if (first == "image") {
        s.word("background");
        const std::string path(s.word("environment image"));
        std::error_code ec;
        if (!std::filesystem::is_regular_file(folder / path, ec))
          s.fail("cannot load the environment '" + io::LineScanner::shown(path) + "': not a file in " +
                 io::LineScanner::shown(folder.string()));
        try {
          spec.scene.environment = std::make_shared<Image>(io::read_png(folder / path, 3));
        } catch (const Error& e) {
          s.fail("cannot load the environment '" + io::LineScanner::shown(path) + "': " + e.message());
        }
      } else {
        spec.scene.background = vec("background");
      }
    } else if (cmd == "plane") {
      Primitive p;
      p.kind = Primitive::Plane;
      p.p = vec("point");
      p.n = direction("normal");
      p.u = direction("u axis");
      if (p.n.cross(p.u).norm() < 1e-6) s.fail("the plane's u axis is parallel to its normal");
      p.v = p.n.cross(p.u).normalized();
      p.half = Vec3(s.real("half_u"), s.real("half_v"), 0);
      if (p.half.x() < 0 || p.half.y() < 0) s.fail("plane half sizes must not be negative (0 = unbounded)");
      p.tex = parse_texture(s, folder);
      spec.scene.prims.push_back(p);
    } else if (cmd == "box") {
      Primitive p;
      p.kind = Primitive::Box;
      p.p = vec("centre");
      p.half = vec("half extents");
      if (!(p.half.minCoeff() > 0)) s.fail("box half extents must be positive");
      p.tex = parse_texture(s, folder);
      spec.scene.prims.push_back(p);
    } else if (cmd == "sphere") {
      Primitive p;
      p.kind = Primitive::Sphere;
      p.p = vec("centre");
      p.radius = s.real("radius");
      if (p.radius <= 0) s.fail("sphere radius must be positive");
      p.tex = parse_texture(s, folder);
      spec.scene.prims.push_back(p);
    } else if (cmd == "mesh") {
      MeshPlacement m;
      const std::string file(s.word("mesh file"));
      m.file = folder / file;
      m.centre = vec("centre");
      m.radius = s.real("radius");
      if (!(m.radius > 0) || !std::isfinite(m.radius)) s.fail("mesh radius must be positive");
      if (!s.at_end_of_line()) {
        if (s.word("up") != "up") s.fail("expected 'up' after the mesh's radius");
        m.up = std::string(s.word("up axis"));
        if (m.up != "+y" && m.up != "+z" && m.up != "-y") s.fail("the mesh's up axis must be +y, +z or -y");
      }
#ifdef EVNERF_HAVE_MESH
      try {
        spec.scene.surfaces.push_back(load_mesh(m));
      } catch (const Error& e) {
        s.fail((e.file().empty() ? "" : e.file() + ": ") + e.message());
      }
#else
      s.fail("this build of evnerf reads no meshes (it was built without libassimp-dev and libembree-dev)");
#endif
    } else if (cmd == "path" || cmd == "novel") {
      const bool novel = cmd == "novel";
      CameraPath p;
      const std::string kind(s.word("path kind"));
      if (kind == "slider") {
        const Vec3 a = vec("start"), b = vec("end"), look = vec("look");
        p = slider_path(a, b, look, s.real("duration"));
      } else if (kind == "arc") {
        const Vec3 c = vec("centre");
        const double r = s.real("radius"), h = s.real("height"), a0 = s.real("angle0"), a1 = s.real("angle1");
        p = arc_path(c, r, h, a0, a1, s.real("duration"));
      } else if (kind == "handheld") {
        const Vec3 a = vec("start"), look = vec("look");
        const double amp = s.real("amplitude");
        p = handheld_path(a, look, amp, s.real("duration"));
      } else if (kind == "orbit") {
        const Vec3 c = vec("centre");
        const double r = s.real("radius"), e = s.real("elevation"), duration = s.real("duration");
        const double wobble = s.at_end_of_line() ? 0.0 : s.real("wobble");
        if (!(r > 0)) s.fail("orbit radius must be positive");
        if (std::abs(e) + std::abs(wobble) >= 89) s.fail("the orbit's elevation (with its wobble) must stay within ±89 degrees");
        p = orbit_path(c, r, e * std::numbers::pi / 180, duration, wobble * std::numbers::pi / 180);
      } else if (kind == "spiral") {
        const Vec3 c = vec("centre");
        const double r = s.real("radius"), e0 = s.real("elevation0"), e1 = s.real("elevation1"), turns = s.real("revolutions");
        if (!(r > 0)) s.fail("spiral radius must be positive");
        if (std::abs(e0) >= 89 || std::abs(e1) >= 89) s.fail("the spiral's elevations must lie within ±89 degrees");
        p = spiral_path(c, r, e0 * std::numbers::pi / 180, e1 * std::numbers::pi / 180, turns, s.real("duration"));
      } else {
        s.fail("unknown path '" + io::LineScanner::shown(kind) + "' (slider, arc, handheld, orbit, spiral)");
      }
      if (!(p.duration > 0) || p.duration > 3600) s.fail("path duration must lie in (0, 3600] seconds");
      if (novel) {
        spec.novel = std::move(p);
      } else {
        spec.path = std::move(p);
        have_path = true;
      }
    } else {
      s.fail("unknown directive '" + io::LineScanner::shown(cmd) + "'");
    }
    s.expect_end();
  }
  if (spec.scene.prims.empty() && spec.scene.surfaces.empty()) throw Error(file, 0, "scene has no primitives");
  if (!have_path) throw Error(file, 0, "scene has no camera path ('path ...' line)");
  return spec;
}

/// Built-in scenes: "planes" (three textured planes at 1, 2 and 3.5 m before a wall, linear slider),
/// "object" (box and sphere on a textured floor before a wall, orbit arc), "room" (inside a textured
/// room with a box, hand-held zig-zag), "blocks" (the colour scene: three boxes and a sphere in coloured
/// fractal noise, stripes and checkers on a coloured-noise floor before a coloured-noise wall, orbit arc;
/// `evnerf simulate blocks` simulates it through an RGGB mosaic).
inline const char* builtin_scene_text(const std::string& name) {
  if (name == "planes")
    return "light -0.2 0.3 1 0.4 0.6\n"
           "plane -0.35 0.1 1.0  0 0 -1  1 0 0  0.35 0.3  checker 6\n"
           "plane 0.45 -0.15 2.0  0 0 -1  1 0 0  0.6 0.45  noise 3 5 7\n"
           "plane -0.2 0.3 3.5  0 0 -1  1 0 0  1.1 0.6  stripes 2.5 colors 0.85 0.8 0.7 0.2 0.25 0.3\n"
           "plane 0 0 6  0 0 -1  1 0 0  0 0  noise 1.2 6 3\n"
           "path slider -0.3 0 0 0.3 0 0 0 0 1 2.0\n";
  if (name == "object")
    return "light -0.4 0.8 0.6 0.35 0.65\n"
           "box 0 0.1 0  0.35 0.35 0.35  checker 5 colors 0.9 0.6 0.3 0.2 0.15 0.1\n"
           "sphere 0.75 0.2 0.3 0.25  stripes 6\n"
           "plane 0 0.45 0  0 -1 0  1 0 0  0 0  checker 2 colors 0.7 0.7 0.7 0.3 0.3 0.3\n"
           "plane 0 0 3  0 0 -1  1 0 0  0 0  noise 1.5 6 11\n"
           "path arc 0 0 0 2.6 -0.8 -0.5 0.5 3.0\n";
  if (name == "room")
    return "light 0.3 0.9 0.4 0.45 0.55\n"
           "box 0 0 0  2.5 1.5 2.5  noise 1.4 6 5\n"
           "box 0.6 1.0 1.2  0.4 0.5 0.4  checker 4 colors 0.85 0.3 0.3 0.2 0.2 0.5\n"
           "path handheld 0 0 -1.5  0 0 1  0.4 3.0\n";
  if (name == "blocks")
    return "light -0.3 0.8 0.5 0.35 0.65\n"
           "box -0.45 0.15 0.1  0.3 0.3 0.3  noise 3 5 21 colors 0.95 0.45 0.1 0.25 0.05 0.05\n"
           "box 0.35 0.2 -0.2  0.25 0.25 0.25  stripes 5 colors 0.1 0.55 0.9 0.9 0.85 0.2\n"
           "sphere -0.02 0.25 -0.55 0.2  noise 4 4 33 colors 0.2 0.8 0.3 0.6 0.1 0.6\n"
           "box 0.85 0.3 0.4  0.15 0.15 0.15  checker 4 colors 0.9 0.9 0.9 0.8 0.1 0.2\n"
           "plane 0 0.45 0  0 -1 0  1 0 0  0 0  noise 2 6 41 colors 0.75 0.7 0.55 0.25 0.3 0.4\n"
           "plane 0 0 3  0 0 -1  1 0 0  0 0  noise 1.5 6 12 colors 0.3 0.5 0.7 0.8 0.7 0.5\n"
           "path arc 0 0 0 2.6 -0.8 -0.5 0.5 3.0\n";
  return nullptr;
}
inline std::vector<std::string> builtin_scenes() { return {"planes", "object", "room", "blocks"}; }

/// A built-in scene by name, or a scene description file.
inline SceneSpec load_scene(const std::string& name_or_path) {
  if (const char* text = builtin_scene_text(name_or_path)) {
    auto spec = parse_scene(text, name_or_path + " (built-in)");
    spec.scene.name = name_or_path;
    return spec;
  }
  if (!std::filesystem::exists(name_or_path))
    throw Error(name_or_path, 0, "no such scene file, and not a built-in scene (planes, object, room, blocks)");
  auto spec = parse_scene(read_file(name_or_path), name_or_path, std::filesystem::path(name_or_path).parent_path());
  return spec;
}

}  // namespace evnerf::sim

#ifdef EVNERF_HAVE_MESH
#include "mesh.hpp"
#endif
