// view/session.hpp — what `evnerf view` serves, without the HTTP: a trained scene (evaluation::Renderable)
// answering the page's two questions. `info`: the sensor, the recorded and the novel path, where the scene
// lies in front of the first camera, and how frames are toned. `frame`: the scene seen by any camera pose
// (view/request.hpp reads it from the query) at the sensor's resolution divided by a factor (the page asks
// for a coarser frame while the camera moves), intensity or depth, as a JPEG. view/server.hpp puts it on a
// loopback port. Depends on eval/, io/ and render/.
#pragma once
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "../core/error.hpp"
#include "../eval/alignment.hpp"
#include "../eval/evaluate.hpp"
#include "../io/image_io.hpp"
#include "../render/novel.hpp"
#include "request.hpp"

namespace evnerf::view {

/// A trained scene the viewer shows. The tone is fixed when the session opens, so that a frame's grey
/// means the same luminance wherever the camera goes: the luminance clamped to [0, 1] as `render`'s PNGs
/// are, or, where the recorded views pass 1, their log over its 0.1–99.9 % range (eval::HdrTone).
class Session {
 public:
  /// The novel path's poses in `info` (render::novel_pose between the first and the last recorded pose).
  static constexpr int kNovelViews = 60;

  explicit Session(evaluation::Renderable model) : m_(std::move(model)) {
    if (!m_.render_with)
      throw Error("view: this checkpoint renders only at its own sensor (channels.json of train --per-channel); view takes a model.ckpt");
    const auto& d = m_.desc;
    require(!d.poses.empty(), "view: the checkpoint records no pose");
    // What the first camera sees at a quarter of its resolution: the distance the camera orbits around
    // (the median depth where the view is opaque), and with the other sampled views, the tone.
    std::vector<Image> lum;
    const std::size_t n = d.poses.size(), samples = std::min<std::size_t>(n, 8);
    const geometry::Camera small = camera(4);
    for (std::size_t k = 0; k < samples; ++k) {
      const auto r = m_.render_with(small, d.poses[samples > 1 ? k * (n - 1) / (samples - 1) : 0]);
      lum.push_back(r.luminance);
      if (k == 0) {
        std::vector<float> z;  // the rendered depth is the expected depth times the opacity
        for (std::size_t i = 0; i < r.depth.data.size(); ++i)
          if (r.opacity.data[i] >= 0.5f && std::isfinite(r.depth.data[i])) z.push_back(r.depth.data[i] / r.opacity.data[i]);
        focus_ = 0.5 * (m_.near + m_.far);
        if (!z.empty()) {
          std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 2), z.end());
          focus_ = z[z.size() / 2];
        }
      }
    }
    float top = 0;
    for (const auto& l : lum)
      for (const float x : l.data) top = std::max(top, x);
    if (top > 1.0f) {
      try {
        tone_ = eval::HdrTone::of(lum, eval::kLogEps);
      } catch (const Error&) {  // every sampled view one brightness: clamp
      }
    }
  }

  const evaluation::Renderable& model() const { return m_; }
  /// The fixed tone: none where the luminance is clamped to [0, 1].
  const std::optional<eval::HdrTone>& tone() const { return tone_; }
  /// The depth range the depth frames' colours span (as `render`'s depth PNGs).
  std::pair<float, float> depth_range() const { return {static_cast<float>(m_.near), static_cast<float>(m_.far * 0.6)}; }

  /// The sensor at its resolution divided by `scale` (at least one pixel each way).
  geometry::Camera camera(int scale) const {
    const auto& c = m_.desc.camera;
    return scale == 1 ? c : c.resized(std::max(1, c.width() / scale), std::max(1, c.height() / scale));
  }

  /// What the page needs before its first frame (GET /info).
  nlohmann::json info() const {
    const auto& d = m_.desc;
    nlohmann::json j;
    j["name"] = m_.name;
    j["kind"] = m_.gaussians ? "gaussians" : "field";
    j["width"] = d.camera.width();
    j["height"] = d.camera.height();
    j["near"] = m_.near;
    j["far"] = m_.far;
    j["focus"] = focus_;
    // Up on the page is up in the first camera's view (its −y axis in the world).
    const Vec3 up = -(d.poses.front().rotation().col(1));
    j["up"] = {up.x(), up.y(), up.z()};
    // A field renders a full frame in a few hundred milliseconds on two cores: the page asks for a quarter
    // of its pixels while the camera moves; Gaussians render every frame at full resolution.
    j["moving_scale"] = m_.gaussians ? 1 : 2;
    j["max_scale"] = kMaxScale;
    j["recorded"] = nlohmann::json::array();
    for (const auto& p : d.poses) j["recorded"].push_back(pose_numbers(p));
    j["novel"] = nlohmann::json::array();
    for (int k = 0; k < kNovelViews; ++k)
      j["novel"].push_back(pose_numbers(render::novel_pose(d.poses.front(), d.poses.back(), k, kNovelViews)));
    if (tone_) j["tone"] = {{"kind", "log"}, {"offset", tone_->offset}, {"lo", tone_->lo}, {"hi", tone_->hi}};
    else j["tone"] = {{"kind", "clamp"}};
    const auto [lo, hi] = depth_range();
    j["depth_range"] = {lo, hi};
    return j;
  }

  /// The toned image of a request: intensity (1 or 3 channels, in [0, 1]) or depth in colour.
  Image image(const FrameRequest& r) const {
    render::Rendering out;
    {
      const std::lock_guard<std::mutex> lock(render_);  // one render at a time: the model's buffers are its own
      out = m_.render_with(camera(r.scale), r.pose);
    }
    if (r.depth) {
      const auto [lo, hi] = depth_range();
      return io::colorize(out.depth, lo, hi);
    }
    return tone_ ? tone_->apply(out.luminance) : out.luminance;
  }

  /// One frame as the page receives it: JPEG bytes, the size, and the server's time for it (render and encode).
  struct Frame {
    std::string jpeg;
    int width = 0, height = 0;
    double ms = 0;
  };
  Frame frame(const FrameRequest& r) const {
    const auto t0 = std::chrono::steady_clock::now();
    const Image img = image(r);
    Frame f{io::encode_jpeg(img, 90), img.width, img.height, 0};
    f.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return f;
  }

 private:
  evaluation::Renderable m_;
  std::optional<eval::HdrTone> tone_;
  double focus_ = 1;
  mutable std::mutex render_;
};

}  // namespace evnerf::view
