// Helpers shared by the tests: finite-difference gradient checks in double, paths to ../shared/data.
#pragma once
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

/// Checks that string `s` contains `sub`, printing `s` on failure.
#define CHECK_CONTAINS(s, sub)                                          \
  do {                                                                  \
    const std::string evtest_s_ = (s);                                  \
    CHECK_MESSAGE(evtest_s_.find(sub) != std::string::npos, evtest_s_); \
  } while (0)

namespace evtest {

/// Folder of the shared test recordings, or empty when ../shared is absent (tests then skip).
inline std::filesystem::path shared_data(const std::string& sub = {}) {
  std::filesystem::path p = EVNERF_SHARED_DATA;
  if (!sub.empty()) p /= sub;
  return std::filesystem::exists(p) ? p : std::filesystem::path{};
}

/// Central finite differences of a scalar function of x, compared with an analytic gradient.
/// Returns the largest relative error max|a − n| / max(1, |n|).
inline double max_fd_error(const std::function<double(const std::vector<double>&)>& f, std::vector<double> x,
                           const std::vector<double>& analytic, double h = 1e-6) {
  double worst = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double x0 = x[i];
    x[i] = x0 + h;
    const double fp = f(x);
    x[i] = x0 - h;
    const double fm = f(x);
    x[i] = x0;
    const double num = (fp - fm) / (2 * h);
    worst = std::max(worst, std::abs(num - analytic[i]) / std::max(1.0, std::abs(num)));
  }
  return worst;
}

}  // namespace evtest
