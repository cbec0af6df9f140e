// events/hot_pixels.hpp — pixels suspected of firing on their own (hot pixels): a pixel whose event count
// stands far above its neighbours'. The scene's events come from edges, which are lines: a pixel on one
// shares its count with at least two of its eight neighbours, so a pixel is suspected when its count exceeds
// the second largest of its neighbours' by a margin (kRatio times it, plus kMargin). Behind a 2×2 colour
// mosaic the eight neighbours sit behind other filters and may see none of an edge's contrast (a yellow
// object fires red and green sites, not blue ones), so the pixel must also stand out against the eight
// nearest pixels of its own filter, two apart; a hot pixel stands out against both. A hot pixel on busy
// texture adds its own events to the texture's and is still found; an isolated bright dot of texture can be
// flagged too, hence "suspected". Depends on events/event_stream.hpp.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "event_stream.hpp"

namespace evnerf::events {

struct HotPixel {
  int x = 0, y = 0;
  std::size_t events = 0;      ///< the pixel's count
  std::size_t neighbours = 0;  ///< the second largest count among its eight neighbours or among the eight
                               ///< nearest pixels two apart, whichever is larger
};

inline constexpr double kHotRatio = 1.3;
inline constexpr std::size_t kHotMargin = 40;

/// The suspected hot pixels of `e`, busiest first.
inline std::vector<HotPixel> suspected_hot_pixels(const EventStream& e) {
  const int W = e.width, H = e.height;
  std::vector<HotPixel> hot;
  if (W <= 0 || H <= 0) return hot;
  std::vector<std::uint32_t> count(static_cast<std::size_t>(W) * H, 0);
  for (std::size_t i = 0; i < e.size(); ++i) ++count[static_cast<std::size_t>(e.y[i]) * W + e.x[i]];
  // The second largest of the eight counts `pitch` pixels away (outside the sensor: none).
  const auto second_around = [&](int x, int y, int pitch) {
    std::size_t first = 0, second = 0;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int u = x + pitch * dx, v = y + pitch * dy;
        if ((dx == 0 && dy == 0) || u < 0 || v < 0 || u >= W || v >= H) continue;
        const std::size_t n = count[static_cast<std::size_t>(v) * W + u];
        if (n > first) {
          second = first;
          first = n;
        } else if (n > second) {
          second = n;
        }
      }
    return second;
  };
  const auto stands_out = [](std::size_t c, std::size_t second) {
    return static_cast<double>(c) > kHotRatio * static_cast<double>(second) + static_cast<double>(kHotMargin);
  };
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t c = count[static_cast<std::size_t>(y) * W + x];
      if (c < kHotMargin) continue;
      const std::size_t near = second_around(x, y, 1);
      if (!stands_out(c, near)) continue;
      const std::size_t same_filter = second_around(x, y, 2);
      if (stands_out(c, same_filter)) hot.push_back({x, y, c, std::max(near, same_filter)});
    }
  std::sort(hot.begin(), hot.end(), [](const HotPixel& a, const HotPixel& b) { return a.events > b.events; });
  return hot;
}

}  // namespace evnerf::events
