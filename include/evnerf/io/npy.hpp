// io/npy.hpp — NumPy .npy arrays through xtensor, with atomic writes and errors that name the file;
// a binary cache of parsed event streams. Depends on core/, events/ and xtensor only.
#pragma once
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <xtensor/xadapt.hpp>
#include <xtensor/xarray.hpp>
#include <xtensor/xnpy.hpp>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../events/event_stream.hpp"

namespace evnerf::io {

/// Writes data (row-major, `shape`) as .npy, atomically.
template <class T>
void save_npy(const std::filesystem::path& path, const T* data, const std::vector<std::size_t>& shape) {
  std::size_t n = 1;
  for (auto s : shape) n *= s;
  auto view = xt::adapt(data, n, xt::no_ownership(), shape);
  write_file_atomic(path, xt::dump_npy(view));
}
template <class T>
void save_npy(const std::filesystem::path& path, const std::vector<T>& v) {
  save_npy(path, v.data(), {v.size()});
}

template <class T>
struct NpyArray {
  std::vector<std::size_t> shape;
  std::vector<T> data;
};

/// Reads a .npy of element type T. Errors name the file: missing, wrong type, truncated or corrupt.
template <class T>
NpyArray<T> load_npy(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  NpyArray<T> out;
  try {
    std::istringstream in(bytes);
    auto arr = xt::load_npy<T>(in);
    out.shape.assign(arr.shape().begin(), arr.shape().end());
    const std::size_t payload = arr.size() * sizeof(T);
    // The payload sits at the end of the file behind a header padded to 16 bytes: anything else means
    // the file was truncated or has trailing junk.
    if (bytes.size() < payload + 10 || (bytes.size() - payload) % 16 != 0)
      throw Error(path.string(), 0, "corrupt or truncated .npy (size does not match its header)");
    out.data.assign(arr.data(), arr.data() + arr.size());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path.string(), 0, std::string("cannot read .npy: ") + e.what());
  }
  return out;
}

/// Where parsed event streams are cached: $EVNERF_CACHE, else $XDG_CACHE_HOME/evnerf, else ~/.cache/evnerf.
inline std::filesystem::path default_cache_root() {
  if (const char* c = std::getenv("EVNERF_CACHE"); c && *c) return c;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::filesystem::path(x) / "evnerf";
  if (const char* h = std::getenv("HOME"); h && *h) return std::filesystem::path(h) / ".cache" / "evnerf";
  return std::filesystem::temp_directory_path() / "evnerf-cache";
}

/// Saves a stream as four .npy files (t f8, x u2, y u2, p i1) plus a `meta.txt` naming the source's size
/// and modification time, so a changed source invalidates the cache.
inline void save_event_cache(const std::filesystem::path& dir, const events::EventStream& ev, const std::string& stamp) {
  std::filesystem::create_directories(dir);
  save_npy(dir / "t.npy", ev.t);
  save_npy(dir / "x.npy", ev.x);
  save_npy(dir / "y.npy", ev.y);
  save_npy(dir / "p.npy", ev.polarity);
  write_file_atomic(dir / "meta.txt", stamp + " " + std::to_string(ev.width) + " " + std::to_string(ev.height) + "\n");
}

/// Loads a cached stream if its stamp matches; returns false (and leaves `ev` alone) otherwise.
inline bool load_event_cache(const std::filesystem::path& dir, const std::string& stamp, events::EventStream& ev) {
  std::error_code ec;
  if (!std::filesystem::exists(dir / "meta.txt", ec)) return false;
  const std::string meta = read_file(dir / "meta.txt");
  std::istringstream m(meta);
  std::string s;
  int w = 0, h = 0;
  if (!(m >> s >> w >> h) || s != stamp) return false;
  events::EventStream out;
  out.width = w;
  out.height = h;
  out.t = load_npy<double>(dir / "t.npy").data;
  out.x = load_npy<std::uint16_t>(dir / "x.npy").data;
  out.y = load_npy<std::uint16_t>(dir / "y.npy").data;
  out.polarity = load_npy<std::int8_t>(dir / "p.npy").data;
  if (out.x.size() != out.t.size() || out.y.size() != out.t.size() || out.polarity.size() != out.t.size())
    throw Error(dir.string(), 0, "event cache is inconsistent (arrays differ in length); delete it");
  ev = std::move(out);
  return true;
}

}  // namespace evnerf::io
