// The Python module's variant-independent part (python::define_common, include/evnerf/python/common_impl.hpp)
// compiled once for the two modules here, which are built with EVNERF_SEPARATE_COMPILATION and compile only
// their variants (core/compiled.hpp).
#include <evnerf/python/common_impl.hpp>
