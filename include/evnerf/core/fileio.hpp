// core/fileio.hpp — whole-file reads and atomic writes (write to a temporary, fsync, rename), checksums, and
// what the readers of large files share (FileCloser, huge_pages). Depends on the standard library and POSIX only.
#pragma once
#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <memory>
#include <vector>
#include <unistd.h>
#include <fcntl.h>
#include <sys/mman.h>

#include "error.hpp"

namespace evnerf {

/// Closes a FILE held by a std::unique_ptr<std::FILE, FileCloser>.
struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

/// Asks the kernel for huge pages behind a large vector's reserved memory (where transparent huge pages are
/// on request): the events of a long recording fill hundreds of megabytes, and a page fault per 4 KiB is
/// most of the time of a read on machines where faults are dear.
template <class T>
void huge_pages(std::vector<T>& v) {
#ifdef MADV_HUGEPAGE
  constexpr std::uintptr_t kHuge = std::uintptr_t(1) << 21;
  const auto a = reinterpret_cast<std::uintptr_t>(v.data()), e = a + v.capacity() * sizeof(T);
  const std::uintptr_t b = (a + kHuge - 1) & ~(kHuge - 1), f = e & ~(kHuge - 1);
  if (f > b) ::madvise(reinterpret_cast<void*>(b), f - b, MADV_HUGEPAGE);  // advice only: a refusal costs nothing
#else
  (void)v;
#endif
}

/// A long read's progress: `done` bytes of the file's `total` read so far. The readers of whole recordings
/// call it after each block they read (64 KiB to a few MiB; an AEDAT4 packet, a bag's chunk), from the
/// reading thread; it may throw to abandon the read. An empty function is never called.
using ReadProgress = std::function<void(std::uint64_t done, std::uint64_t total)>;

/// Reads a whole file into a string, reporting to `progress` (if given) every 16 MiB. Errors name the file.
inline std::string read_file(const std::filesystem::path& path, const ReadProgress& progress = {}) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error(path.string(), 0, "cannot open file (missing or unreadable)");
  std::string buf;
  if (std::fseek(f, 0, SEEK_END) == 0) {
    long size = std::ftell(f);
    if (size > 0) buf.resize(static_cast<std::size_t>(size));
    std::fseek(f, 0, SEEK_SET);
  }
  std::size_t got = 0;
  if (!progress) {
    got = buf.empty() ? 0 : std::fread(buf.data(), 1, buf.size(), f);
  } else {
    constexpr std::size_t kPiece = std::size_t(16) << 20;
    for (std::size_t k = 1; got < buf.size() && k > 0; got += k) {
      k = std::fread(buf.data() + got, 1, std::min(kPiece, buf.size() - got), f);
      try {
        progress(got + k, buf.size());
      } catch (...) {
        std::fclose(f);
        throw;
      }
    }
  }
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
/// The bytes go to `<path>.tmp.<pid>`, are flushed to the disk (fsync), and the temporary is renamed over
/// `path`. On any failure (no such folder, no permission, disk full, quota) the temporary is removed, the
/// old file stays as it was, and the Error names `path` and the system's reason.
inline void write_file_atomic(const std::filesystem::path& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  auto reason = [](int err) { return std::string(std::strerror(err)); };
  if (path.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(path.parent_path(), ec);
    if (ec) throw Error(path.string(), 0, "cannot create the folder " + path.parent_path().string() + ": " + ec.message());
  }
  const fs::path tmp = path.string() + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(path.string(), 0, "cannot create a file in its folder: " + reason(errno));
  auto give_up = [&](const std::string& what, int err) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw Error(path.string(), 0, what + ": " + reason(err) + " (the previous file, if any, is unchanged)");
  };
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t w = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      const int err = w < 0 ? errno : ENOSPC;
      give_up("write failed after " + std::to_string(off) + " of " + std::to_string(bytes.size()) + " bytes", err);
    }
    off += static_cast<std::size_t>(w);
  }
  if (::fsync(fd) != 0) give_up("cannot flush the file to the disk", errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw Error(path.string(), 0, "cannot close the file: " + reason(err) + " (the previous file, if any, is unchanged)");
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw Error(path.string(), 0, "cannot rename the temporary file into place: " + reason(err));
  }
  // The rename itself reaches the disk when the folder is flushed (best effort: some filesystems refuse).
  const std::string dir = path.has_parent_path() ? path.parent_path().string() : std::string(".");
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
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
