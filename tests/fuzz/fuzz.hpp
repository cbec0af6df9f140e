// tests/fuzz/fuzz.hpp — what every libFuzzer harness shares. A harness hands the input to one reader;
// evnerf::Error (a clear refusal) is the only acceptable failure. Any other exception escapes and libFuzzer
// reports it as a crash, as it does every sanitizer report, leak, timeout and allocation above its limit.
#pragma once
#include <cstddef>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include <unistd.h>

#include <evnerf/core/error.hpp>
#include <evnerf/core/warn.hpp>

namespace evfuzz {

inline std::string_view text(const std::uint8_t* data, std::size_t size) { return {reinterpret_cast<const char*>(data), size}; }

/// Writes the input to a file in /dev/shm named for the harness and this process, for readers that open
/// paths (HDF5, bags, .npz); returns its path, or "" when it cannot be written.
inline std::string to_file(const std::uint8_t* data, std::size_t size, const char* name) {
  static thread_local std::string path;
  path = std::string("/dev/shm/evnerf_fuzz_") + std::to_string(::getpid()) + "_" + name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return {};
  const bool ok = std::fwrite(data, 1, size, f) == size;
  return std::fclose(f) == 0 && ok ? path : std::string();
}

/// Warnings (a recording cut short, read to its last whole event) belong to a successful read: each is kept
/// as short as an error's message, and none is printed (a fuzzer cuts files at every byte).
inline const bool quiet_warnings = [] {
  evnerf::set_warning_handler([](const std::string& m) {
    if (m.size() > 700) {
      std::fprintf(stderr, "warning of %zu characters: %.300s…\n", m.size(), m.c_str());
      std::abort();
    }
  });
  return true;
}();

/// Stops the run with a message when an invariant of a successful read does not hold.
[[noreturn]] inline void broken(const char* what) {
  std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
  std::abort();
}
inline void expect(bool ok, const char* what) {
  if (!ok) broken(what);
}

/// Runs `read`; an evnerf::Error is a refusal and must say where and what briefly (the file name given to the
/// reader plus at most a few hundred characters: numbers and fields are echoed short).
template <class Fn>
int run(Fn&& read) {
  try {
    read();
  } catch (const evnerf::Error& e) {
    if (std::strlen(e.what()) > 700) {
      std::fprintf(stderr, "error message of %zu characters: %.300s…\n", std::strlen(e.what()), e.what());
      std::abort();
    }
    if (e.message().empty()) broken("an error without a message");
  }
  return 0;
}

}  // namespace evfuzz
