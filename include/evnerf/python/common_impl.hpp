// python/common_impl.hpp — the definition of python::define_common (python/common.hpp). Included by
// python/common.hpp, or compiled once by a program that defines EVNERF_SEPARATE_COMPILATION
// (core/compiled.hpp): examples/python/python_common.cpp. Needs pybind11.
#pragma once
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "../eval/evaluate.hpp"
#include "../sim/simulate.hpp"
#include "common.hpp"
#include "convert.hpp"

namespace evnerf::python {

namespace detail {

/// evnerf.Dataset: a recording's arrays, read-only, and its summary.
inline void define_dataset(py::module_& m) {
  py::class_<Dataset> ds(m, "Dataset", "A recording: camera, events, poses, optional frames.", py::module_local());
  ds.def(py::init(&make_dataset), py::arg("x"), py::arg("y"), py::arg("t"), py::arg("p"), py::kw_only(), py::arg("width"),
         py::arg("height"), py::arg("intrinsics"), py::arg("poses") = py::none(), py::arg("frame_times") = py::none(),
         py::arg("frames") = py::none(), py::arg("bayer") = "", py::arg("name") = "arrays",
         "Events x, y (integer pixels), t (float seconds), p (bool, 0/1 or -1/+1) on a width x height sensor; intrinsics [fx, fy, cx, cy"
         "(, k1, k2, p1, p2(, k3))]; poses N x 8 (t, px, py, pz, qx, qy, qz, qw, camera to world); frames for evaluation only "
         "(N x H x W (x 3), float 0..1 or uint8) at frame_times; bayer: the colour filter of a colour sensor ('rggb', ...).");
  ds.def_property_readonly("width", [](const Dataset& s) { return s.d->camera.width(); });
  ds.def_property_readonly("height", [](const Dataset& s) { return s.d->camera.height(); });
  ds.def_property_readonly("name", [](const Dataset& s) { return s.d->folder.string(); });
  ds.def_property_readonly("bayer", [](const Dataset& s) { return s.d->bayer_pattern; });
  ds.def_property_readonly(
      "intrinsics",
      [](const Dataset& s) {
        const auto& c = s.d->camera;
        const auto& k = c.distortion();
        return std::vector<double>{c.fx(), c.fy(), c.cx(), c.cy(), k[0], k[1], k[2], k[3], k[4]};
      },
      "[fx, fy, cx, cy, k1, k2, p1, p2, k3]");
  ds.def_property_readonly(
      "events",
      [](py::object self) {
        const auto& s = self.cast<const Dataset&>();
        const auto& e = s.d->events;
        py::dict v;
        v["x"] = view(e.x, self);
        v["y"] = view(e.y, self);
        v["t"] = view(e.t, self);
        v["p"] = view(e.polarity, self);
        return py::module_::import("types").attr("SimpleNamespace")(**v);
      },
      "x, y (uint16), t (float64 seconds), p (int8, ±1): read-only numpy views of the recording's events, no copy");
  ds.def("__len__", [](const Dataset& s) { return s.d->events.size(); });
  ds.def_property_readonly(
      "poses",
      [](const Dataset& s) {
        const auto& tr = s.d->trajectory;
        py::array_t<double> a({static_cast<py::ssize_t>(tr.size()), py::ssize_t{8}});
        for (std::size_t i = 0; i < tr.size(); ++i) {
          const auto& p = tr.poses()[i];
          const double r[8] = {tr.times()[i], p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(), p.q.w()};
          for (int c = 0; c < 8; ++c) a.mutable_at(static_cast<py::ssize_t>(i), c) = r[c];
        }
        return a;
      },
      "N x 8: t, px, py, pz, qx, qy, qz, qw (camera to world)");
  ds.def(
      "pose_at", [](const Dataset& s, double t) { return matrix_of(s.d->trajectory.pose_at(t)); }, py::arg("t"),
      "the 4x4 camera-to-world pose at time t (interpolated)");
  ds.def_property_readonly("frame_times",
                           [](const Dataset& s) { return to_numpy(s.d->frames.t, {static_cast<py::ssize_t>(s.d->frames.size())}); });
  ds.def(
      "frame", [](const Dataset& s, std::size_t i) { return image_to_numpy(io::frame_image(s.d->frames, i)); }, py::arg("i"),
      "frame i as an H x W (x 3) float array in [0, 1]");
  ds.def("__repr__", [](const Dataset& s) {
    const auto& d = *s.d;
    return "<evnerf.Dataset '" + d.folder.string() + "': " + std::to_string(d.camera.width()) + "x" + std::to_string(d.camera.height()) +
           ", " + std::to_string(d.events.size()) + " events, " + std::to_string(d.trajectory.size()) + " poses, " +
           std::to_string(d.frames.size()) + " frames>";
  });
}

/// evnerf.load, evnerf.simulate and evnerf.sensor_model: recordings read or made.
inline void define_recordings(py::module_& m) {
  m.def(
      "load",
      [](const fs::path& path, std::optional<fs::path> calib, std::optional<fs::path> poses,
         std::optional<std::pair<double, double>> window, const std::string& format, std::optional<std::pair<int, int>> sensor_size,
         py::object progress) {
        io::LoadOptions o;
        if (calib) o.calib = *calib;
        if (poses) o.poses = *poses;
        if (sensor_size) {
          if (sensor_size->first <= 0 || sensor_size->second <= 0 || sensor_size->first > 65535 || sensor_size->second > 65535)
            throw Error("load: sensor_size must be (width, height), each 1 to 65535");
          o.width = sensor_size->first, o.height = sensor_size->second;
        }
        if (window) {
          o.t_begin = window->first;
          o.t_end = window->second;
        }
        o.format = format;
        if (!progress.is_none()) {
          if (!PyCallable_Check(progress.ptr())) throw Error("load: progress must be a callable (bytes_read, bytes_total)");
          o.progress = [progress](std::uint64_t done, std::uint64_t total) {
            py::gil_scoped_acquire gil;
            progress(done, total);  // what it raises (KeyboardInterrupt among them) ends the read
          };
        }
        py::gil_scoped_release nogil;
        return Dataset{std::make_shared<io::Dataset>(io::load(path, o))};
      },
      py::arg("path"), py::kw_only(), py::arg("calib") = py::none(), py::arg("poses") = py::none(), py::arg("time_window") = py::none(),
      py::arg("format") = "", py::arg("sensor_size") = py::none(), py::arg("progress") = py::none(),
      "Any recording evnerf reads (IJRR folder, EventNeRF or Robust e-NeRF folder, Prophesee .raw or .dat, event HDF5, ROS bag, "
      "AEDAT4); calib and poses as the command line's --calib and --poses, time_window (t0, t1) seconds, format as --format, "
      "sensor_size (width, height) as --sensor-size; progress(bytes_read, bytes_total), if given, is called as a long read goes on "
      "(IJRR text, Prophesee, AEDAT4, ROS bags), and what it raises stops the read.");

  // The docstring lists the sensor's keywords from their table (sim::sensor_params); static, as pybind11
  // keeps the pointer.
  static const std::string simulate_doc =
      "A simulated recording of a built-in scene (evnerf.scenes), 'random', 'mesh' (mesh= a 3-D file, seen along an orbit as "
      "`evnerf simulate mesh FILE` sees it, with held-out views when written to out) or a scene file, as `evnerf simulate` makes it; "
      "width and height 0: the scene's default (240 x 180, 346 x 260 for a mesh). "
      "sensor: 'ideal', 'realistic', 'davis' (realistic with a DAVIS240C's 1.5 ms refractory period) or 'random' (drawn from the "
      "seed), and any of " +
      sim::sensor_param_names() +
      " as keywords (evnerf.sensor_model shows the result). "
      "pose_noise=(T, R) and time_offset make the poses only roughly known (simulate's --pose-noise, --time-offset), the true ones kept. "
      "Without out it stays in memory (frames, no depth or linear truth); with out it is written there (IJRR layout) and loaded.";
  m.def(
      "simulate",
      [](const std::string& scene, std::optional<fs::path> out, const std::string& sensor, bool bayer, bool hdr, std::uint64_t seed,
         int width, int height, double focal, double noise_ratio, std::optional<fs::path> mesh, std::pair<double, double> pose_noise,
         double time_offset, const py::kwargs& sensor_parameters) {
        sim::SimulateOptions o;
        if (mesh) o.mesh.file = *mesh;
        if (mesh && scene != "mesh") throw Error("simulate: mesh= goes with the scene 'mesh'");
        o.sensor = sensor_options(sensor, sensor_parameters);
        o.bayer = bayer;
        o.hdr = hdr;
        o.seed = seed;
        o.width = width;
        o.height = height;
        o.focal = focal;
        o.noise_ratio = noise_ratio;
        o.pose_noise_translation = pose_noise.first;
        o.pose_noise_rotation = pose_noise.second;
        o.time_offset = time_offset;
        o.progress = false;
        py::gil_scoped_release nogil;
        std::string text;
        auto rec = sim::simulate(scene, o, &text);
        if (!out) return Dataset{std::make_shared<io::Dataset>(sim::to_dataset(std::move(rec), scene))};
        sim::write_recording(*out, rec);
        if (!text.empty()) write_file_atomic(*out / "scene.txt", text);
        return Dataset{std::make_shared<io::Dataset>(io::load(*out))};
      },
      py::arg("scene") = "planes", py::kw_only(), py::arg("out") = py::none(), py::arg("sensor") = "ideal", py::arg("bayer") = false,
      py::arg("hdr") = false, py::arg("seed") = 1, py::arg("width") = 0, py::arg("height") = 0, py::arg("focal") = 0.0,
      py::arg("noise_ratio") = 0.0, py::arg("mesh") = py::none(), py::arg("pose_noise") = std::pair<double, double>{0.0, 0.0},
      py::arg("time_offset") = 0.0, simulate_doc.c_str());
  m.def(
      "sensor_model",
      [](const std::string& sensor, std::uint64_t seed, const py::kwargs& sensor_parameters) {
        const auto c = sim::sensor_model(sensor_options(sensor, sensor_parameters), seed);
        py::dict d;
        sim::sensor_params([&](const auto& p) { d[p.name] = c.*p.value; });
        return d;
      },
      py::arg("sensor") = "ideal", py::kw_only(), py::arg("seed") = 1,
      "The sensor simulate() records with for these arguments (random: the values drawn from the seed), as a dict.");
}

/// evnerf.Model and what trains, opens, renders and scores one.
inline void define_models(py::module_& m) {
  py::class_<Model> model(m, "Model", "A trained or loaded model of any of this module's variants.", py::module_local());
  model.def_readonly("variant", &Model::variant);
  model.def_readonly("channels", &Model::channels);
  model.def_readonly("run", &Model::run,
                     "what train() did (steps, seconds, final_loss, stopped, collapse checks, the refractory period it ended with: learned "
                     "or given, None when the counts were read as they are); empty when loaded");
  model.def_property_readonly("width", [](const Model& s) { return s.renderable.desc.camera.width(); });
  model.def_property_readonly("height", [](const Model& s) { return s.renderable.desc.camera.height(); });
  model.def_property_readonly("boundary_times", [](const Model& s) {
    return to_numpy(s.renderable.desc.times, {static_cast<py::ssize_t>(s.renderable.desc.times.size())});
  });
  model.def_property_readonly(
      "boundary_poses", [](const Model& s) { return matrices_of(s.renderable.desc.poses); },
      "N x 4 x 4 camera-to-world poses at the slice boundaries");
  model.def_property_readonly(
      "step", [](const Model& s) -> py::object { return s.step ? py::object(py::int_(s.step())) : py::object(py::none()); });
  model.def_property_readonly(
      "thresholds",
      [](const Model& s) -> py::object {
        if (!s.thresholds) return py::none();
        const auto v = s.thresholds();
        return to_numpy(v, {static_cast<py::ssize_t>(v.size() / 2), 2});
      },
      "per slice (B+, B-) as an N x 2 array (None for a per-channel model)");
  model.def(
      "render",
      [](const Model& s, py::handle pose) {
        const auto p = pose_of(pose);
        Rendering r;
        {
          py::gil_scoped_release nogil;
          r = s.renderable.render(p);
        }
        return py::make_tuple(image_to_numpy(r.luminance), image_to_numpy(r.depth));
      },
      py::arg("pose"),
      "(intensity, depth) at a camera-to-world pose (4x4, or [px, py, pz, qx, qy, qz, qw]): H x W (x 3) linear intensity, H x W depth");
  model.def(
      "save",
      [](const Model& s, const fs::path& p) {
        if (!s.save) throw Error(p.string(), 0, "a per-channel model is saved by train --per-channel only");
        py::gil_scoped_release nogil;
        s.save(p);
      },
      py::arg("path"), "writes model.ckpt (atomically)");
  model.def("__repr__", [](const Model& s) {
    return "<evnerf.Model '" + s.variant + "': " + std::to_string(s.renderable.desc.camera.width()) + "x" +
           std::to_string(s.renderable.desc.camera.height()) + ", " + std::to_string(s.renderable.desc.times.size()) + " boundaries" +
           (s.step ? ", step " + std::to_string(s.step()) : std::string()) + ">";
  });

  m.def(
      "settings",
      [] {
        nlohmann::json rows = nlohmann::json::array();
        const train::Config defaults;
        for (const auto& s : train::settings())
          rows.push_back({{"name", s.name},
                          {"default", s.get(defaults)},
                          {"allowed", s.numeric()    ? s.range_text()
                                      : s.integral() ? "any"
                                                     : "any of its kind"},
                          {"integer", s.integral()},
                          {"numeric", s.numeric()},
                          {"lo", s.lo},
                          {"hi", s.hi},
                          {"lo_open", s.lo_open},
                          {"hi_open", s.hi_open},
                          {"help", s.help}});
        return json_to_python(rows);
      },
      "the training settings train() takes as keywords: name, default, allowed values, help (train::settings(), the same table as "
      "the command line's flags)");

  m.def(
      "evaluate",
      [](const Model& s, const Dataset& d, const std::string& alignment, int holdout) {
        evaluation::Evaluation e;
        {
          py::gil_scoped_release nogil;
          e = evaluation::evaluate(s.renderable, *d.d, evaluation::alignments_from(alignment), holdout);
        }
        py::dict r = json_to_python(e.json);
        py::list images;
        for (const auto& im : e.methods.front().images) images.append(image_to_numpy(im));
        r["frames"] = e.ids;
        r["renders"] = images;
        return r;
      },
      py::arg("model"), py::arg("dataset"), py::kw_only(), py::arg("alignment") = "global-log-affine", py::arg("holdout") = 0,
      "Renders at the dataset's frames inside the trained time and scores it and both baselines: metrics.json as a dict "
      "(alignment, methods, secondary, ...), plus frames (their indices) and renders (the model's images).");
  m.def(
      "baselines",
      [](const Dataset& d, double contrast, const std::string& alignment) {
        require(contrast > 0 && std::isfinite(contrast), "baselines: the contrast must be positive");
        evaluation::BaselineRun b;
        {
          py::gil_scoped_release nogil;
          b = evaluation::run_baselines(*d.d, evaluation::alignments_from(alignment), contrast);
        }
        py::dict r = json_to_python(b.scored.json);
        py::dict images;
        for (const auto& meth : b.methods) {
          py::list l;
          for (const auto& im : meth.images) l.append(image_to_numpy(im));
          images[py::str(meth.name)] = l;
        }
        r["frames"] = b.ids;
        r["images"] = images;
        return r;
      },
      py::arg("dataset"), py::kw_only(), py::arg("contrast") = 0.2, py::arg("alignment") = "global-log-affine",
      "Direct integration and the high-pass filter at the frames inside the events' span, scored: metrics as a dict, "
      "frames, and images[name] (one array per frame).");
  m.def(
      "score",
      [](py::handle images, py::handle truth, const std::string& alignment, bool oracle) {
        const auto a = eval::parse_alignment(alignment);
        const auto pred = image_list(images, "images");
        const auto gt = image_list(truth, "truth");
        std::vector<Image> aligned, truths;
        const auto s = eval::score_sequence(pred, gt, a, &aligned);
        py::list per;
        for (const auto& x : s) per.append(py::dict(py::arg("mse") = x.mse, py::arg("psnr") = x.psnr, py::arg("ssim") = x.ssim));
        const auto mean = eval::mean(s);
        py::dict r(py::arg("alignment") = eval::to_string(a), py::arg("mse") = mean.mse, py::arg("psnr") = mean.psnr,
                   py::arg("ssim") = mean.ssim, py::arg("per_frame") = per);
        if (oracle && !gt.empty()) {
          for (const auto& g : gt) truths.push_back(eval::scored_truth(g, a));
          const auto o = eval::offset_oracle(aligned, truths);
          r["oracle"] =
              py::dict(py::arg("rows_psnr") = o.rows_psnr, py::arg("columns_psnr") = o.columns_psnr, py::arg("both_psnr") = o.both_psnr);
        }
        return r;
      },
      py::arg("images"), py::arg("truth"), py::kw_only(), py::arg("alignment") = "global-log-affine", py::arg("oracle") = false,
      "MSE, PSNR and SSIM of a sequence of images against the truth (N x H x W (x 3) arrays or lists) under an alignment. "
      "oracle=True adds eval's offset oracle (oracle: rows_psnr, columns_psnr, both_psnr): the PSNR with gains per image row, "
      "per column and both, constant over the sequence, fitted to the truth; what a straight motion never shows the events "
      "(a diagnosis, never a score).");
}

}  // namespace detail

EVNERF_COMPILED void define_common(py::module_& m, const std::vector<std::string>& names) {
  using namespace detail;
  // Module-local: a second module of one's own variants (examples/python/custom_module.cpp) keeps its own
  // Error and classes beside this one.
  py::register_local_exception<Error>(m, "Error", PyExc_ValueError);
  m.attr("__version__") = version;
  m.attr("variants") = names;
  m.attr("scenes") = sim::builtin_scenes();
  m.attr("alignments") = std::vector<std::string>{"global-log-affine", "log-affine", "eventnerf", "global-log-offset", "min-max", "none"};

  define_dataset(m);
  define_recordings(m);
  define_models(m);
}

}  // namespace evnerf::python
