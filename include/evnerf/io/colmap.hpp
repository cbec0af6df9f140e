// io/colmap.hpp — COLMAP's text model (cameras.txt, images.txt): cameras and world-to-camera poses,
// converted to evnerf's camera-to-world. Depends on core/, geometry/ and io/text.hpp only.
#pragma once
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "../core/fileio.hpp"
#include "../geometry/camera.hpp"
#include "text.hpp"

namespace evnerf::io {

struct ColmapImage {
  int id = 0, camera_id = 0;
  std::string name;
  geometry::Pose c2w;  ///< camera-to-world (COLMAP stores world-to-camera; converted here)
};
struct ColmapModel {
  std::map<int, geometry::Camera> cameras;
  std::vector<ColmapImage> images;
};

/// Parses cameras.txt. Supported models: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV.
inline std::map<int, geometry::Camera> parse_colmap_cameras(std::string_view text, const std::string& file) {
  std::map<int, geometry::Camera> cams;
  LineScanner s(text, file);
  while (s.next_line()) {
    const int id = static_cast<int>(s.integer("CAMERA_ID"));
    const std::string model(s.word("MODEL"));
    const int w = static_cast<int>(s.integer("WIDTH")), h = static_cast<int>(s.integer("HEIGHT"));
    if (w <= 0 || h <= 0) s.fail("image size must be positive");
    std::vector<double> p;
    while (!s.at_end_of_line()) p.push_back(s.real("PARAMS"));
    auto need = [&](std::size_t n) {
      if (p.size() != n) s.fail(model + " needs " + std::to_string(n) + " parameters, found " + std::to_string(p.size()));
    };
    geometry::Camera cam;
    if (model == "SIMPLE_PINHOLE") {
      need(3);
      cam = geometry::Camera(w, h, p[0], p[0], p[1], p[2]);
    } else if (model == "PINHOLE") {
      need(4);
      cam = geometry::Camera(w, h, p[0], p[1], p[2], p[3]);
    } else if (model == "SIMPLE_RADIAL") {
      need(4);
      cam = geometry::Camera(w, h, p[0], p[0], p[1], p[2], {p[3], 0, 0, 0, 0});
    } else if (model == "RADIAL") {
      need(5);
      cam = geometry::Camera(w, h, p[0], p[0], p[1], p[2], {p[3], p[4], 0, 0, 0});
    } else if (model == "OPENCV") {
      need(8);
      cam = geometry::Camera(w, h, p[0], p[1], p[2], p[3], {p[4], p[5], p[6], p[7], 0});
    } else {
      s.fail("unsupported camera model '" + model + "'");
    }
    cams[id] = cam;
  }
  return cams;
}

/// Parses images.txt: pairs of lines, the first `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`
/// (world-to-camera), the second the 2-D points (ignored).
inline std::vector<ColmapImage> parse_colmap_images(std::string_view text, const std::string& file) {
  std::vector<ColmapImage> out;
  // The points line may be empty, so walk raw lines rather than skipping blanks.
  std::size_t pos = 0, line_no = 0;
  bool header_line = true;
  while (pos <= text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.front() == '#') continue;
    if (header_line) {
      if (line.find_first_not_of(" \t\r") == std::string_view::npos) {
        if (pos > text.size()) break;
        continue;
      }
      LineScanner s(line, file);
      s.next_line();
      ColmapImage im;
      try {
        im.id = static_cast<int>(s.integer("IMAGE_ID"));
        const double qw = s.real("QW"), qx = s.real("QX"), qy = s.real("QY"), qz = s.real("QZ");
        const double tx = s.real("TX"), ty = s.real("TY"), tz = s.real("TZ");
        im.camera_id = static_cast<int>(s.integer("CAMERA_ID"));
        im.name = std::string(s.rest("NAME"));
        const double norm = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
        if (!(norm > 0.5 && norm < 1.5)) s.fail("quaternion is far from unit length (norm " + short_number(norm) + ")");
        geometry::Pose w2c;
        w2c.q = Quat(qw / norm, qx / norm, qy / norm, qz / norm);
        w2c.t = Vec3(tx, ty, tz);
        im.c2w = w2c.inverse();
      } catch (const Error& e) {
        throw Error(file, line_no, e.message());
      }
      out.push_back(std::move(im));
      header_line = false;
    } else {
      header_line = true;  // 2-D points line
    }
    if (pos > text.size()) break;
  }
  return out;
}

inline ColmapModel read_colmap_text(const std::filesystem::path& folder) {
  ColmapModel m;
  m.cameras = parse_colmap_cameras(read_file(folder / "cameras.txt"), (folder / "cameras.txt").string());
  m.images = parse_colmap_images(read_file(folder / "images.txt"), (folder / "images.txt").string());
  for (auto& im : m.images)
    if (!m.cameras.count(im.camera_id))
      throw Error((folder / "images.txt").string(), 0, "image '" + im.name + "' refers to unknown camera " + std::to_string(im.camera_id));
  return m;
}

}  // namespace evnerf::io
