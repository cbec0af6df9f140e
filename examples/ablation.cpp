// The paper's ablation as compile-time variants: full model vs no joint thresholds vs no noise injection
// (and, for Fast, vs no total-variation term), trained on the same recording with the same seed, scored
// against its frames (MSE / SSIM / PSNR).
// Usage: ablation <recording folder> [iterations] [--paper]
#include <evnerf/evnerf.hpp>

#include <array>
#include <cstdio>
#include <cstring>

using namespace evnerf;

/// Trains one variant and scores it at every frame inside the trained span: {global-log-affine, min–max}
/// alignment (eval's primary and the spec's).
template <class Model>
std::array<eval::Scores, 2> train_and_score(const io::Dataset& d, const train::Config& cfg, const char* name) {
  const auto td = train::prepare(d, cfg);
  train::Trainer<Model> trainer(td, cfg, std::string("ablation_out/") + name, name, train::describe(td, d.folder.string()));
  trainer.run();
  const Model& model = trainer.model();
  std::vector<Image> preds, gts;
  for (std::size_t i = 0; i < d.frames.size(); ++i) {
    const double t = d.frames.t[i];
    if (!(t > td.slices.boundaries.front() && t <= td.slices.boundaries.back())) continue;
    preds.push_back(eval::to_grey(model.render(d.camera, td.pixel_dirs, d.trajectory.pose_at(t)).luminance));
    gts.push_back(eval::to_grey(io::frame_image(d.frames, i)));
  }
  return {eval::mean(eval::score_sequence(preds, gts, eval::Alignment::GlobalLogAffine)),
          eval::mean(eval::score_sequence(preds, gts, eval::Alignment::MinMax))};
}

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: ablation <recording folder> [iterations] [--paper]\n");
    return 2;
  }
  try {
    const auto d = io::load_ijrr(argv[1]);
    train::Config cfg;
    cfg.iterations = argc > 2 && argv[2][0] != '-' ? std::atol(argv[2]) : 600;
    cfg.progress = false;
    const bool paper = argc > 2 && std::strcmp(argv[argc - 1], "--paper") == 0;
    struct Row {
      const char* name;
      std::array<eval::Scores, 2> s;
    };
    std::vector<Row> rows;
    if (paper) {
      rows.push_back({"full", train_and_score<presets::Paper>(d, cfg, "full")});
      rows.push_back({"without joint training", train_and_score<presets::PaperNoJointThresholds>(d, cfg, "no-joint")});
      rows.push_back({"without noise injection", train_and_score<presets::PaperNoNoiseInjection>(d, cfg, "no-noise")});
    } else {
      rows.push_back({"full", train_and_score<presets::Fast>(d, cfg, "full")});
      rows.push_back({"without joint training", train_and_score<presets::FastNoJointThresholds>(d, cfg, "no-joint")});
      rows.push_back({"without noise injection", train_and_score<presets::FastNoNoiseInjection>(d, cfg, "no-noise")});
      rows.push_back({"without total variation", train_and_score<presets::FastNoTv>(d, cfg, "no-tv")});
    }
    std::printf("%-26s %8s %8s %8s | %8s %8s %8s   (%s preset, %ld iterations)\n", "variant", "MSE", "SSIM", "PSNR", "MSE", "SSIM", "PSNR",
                paper ? "Paper" : "Fast", cfg.iterations);
    std::printf("%-26s %26s | %26s\n", "", "global-log-affine alignment", "min-max alignment");
    for (auto& r : rows)
      std::printf("%-26s %8.4f %8.4f %8.2f | %8.4f %8.4f %8.2f\n", r.name, r.s[0].mse, r.s[0].ssim, r.s[0].psnr, r.s[1].mse, r.s[1].ssim,
                  r.s[1].psnr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ablation: %s\n", e.what());
    return 1;
  }
}
