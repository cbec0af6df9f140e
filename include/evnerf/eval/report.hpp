// eval/report.hpp — scoring several reconstructions of one sequence against its frames under several
// alignments, and the `metrics.json` they make (through nlohmann::json). The command line's `eval` and
// `baselines` and any user's own evaluation share it. Depends on core/ and eval/metrics.hpp.
#pragma once
#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "metrics.hpp"

namespace evnerf::eval {

/// One reconstruction of the sequence: a name and one image per evaluated frame.
struct Method {
  std::string name;
  std::vector<Image> images;
};

/// The reference scored beside a model where no baseline can be (views off the training path): "flat", one
/// frame of one brightness per channel for each of `like`, which each alignment brings to its best level
/// over the frames. It is what a model that renders nothing of the scene scores there. A view that is mostly
/// plain background gives it a high score, so a model's score says most as its margin above this one.
inline Method flat_frames(const std::vector<Image>& like) {
  Method m{"flat", {}};
  for (const auto& im : like) m.images.emplace_back(im.width, im.height, im.channels, 0.5f);
  return m;
}

/// Every method's per-frame scores under one alignment.
struct AlignedScores {
  Alignment alignment = Alignment::GlobalLogAffine;
  std::vector<std::string> names;
  std::vector<std::vector<Scores>> per_frame;  ///< [method][frame]
  std::vector<std::vector<Image>> aligned;     ///< [method][frame], when asked for
};

/// Scores each method against `gts` under `how` (each method gets its own global fit).
inline AlignedScores score_methods(const std::vector<Method>& methods, const std::vector<Image>& gts, Alignment how,
                                   bool keep_aligned = false, const HdrTone* hdr = nullptr) {
  AlignedScores r;
  r.alignment = how;
  for (const auto& m : methods) {
    require(m.images.size() == gts.size(), "score_methods: '" + m.name + "' has " + std::to_string(m.images.size()) + " images for " +
                                               std::to_string(gts.size()) + " frames");
    r.names.push_back(m.name);
    std::vector<Image> al;
    r.per_frame.push_back(score_sequence(m.images, gts, how, keep_aligned ? &al : nullptr, hdr));
    r.aligned.push_back(std::move(al));
  }
  return r;
}

/// A finite number, or null (JSON has no NaN or infinity).
inline nlohmann::json json_number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
inline nlohmann::json to_json(const Scores& s) {
  return {{"mse", json_number(s.mse)}, {"psnr", json_number(s.psnr)}, {"ssim", json_number(s.ssim)}};
}
/// {"<name>": {"mse", "psnr", "ssim"[, "per_frame": [...]]}, ...} of a subset of frames (all when empty).
inline nlohmann::json methods_json(const AlignedScores& a, bool per_frame, const std::vector<std::size_t>& subset = {}) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t m = 0; m < a.names.size(); ++m) {
    std::vector<Scores> s;
    if (subset.empty()) {
      s = a.per_frame[m];
    } else {
      for (auto q : subset) s.push_back(a.per_frame[m].at(q));
    }
    nlohmann::json e = to_json(mean(s));
    if (per_frame) {
      e["per_frame"] = nlohmann::json::array();
      for (const auto& x : s) e["per_frame"].push_back(to_json(x));
    }
    j[a.names[m]] = std::move(e);
  }
  return j;
}

/// `metrics.json`: {"alignment", "frames", "methods" (per frame too), "secondary": {"alignment",
/// "methods"} (the first of `others`), "other_alignments": [the rest]}.
inline nlohmann::json metrics_json(const AlignedScores& primary, const std::vector<AlignedScores>& others,
                                   const std::vector<std::size_t>& frames) {
  nlohmann::json j;
  j["alignment"] = to_string(primary.alignment);
  j["frames"] = frames;
  j["methods"] = methods_json(primary, true);
  for (std::size_t k = 0; k < others.size(); ++k) {
    nlohmann::json o = {{"alignment", to_string(others[k].alignment)}, {"methods", methods_json(others[k], false)}};
    if (k == 0) j["secondary"] = std::move(o);
    else j["other_alignments"].push_back(std::move(o));
  }
  return j;
}

/// The primary alignment's error split by scale (ErrorScales), per method, averaged over the frames (PSNR in
/// dB, as the scores): {"sigma_px", "methods": {"<name>": {"coarse_mse", "coarse_psnr", "fine_mse",
/// "fine_psnr", "row_mse", "row_psnr", "column_mse", "column_psnr", and offset_oracle's "oracle_rows_psnr",
/// "oracle_columns_psnr", "oracle_both_psnr"}}}. `a` must hold the aligned predictions (score_methods with keep_aligned) and `truths` the
/// truth as it was scored (tone-mapped for HDR truth, normalised under min-max).
inline nlohmann::json error_scales_json(const AlignedScores& a, const std::vector<Image>& truths, double sigma = kErrorScaleSigma) {
  nlohmann::json j = {{"sigma_px", sigma}, {"methods", nlohmann::json::object()}};
  for (std::size_t m = 0; m < a.names.size(); ++m) {
    require(a.aligned[m].size() == truths.size(), "error_scales_json: the aligned predictions were not kept");
    double cm = 0, fm = 0, cp = 0, fp = 0, rm = 0, rp = 0, km = 0, kp = 0;
    const double n = static_cast<double>(truths.size());
    for (std::size_t f = 0; f < truths.size(); ++f) {
      const auto e = error_scales(a.aligned[m][f], truths[f], sigma);
      cm += e.coarse_mse / n;
      fm += e.fine_mse / n;
      cp += e.coarse_psnr() / n;
      fp += e.fine_psnr() / n;
      rm += e.row_mse / n;
      rp += e.row_psnr() / n;
      km += e.column_mse / n;
      kp += e.column_psnr() / n;
    }
    const auto o = offset_oracle(a.aligned[m], truths);
    j["methods"][a.names[m]] = {{"coarse_mse", json_number(cm)},
                                {"coarse_psnr", json_number(cp)},
                                {"fine_mse", json_number(fm)},
                                {"fine_psnr", json_number(fp)},
                                {"row_mse", json_number(rm)},
                                {"row_psnr", json_number(rp)},
                                {"column_mse", json_number(km)},
                                {"column_psnr", json_number(kp)},
                                {"oracle_rows_psnr", json_number(o.rows_psnr)},
                                {"oracle_columns_psnr", json_number(o.columns_psnr)},
                                {"oracle_both_psnr", json_number(o.both_psnr)}};
  }
  return j;
}

/// Mean absolute relative depth error after one median scale per frame (rendered depth times the median of
/// ground truth / rendered), over pixels with finite ground truth nearer than `far` and positive renders.
/// Returns NaN when no pixel qualifies.
inline double depth_absrel_median_scaled(const std::vector<std::vector<float>>& gt, const std::vector<Image>& pred, double far) {
  require(gt.size() == pred.size(), "depth_absrel: need as many ground-truth depth maps as renders");
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < gt.size(); ++k) {
    require(gt[k].size() == pred[k].data.size(), "depth_absrel: depth map sizes differ");
    std::vector<double> ratio;
    for (std::size_t p = 0; p < gt[k].size(); ++p)
      if (std::isfinite(gt[k][p]) && gt[k][p] < far && pred[k].data[p] > 0) ratio.push_back(gt[k][p] / pred[k].data[p]);
    if (ratio.empty()) continue;
    std::nth_element(ratio.begin(), ratio.begin() + static_cast<std::ptrdiff_t>(ratio.size() / 2), ratio.end());
    const double sc = ratio[ratio.size() / 2];
    for (std::size_t p = 0; p < gt[k].size(); ++p)
      if (std::isfinite(gt[k][p]) && gt[k][p] < far) {
        sum += std::abs(pred[k].data[p] * sc - gt[k][p]) / gt[k][p];
        ++n;
      }
  }
  return n ? sum / static_cast<double>(n) : std::nan("");
}

}  // namespace evnerf::eval
