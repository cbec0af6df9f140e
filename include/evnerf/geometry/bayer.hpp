// geometry/bayer.hpp — colour filter mosaics of colour event cameras (Color-DAVIS346: RGGB; ESIM) and of
// the frames that recordings carry (ROS's bayer_rggb8, bayer_bggr8, bayer_gbrg8, bayer_grbg8), and the
// bilinear demosaicing of such a frame; the paper's colour geometry (each channel a quarter-resolution
// sensor of its own, upsampled back). Depends on core/ and geometry/camera.hpp.
#pragma once
#include <algorithm>
#include <array>
#include <string>
#include <string_view>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "camera.hpp"

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

/// Where a channel's quarter-resolution sensor sits in each 2×2 block: its first site in the order (0,0),
/// (1,0), (0,1), (1,1). Green has two sites per block; the quarter-resolution sensor is the first one's
/// (the paper reconstructs each channel at a quarter of the resolution).
struct Site {
  int ox = 0, oy = 0;
};
inline Site site_of(const BayerPattern& p, int channel) {
  require(channel >= 0 && channel <= 2, "site_of: the channel must be 0 (R), 1 (G) or 2 (B)");
  for (int i = 0; i < 4; ++i)
    if (p.channel[static_cast<std::size_t>(i)] == channel) return {i & 1, i >> 1};
  throw Error("site_of: the pattern '" + p.name() + "' has no channel " + std::to_string(channel));
}

/// The camera of the sites (2x'+ox, 2y'+oy) taken as a sensor of their own: pixel (x', y') of it sees what
/// full-resolution pixel (2x'+ox, 2y'+oy) sees (pixel centres at integer + 0.5 in both), through the same
/// lens (distortion acts on normalised coordinates, unchanged).
inline Camera site_camera(const Camera& full, Site s) {
  const int w = (full.width() - s.ox + 1) / 2, h = (full.height() - s.oy + 1) / 2;
  require(w > 0 && h > 0, "site_camera: the sensor is too small for a 2x2 mosaic");
  // full-resolution u = fx·n + cx, site coordinate u' = (u − ox + 0.5) / 2
  return Camera(w, h, full.fx() / 2, full.fy() / 2, (full.cx() - s.ox + 0.5) / 2, (full.cy() - s.oy + 0.5) / 2, full.distortion());
}

/// A site sensor's image brought back to the full resolution: full pixel (x, y) takes the bilinear
/// interpolation at site coordinate ((x − ox) / 2, (y − oy) / 2), clamped to the site grid (every channel
/// of `sub` alike). At a site the value is the site's own.
inline Image upsample_sites(const Image& sub, Site s, int width, int height) {
  require(sub.width > 0 && sub.height > 0, "upsample_sites: empty image");
  Image out(width, height, sub.channels);
  auto axis = [](int x, int o, int n, int& i0, int& i1, float& f) {
    const double v = std::clamp((x - o) / 2.0, 0.0, double(n - 1));
    i0 = static_cast<int>(v);
    i1 = std::min(i0 + 1, n - 1);
    f = static_cast<float>(v - i0);
  };
  for (int y = 0; y < height; ++y) {
    int y0, y1;
    float fy;
    axis(y, s.oy, sub.height, y0, y1, fy);
    for (int x = 0; x < width; ++x) {
      int x0, x1;
      float fx;
      axis(x, s.ox, sub.width, x0, x1, fx);
      for (int c = 0; c < sub.channels; ++c) {
        const float top = sub.at(x0, y0, c) + fx * (sub.at(x1, y0, c) - sub.at(x0, y0, c));
        const float bottom = sub.at(x0, y1, c) + fx * (sub.at(x1, y1, c) - sub.at(x0, y1, c));
        out.at(x, y, c) = top + fy * (bottom - top);
      }
    }
  }
  return out;
}

}  // namespace evnerf::geometry
