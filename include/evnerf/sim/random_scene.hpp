// sim/random_scene.hpp — procedural random scenes from a seed (`evnerf simulate random --seed N`), written
// as the scene description text of sim/scene.hpp, so a scene is its text: the generator draws from the
// counter-based Rng (the same numbers on every machine) one statement at a time (C++ leaves the order of a
// call's arguments to the compiler, so no call takes two draws) and writes every value rounded to a few
// digits. GCC and clang give every seed the same text.
// What a seed gives: one of the three kinds of path (slider, orbit arc, hand-held; seed mod 3), a floor and
// a back wall, 2–5 boxes, spheres and rectangles in view, textures with natural-image statistics (fractal
// value noise, whose octaves halve in amplitude as they double in frequency, i.e. a 1/f² power spectrum),
// checkers and stripes no finer than the sensor resolves at their distance, or photos from a folder; colours
// in which dark (albedo down to 0.01) and bright (up to 0.95) regions are both large; and a light of high
// dynamic range (ambient 0.05–0.4 against a directional light of 0.4–2.5, so radiance spans up to 8.6 nats).
// Depends on core/ and sim/scene.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "../core/rng.hpp"
#include "scene.hpp"

namespace evnerf::sim {

/// Bumped when the generator changes what a seed gives (tests pin seed 1's text to catch accidents).
inline constexpr int kRandomSceneVersion = 1;

namespace detail {
class SceneWriter {
 public:
  SceneWriter(std::uint64_t seed, const std::vector<std::string>& pictures) : rng_(Rng(seed).split(0x5CE7E)), pictures_(pictures) {}

  double uniform(double lo, double hi) { return rng_.uniform(lo, hi); }
  /// Log-uniform in [lo, hi]: dark albedos and light levels are spread evenly in log.
  double log_uniform(double lo, double hi) { return lo * std::pow(hi / lo, rng_.uniform()); }
  std::uint64_t below(std::uint64_t n) { return rng_.below(n); }

  /// An RGB colour of the given brightness (its largest channel), with a random tint.
  Vec3 colour(double brightness) {
    const double b = uniform(0.35, 1.0), g = uniform(0.35, 1.0), r = uniform(0.35, 1.0);
    const Vec3 c(r, g, b);
    return c / c.maxCoeff() * brightness;
  }
  /// A texture: half fractal noise, a fifth each checkers and stripes, a tenth photos (noise when there are
  /// none). Its colours are bright and dark (6 in 8), both dark (1 in 8) or both bright (1 in 8), so scenes
  /// have large dark regions next to bright ones.
  /// `distance` is about how far the camera sees the surface from: a checker square or stripe spans 8 to 27
  /// pixels there at the default 200-pixel focal length (scale 12.5/distance and below), the noise's coarsest
  /// blobs 3 to 13 times that, so no texture is finer than the sensor resolves.
  std::string texture(double distance) {
    const double resolvable = 12.5 / distance;  // periods per metre at which half a period spans 8 pixels
    std::uint64_t kind = below(10);
    kind = kind < 5 ? 0 : kind < 7 ? 1 : kind < 9 ? 2 : pictures_.empty() ? 0 : 3;
    std::string t;
    if (kind == 0) {
      const int seed = static_cast<int>(below(100000)), octaves = 4 + static_cast<int>(below(3));
      t = fmt("noise %.3f %d %d", uniform(0.08, 0.3) * resolvable, octaves, seed);
    } else if (kind == 1) t = fmt("checker %.3f", uniform(0.3, 1.0) * resolvable);
    else if (kind == 2) t = fmt("stripes %.3f", uniform(0.3, 1.0) * resolvable);
    else {
      const double scale = uniform(0.3, 1.5);
      return fmt("image %s %.3f", pictures_[below(pictures_.size())].c_str(), scale);
    }
    const std::uint64_t mood = below(8);
    const double hi = mood == 0 ? log_uniform(0.01, 0.1) : log_uniform(0.3, 0.95);
    const double lo = mood == 1 ? log_uniform(0.3, 0.9) * hi : log_uniform(0.01, 0.15);
    const Vec3 a = colour(hi), b = colour(std::min(lo, hi));
    return t + fmt(" colors %.4f %.4f %.4f %.4f %.4f %.4f", a.x(), a.y(), a.z(), b.x(), b.y(), b.z());
  }

  template <class... A>
  static std::string fmt(const char* f, A... a) {
    char buf[512];
    std::snprintf(buf, sizeof buf, f, a...);
    return buf;
  }

 private:
  Rng rng_;
  const std::vector<std::string>& pictures_;
};
}  // namespace detail

/// The PNG files of a folder, sorted by name (a scene's photos are drawn from this list by index).
inline std::vector<std::string> texture_pictures(const std::filesystem::path& dir) {
  std::vector<std::string> out;
  if (dir.empty()) return out;
  if (!std::filesystem::is_directory(dir)) throw Error(dir.string(), 0, "--textures: not a folder");
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && (e.path().extension() == ".png" || e.path().extension() == ".PNG"))
      out.push_back(std::filesystem::absolute(e.path()).string());
  std::sort(out.begin(), out.end());
  if (out.empty()) throw Error(dir.string(), 0, "--textures: the folder has no .png files");
  for (const auto& p : out)
    if (p.find_first_of(" \t\r\n#") != std::string::npos)
      throw Error(p, 0, "--textures: a picture's path must not contain spaces or '#' (the scene format splits on them)");
  return out;
}

/// The description text of random scene `seed` (see the file comment). `pictures` (absolute PNG paths, from
/// texture_pictures) add photo textures; without them a seed gives the same text on every machine.
inline std::string random_scene_text(std::uint64_t seed, const std::vector<std::string>& pictures = {}) {
  detail::SceneWriter w(seed, pictures);
  using detail::SceneWriter;
  std::string s = SceneWriter::fmt("# evnerf random scene, seed %llu (generator version %d)\n", static_cast<unsigned long long>(seed),
                                   kRandomSceneVersion);
  const int path_kind = static_cast<int>(seed % 3);  // 0 slider, 1 orbit arc, 2 hand-held: seeds 1..3 show all three
  // Light: travels down (+y is down) and into the scene; ambient against direct light spans a high range.
  const double lz = w.uniform(-0.3, 1.0), ly = w.uniform(0.3, 1.0), lx = w.uniform(-0.6, 0.6);
  const double direct = w.uniform(0.4, 2.5), ambient = w.log_uniform(0.05, 0.4);
  s += SceneWriter::fmt("light %.4f %.4f %.4f %.4f %.4f\n", lx, ly, lz, ambient, direct);
  const double bg = w.log_uniform(0.005, 0.05);
  s += SceneWriter::fmt("background %.4f %.4f %.4f\n", bg, bg, bg);
  const int objects = 2 + static_cast<int>(w.below(4));
  if (path_kind == 1) {
    // Orbit: objects on a floor around the origin, a wall behind them, the camera circling above.
    const double floor_y = w.uniform(0.3, 0.5), wall_z = w.uniform(2.5, 3.5);
    s += SceneWriter::fmt("plane 0 %.4f 0  0 -1 0  1 0 0  0 0  %s\n", floor_y, w.texture(2.6).c_str());
    s += SceneWriter::fmt("plane 0 0 %.4f  0 0 -1  1 0 0  0 0  %s\n", wall_z, w.texture(wall_z + 2.6).c_str());
    for (int k = 0; k < objects; ++k) {
      const double x = w.uniform(-0.8, 0.8), z = w.uniform(-0.6, 0.8);
      if (w.below(2) == 0) {
        const double hx = w.uniform(0.12, 0.4), hy = w.uniform(0.12, 0.4), hz = w.uniform(0.12, 0.4);
        s += SceneWriter::fmt("box %.4f %.4f %.4f  %.4f %.4f %.4f  %s\n", x, floor_y - hy, z, hx, hy, hz, w.texture(2.6).c_str());
      } else {
        const double r = w.uniform(0.12, 0.35);
        s += SceneWriter::fmt("sphere %.4f %.4f %.4f  %.4f  %s\n", x, floor_y - r, z, r, w.texture(2.6).c_str());
      }
    }
    const double a0 = w.uniform(-0.7, -0.3), a1 = a0 + w.uniform(0.6, 1.0);
    const double duration = w.uniform(2.0, 3.0), height = w.uniform(-1.0, -0.4), radius = w.uniform(2.2, 3.0);
    s += SceneWriter::fmt("path arc 0 0 0 %.4f %.4f %.4f %.4f %.4f\n", radius, height, a0, a1, duration);
    return s;
  }
  // Slider and hand-held: the camera near the origin looking along +z at objects 1.2–3.8 m away, a floor
  // below and a wall behind.
  const double floor_y = w.uniform(0.5, 0.9), wall_z = w.uniform(4.5, 6.0);
  s += SceneWriter::fmt("plane 0 %.4f 0  0 -1 0  1 0 0  0 0  %s\n", floor_y, w.texture(2.5).c_str());
  s += SceneWriter::fmt("plane 0 0 %.4f  0 0 -1  1 0 0  0 0  %s\n", wall_z, w.texture(wall_z).c_str());
  for (int k = 0; k < objects; ++k) {
    const double z = w.uniform(1.2, 3.8), x = w.uniform(-0.4, 0.4) * z, y = std::min(w.uniform(-0.3, 0.25) * z, floor_y - 0.2);
    const std::uint64_t kind = w.below(3);
    if (kind == 0) {
      const double hx = w.uniform(0.1, 0.35), hy = w.uniform(0.1, 0.35), hz = w.uniform(0.1, 0.35);
      s += SceneWriter::fmt("box %.4f %.4f %.4f  %.4f %.4f %.4f  %s\n", x, y, z, hx, hy, hz, w.texture(z).c_str());
    } else if (kind == 1) {
      const std::string texture = w.texture(z);
      s += SceneWriter::fmt("sphere %.4f %.4f %.4f  %.4f  %s\n", x, y, z, w.uniform(0.1, 0.35), texture.c_str());
    } else {
      // A rectangle facing the camera, tilted a little; its u axis is made orthogonal to the normal.
      const double ny = w.uniform(-0.25, 0.25), nx = w.uniform(-0.35, 0.35);
      const Vec3 n = Vec3(nx, ny, -1.0).normalized();
      const Vec3 u = (Vec3::UnitX() - n.x() * n).normalized();
      const std::string texture = w.texture(z);
      const double half_v = w.uniform(0.15, 0.4), half_u = w.uniform(0.15, 0.5);
      s += SceneWriter::fmt("plane %.4f %.4f %.4f  %.4f %.4f %.4f  %.4f %.4f %.4f  %.4f %.4f  %s\n", x, y, z, n.x(), n.y(), n.z(), u.x(),
                            u.y(), u.z(), half_u, half_v, texture.c_str());
    }
  }
  if (path_kind == 0) {
    const double duration = w.uniform(2.0, 3.0);
    const double half = w.uniform(0.2, 0.4);
    const double look_y = w.uniform(-0.05, 0.1), look_x = w.uniform(-0.1, 0.1);
    s += SceneWriter::fmt("path slider %.4f 0 0 %.4f 0 0 %.4f %.4f 1 %.4f\n", -half, half, look_x, look_y, duration);
  } else {
    // Sideways speed peaks at 1.5·2π·amplitude/duration: 0.3–0.75 m/s (the built-in room walks at 1.3).
    const double duration = w.uniform(2.5, 3.0), amplitude = w.uniform(0.1, 0.2);
    const double look_y = w.uniform(-0.05, 0.1), look_x = w.uniform(-0.1, 0.1);
    s += SceneWriter::fmt("path handheld 0 0 0  %.4f %.4f 1  %.4f %.4f\n", look_x, look_y, amplitude, duration);
  }
  return s;
}

/// The scene named by `random` and a seed, parsed from its text (the text is returned too, to be saved).
inline SceneSpec random_scene(std::uint64_t seed, const std::vector<std::string>& pictures, std::string* text = nullptr) {
  const std::string t = random_scene_text(seed, pictures);
  auto spec = parse_scene(t, "random scene (seed " + std::to_string(seed) + ")");
  spec.scene.name = "random-" + std::to_string(seed);
  if (text) *text = t;
  return spec;
}

}  // namespace evnerf::sim
