// train/data.hpp — a recording made into what training reads: train::prepare cuts an io::Dataset into
// TrainingData (events/training_data.hpp) under the settings; the scene box a Config gives; and what a
// checkpoint records of the run (train::describe). Depends on core/, events/, geometry/, io/,
// render/scene.hpp (the scene box) and train/settings.hpp, not on the model's parts.
#pragma once
#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../events/hot_pixels.hpp"
#include "../events/intervals.hpp"
#include "../events/pixels.hpp"
#include "../events/slicing.hpp"
#include "../events/training_data.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../io/checkpoint.hpp"
#include "../io/recording.hpp"
#include "../render/scene.hpp"
#include "settings.hpp"

namespace evnerf::train {

/// Slice boundaries (frame times inside the events' span whose poses exist, else uniform at ~24 Hz),
/// slice counts, boundary poses and the camera's pixel directions.
inline TrainingData prepare(const io::Dataset& d, const Config& cfg, std::vector<std::size_t>* frame_of_boundary = nullptr) {
  require(!d.trajectory.empty(), d.folder.string() + ": no poses (groundtruth.txt) — poses are required for training");
  const auto policy = cfg.clamp_poses ? geometry::OutOfRange::Clamp : geometry::OutOfRange::Error;
  std::vector<double> b;
  std::vector<std::size_t> frame_ids;
  const double t0 = d.events.t_begin(), t1 = d.events.t_end();
  for (std::size_t i = 0; i < d.frames.size(); ++i) {
    const double t = d.frames.t[i];
    if (t < t0 - 1e-9 && !cfg.clamp_poses) continue;
    if (t > t1 + 1e-9) continue;
    if (!cfg.clamp_poses && !d.trajectory.covers(t)) continue;
    b.push_back(t);
    frame_ids.push_back(i);
  }
  if (b.size() < 2) {
    const double lo = std::max(t0, d.trajectory.front()), hi = std::min(t1, d.trajectory.back());
    if (!(hi > lo))
      throw Error(d.folder.string() + ": the poses (" + short_number(d.trajectory.front()) + " .. " + short_number(d.trajectory.back()) +
                  " s) do not cover the events (" + short_number(t0) + " .. " + short_number(t1) + " s)");
    b = events::uniform_boundaries(lo, hi, std::max<std::size_t>(2, static_cast<std::size_t>((hi - lo) * 24)));
    frame_ids.assign(b.size(), static_cast<std::size_t>(-1));
  }
  require(cfg.subslices >= 1 && cfg.subslices <= 64, "train: subslices must be between 1 and 64");
  require(cfg.subslices == 1 || cfg.holdout == 0, "train: subslices and holdout cannot be combined (holdout counts frame boundaries)");
  if (cfg.subslices > 1) {
    std::vector<double> fine;
    std::vector<std::size_t> ids;
    for (std::size_t i = 0; i + 1 < b.size(); ++i)
      for (int k = 0; k < cfg.subslices; ++k) {
        fine.push_back(b[i] + (b[i + 1] - b[i]) * k / cfg.subslices);
        ids.push_back(k == 0 ? frame_ids[i] : static_cast<std::size_t>(-1));
      }
    fine.push_back(b.back());
    ids.push_back(frame_ids.back());
    b = std::move(fine);
    frame_ids = std::move(ids);
  }
  TrainingData td;
  td.camera = d.camera;
  td.slices = events::slice_events(d.events, b, !cfg.refractory || *cfg.refractory > 0);  // a period reads the intervals
  for (double t : b) td.boundary_poses.push_back(d.trajectory.pose_at(t, policy));
  td.trajectory = d.trajectory;
  td.pixel_dirs = render::pixel_directions(d.camera);
  td.slice_enabled.assign(td.slices.size(), true);
  td.prefix = events::CountPrefix(td.slices);
  td.slices_per_interval = cfg.subslices;
  td.bayer = io::bayer_of(d);
  require(d.sites.empty() || d.sites.size() == static_cast<std::size_t>(d.camera.width()) * d.camera.height(),
          d.folder.string() + ": the pixel sites do not match the camera");
  td.sites = events::PixelSites(d.sites);
  if (!cfg.keep_hot_pixels) {
    td.masked = events::suspected_hot_pixels(d.events);
    if (!td.masked.empty()) {
      const int w = d.camera.width();
      std::vector<std::uint8_t> mask =
          d.sites.empty() ? std::vector<std::uint8_t>(static_cast<std::size_t>(w) * d.camera.height(), 1) : d.sites;
      for (const auto& h : td.masked) mask[static_cast<std::size_t>(h.y) * w + h.x] = 0;
      td.sites = events::PixelSites(std::move(mask));
    }
  }
  if (!cfg.refractory) {  // a learned period starts from the data's bound and stays below it
    std::vector<std::uint8_t> hot;
    if (!td.masked.empty()) {
      hot.assign(static_cast<std::size_t>(d.camera.width()) * d.camera.height(), 0);
      for (const auto& h : td.masked) hot[static_cast<std::size_t>(h.y) * d.camera.width() + h.x] = 1;
    }
    td.refractory_bound = events::interval_statistics(d.events, hot).refractory_bound();
  }
  if (cfg.holdout > 0)
    for (std::size_t k = cfg.holdout; k + 1 < b.size(); k += cfg.holdout) {
      td.slice_enabled[k - 1] = false;  // both slices touching boundary k
      td.slice_enabled[k] = false;
    }
  if (frame_of_boundary) *frame_of_boundary = frame_ids;
  return td;
}

/// Scene box from the boundary poses and near/far, with the Config's density unit and backdrop.
inline render::SceneBox scene_box(const TrainingData& td, const Config& cfg) {
  std::vector<Vec3> c;
  for (auto& p : td.boundary_poses) c.push_back(p.t);
  auto box = render::SceneBox::from_cameras(c, cfg.near, cfg.far);
  if (cfg.density_per_box) box.density_length = box.scale;
  box.background = cfg.background;
  box.background_learned = cfg.learn_background && !cfg.background;  // a known backdrop needs no learning
  return box;
}

/// What a checkpoint records of a run on `td` (io::CheckpointRun): the recording's path, the camera and the
/// slice boundaries' times and poses, so that `render` and `eval` need no recording. train::run sets the
/// shards per step.
inline io::CheckpointRun describe(const TrainingData& td, const std::string& recording) {
  io::CheckpointRun r;
  r.recording = recording;
  r.camera = td.camera;
  r.times.assign(td.slices.boundaries.begin(), td.slices.boundaries.end());
  r.poses = td.boundary_poses;
  return r;
}
/// What render and eval read of a checkpoint's run.
using Described = io::CheckpointRun;

}  // namespace evnerf::train
