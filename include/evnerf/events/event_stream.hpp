// events/event_stream.hpp — an event camera's output as a structure of arrays.
// Depends on core/ only.
#pragma once
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/error.hpp"

namespace evnerf::events {

/// Events as parallel arrays. Units: t in seconds (double, the recording's own time origin; IJRR gives
/// nanosecond-resolution decimal seconds, which double keeps to ~1e-16 relative), x and y in pixels with
/// the origin at the top-left, polarity +1 (brighter, "ON") or -1 (darker, "OFF").
struct EventStream {
  int width = 0, height = 0;
  std::vector<double> t;
  std::vector<std::uint16_t> x, y;
  std::vector<std::int8_t> polarity;

  std::size_t size() const { return t.size(); }
  bool empty() const { return t.empty(); }
  void reserve(std::size_t n) {
    t.reserve(n);
    x.reserve(n);
    y.reserve(n);
    polarity.reserve(n);
  }
  void push_back(double ts, int xs, int ys, int p) {
    t.push_back(ts);
    x.push_back(static_cast<std::uint16_t>(xs));
    y.push_back(static_cast<std::uint16_t>(ys));
    polarity.push_back(static_cast<std::int8_t>(p));
  }
  /// Keeps only the events with t0 ≤ t < t1 (times in order, as validate() requires).
  void keep_time_window(double t0, double t1) {
    const auto a = std::lower_bound(t.begin(), t.end(), t0) - t.begin();
    const auto b = std::max(a, std::lower_bound(t.begin(), t.end(), t1) - t.begin());
    auto cut = [&](auto& v) {
      v.erase(v.begin() + b, v.end());
      v.erase(v.begin(), v.begin() + a);
    };
    cut(t);
    cut(x);
    cut(y);
    cut(polarity);
  }
  double t_begin() const { return t.empty() ? 0.0 : t.front(); }
  double t_end() const { return t.empty() ? 0.0 : t.back(); }
  std::size_t count_positive() const {
    std::size_t n = 0;
    for (auto p : polarity) n += p > 0;
    return n;
  }
  /// The errors validate() throws, for readers that check before converting (the Python module's arrays).
  static Error outside_sensor(const std::string& source, std::size_t i, int width, int height) {
    return Error(source + ": event " + std::to_string(i) + " lies outside the " + std::to_string(width) + "x" + std::to_string(height) +
                 " sensor");
  }
  static Error bad_polarity(const std::string& source, std::size_t i, long long p) {
    return Error(source + ": event " + std::to_string(i) + " has polarity " + std::to_string(p));
  }
  /// Checks the invariants every consumer relies on; throws naming the first offending event.
  void validate(const std::string& source = "events") const {
    require(x.size() == t.size() && y.size() == t.size() && polarity.size() == t.size(), source + ": arrays differ in length");
    require(width > 0 && height > 0, source + ": sensor size not set");
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (x[i] >= width || y[i] >= height) throw outside_sensor(source, i, width, height);
      if (polarity[i] != 1 && polarity[i] != -1) throw bad_polarity(source, i, polarity[i]);
      if (i > 0 && t[i] < t[i - 1]) throw Error(source + ": event " + std::to_string(i) + " goes back in time");
    }
  }
};

}  // namespace evnerf::events
