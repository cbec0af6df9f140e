// geometry/bayer.hpp — colour filter mosaics of colour event cameras (Color-DAVIS346: RGGB; ESIM) and of
// the frames that recordings carry (ROS's bayer_rggb8, bayer_bggr8, bayer_gbrg8, bayer_grbg8), and the
// bilinear demosaicing of such a frame. Depends on core/ only.
#pragma once
#include <array>
#include <string>
#include <string_view>

#include "../core/error.hpp"
#include "../core/types.hpp"

namespace evnerf::geometry {

/// Channel seen by pixel (x, y) under RGGB: 0 = R at (even x, even y), 2 = B at (odd, odd), 1 = G otherwise.
constexpr int rggb_channel(int x, int y) {
  const int ox = x & 1, oy = y & 1;
  return (ox == 0 && oy == 0) ? 0 : (ox == 1 && oy == 1) ? 2 : 1;
}

/// A 2×2 mosaic, named by its first row then its second, left to right ("rggb": R G / G B).
struct BayerPattern {
  std::array<int, 4> channel{0, 1, 1, 2};  ///< channel of (0,0), (1,0), (0,1), (1,1): 0 R, 1 G, 2 B

  /// "rggb", "bggr", "gbrg" or "grbg" (case-insensitive); false for anything else.
  static bool parse(std::string_view name, BayerPattern& out) {
    if (name.size() != 4) return false;
    BayerPattern p;
    int r = 0, g = 0, b = 0;
    for (int i = 0; i < 4; ++i) {
      const char c = static_cast<char>(name[static_cast<std::size_t>(i)] | 0x20);
      p.channel[static_cast<std::size_t>(i)] = c == 'r' ? (++r, 0) : c == 'g' ? (++g, 1) : c == 'b' ? (++b, 2) : -1;
    }
    const auto& c = p.channel;
    const bool diagonal = (c[0] == 1 && c[3] == 1) || (c[1] == 1 && c[2] == 1);  // the two greens share no row or column
    if (r != 1 || g != 2 || b != 1 || !diagonal) return false;
    out = p;
    return true;
  }
  std::string name() const {
    std::string s;
    for (int c : channel) s += "rgb"[c];
    return s;
  }
  constexpr int at(int x, int y) const { return channel[static_cast<std::size_t>((x & 1) + 2 * (y & 1))]; }
};

/// Bilinear demosaicing: each channel at each pixel is the mean of that channel's samples in the pixel's
/// 3×3 neighbourhood (inside the image), the pixel's own sample where it has the channel.
inline Image demosaic(const Image& mosaic, const BayerPattern& p) {
  require(mosaic.channels == 1, "demosaic: the mosaic must have one channel");
  Image rgb(mosaic.width, mosaic.height, 3);
  for (int y = 0; y < mosaic.height; ++y)
    for (int x = 0; x < mosaic.width; ++x) {
      const int own = p.at(x, y);
      float sum[3] = {0, 0, 0};
      int n[3] = {0, 0, 0};
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= mosaic.width || yy >= mosaic.height) continue;
          const int c = p.at(xx, yy);
          sum[c] += mosaic.at(xx, yy);
          ++n[c];
        }
      for (int c = 0; c < 3; ++c) rgb.at(x, y, c) = c == own ? mosaic.at(x, y) : n[c] ? sum[c] / static_cast<float>(n[c]) : 0.f;
    }
  return rgb;
}

}  // namespace evnerf::geometry
