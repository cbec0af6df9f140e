// The Python module `evnerf` over the built-in variants Python users train most: fast (the default), colour
// (CED's colour cameras), paper (the paper's model) and splat (Gaussians). The whole module is evnerf::python::define
// (include/evnerf/python/module.hpp); a module with your own variants is the same line
// (examples/python/custom_module.cpp). Built by -DEVNERF_PYTHON=ON or `pip install .` (README).
#include <evnerf/python/module.hpp>

using namespace evnerf::presets;
using evnerf::Variant;

EVNERF_PYTHON_MODULE(evnerf, Variant<Fast, "fast">, Variant<FastColour, "colour">, Variant<Paper, "paper">, Variant<Splat, "splat">)
