// io/npy.hpp — NumPy .npy arrays: written through xtensor (atomically), read by a small direct reader;
// a binary cache of parsed event streams. Depends on core/, events/ and xtensor only.
#pragma once
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <type_traits>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <xtensor/xadapt.hpp>
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

namespace detail {
template <class T>
constexpr std::string_view npy_type() {
  if constexpr (std::is_same_v<T, double>) return "f8";
  else if constexpr (std::is_same_v<T, float>) return "f4";
  else if constexpr (std::is_same_v<T, std::int8_t>) return "i1";
  else if constexpr (std::is_same_v<T, std::uint8_t>) return "u1";
  else if constexpr (std::is_same_v<T, std::int16_t>) return "i2";
  else if constexpr (std::is_same_v<T, std::uint16_t>) return "u2";
  else if constexpr (std::is_same_v<T, std::int32_t>) return "i4";
  else if constexpr (std::is_same_v<T, std::uint32_t>) return "u4";
  else if constexpr (std::is_same_v<T, std::int64_t>) return "i8";
  else if constexpr (std::is_same_v<T, std::uint64_t>) return "u8";
  else static_assert(sizeof(T) == 0, "load_npy supports fixed-width integer and floating-point element types");
}
/// The value text after `'key':` in a .npy header dictionary, up to the next top-level comma or brace.
inline std::string_view npy_field(std::string_view header, std::string_view key) {
  std::string quoted(key.size() + 2, '\'');
  key.copy(quoted.data() + 1, key.size());
  const std::size_t k = header.find(quoted);
  if (k == std::string_view::npos) return {};
  std::size_t b = header.find(':', k);
  if (b == std::string_view::npos) return {};
  ++b;
  while (b < header.size() && header[b] == ' ') ++b;
  std::size_t e = b;
  int depth = 0;
  while (e < header.size() && (depth > 0 || (header[e] != ',' && header[e] != '}'))) {
    depth += header[e] == '(';
    depth -= header[e] == ')';
    ++e;
  }
  return header.substr(b, e - b);
}
}  // namespace detail

/// Reads a .npy (format 1.0–3.0, little-endian, C order) of element type T straight into memory: the
/// header is parsed here and the payload read once, with no intermediate copies (xtensor's reader copies
/// the file several times, which made cache loads 3× slower). Errors name the file: missing, wrong
/// type, truncated, trailing bytes or a corrupt header.
template <class T>
NpyArray<T> load_npy(const std::filesystem::path& path) {
  static_assert(std::endian::native == std::endian::little, "evnerf's .npy reader assumes a little-endian host");
  const std::string file = path.string();
  auto fail = [&](const std::string& what) -> void { throw Error(file, 0, "cannot read .npy: " + what); };
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw Error(file, 0, "cannot open file (missing or unreadable)");
  unsigned char pre[12];
  if (std::fread(pre, 1, 8, f.get()) != 8 || std::memcmp(pre, "\x93NUMPY", 6) != 0) fail("not a .npy file (bad magic)");
  const int major = pre[6];
  if (major < 1 || major > 3) fail("unsupported format version " + std::to_string(major));
  const std::size_t len_bytes = major == 1 ? 2 : 4;
  if (std::fread(pre + 8, 1, len_bytes, f.get()) != len_bytes) fail("truncated header");
  std::size_t header_len = pre[8] | (std::size_t{pre[9]} << 8);
  if (major > 1) header_len |= (std::size_t{pre[10]} << 16) | (std::size_t{pre[11]} << 24);
  if (header_len > (1u << 20)) fail("header length " + std::to_string(header_len) + " is implausible");
  std::string header(header_len, '\0');
  if (std::fread(header.data(), 1, header_len, f.get()) != header_len) fail("truncated header");

  std::string_view descr = detail::npy_field(header, "descr");
  if (descr.size() < 4 || (descr.front() != '\'' && descr.front() != '"')) fail("header has no element type");
  descr = descr.substr(1, descr.size() - 2);
  const char order = descr[0];
  const std::string_view type = descr.substr(1);
  if (type != detail::npy_type<T>() || (order == '>' && sizeof(T) > 1) || (order != '<' && order != '|' && order != '=' && order != '>'))
    fail("element type is '" + std::string(descr) + "', expected '" + (sizeof(T) == 1 ? "|" : "<") +
         std::string(detail::npy_type<T>()) + "'");
  NpyArray<T> out;
  const std::string_view shape = detail::npy_field(header, "shape");
  if (shape.empty() || shape.front() != '(' || shape.back() != ')') fail("header has no shape");
  std::size_t n = 1;
  for (std::size_t i = 1; i + 1 < shape.size();) {
    while (i + 1 < shape.size() && (shape[i] == ' ' || shape[i] == ',')) ++i;
    if (i + 1 >= shape.size()) break;
    std::size_t d = 0;
    auto [q, ec] = std::from_chars(shape.data() + i, shape.data() + shape.size() - 1, d);
    if (ec != std::errc()) fail("shape '" + std::string(shape) + "' is not a tuple of sizes");
    out.shape.push_back(d);
    n *= d;
    i = static_cast<std::size_t>(q - shape.data());
  }
  if (detail::npy_field(header, "fortran_order") == "True" && out.shape.size() > 1)
    fail("Fortran-ordered arrays are not supported; save with C order");

  const std::size_t payload = n * sizeof(T);
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  const std::size_t offset = 6 + 2 + len_bytes + header_len;
  if (ec || size != offset + payload)
    throw Error(file, 0, "corrupt or truncated .npy (size does not match its header: " + std::to_string(size) +
                             " bytes, expected " + std::to_string(offset + payload) + ")");
  out.data.resize(n);
  if (n > 0 && std::fread(out.data.data(), sizeof(T), n, f.get()) != n) fail("read error in the payload");
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
