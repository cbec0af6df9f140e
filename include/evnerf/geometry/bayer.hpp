// geometry/bayer.hpp — the RGGB colour filter layout of colour event cameras (Color-DAVIS346, ESIM).
// Depends on nothing.
#pragma once

namespace evnerf::geometry {

/// Channel seen by pixel (x, y) under RGGB: 0 = R at (even x, even y), 2 = B at (odd, odd), 1 = G otherwise.
constexpr int rggb_channel(int x, int y) {
  const int ox = x & 1, oy = y & 1;
  return (ox == 0 && oy == 0) ? 0 : (ox == 1 && oy == 1) ? 2 : 1;
}

}  // namespace evnerf::geometry
