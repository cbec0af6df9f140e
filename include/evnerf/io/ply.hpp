// io/ply.hpp — PLY files of one `vertex` element, binary little-endian: float properties, then optional
// `red green blue` bytes, and optionally a `face` element of triangles (`property list uchar uint
// vertex_indices`). What `evnerf export` writes (a Gaussian scene in the layout of 3D Gaussian splatting, a
// point cloud, a mesh) and what its tests read back. The reader takes exactly this shape (a header of
// `format binary_little_endian 1.0`, one vertex element of float and uchar properties, then at most one face
// element of triangles) and refuses anything else by name. Depends on core/.
#pragma once
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/fileio.hpp"

namespace evnerf::io {

/// The vertices of a PLY file: `floats` per vertex (row-major, names.size() each), and with `colour` three
/// bytes per vertex in `rgb`; and its triangles, if any (`faces`: three vertex indices each).
struct PlyVertices {
  std::vector<std::string> names;  ///< the float properties, in file order
  std::vector<float> floats;
  bool colour = false;  ///< the file has `red green blue` bytes (whether or not it has vertices)
  std::vector<std::uint8_t> rgb;
  std::vector<std::array<std::uint32_t, 3>> faces;  ///< written as a face element when not empty
  std::size_t size() const { return names.empty() ? rgb.size() / 3 : floats.size() / names.size(); }
};

/// `v` as a binary little-endian PLY file, written atomically; `comment` lines go into the header.
inline void write_ply(const std::filesystem::path& path, const PlyVertices& v, const std::vector<std::string>& comments = {}) {
  const std::size_t n = v.size();
  require(v.floats.size() == n * v.names.size() && v.rgb.size() == (v.colour ? 3 * n : 0),
          path.string() + ": the vertices' values do not match their properties");
  for (const auto& f : v.faces)
    require(f[0] < n && f[1] < n && f[2] < n, path.string() + ": a triangle names a vertex the file does not have");
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  for (const auto& c : comments) out += "comment " + c + "\n";
  out += "element vertex " + std::to_string(n) + "\n";
  for (const auto& name : v.names) out += "property float " + name + "\n";
  if (v.colour) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!v.faces.empty()) out += "element face " + std::to_string(v.faces.size()) + "\nproperty list uchar uint vertex_indices\n";
  out += "end_header\n";
  const std::size_t F = v.names.size(), row = 4 * F + (v.colour ? 3 : 0);
  const std::size_t head = out.size();
  out.resize(head + n * row + v.faces.size() * 13);
  for (std::size_t i = 0; i < n; ++i) {
    char* p = out.data() + head + i * row;
    for (std::size_t k = 0; k < F; ++k) {
      const float f = v.floats[i * F + k];
      std::uint32_t u;
      std::memcpy(&u, &f, 4);
      for (int b = 0; b < 4; ++b) p[4 * k + b] = static_cast<char>((u >> (8 * b)) & 0xFF);  // little-endian on any host
    }
    if (v.colour)
      for (int c = 0; c < 3; ++c) p[4 * F + c] = static_cast<char>(v.rgb[3 * i + c]);
  }
  for (std::size_t i = 0; i < v.faces.size(); ++i) {
    char* p = out.data() + head + n * row + 13 * i;
    p[0] = 3;
    for (int k = 0; k < 3; ++k)
      for (int b = 0; b < 4; ++b) p[1 + 4 * k + b] = static_cast<char>((v.faces[i][k] >> (8 * b)) & 0xFF);
  }
  write_file_atomic(path, out);
}

/// Reads a file write_ply writes (or any PLY of that shape); errors name the file and the header line or
/// byte offset.
inline PlyVertices read_ply(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  const std::string f = path.string();
  PlyVertices v;
  std::size_t pos = 0, n = 0, n_faces = 0;
  int line = 0;
  bool rgb = false, have_vertex = false, have_face = false, face_list = false;
  auto next_line = [&]() -> std::string {
    const std::size_t e = bytes.find('\n', pos);
    if (e == std::string::npos) throw Error(f, line + 1, "the header ends before end_header");
    std::string s = bytes.substr(pos, e - pos);
    pos = e + 1;
    ++line;
    return s;
  };
  if (next_line() != "ply") throw Error(f, 1, "not a PLY file (the first line is not 'ply')");
  if (next_line() != "format binary_little_endian 1.0") throw Error(f, 2, "expected 'format binary_little_endian 1.0'");
  for (;;) {
    const std::string s = next_line();
    if (s == "end_header") break;
    std::istringstream in(s);
    std::string word, type, name;
    in >> word;
    if (word == "comment" || word == "obj_info") continue;
    if (word == "element" && have_vertex && !have_face) {
      in >> name >> n_faces;
      if (name != "face" || !in) throw Error(f, line, "expected at most one 'element face N' after the vertices, got '" + s + "'");
      if (n_faces > bytes.size() / 13) throw Error(f, line, "more faces (" + std::to_string(n_faces) + ") than the file has bytes");
      have_face = true;
    } else if (word == "element") {
      in >> name >> n;
      if (name != "vertex" || have_vertex || !in) throw Error(f, line, "expected one 'element vertex N', got '" + s + "'");
      if (n > bytes.size()) throw Error(f, line, "more vertices (" + std::to_string(n) + ") than the file has bytes");
      have_vertex = true;
    } else if (word == "property" && have_face) {
      if (face_list || (s != "property list uchar uint vertex_indices" && s != "property list uchar int vertex_indices"))
        throw Error(f, line, "unsupported face property '" + s + "' (one 'property list uchar uint vertex_indices')");
      face_list = true;
    } else if (word == "property" && have_vertex) {
      in >> type >> name;
      if (type == "float" && !rgb) v.names.push_back(name);
      else if (type == "uchar" && (name == "red" || name == "green" || name == "blue")) rgb = true;
      else throw Error(f, line, "unsupported property '" + s + "' (float properties, then uchar red green blue)");
    } else {
      throw Error(f, line, "unexpected header line '" + s + "'");
    }
  }
  if (!have_vertex) throw Error(f, line, "no vertex element");
  if (have_face && !face_list) throw Error(f, line, "the face element has no vertex_indices list");
  const std::size_t F = v.names.size(), row = 4 * F + (rgb ? 3 : 0);
  if (row == 0 || bytes.size() - pos != n * row + 13 * n_faces)
    throw Error(f, 0,
                "byte " + std::to_string(pos) + ": " + std::to_string(n) + " vertices of " + std::to_string(row) + " bytes" +
                    (n_faces ? " and " + std::to_string(n_faces) + " triangles of 13" : std::string()) + " need " +
                    std::to_string(n * row + 13 * n_faces) + " bytes, the file has " + std::to_string(bytes.size() - pos));
  v.floats.resize(n * F);
  v.colour = rgb;
  if (rgb) v.rgb.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char* p = reinterpret_cast<const unsigned char*>(bytes.data() + pos + i * row);
    for (std::size_t k = 0; k < F; ++k) {
      std::uint32_t u = 0;
      for (int b = 0; b < 4; ++b) u |= static_cast<std::uint32_t>(p[4 * k + b]) << (8 * b);
      std::memcpy(&v.floats[i * F + k], &u, 4);
    }
    if (rgb)
      for (int c = 0; c < 3; ++c) v.rgb[3 * i + c] = p[4 * F + c];
  }
  v.faces.resize(n_faces);
  for (std::size_t i = 0; i < n_faces; ++i) {
    const std::size_t at = pos + n * row + 13 * i;
    const unsigned char* p = reinterpret_cast<const unsigned char*>(bytes.data() + at);
    if (p[0] != 3)
      throw Error(f, 0, "byte " + std::to_string(at) + ": face " + std::to_string(i) + " has " + std::to_string(p[0]) + " vertices, not 3");
    for (int k = 0; k < 3; ++k) {
      std::uint32_t u = 0;
      for (int b = 0; b < 4; ++b) u |= static_cast<std::uint32_t>(p[1 + 4 * k + b]) << (8 * b);
      if (u >= n)
        throw Error(f, 0,
                    "byte " + std::to_string(at) + ": face " + std::to_string(i) + " names vertex " + std::to_string(u) + " of " +
                        std::to_string(n));
      v.faces[i][k] = u;
    }
  }
  return v;
}

}  // namespace evnerf::io
