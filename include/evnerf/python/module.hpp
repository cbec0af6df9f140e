// python/module.hpp — evnerf as a Python module (pybind11) over any list of variants, so that research code
// in Python loads recordings, trains, renders and scores without files in between:
//
//   #include <evnerf/python/module.hpp>
//   using Mine = evnerf::EvNerf<...>;
//   EVNERF_PYTHON_MODULE(evnerf, evnerf::Variant<evnerf::presets::Fast, "fast">, evnerf::Variant<Mine, "mine">)
//
// (or call evnerf::python::define<V...>(m) in a PYBIND11_MODULE of your own). The first variant is
// train()'s default. What Python sees:
//   load(path, ...)              any recording io::load reads → Dataset
//   Dataset(x=, y=, t=, p=, ...) a recording from numpy arrays (poses, intrinsics, optional frames)
//   Dataset.events.x/.y/.t/.p    read-only numpy views of the events (no copy; they keep the Dataset alive)
//   simulate(scene, ...)         a simulated recording (in memory, or written to `out` and loaded)
//   train(dataset, preset=, callback=, ...)  → Model; callback(step, loss, thresholds) may return False to stop
//   Model.render(pose)           intensity and depth as numpy arrays, at any camera-to-world pose
//   load_model(path), Model.save(path), evaluate(model, dataset), baselines(dataset), score(images, truth)
// Errors are evnerf.Error (a ValueError) with the C++ library's messages. Training and rendering release
// the GIL; a callback reacquires it, and Ctrl-C stops training after the current step.
// The conversions between numpy and the library are python/convert.hpp. Needs pybind11 (Debian's
// pybind11-dev); not included by the umbrella header.
#pragma once
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "../eval/evaluate.hpp"
#include "../eval/load.hpp"
#include "../evnerf.hpp"
#include "../sim/simulate.hpp"
#include "../model/variants.hpp"

#include "common.hpp"
#include "convert.hpp"

namespace evnerf::python {

namespace detail {

/// Every slice's thresholds (B+, B−), row-major N×2.
template <class M>
std::vector<double> thresholds_of(const M& model) {
  std::vector<double> v(2 * model.n_slices());
  for (std::size_t i = 0; i < model.n_slices(); ++i) {
    v[2 * i] = model.threshold_pos(i);
    v[2 * i + 1] = model.threshold_neg(i);
  }
  return v;
}

/// A Model around one model object of type M (shared with the closures).
template <class M>
Model wrap(std::shared_ptr<M> model, const std::string& variant, std::shared_ptr<const io::CheckpointRun> run) {
  Model m;
  m.variant = variant;
  m.channels = M::channels;
  m.renderable.name = variant;
  m.renderable.desc = *run;
  m.renderable.near = model->box().near;
  m.renderable.far = model->box().far;
  auto dirs = std::make_shared<const std::vector<Vec3f>>(render::pixel_directions(m.renderable.desc.camera));
  m.renderable.render = [model, dirs, cam = m.renderable.desc.camera](const geometry::Pose& pose) {
    return model->render(cam, *dirs, pose);
  };
  m.renderable.render_with = [model](const geometry::Camera& cam, const geometry::Pose& pose) {
    return model->render(cam, render::pixel_directions(cam), pose);
  };
  m.thresholds = [model] { return thresholds_of(*model); };
  m.step = [model] { return model->step(); };
  m.save = [model, variant, run](const fs::path& p) { train::save_checkpoint(p, *model, variant, *run); };
  return m;
}

template <class... V>
Model load_model(const fs::path& path, const std::string& channel_upsampling) {
  if (path.extension() == ".json") {  // train --per-channel: three grey models
    Model m;
    m.renderable = evaluation::load_renderable<V...>(path, evaluation::parse_channel_upsampling(channel_upsampling));
    m.variant = m.renderable.name;
    m.channels = 3;
    return m;
  }
  Model out;
  with_variant<V...>(checkpoint_variant<V...>(path), [&]<class M>(const std::string& name) {
    auto model = std::make_shared<M>();
    const auto run = std::make_shared<const io::CheckpointRun>(train::load_checkpoint(path, *model));
    if (run->times.empty())
      throw Error(path.string(), 0,
                  "the checkpoint records no training run (no camera, no slice boundaries): a model needs one that "
                  "train wrote");
    out = wrap(model, name, run);
    return 0;
  });
  return out;
}

template <class... V>
Model train_model(const Dataset& ds, const std::string& preset, py::object callback, const std::optional<fs::path>& out, bool resume,
                  const py::kwargs& kw) {
  const auto cfg = config_of(kw);
  if (resume && !out) throw Error("train: resume needs out (the folder whose model.ckpt to continue)");
  const fs::path dir = out ? *out : fs::path();
  Model result;
  with_variant<V...>(preset, [&]<class M>(const std::string& name) {
    struct Run {
      TrainingData td;
      std::unique_ptr<train::Trainer<M>> trainer;
    };
    auto run = std::make_shared<Run>();
    const auto described = std::make_shared<io::CheckpointRun>();
    {
      py::gil_scoped_release nogil;
      run->td = train::prepare(*ds.d, cfg);
      *described = train::describe(run->td, ds.d->folder.string());
      described->shards = static_cast<std::uint64_t>(cfg.shard_count());
      run->trainer = std::make_unique<train::Trainer<M>>(run->td, cfg, dir, name, *described);
    }
    if (resume) run->trainer->resume();
    std::exception_ptr raised;
    train::RunResult r;
    auto& model = run->trainer->model();
    {
      py::gil_scoped_release nogil;
      r = run->trainer->run([&](const train::StepReport& rep) -> bool {
        py::gil_scoped_acquire gil;
        try {
          if (PyErr_CheckSignals() != 0) throw py::error_already_set();
          if (callback.is_none()) return true;
          const py::object go =
              callback(rep.step, rep.stats.loss, to_numpy(thresholds_of(model), {static_cast<py::ssize_t>(model.n_slices()), 2}));
          return go.is_none() || go.cast<bool>();
        } catch (...) {
          raised = std::current_exception();
          return false;
        }
      });
    }
    if (raised) std::rethrow_exception(raised);
    if (r.diverged) throw Error("train: the run diverged at step " + std::to_string(model.step()) + " (see the message above)");
    if (r.collapsed && !cfg.allow_collapse)
      throw Error("train: the run collapsed (" + r.checks.back().describe() + "); pass allow_collapse=True to go on");
    // The model outlives the trainer (and its reference to the training data) in `run`.
    std::shared_ptr<M> shared(run, &model);
    result = wrap(shared, name, described);
    py::list checks;
    for (const auto& c : r.checks)
      checks.append(py::dict(py::arg("step") = c.step, py::arg("log_spread") = c.log_spread, py::arg("collapsed") = c.collapsed()));
    result.run =
        py::dict(py::arg("steps") = r.steps, py::arg("seconds") = r.seconds, py::arg("final_loss") = r.final_loss,
                 py::arg("rays_per_second") = r.rays_per_second, py::arg("stopped") = r.stopped, py::arg("collapse_checks") = checks,
                 py::arg("refractory") = model.refractory().active() ? py::object(py::float_(model.refractory().seconds)) : py::none());
    return 0;
  });
  return result;
}

}  // namespace detail

/// Defines the module's functions and classes over the variants V... (the first is train()'s default): those
/// that depend on no model type (define_common), then load_model and train over V....
template <class... V>
void define(py::module_& m) {
  using namespace detail;
  static_assert(sizeof...(V) >= 1, "evnerf::python::define needs at least one variant");
  const std::string default_variant = std::get<0>(std::tuple<V...>{}).name;
  const std::vector<std::string> names{V::name...};
  define_common(m, names);
  static std::string train_doc;
  m.def("load_model", &load_model<V...>, py::arg("path"), py::arg("channel_upsampling") = "volume",
        "a model.ckpt of any compiled-in variant, or channels.json of train --per-channel (channel_upsampling: 'volume' "
        "renders each channel's volume at every pixel, 'sites' renders its sites and interpolates)");
  m.def("train", &train_model<V...>, py::arg("dataset"), py::kw_only(), py::arg("preset") = default_variant,
        py::arg("callback") = py::none(), py::arg("out") = py::none(), py::arg("resume") = false,
        (train_doc = "Trains a variant (" +
                     [&] {
                       std::string s;
                       for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
                       return s;
                     }() +
                     ") on a dataset; returns the Model. Settings as keywords (evnerf.settings() describes each): " + setting_names() +
                     ". callback(step, loss, thresholds) "
                     "runs after every step; returning False stops the run. With out, settings.json, log.jsonl and model.ckpt are written "
                     "there (resume "
                     "continues from it); without, nothing is written.")
            .c_str());
}

}  // namespace evnerf::python

/// A Python module named `name` over the variants `...` (evnerf::Variant<Model, "name">; the first is train()'s
/// default).
#define EVNERF_PYTHON_MODULE(name, ...) \
  PYBIND11_MODULE(name, m) { ::evnerf::python::define<__VA_ARGS__>(m); }
