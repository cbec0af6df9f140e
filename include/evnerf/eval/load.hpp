// eval/load.hpp — a checkpoint of any variant of a list as an evaluation::Renderable: the variant that can
// load it (model/variants.hpp's checkpoint_variant), its record of the run, and renders at any pose; or the
// channels.json of train --per-channel over such models. What cli::main and the Python module instantiate
// per list of variants. Depends on eval/evaluate.hpp, train/trainer.hpp and model/variants.hpp.
#pragma once
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "../model/variants.hpp"
#include "../render/renderer.hpp"
#include "../train/trainer.hpp"
#include "evaluate.hpp"

namespace evnerf::evaluation {

/// One checkpoint, by the variant of V... that can load it.
template <class... V>
Renderable load_model(const fs::path& ckpt) {
  Renderable r;
  with_variant<V...>(checkpoint_variant<V...>(ckpt), [&]<class Model>(const std::string& name) {
    auto model = std::make_shared<Model>();
    r.desc = train::load_checkpoint(ckpt, *model);
    if (r.desc.times.empty())
      throw Error(ckpt.string(), 0,
                  "the checkpoint records no training run (no camera, no slice boundaries): render and eval need one "
                  "that train wrote");
    r.name = name;
    if (model->pose_refinement().active()) {  // the training path as the model saw it
      r.desc.poses = model->refined_poses();
      r.poses_refined = true;
      r.time_offset = model->pose_refinement().offset;
    }
    const auto& values = model->render_params();
    for (std::size_t i = 0; i < 2 * model->n_slices(); ++i) r.thresholds.push_back(double(values[model->threshold_offset() + i]));
    if (const auto b = model->renderer().backdrop(values.data()); b && model->renderer().learns_backdrop())
      for (const auto v : *b) r.backdrop.push_back(double(v));
    r.near = model->box().near;
    r.far = model->box().far;
    auto dirs = std::make_shared<const std::vector<Vec3f>>(render::pixel_directions(r.desc.camera));
    r.render = [model, dirs, cam = r.desc.camera](const geometry::Pose& pose) { return model->render(cam, *dirs, pose); };
    r.render_with = [model](const geometry::Camera& cam, const geometry::Pose& pose) {
      return model->render(cam, render::pixel_directions(cam), pose);
    };
    if constexpr (requires { typename Model::representation_type::layout; }) {
      r.gaussians = [model] { return gaussians_of(model->renderer(), model->render_params().data()); };
    } else if constexpr (requires(const Vec3* p, float* o) { model->renderer().probe(model->render_params().data(), p, p, 0, o, o); }) {
      r.field.channels = Model::renderer_type::channels;
      r.field.density_length = model->box().density_length;
      r.field.at = [model](const std::vector<Vec3>& pts, const std::vector<Vec3>& dirs, std::vector<float>& sigma,
                           std::vector<float>& lum) {
        sigma.resize(pts.size());
        lum.resize(pts.size() * Model::renderer_type::channels);
        model->renderer().probe(model->render_params().data(), pts.data(), dirs.data(), pts.size(), sigma.data(), lum.data());
      };
    }
    return 0;
  });
  return r;
}

/// load_renderable over the variants V...: a model.ckpt of any of them, or a channels.json of three.
template <class... V>
Renderable load_renderable(const fs::path& ckpt, ChannelUpsampling up = ChannelUpsampling::Volume) {
  return load_renderable(ckpt, up, &load_model<V...>);
}

}  // namespace evnerf::evaluation
