// io/ply.hpp — PLY files of one `vertex` element, binary little-endian: float properties, then optional
// `red green blue` bytes. What `evnerf export` writes (a Gaussian scene in the layout of 3D Gaussian
// splatting, a point cloud) and what its tests read back. The reader takes exactly this shape (a header of
// `format binary_little_endian 1.0`, one vertex element of float and uchar properties) and refuses anything
// else by name. Depends on core/.
#pragma once
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
/// bytes per vertex in `rgb`.
struct PlyVertices {
  std::vector<std::string> names;  ///< the float properties, in file order
  std::vector<float> floats;
  bool colour = false;  ///< the file has `red green blue` bytes (whether or not it has vertices)
  std::vector<std::uint8_t> rgb;
  std::size_t size() const { return names.empty() ? rgb.size() / 3 : floats.size() / names.size(); }
};

/// `v` as a binary little-endian PLY file, written atomically; `comment` lines go into the header.
inline void write_ply(const std::filesystem::path& path, const PlyVertices& v, const std::vector<std::string>& comments = {}) {
  const std::size_t n = v.size();
  require(v.floats.size() == n * v.names.size() && v.rgb.size() == (v.colour ? 3 * n : 0),
          path.string() + ": the vertices' values do not match their properties");
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  for (const auto& c : comments) out += "comment " + c + "\n";
  out += "element vertex " + std::to_string(n) + "\n";
  for (const auto& name : v.names) out += "property float " + name + "\n";
  if (v.colour) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out += "end_header\n";
  const std::size_t F = v.names.size(), row = 4 * F + (v.colour ? 3 : 0);
  const std::size_t head = out.size();
  out.resize(head + n * row);
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
  write_file_atomic(path, out);
}

/// Reads a file write_ply writes (or any PLY of that shape); errors name the file and the header line or
/// byte offset.
inline PlyVertices read_ply(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  const std::string f = path.string();
  PlyVertices v;
  std::size_t pos = 0, n = 0;
  int line = 0;
  bool rgb = false, have_vertex = false;
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
    if (word == "element") {
      in >> name >> n;
      if (name != "vertex" || have_vertex || !in) throw Error(f, line, "expected one 'element vertex N', got '" + s + "'");
      if (n > bytes.size()) throw Error(f, line, "more vertices (" + std::to_string(n) + ") than the file has bytes");
      have_vertex = true;
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
  const std::size_t F = v.names.size(), row = 4 * F + (rgb ? 3 : 0);
  if (row == 0 || bytes.size() - pos != n * row)
    throw Error(f, 0,
                "byte " + std::to_string(pos) + ": " + std::to_string(n) + " vertices of " + std::to_string(row) + " bytes need " +
                    std::to_string(n * row) + " bytes, the file has " + std::to_string(bytes.size() - pos));
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
  return v;
}

}  // namespace evnerf::io
