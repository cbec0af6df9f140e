// io/inspect.hpp — a summary of a recording (counts, spans, coverage) and the warnings a user should see
// before training on it: the ON share and the asymmetry it suggests, suspected hot pixels. Depends on
// io/dataset.hpp and events/hot_pixels.hpp.
#pragma once
#include <cstdio>
#include <string>
#include <vector>

#include "../events/hot_pixels.hpp"
#include "../events/intervals.hpp"
#include "dataset.hpp"

namespace evnerf::io {

struct Summary {
  int width = 0, height = 0;
  std::size_t events = 0, on = 0, off = 0, frames = 0, poses = 0;
  double t_begin = 0, t_end = 0, rate = 0;  ///< seconds; events per second
  double frame_begin = 0, frame_end = 0, pose_begin = 0, pose_end = 0;
  std::vector<events::HotPixel> hot;     ///< suspected hot pixels (events::suspected_hot_pixels), busiest first
  events::IntervalStatistics intervals;  ///< each pixel's intervals between consecutive events
  std::vector<std::string> warnings;
};

/// The ON share outside which inspect warns that the thresholds look asymmetric: over a recording whose
/// brightness returns, ON and OFF counts go as 1/C⁺ and 1/C⁻.
inline constexpr double kBalancedOnShare[2] = {0.45, 0.55};

inline Summary summarize(const Dataset& d) {
  Summary s;
  s.width = d.camera.width();
  s.height = d.camera.height();
  s.events = d.events.size();
  s.on = d.events.count_positive();
  s.off = s.events - s.on;
  s.t_begin = d.events.t_begin();
  s.t_end = d.events.t_end();
  s.rate = s.t_end > s.t_begin ? static_cast<double>(s.events) / (s.t_end - s.t_begin) : 0;
  s.hot = events::suspected_hot_pixels(d.events);
  s.intervals = events::interval_statistics(d.events);
  s.frames = d.frames.size();
  if (s.frames) {
    s.frame_begin = d.frames.t.front();
    s.frame_end = d.frames.t.back();
  }
  s.poses = d.trajectory.size();
  if (d.uncalibrated)
    s.warnings.push_back("no calibration: training needs calib.txt beside the file or --calib (the camera here is a pinhole guess)");
  char buf[256];
  if (s.poses) {
    s.pose_begin = d.trajectory.front();
    s.pose_end = d.trajectory.back();
    for (std::size_t i = 0; i < d.frames.size(); ++i) {
      if (d.frames.t[i] < s.pose_begin) {
        std::snprintf(buf, sizeof buf, "frame %zu (t = %.6f s) precedes the first pose (t = %.6f s)", i, d.frames.t[i], s.pose_begin);
        s.warnings.push_back(buf);
      } else if (d.frames.t[i] > s.pose_end) {
        std::snprintf(buf, sizeof buf, "frame %zu (t = %.6f s) follows the last pose (t = %.6f s)", i, d.frames.t[i], s.pose_end);
        s.warnings.push_back(buf);
      }
    }
    if (s.events && s.t_begin < s.pose_begin) {
      std::snprintf(buf, sizeof buf, "events start (t = %.6f s) before the first pose (t = %.6f s)", s.t_begin, s.pose_begin);
      s.warnings.push_back(buf);
    }
    if (s.events && s.t_end > s.pose_end) {
      std::snprintf(buf, sizeof buf, "events end (t = %.6f s) after the last pose (t = %.6f s)", s.t_end, s.pose_end);
      s.warnings.push_back(buf);
    }
  } else {
    s.warnings.push_back("no groundtruth.txt: poses are needed for training");
  }
  if (s.frames) {
    std::size_t inside = 0;
    for (double t : d.frames.t) inside += t >= s.t_begin && t <= s.t_end;
    if (inside < 2) s.warnings.push_back("fewer than two frames lie within the events' time span");
    std::size_t after = 0;
    for (double t : d.frames.t) after += t > s.t_end;
    if (after) {
      std::snprintf(buf, sizeof buf, "%zu frames lie after the last event (no events to reconstruct them from)", after);
      s.warnings.push_back(buf);
    }
  } else {
    s.warnings.push_back("no images.txt: no frames for evaluation, slices will be uniform");
  }
  return s;
}

inline std::string format_summary(const Summary& s) {
  std::string o;
  char buf[512];
  std::snprintf(buf, sizeof buf, "sensor        %d x %d\n", s.width, s.height);
  o += buf;
  std::snprintf(buf, sizeof buf, "events        %zu (ON %zu = %.1f %%, OFF %zu = %.1f %%)\n", s.events, s.on,
                s.events ? 100.0 * s.on / s.events : 0.0, s.off, s.events ? 100.0 * s.off / s.events : 0.0);
  o += buf;
  std::snprintf(buf, sizeof buf, "time span     %.6f .. %.6f s (%.6f s)\n", s.t_begin, s.t_end, s.t_end - s.t_begin);
  o += buf;
  std::snprintf(buf, sizeof buf, "event rate    %.3f Mev/s\n", s.rate / 1e6);
  o += buf;
  if (s.frames) std::snprintf(buf, sizeof buf, "frames        %zu, %.6f .. %.6f s\n", s.frames, s.frame_begin, s.frame_end);
  else std::snprintf(buf, sizeof buf, "frames        none\n");
  o += buf;
  if (s.poses)
    std::snprintf(buf, sizeof buf, "poses         %zu, %.6f .. %.6f s (events covered: %s)\n", s.poses, s.pose_begin, s.pose_end,
                  (s.t_begin >= s.pose_begin && s.t_end <= s.pose_end) ? "all" : "partly");
  else std::snprintf(buf, sizeof buf, "poses         none\n");
  o += buf;
  if (s.intervals.intervals > 0) {
    std::snprintf(buf, sizeof buf,
                  "pixel intervals %zu between one pixel's consecutive events: shortest %.1f us; quantiles 0.1 %% %.1f us, 0.5 %% %.1f us, "
                  "1 %% %.1f us (the refractory period is at most about %.1f us)\n",
                  s.intervals.intervals, 1e6 * s.intervals.minimum, 1e6 * s.intervals.quantile[0], 1e6 * s.intervals.quantile[1],
                  1e6 * s.intervals.quantile[2], 1e6 * s.intervals.refractory_bound());
    o += buf;
  }
  if (!s.hot.empty()) {
    std::snprintf(buf, sizeof buf, "hot pixels    %zu suspected (a count far above its neighbours'):", s.hot.size());
    o += buf;
    for (std::size_t k = 0; k < s.hot.size() && k < 8; ++k) {
      std::snprintf(buf, sizeof buf, " (%d, %d) %zu vs %zu", s.hot[k].x, s.hot[k].y, s.hot[k].events, s.hot[k].neighbours);
      o += buf;
    }
    o += s.hot.size() > 8 ? " ...\n" : "\n";
  }
  if (s.events > 0) {
    const double on = static_cast<double>(s.on) / static_cast<double>(s.events);
    if (s.on == 0 || s.off == 0) {
      o += std::string("warning: the recording has no ") + (s.on == 0 ? "ON" : "OFF") +
           " events: one polarity is missing (filtered out, or a sensor that reports only changes of one sign)\n";
    } else if (on < kBalancedOnShare[0] || on > kBalancedOnShare[1]) {
      std::snprintf(buf, sizeof buf,
                    "warning: ON events are %.1f %% of the recording: its thresholds are likely asymmetric (where the brightness "
                    "returns, C-/C+ is about ON/OFF = %.2f)\n",
                    100 * on, static_cast<double>(s.on) / static_cast<double>(s.off));
      o += buf;
    }
  }
  for (auto& w : s.warnings) o += "warning: " + w + "\n";
  return o;
}

}  // namespace evnerf::io
