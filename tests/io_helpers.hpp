// Helpers the reader tests share: a fresh temporary folder, a file written whole, the message of an error.
#pragma once
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <unistd.h>

#include <evnerf/core/error.hpp>

namespace evtest {

/// An empty folder of the system's temporary directory, per test name and process.
inline std::filesystem::path temp_dir(const std::string& name) {
  std::filesystem::path d = std::filesystem::temp_directory_path() / ("evnerf_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}
inline void write(const std::filesystem::path& p, const std::string& s) { std::ofstream(p) << s; }
/// What f throws as an evnerf::Error, or "no error".
inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const evnerf::Error& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace evtest
