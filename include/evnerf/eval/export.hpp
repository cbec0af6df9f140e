// eval/export.hpp — a trained scene in the files other tools open (`evnerf export`): the Gaussians of a
// Gaussian scene in the PLY layout of 3D Gaussian splatting (graphdeco-inria/gaussian-splatting), which every
// 3DGS viewer reads; a point cloud of any model, from its depth at the recorded poses; a field's surface as
// a mesh (eval/mesh.hpp); and the cameras as a NeRF / nerfstudio transforms.json. Each is a function of its own. The world frame is the recording's,
// as the poses give it: a camera looks along its +z with +y down in the image (OpenCV's and COLMAP's
// convention, which 3DGS keeps), so a viewer that takes +y as up shows the scene upside down until it is
// turned. Depends on io/ply.hpp, io/checkpoint.hpp (the run's cameras), render/scene.hpp, eval/mesh.hpp and
// nlohmann-json.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../io/checkpoint.hpp"
#include "../io/ply.hpp"
#include "../render/scene.hpp"
#include "mesh.hpp"

namespace evnerf::evaluation {

/// The Gaussians of a scene in world units: centre, log standard deviations along the Gaussian's axes,
/// rotation as a unit quaternion (w, x, y, z), opacity logit, and luminance per channel seen along the mean
/// direction (the degree-0 harmonic through the scene's activation).
struct GaussianCloud {
  int channels = 1;
  std::vector<std::array<float, 3>> mean, log_scale;
  std::vector<std::array<float, 4>> rotation;
  std::vector<float> opacity_logit;
  std::vector<float> luminance;  ///< channels per Gaussian
  std::size_t size() const { return mean.size(); }
};

/// 3DGS's constant of the degree-0 spherical harmonic: a colour c is stored as (c − 0.5) / kSh0.
inline constexpr double kSh0 = 0.28209479177387814;
/// A Gaussian under this opacity is not drawn (3DGS's cut, the rasterizer's too): export leaves it out.
inline constexpr double kMinExportOpacity = 1.0 / 255.0;

/// The drawn Gaussians (opacity ≥ kMinExportOpacity) of a splatting representation `rep` under `params`.
template <class Rep, class T>
GaussianCloud gaussians_of(const Rep& rep, const T* params) {
  using L = typename Rep::layout;
  std::vector<T> scene;
  rep.to_scene(params, scene);
  GaussianCloud g;
  g.channels = L::channels;
  for (std::size_t i = 0; i < Rep::capacity; ++i) {
    const T* b = scene.data() + i * L::size;
    const double logit = static_cast<double>(b[L::opacity]);
    if (1.0 / (1.0 + std::exp(-logit)) < kMinExportOpacity) continue;
    g.mean.push_back({float(b[L::mean]), float(b[L::mean + 1]), float(b[L::mean + 2])});
    g.log_scale.push_back({float(b[L::log_scale]), float(b[L::log_scale + 1]), float(b[L::log_scale + 2])});
    double q[4], n = 0;
    for (int k = 0; k < 4; ++k) n += double(b[L::rotation + k]) * double(b[L::rotation + k]);
    n = n > 0 ? std::sqrt(n) : 1;
    for (int k = 0; k < 4; ++k) q[k] = double(b[L::rotation + k]) / n;
    g.rotation.push_back({float(q[0]), float(q[1]), float(q[2]), float(q[3])});
    g.opacity_logit.push_back(float(logit));
    for (int c = 0; c < L::channels; ++c) g.luminance.push_back(float(Rep::activation::f(double(b[L::colour + c * L::sh]) * kSh0)));
  }
  return g;
}

/// The luminance that export writes as white: the 99th percentile of `v` (a few bright outliers clip), or 1
/// where every value is 0.
inline double export_white(std::vector<float> v) {
  if (v.empty()) return 1;
  const std::size_t k = static_cast<std::size_t>(0.99 * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k] > 0 ? double(v[k]) : 1.0;
}

/// A Gaussian scene in 3DGS's PLY layout: x y z, nx ny nz (zero), f_dc_0..2, opacity (logit), scale_0..2
/// (log), rot_0..3 (w x y z). Colours are degree 0 only (a scene's view-dependent harmonics pass through its
/// activation and have no linear equivalent), each luminance divided by `white` (export_white's by default),
/// grey written to all three channels; a viewer shows 3DGS's colour 0.5 + kSh0 · f_dc, clipped to [0, 1].
inline io::PlyVertices gaussians_ply(const GaussianCloud& g, double white = 0) {
  if (!(white > 0)) white = export_white(g.luminance);
  io::PlyVertices v;
  v.names = {"x",       "y",       "z",       "nx",      "ny",    "nz",    "f_dc_0", "f_dc_1", "f_dc_2",
             "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2",  "rot_3"};
  v.floats.reserve(g.size() * v.names.size());
  for (std::size_t i = 0; i < g.size(); ++i) {
    for (int a = 0; a < 3; ++a) v.floats.push_back(g.mean[i][a]);
    for (int a = 0; a < 3; ++a) v.floats.push_back(0.f);
    for (int c = 0; c < 3; ++c) {
      const double l = g.luminance[i * g.channels + (g.channels == 3 ? c : 0)] / white;
      v.floats.push_back(float((l - 0.5) / kSh0));
    }
    v.floats.push_back(g.opacity_logit[i]);
    for (int a = 0; a < 3; ++a) v.floats.push_back(g.log_scale[i][a]);
    for (int k = 0; k < 4; ++k) v.floats.push_back(g.rotation[i][k]);
  }
  return v;
}

/// A point cloud of a model that renders as `render` does, at the cameras of `run` (what its checkpoint
/// records): at every `stride`-th pixel (in x and y) of every `pose_stride`-th recorded pose,
/// where the rendered opacity reaches `min_opacity`, the point at the expected depth (depth / opacity along
/// the pixel's ray), with its luminance (grey or RGB) as bytes scaled by `white` (the 99th percentile of the
/// points' when 0). Properties x y z, luminance (per channel's mean), red green blue.
inline io::PlyVertices point_cloud(const io::CheckpointRun& run, const std::function<Rendering(const geometry::Pose&)>& render,
                                   int stride = 4, int pose_stride = 1, double min_opacity = 0.9, double white = 0) {
  require(stride >= 1 && pose_stride >= 1 && min_opacity > 0 && min_opacity <= 1,
          "export: the strides must be at least 1 and the opacity in (0, 1]");
  const auto& cam = run.camera;
  const auto dirs = render::pixel_directions(cam);
  std::vector<float> xyz, lum;
  std::vector<std::array<float, 3>> col;
  for (std::size_t i = 0; i < run.poses.size(); i += static_cast<std::size_t>(pose_stride)) {
    const auto& pose = run.poses[i];
    const Rendering r = render(pose);
    const int C = r.luminance.channels;
    for (int y = stride / 2; y < cam.height(); y += stride)
      for (int x = stride / 2; x < cam.width(); x += stride) {
        const double o = r.opacity.at(x, y);
        if (!(o >= min_opacity)) continue;
        const double z = r.depth.at(x, y) / o;
        const Vec3 p = pose.t + pose.q * (dirs[static_cast<std::size_t>(y) * cam.width() + x].cast<double>() * z);
        if (!p.allFinite()) continue;
        for (int a = 0; a < 3; ++a) xyz.push_back(float(p[a]));
        std::array<float, 3> c{};
        double mean = 0;
        for (int k = 0; k < 3; ++k) {
          c[k] = r.luminance.at(x, y, C == 3 ? k : 0);
          mean += c[k] / 3.0;
        }
        col.push_back(c);
        lum.push_back(float(mean));
      }
  }
  if (!(white > 0)) white = export_white(lum);
  io::PlyVertices v;
  v.names = {"x", "y", "z", "luminance"};
  v.colour = true;
  for (std::size_t i = 0; i < lum.size(); ++i) {
    for (int a = 0; a < 3; ++a) v.floats.push_back(xyz[3 * i + a]);
    v.floats.push_back(lum[i]);
    for (int k = 0; k < 3; ++k)
      v.rgb.push_back(static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(double(col[i][k]) / white, 0.0, 1.0))));
  }
  return v;
}

/// A mesh as PLY: vertices x y z, luminance (the mean of the channels), red green blue (each channel over
/// `white`, export_white's of the luminance when 0; grey in all three), and its triangles (`face`).
inline io::PlyVertices mesh_ply(const TriangleMesh& m, const std::vector<float>& lum, int channels, double white = 0) {
  require(channels == 1 || channels == 3, "export: a mesh's luminance has one or three channels");
  require(lum.size() == m.vertices.size() * static_cast<std::size_t>(channels), "export: a mesh needs a luminance per vertex and channel");
  std::vector<float> mean(m.vertices.size());
  for (std::size_t i = 0; i < mean.size(); ++i) {
    double s = 0;
    for (int c = 0; c < channels; ++c) s += lum[i * channels + c];
    mean[i] = static_cast<float>(s / channels);
  }
  if (!(white > 0)) white = export_white(mean);
  io::PlyVertices v;
  v.names = {"x", "y", "z", "luminance"};
  v.colour = true;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    for (int a = 0; a < 3; ++a) v.floats.push_back(static_cast<float>(m.vertices[i][a]));
    v.floats.push_back(mean[i]);
    for (int c = 0; c < 3; ++c) {
      const double l = lum[i * channels + (channels == 3 ? c : 0)] / white;
      v.rgb.push_back(static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(l, 0.0, 1.0))));
    }
  }
  v.faces = m.triangles;
  return v;
}

/// The recorded poses as a NeRF / nerfstudio transforms.json: the pinhole intrinsics with OpenCV's
/// distortion (camera_model OPENCV: k1 k2 p1 p2, and k3), and per slice boundary its camera-to-world matrix
/// in their convention (the camera looks along −z with +y up: the recording's OpenCV axes with y and z
/// flipped), its time and the name `render` gives its image (boundary_NNNN.png).
inline nlohmann::ordered_json transforms_json(const io::CheckpointRun& desc) {
  const auto& cam = desc.camera;
  const auto& k = cam.distortion();
  nlohmann::ordered_json j = {
      {"camera_model", "OPENCV"}, {"fl_x", cam.fx()}, {"fl_y", cam.fy()}, {"cx", cam.cx()}, {"cy", cam.cy()}, {"w", cam.width()},
      {"h", cam.height()},        {"k1", k[0]},       {"k2", k[1]},       {"p1", k[2]},     {"p2", k[3]},     {"k3", k[4]}};
  nlohmann::ordered_json frames = nlohmann::ordered_json::array();
  for (std::size_t i = 0; i < desc.poses.size(); ++i) {
    Eigen::Matrix4d m = desc.poses[i].matrix();
    m.col(1) *= -1;  // OpenCV's camera axes (y down, z forward) to OpenGL's (y up, z backward)
    m.col(2) *= -1;
    nlohmann::ordered_json rows = nlohmann::ordered_json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    char name[64];
    std::snprintf(name, sizeof name, "boundary_%04zu.png", i);
    frames.push_back({{"file_path", name}, {"time", i < desc.times.size() ? desc.times[i] : 0.0}, {"transform_matrix", rows}});
  }
  j["frames"] = std::move(frames);
  return j;
}

}  // namespace evnerf::evaluation
