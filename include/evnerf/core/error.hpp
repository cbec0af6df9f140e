// core/error.hpp — the one exception type of evnerf: what went wrong and where (file:line for parsers).
// Depends on the standard library only.
#pragma once
#include <cstdio>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace evnerf {

/// Every error evnerf reports. `what()` reads "<file>:<line>: <message>" when a location is known.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message), message_(message) {}
  Error(const std::string& file, std::size_t line, const std::string& message)
      : std::runtime_error(file + ":" + std::to_string(line) + ": " + message), file_(file), line_(line), message_(message) {}

  const std::string& file() const noexcept { return file_; }
  std::size_t line() const noexcept { return line_; }  ///< 1-based; 0 when not tied to a line
  const std::string& message() const noexcept { return message_; }

 private:
  std::string file_;
  std::size_t line_ = 0;
  std::string message_;
};

/// Throws Error(message) unless `cond` holds.
inline void require(bool cond, const std::string& message) {
  if (!cond) throw Error(message);
}

/// A number as messages show it: at most `digits` significant digits (15 keeps an IJRR timestamp's
/// microseconds), exponent form for very large or small values (1e+308, not a 309-digit string).
inline std::string short_number(double v, int digits = 15) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits < 1 ? 1 : digits > 17 ? 17 : digits, v);
  return b;
}

/// Throws unless `v` is finite, naming the quantity.
inline void require_finite(double v, const std::string& what) {
  if (!std::isfinite(v)) throw Error(what + " is not finite (" + short_number(v) + ")");
}

}  // namespace evnerf
