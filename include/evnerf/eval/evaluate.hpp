// eval/evaluate.hpp — a trained model against a recording's frames, as `evnerf eval` and `evnerf baselines` do it
// and as a program or the Python module does it without writing files: the frames inside the trained time,
// the truth (frames, or the simulator's linear HDR truth), the baselines, scores under every alignment with
// metrics.json's structure, and a trained model as something that renders at a pose (a Renderable: one
// model.ckpt opened by eval/load.hpp, or the channels.json of train --per-channel). Depends on io/, eval/,
// render/scene.hpp and train/data.hpp, not on the model's parts.
#pragma once
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "baselines.hpp"
#include "export.hpp"
#include "metrics.hpp"
#include "report.hpp"
#include "seeds.hpp"
#include "../geometry/bayer.hpp"
#include "../io/dataset.hpp"
#include "../render/scene.hpp"
#include "../train/data.hpp"

namespace evnerf::evaluation {

namespace fs = std::filesystem;

/// Frames of a recording that lie strictly inside (lo, hi] (where event methods can work).
inline std::vector<std::size_t> frames_inside(const io::Dataset& d, double lo, double hi) {
  std::vector<std::size_t> ids;
  for (std::size_t i = 0; i < d.frames.size(); ++i)
    if (d.frames.t[i] > lo + 1e-9 && d.frames.t[i] <= hi + 1e-9) ids.push_back(i);
  return ids;
}

/// The requested alignment first, then the others of global-log-affine, log-affine, min-max, eventnerf and
/// global-log-offset.
inline std::vector<eval::Alignment> alignments_from(const std::string& flag) {
  const auto first = eval::parse_alignment(flag);
  std::vector<eval::Alignment> all{first};
  for (auto al : {eval::Alignment::GlobalLogAffine, eval::Alignment::LogAffine, eval::Alignment::MinMax, eval::Alignment::EventNerf,
                  eval::Alignment::GlobalLogOffset})
    if (al != first) all.push_back(al);
  return all;
}

/// Whether a recording is scored in colour: its frames are RGB.
inline bool colour_frames(const io::Dataset& d, const std::vector<std::size_t>& ids) {
  return !ids.empty() && io::frame_image(d.frames, ids.front()).channels == 3;
}

/// The baselines' reconstructions at the given frames. In colour, each pixel integrates its own events
/// (its channel of the mosaic), and the mosaic is then demosaiced.
inline std::vector<eval::Method> baseline_methods(const io::Dataset& d, const std::vector<std::size_t>& ids, double contrast,
                                                  bool colour = false) {
  std::vector<double> times;
  for (auto i : ids) times.push_back(d.frames.t[i]);
  std::vector<eval::Method> m{{"direct_integration", eval::direct_integration(d.events, times, contrast)},
                              {"high_pass_filter", eval::high_pass_filter(d.events, times, contrast)}};
  if (colour) {
    const auto p = io::bayer_of(d);
    for (auto& method : m)
      for (auto& img : method.images) img = geometry::demosaic(img, p);
  }
  return m;
}

/// The ground truth of the frames `ids` (grey): the frames, or the simulator's unclipped linear radiance where
/// the recording has it, then with the tone map that scores in the log space (`hdr` set).
struct Truth {
  std::vector<Image> images;
  std::optional<eval::HdrTone> hdr;
  /// What the montage shows of the truth.
  Image shown(std::size_t k) const { return hdr ? hdr->apply(images[k]) : images[k]; }
};
inline Truth load_truth(const io::Dataset& d, const std::vector<std::size_t>& ids, bool colour = false) {
  Truth t;
  const bool linear = d.linear.size() == d.frames.size() && !d.linear.empty();
  auto keep = [&](const Image& img) { return colour && img.channels == 3 ? img : eval::to_grey(img); };
  for (auto i : ids) {
    if (!linear) {
      t.images.push_back(keep(io::frame_image(d.frames, i)));
      continue;
    }
    const auto a = io::load_npy<float>(d.linear[i]);
    const int C = a.shape.size() == 3 ? static_cast<int>(a.shape[2]) : 1;
    if (a.shape.size() < 2 || a.shape.size() > 3 || a.shape[0] != static_cast<std::size_t>(d.camera.height()) ||
        a.shape[1] != static_cast<std::size_t>(d.camera.width()) || (C != 1 && C != 3))
      throw Error(d.linear[i].string(), 0, "linear truth: expected a float32 array of H×W or H×W×3 with the sensor's size");
    Image img(d.camera.width(), d.camera.height(), C);
    img.data = a.data;
    t.images.push_back(keep(img));
  }
  if (linear) t.hdr = eval::HdrTone::of(t.images, d.linear_log_offset);
  return t;
}

/// Scores of several methods under every alignment (the first is the primary, with the aligned images kept)
/// and metrics.json; in colour, the same in grey as secondary scores.
struct Scored {
  eval::AlignedScores primary;
  std::vector<eval::AlignedScores> others;
  std::optional<eval::AlignedScores> grey;  ///< colour truth only: every method and the truth in luminance
  std::vector<Image> scored_truth;          ///< the truth as the primary alignment compared it
  nlohmann::json json;
};
inline Scored score_all(const std::vector<eval::Method>& methods, const Truth& truth, const std::vector<eval::Alignment>& als,
                        const std::vector<std::size_t>& ids) {
  require(!als.empty(), "score_all: no alignment");
  Scored s;
  const eval::HdrTone* hdr = truth.hdr ? &*truth.hdr : nullptr;
  s.primary = eval::score_methods(methods, truth.images, als.front(), true, hdr);
  for (std::size_t k = 1; k < als.size(); ++k) s.others.push_back(eval::score_methods(methods, truth.images, als[k], false, hdr));
  auto& j = s.json;
  j = eval::metrics_json(s.primary, s.others, ids);
  j["truth"] = hdr ? nlohmann::json{{"kind", "linear-hdr"}, {"log_offset", hdr->offset}, {"log_range", {hdr->lo, hdr->hi}}}
                   : nlohmann::json{{"kind", "frames"}};
  auto& scored_truth = s.scored_truth;
  for (const auto& g : truth.images) scored_truth.push_back(eval::scored_truth(g, als.front(), hdr));
  j["error_scales"] = eval::error_scales_json(s.primary, scored_truth);
  const int channels = truth.images.empty() ? 1 : truth.images.front().channels;
  j["channels"] = channels;
  if (channels == 3) {  // colour: the same methods in grey (Rec. 601 luminance), as secondary scores
    Truth grey;
    for (const auto& im : truth.images) grey.images.push_back(eval::to_grey(im));
    if (hdr) grey.hdr = eval::HdrTone::of(grey.images, hdr->offset);
    std::vector<eval::Method> gm = methods;
    for (auto& m : gm)
      for (auto& im : m.images) im = eval::to_grey(im);
    s.grey = eval::score_methods(gm, grey.images, als.front(), false, grey.hdr ? &*grey.hdr : nullptr);
    j["grey"] = eval::metrics_json(*s.grey, {}, ids);
  }
  return s;
}

/// The baselines of a recording at its frames inside the events' span (what `evnerf baselines` scores).
struct BaselineRun {
  std::vector<std::size_t> ids;
  Truth truth;
  std::vector<eval::Method> methods;
  Scored scored;
  bool colour = false;
};
inline BaselineRun run_baselines(const io::Dataset& d, const std::vector<eval::Alignment>& als, double contrast) {
  BaselineRun b;
  b.ids = frames_inside(d, d.events.t_begin(), d.events.t_end());
  require(!b.ids.empty(), d.folder.string() + ": no frames inside the events' time span");
  b.colour = colour_frames(d, b.ids);
  b.truth = load_truth(d, b.ids, b.colour);
  b.methods = baseline_methods(d, b.ids, contrast, b.colour);
  b.scored = score_all(b.methods, b.truth, als, b.ids);
  return b;
}

/// The paper's colour model (train --per-channel): a grey model per colour channel, each trained on its
/// channel's quarter-resolution sites (io::channel_dataset; green optionally on both its sites at the full
/// sensor), in these subfolders of the run.
inline constexpr const char* kChannelDirs[3] = {"r", "g", "b"};

/// channels.json: the full sensor's camera, the mosaic, which green sites trained green's model, and each
/// channel's checkpoint (relative paths).
inline nlohmann::json per_channel_manifest(const geometry::Camera& c, const geometry::BayerPattern& p,
                                           io::GreenSites green = io::GreenSites::First) {
  nlohmann::json j = {{"kind", "evnerf per-channel colour"},
                      {"pattern", p.name()},
                      {"green_sites", io::green_sites_name(green)},
                      {"camera",
                       {{"width", c.width()},
                        {"height", c.height()},
                        {"fx", c.fx()},
                        {"fy", c.fy()},
                        {"cx", c.cx()},
                        {"cy", c.cy()},
                        {"distortion", c.distortion()}}},
                      {"channels", nlohmann::json::array()}};
  for (int k = 0; k < 3; ++k) j["channels"].push_back(std::string(kChannelDirs[k]) + "/model.ckpt");
  return j;
}

/// What render and eval need of a trained model: its name, the training description (boundary times and
/// poses; the camera is the recording's sensor), near and far for the depth maps, and a render at any pose.
struct Renderable {
  std::string name;
  train::Described desc;
  double near = 0, far = 1;
  std::function<Rendering(const geometry::Pose&)> render;
  /// The same model seen by another camera (a single model.ckpt; empty for channels.json).
  std::function<Rendering(const geometry::Camera&, const geometry::Pose&)> render_with;
  /// Whether desc.poses are the model's refined poses (train --refine-poses, --learn-time-offset), and the
  /// clock offset it learned (seconds).
  bool poses_refined = false;
  double time_offset = 0;
  /// A Gaussian scene's Gaussians (evaluation::gaussians_of); empty for a field.
  std::function<GaussianCloud()> gaussians;
  /// A field's density and luminance at any point (what export meshes); empty for Gaussians and channels.json.
  FieldProbe field;
  /// What the model learned of the recording beside its scene, for a model that starts from it (train
  /// --start-from): its learned backdrop's luminance per channel (empty: none learned) and its thresholds
  /// per slice, B⁺ and B⁻ interleaved (empty for channels.json).
  std::vector<double> backdrop, thresholds;
  /// The pose the model saw at time t on its training path: the refined knots' (interpolated between
  /// boundaries, the nearest outside them) when it refined its poses, else the recording's.
  geometry::Pose training_pose(const io::Dataset& d, double t) const {
    if (poses_refined) return geometry::Trajectory(desc.times, desc.poses, "refined poses").pose_at(t, geometry::OutOfRange::Clamp);
    return d.trajectory.covers(t) ? d.trajectory.pose_at(t) : d.trajectory.pose_at(t, geometry::OutOfRange::Clamp);
  }
};

/// How the paper's colour model (train --per-channel) reaches the full sensor from its three channels' models,
/// each trained on its channel's quarter-resolution sites: render each channel's volume at every pixel of the
/// full sensor (`Volume`), or render it at its own sites and interpolate bilinearly (`Sites`,
/// geometry::upsample_sites: the 2-D upsampling of the paper's description).
enum class ChannelUpsampling { Volume, Sites };
inline ChannelUpsampling parse_channel_upsampling(const std::string& s) {
  if (s == "volume") return ChannelUpsampling::Volume;
  if (s == "sites") return ChannelUpsampling::Sites;
  throw Error("channel upsampling '" + s + "': expected volume or sites");
}

/// Opens one model.ckpt: load_model<V...> of a program's variants.
using ModelOpener = Renderable (*)(const fs::path& ckpt);

/// A model.ckpt (opened by `open`), or the channels.json of train --per-channel: each channel's model
/// reaches the full sensor as `up` says (its volume rendered at every pixel, or its sites rendered and
/// upsampled), and the three make one RGB image (depth and opacity: the green model's). Boundary times:
/// those all three channels share.
inline Renderable load_renderable(const fs::path& ckpt, ChannelUpsampling up, ModelOpener open) {
  if (ckpt.extension() != ".json") return open(ckpt);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file(ckpt));
  } catch (const nlohmann::json::exception& e) {
    throw Error(ckpt.string(), 0, std::string("not a channels.json of train --per-channel: ") + e.what());
  }
  geometry::Camera cam;
  geometry::BayerPattern pattern;
  io::GreenSites green = io::GreenSites::First;  // manifests written before the option name none
  std::vector<fs::path> files;
  try {
    if (j.value("kind", "") != "evnerf per-channel colour") throw Error("its \"kind\" is not \"evnerf per-channel colour\"");
    if (!geometry::BayerPattern::parse(j.at("pattern").get<std::string>(), pattern))
      throw Error("unknown Bayer pattern '" + j.at("pattern").get<std::string>() + "'");
    if (j.contains("green_sites")) green = io::parse_green_sites(j.at("green_sites").get<std::string>());
    const auto& c = j.at("camera");
    cam = geometry::Camera(c.at("width").get<int>(), c.at("height").get<int>(), c.at("fx").get<double>(), c.at("fy").get<double>(),
                           c.at("cx").get<double>(), c.at("cy").get<double>(), c.at("distortion").get<std::array<double, 5>>());
    if (!j.at("channels").is_array() || j.at("channels").size() != 3) throw Error("\"channels\" must list three checkpoints (R, G, B)");
    for (const auto& f : j.at("channels")) files.push_back(ckpt.parent_path() / f.get<std::string>());
  } catch (const nlohmann::json::exception& e) {
    throw Error(ckpt.string(), 0, std::string("channels.json: ") + e.what());
  } catch (const Error& e) {
    throw Error(ckpt.string(), 0, std::string("channels.json: ") + e.what());
  }
  std::array<Renderable, 3> ch;
  std::array<geometry::Site, 3> sites;
  double lo = -1e300, hi = 1e300;
  for (int k = 0; k < 3; ++k) {
    ch[k] = open(files[k]);
    sites[k] = geometry::site_of(pattern, k);
    const bool full = k == 1 && green == io::GreenSites::Both;  // green trained at the full sensor
    const auto expect = full ? cam : geometry::site_camera(cam, sites[k]);
    if (ch[k].desc.camera.width() != expect.width() || ch[k].desc.camera.height() != expect.height())
      throw Error(files[k].string(), 0,
                  "its camera is not " + std::string(full ? "the full sensor" : "the " + std::string(1, "RGB"[k]) + " sites") +
                      " of the sensor in " + ckpt.string() + " (green_sites: " + io::green_sites_name(green) + ")");
    if (ch[k].desc.times.empty()) throw Error(files[k].string(), 0, "no slice boundaries");
    lo = std::max(lo, ch[k].desc.times.front());
    hi = std::min(hi, ch[k].desc.times.back());
  }
  Renderable r;
  r.name = ch[1].name + "_per_channel";
  r.near = ch[1].near;
  r.far = ch[1].far;
  r.desc = ch[1].desc;
  r.desc.camera = cam;
  r.poses_refined = ch[1].poses_refined;  // each channel refines its own poses: green's (the most sites) stand for all
  r.time_offset = ch[1].time_offset;
  r.desc.times.clear();
  r.desc.poses.clear();
  for (std::size_t i = 0; i < ch[1].desc.times.size(); ++i)
    if (ch[1].desc.times[i] >= lo - 1e-9 && ch[1].desc.times[i] <= hi + 1e-9) {
      r.desc.times.push_back(ch[1].desc.times[i]);
      r.desc.poses.push_back(ch[1].desc.poses[i]);
    }
  const bool green_full = green == io::GreenSites::Both;
  r.render = [ch, sites, cam, up, green_full](const geometry::Pose& pose) {
    const int W = cam.width(), H = cam.height();
    Rendering out;
    out.luminance = Image(W, H, 3);
    for (int k = 0; k < 3; ++k) {
      // Sites: each volume seen at its channel's (first) sites; green trained on both sites is seen there too.
      Rendering rk = up == ChannelUpsampling::Volume ? ch[k].render_with(cam, pose)
                     : k == 1 && green_full          ? ch[k].render_with(geometry::site_camera(cam, sites[k]), pose)
                                                     : ch[k].render(pose);
      if (up == ChannelUpsampling::Sites) {
        rk.luminance = geometry::upsample_sites(rk.luminance, sites[k], W, H);
        rk.depth = geometry::upsample_sites(rk.depth, sites[k], W, H);
        rk.opacity = geometry::upsample_sites(rk.opacity, sites[k], W, H);
      }
      for (std::size_t i = 0; i < rk.luminance.pixels(); ++i) out.luminance.data[3 * i + k] = rk.luminance.data[i];
      if (k == 1) {
        out.depth = std::move(rk.depth);
        out.opacity = std::move(rk.opacity);
      }
    }
    return out;
  };
  return r;
}

/// A model rendered at a recording's frames inside its trained time and scored with both baselines (what
/// `evnerf eval` does, without writing anything).
struct Evaluation {
  std::vector<std::size_t> ids;    ///< the frames scored
  std::vector<Rendering> renders;  ///< the model's, one per frame in `ids`
  Truth truth;
  std::vector<eval::Method> methods;  ///< the model first (grey unless scored in colour), then the baselines
  Scored scored;
  bool colour = false;
  std::vector<std::size_t> heldout;  ///< positions in `ids` of the never-trained frames (holdout > 0)
  /// The recording's held-out views (Dataset::novel), the model's renders there and its scores beside the
  /// flat frame's (eval::flat_frames: no baseline renders a pose it has no events from); empty without them.
  std::vector<Rendering> novel_renders;
  Truth novel_truth;
  std::optional<Scored> novel;
  double seconds_per_render = 0;
  nlohmann::json json;  ///< metrics.json
};

/// What eval says of the poses: whether the training path's renders use refined poses and the clock offset
/// learned; where the recording keeps its true poses (Dataset::true_trajectory), the error at the slice
/// boundaries of the recording's poses and, when refined, of the refined ones (translation in world units,
/// rotation in degrees; mean and largest).
inline nlohmann::json pose_report(const Renderable& model, const io::Dataset& d) {
  nlohmann::json j = {{"refined", model.poses_refined}};
  if (model.poses_refined) j["time_offset_s"] = model.time_offset;
  if (d.true_trajectory.empty() || d.trajectory.empty() || model.desc.times.empty()) return j;
  std::vector<geometry::Pose> truth, given;
  for (const double t : model.desc.times) {
    truth.push_back(d.true_trajectory.pose_at(t, geometry::OutOfRange::Clamp));
    given.push_back(d.trajectory.pose_at(t, geometry::OutOfRange::Clamp));
  }
  auto as_json = [](const geometry::PoseError& e) {
    return nlohmann::json{{"translation_mean", e.translation_mean},
                          {"translation_max", e.translation_max},
                          {"rotation_mean_deg", e.rotation_mean_deg},
                          {"rotation_max_deg", e.rotation_max_deg}};
  };
  j["error_given"] = as_json(geometry::pose_error(given, truth));
  if (model.poses_refined) j["error_refined"] = as_json(geometry::pose_error(model.desc.poses, truth));
  return j;
}

/// Renders `model` at every frame of `d` inside its trained time (the first boundary has no events before
/// it: skipped) and scores it and both baselines under `als` (the first is the primary). With `holdout` K
/// (as given to train), the frames at every K-th boundary were never trained on; their scores are also
/// reported on their own.
inline Evaluation evaluate(const Renderable& model, const io::Dataset& d, const std::vector<eval::Alignment>& als, int holdout = 0) {
  Evaluation e;
  const auto& desc = model.desc;
  require(desc.camera.width() == d.camera.width() && desc.camera.height() == d.camera.height(),
          "eval: the checkpoint's camera does not match the recording's sensor size");
  e.ids = frames_inside(d, desc.times.front(), desc.times.back());
  require(!e.ids.empty(), "eval: no frames inside the trained time range");
  eval::Method ours{"evnerf_" + model.name, {}};
  std::vector<Image> depths;
  const auto t0 = std::chrono::steady_clock::now();
  for (auto i : e.ids) {
    e.renders.push_back(model.render(model.training_pose(d, d.frames.t[i])));
    ours.images.push_back(e.renders.back().luminance);
    depths.push_back(e.renders.back().depth);
  }
  e.seconds_per_render = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / e.ids.size();
  // In colour where both the frames and the model are: RGB scores per channel, grey ones secondary.
  e.colour = colour_frames(d, e.ids) && ours.images.front().channels == 3;
  if (!e.colour)
    for (auto& im : ours.images) im = eval::to_grey(im);
  e.methods = baseline_methods(d, e.ids, 0.2, e.colour);
  e.methods.insert(e.methods.begin(), ours);
  e.truth = load_truth(d, e.ids, e.colour);
  e.scored = score_all(e.methods, e.truth, als, e.ids);
  e.json = e.scored.json;
  e.json["seconds_per_render"] = e.seconds_per_render;
  e.json["poses"] = pose_report(model, d);
  // Depth against simulated ground truth, where the recording has it (median scale alignment).
  if (d.depth.size() == d.frames.size()) {
    std::vector<std::vector<float>> gtd;
    for (auto i : e.ids) gtd.push_back(io::load_npy<float>(d.depth[i]).data);
    const double absrel = eval::depth_absrel_median_scaled(gtd, depths, model.far);
    if (std::isfinite(absrel)) e.json["depth_absrel_median_scaled"] = absrel;
    // The fine part of each method's error split into thirds of the true depth.
    nlohmann::json fd = nlohmann::json::object();
    for (std::size_t m = 0; m < e.scored.primary.names.size(); ++m) {
      const auto b = eval::fine_error_by_depth(e.scored.primary.aligned[m], e.scored.scored_truth, gtd, model.far);
      if (b.edges.empty()) break;
      if (fd.empty()) fd = {{"edges_m", b.edges}, {"pixel_share", b.pixel_share}, {"methods", nlohmann::json::object()}};
      fd["methods"][e.scored.primary.names[m]] = {{"fine_mse", b.fine_mse}};
    }
    if (!fd.empty()) e.json["error_scales"]["fine_by_depth"] = fd;
  }
  if (!d.novel.poses.empty()) {
    // Held-out views: rendered at poses off the training path, scored under the same alignments, each with its
    // own fit over the views.
    eval::Method mine{ours.name, {}};
    std::vector<std::vector<float>> gtd;
    std::vector<Image> nd;
    std::vector<std::size_t> views;
    for (std::size_t k = 0; k < d.novel.poses.size(); ++k) {
      e.novel_renders.push_back(model.render(d.novel.poses[k]));
      const Image& r = e.novel_renders.back().luminance;
      mine.images.push_back(e.colour ? r : eval::to_grey(r));
      nd.push_back(e.novel_renders.back().depth);
      const Image f = io::read_png(d.novel.images[k]);
      if (f.width != d.camera.width() || f.height != d.camera.height())
        throw Error(d.novel.images[k].string(), 0, "a held-out view of another size than the sensor's");
      e.novel_truth.images.push_back(e.colour && f.channels >= 3 ? f : eval::to_grey(f));
      if (k < d.novel.depth.size()) gtd.push_back(io::load_npy<float>(d.novel.depth[k]).data);
      views.push_back(k);
    }
    e.novel = score_all({mine, eval::flat_frames(mine.images)}, e.novel_truth, als, views);
    nlohmann::json nj = e.novel->json;
    nj["count"] = views.size();
    if (gtd.size() == nd.size()) {
      const double absrel = eval::depth_absrel_median_scaled(gtd, nd, model.far);
      if (std::isfinite(absrel)) nj["depth_absrel_median_scaled"] = absrel;
    }
    e.json["novel_views"] = std::move(nj);
  }
  if (holdout > 0) {
    for (std::size_t k = static_cast<std::size_t>(holdout); k + 1 < desc.times.size(); k += static_cast<std::size_t>(holdout))
      for (std::size_t q = 0; q < e.ids.size(); ++q)
        if (std::abs(d.frames.t[e.ids[q]] - desc.times[k]) < 1e-9) e.heldout.push_back(q);
    require(!e.heldout.empty(), "eval: --holdout " + std::to_string(holdout) + " selects no frame of this recording");
    std::vector<std::size_t> frames;
    for (auto q : e.heldout) frames.push_back(e.ids[q]);
    e.json["heldout"] = {{"every", holdout}, {"frames", frames}, {"methods", eval::methods_json(e.scored.primary, false, e.heldout)}};
  }
  return e;
}

}  // namespace evnerf::evaluation
