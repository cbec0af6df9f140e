// events/training_data.hpp — TrainingData: what a model's step reads of a recording (the slices with their
// counts and intervals, the boundary poses, the camera and its pixel directions, held-out slices, the mosaic
// and the pixels that carry events). train::prepare makes it from a recording and the settings; the model
// reads it and knows nothing of either. Depends on core/, events/ and geometry/.
#pragma once
#include <vector>

#include "../core/types.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../geometry/trajectory.hpp"
#include "hot_pixels.hpp"
#include "pixels.hpp"
#include "slicing.hpp"

namespace evnerf {

/// Everything a training step reads: slices with their boundary poses and the camera.
struct TrainingData {
  geometry::Camera camera;
  events::SliceSet slices;
  std::vector<geometry::Pose> boundary_poses;  ///< pose at each slice boundary
  geometry::Trajectory trajectory;             ///< the recording's poses (a learned clock offset reads them
                                               ///< between the boundaries); may be empty otherwise
  std::vector<Vec3f> pixel_dirs;               ///< render::pixel_directions(camera)
  std::vector<bool> slice_enabled;             ///< held-out slices are false (novel-view evaluation)
  events::CountPrefix prefix;                  ///< per-pixel running counts (objectives whose pixels look at the
                                               ///< window's counts need it; train::prepare builds it)
  geometry::BayerPattern bayer;                ///< colour models: the channel of each pixel's events (the
                                               ///< recording's mosaic; RGGB where it names none)
  events::PixelSites sites;                    ///< the pixels that carry events (one colour channel's sites of
                                               ///< a mosaic at the full sensor); all() = every pixel. Steps draw
                                               ///< their pixels and noise among them only.
  std::vector<events::HotPixel> masked;        ///< suspected hot pixels left out of `sites` (unless Config::keep_hot_pixels)
  /// The refractory period's upper bound read off the recording (events::IntervalStatistics::refractory_bound,
  /// suspected hot pixels left out): where a learned period starts, and the most it may reach. Negative where
  /// train::prepare did not read it (the period given).
  double refractory_bound = -1;
  /// A teacher's rendered luminance at every boundary pose (train --start-from: the field a scene of
  /// Gaussians starts from), pose-major, then pixel (y · width + x) and channel; empty: none. loss::Teacher
  /// pulls the rendered log-luminance toward it where the events are silent.
  std::vector<float> teacher;
  int slices_per_interval = 1;  ///< slices per interval of the recording's own cut (train's
                                ///< --subslices): a window objective's W counts such intervals,
                                ///< so its windows span 1..W·this slices, the same time at any cut
};

}  // namespace evnerf
