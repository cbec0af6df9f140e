// core/compiled.hpp — EVNERF_COMPILED: how a function that does not depend on a model type is linked.
// evnerf is header-only: including a header gives every definition, marked inline. A program that builds
// several executables over the same command line can compile those bodies once instead: define
// EVNERF_SEPARATE_COMPILATION in every translation unit, and include <evnerf/cli/run_impl.hpp> in exactly
// one of them (the project's own programs do this: examples/cli_run.cpp). The headers then declare the
// functions marked EVNERF_COMPILED without defining them. Depends on nothing.
#pragma once

#ifdef EVNERF_SEPARATE_COMPILATION
#define EVNERF_COMPILED
#else
#define EVNERF_COMPILED inline
#endif
