// python/common.hpp — the part of the Python module that depends on no model type: its classes (Dataset,
// Model), load, simulate, sensor_model, settings, evaluate, baselines, score. python::define<V...> calls it,
// then adds load_model and train over its variants. Defined in python/common_impl.hpp, included here unless
// the program compiles it once (core/compiled.hpp). Needs pybind11.
#pragma once
#include <string>
#include <vector>

#include <pybind11/pybind11.h>

#include "../core/compiled.hpp"

namespace evnerf::python {

/// Registers the module's variant-independent functions and classes in `m`; `names` are its variants.
EVNERF_COMPILED void define_common(pybind11::module_& m, const std::vector<std::string>& names);

}  // namespace evnerf::python

#ifndef EVNERF_SEPARATE_COMPILATION
#include "common_impl.hpp"
#endif
