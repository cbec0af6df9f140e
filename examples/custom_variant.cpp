// A user's own Ev-NeRF variant in a page: another encoding (Frequency<6> instead of a hash grid),
// another activation (Softplus) and widths, trained on a simulated scene and rendered.
// Usage: custom_variant <recording folder> [iterations]
#include <evnerf/evnerf.hpp>

#include <cstdio>

using namespace evnerf;

// density network: γ(x) with 6 frequencies (39 inputs) → 3 hidden layers of 96 (Softplus) → density + 8 features
// colour network: 8 features + spherical harmonics of degree 3 (9) → 48 → 1 luminance
using MyField = field::Field<nn::Frequency<6>, nn::SphericalHarmonics<3>, nn::Mlp<39, 96, 3, 9, nn::Softplus, nn::Identity>,
                             nn::Mlp<8 + 9, 48, 1, 1, nn::ReLU, nn::Identity>>;
using MyModel = EvNerf<MyField, render::Stratified<48>, loss::JointThresholds, loss::DefaultNoise>;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: custom_variant <recording folder> [iterations]\n");
    return 2;
  }
  try {
    const auto data = io::load_ijrr(argv[1]);
    train::Config cfg;
    cfg.iterations = argc > 2 ? std::atol(argv[2]) : 300;
    cfg.near = 0.3;
    cfg.far = 7.0;
    const auto td = train::prepare(data, cfg);
    MyModel model(td.slices.size(), train::scene_box(td, cfg), cfg.seed, nn::AdamConfig{5e-3});
    auto r = train::run(model, td, cfg, "custom_variant_out", "custom", train::describe(td, argv[1]));
    const auto img = model.render(td.camera, td.pixel_dirs, td.boundary_poses[td.boundary_poses.size() / 2]);
    io::write_png("custom_variant_out/middle.png", img.luminance);
    std::printf("%zu parameters, %ld steps, %.0f rays/s, loss %.4f; wrote custom_variant_out/middle.png\n", MyField::n_params,
                r.steps, r.rays_per_second, r.final_loss);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "custom_variant: %s\n", e.what());
    return 1;
  }
}
