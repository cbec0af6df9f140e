// The command line's body (cli::run, include/evnerf/cli/run_impl.hpp) compiled once for the programs here
// that share it: evnerf, custom_variant and custom_parts are built with EVNERF_SEPARATE_COMPILATION and
// compile only their variants (core/compiled.hpp).
#include <evnerf/cli/run_impl.hpp>
