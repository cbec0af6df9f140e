// core/fileio.hpp — whole-file reads and atomic writes (write to a temporary, fsync, rename), checksums.
// Depends on the standard library and POSIX only.
#pragma once
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <unistd.h>
#include <fcntl.h>

#include "error.hpp"

namespace evnerf {

/// Reads a whole file into a string. Errors name the file.
inline std::string read_file(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error(path.string(), 0, "cannot open file (missing or unreadable)");
  std::string buf;
  if (std::fseek(f, 0, SEEK_END) == 0) {
    long size = std::ftell(f);
    if (size > 0) buf.resize(static_cast<std::size_t>(size));
    std::fseek(f, 0, SEEK_SET);
  }
  std::size_t got = buf.empty() ? 0 : std::fread(buf.data(), 1, buf.size(), f);
  if (got != buf.size()) buf.resize(got);
  // Streams whose size is unknown (pipes): read the rest in chunks.
  char chunk[1 << 16];
  std::size_t k;
  while ((k = std::fread(chunk, 1, sizeof chunk, f)) > 0) buf.append(chunk, k);
  const bool bad = std::ferror(f);
  std::fclose(f);
  if (bad) throw Error(path.string(), 0, "read error");
  return buf;
}

/// Writes `bytes` to `path` atomically: a reader sees the old file or the complete new one, never a part.
inline void write_file_atomic(const std::filesystem::path& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  const fs::path tmp = path.string() + ".tmp." + std::to_string(::getpid());
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) throw Error(tmp.string(), 0, "cannot create file for writing");
  std::size_t off = 0;
  while (off < bytes.size()) {
    ssize_t w = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (w <= 0) {
      ::close(fd);
      fs::remove(tmp);
      throw Error(tmp.string(), 0, "write failed (disk full?)");
    }
    off += static_cast<std::size_t>(w);
  }
  ::fsync(fd);
  ::close(fd);
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp);
    throw Error(path.string(), 0, "cannot rename temporary file into place: " + ec.message());
  }
}

/// 64-bit FNV-1a checksum.
inline std::uint64_t fnv1a64(std::string_view bytes, std::uint64_t h = 0xcbf29ce484222325ull) {
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

}  // namespace evnerf
