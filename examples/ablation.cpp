// The paper's ablation as compile-time variants: full model vs no joint thresholds vs no noise injection,
// trained on the same recording with the same seed, scored against its frames (MSE / SSIM / PSNR).
// Usage: ablation <recording folder> [iterations] [--paper]
#include <evnerf/model.hpp>
#include <evnerf/train/trainer.hpp>

#include <cstdio>
#include <cstring>

using namespace evnerf;

template <class Model>
eval::Scores train_and_score(const io::Dataset& d, const train::Config& cfg, const char* name) {
  const auto td = train::prepare(d, cfg);
  Model model(td.slices.size(), train::scene_box(td, cfg), cfg.seed, nn::AdamConfig{cfg.lr});
  train::run(model, td, cfg, std::string("ablation_out/") + name, name, train::describe(td, d.folder.string()));
  eval::Scores mean;
  int n = 0;
  for (std::size_t i = 0; i < d.frames.size(); ++i) {
    const double t = d.frames.t[i];
    if (!(t > td.slices.boundaries.front() && t <= td.slices.boundaries.back())) continue;
    const auto r = model.render(d.camera, td.pixel_dirs, d.trajectory.pose_at(t));
    const auto s = eval::score(eval::to_grey(r.luminance), eval::to_grey(io::read_png(d.frames.paths[i])), eval::Alignment::LogAffine);
    mean.mse += s.mse;
    mean.ssim += s.ssim;
    mean.psnr += s.psnr;
    ++n;
  }
  mean.mse /= n;
  mean.ssim /= n;
  mean.psnr /= n;
  return mean;
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
    cfg.near = 0.3;
    cfg.far = 7.0;
    cfg.lr = 5e-3;
    cfg.progress = false;
    const bool paper = argc > 2 && std::strcmp(argv[argc - 1], "--paper") == 0;
    struct Row {
      const char* name;
      eval::Scores s;
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
    }
    std::printf("%-26s %8s %8s %8s   (%s preset, %ld iterations, log-affine alignment)\n", "variant", "MSE", "SSIM", "PSNR",
                paper ? "Paper" : "Fast", cfg.iterations);
    for (auto& r : rows) std::printf("%-26s %8.4f %8.4f %8.2f\n", r.name, r.s.mse, r.s.ssim, r.s.psnr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ablation: %s\n", e.what());
    return 1;
  }
}
