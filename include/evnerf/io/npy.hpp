// io/npy.hpp — NumPy .npy arrays: written through xtensor (atomically), read by a small direct reader;
// a binary cache of parsed event streams. Depends on core/, events/ and xtensor only.
#pragma once
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
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

namespace detail {
/// Where a .npy's payload starts and what it holds.
struct NpyLayout {
  std::vector<std::size_t> shape;
  std::size_t count = 0;   ///< elements (the product of the shape)
  std::size_t offset = 0;  ///< bytes before the payload
};
/// Parses a .npy's preamble and header dictionary; `head` starts at the file's first byte and holds at
/// least the whole header (it may hold more). Checks the element type against T and the size of the
/// payload against overflow; errors name `file`.
/// The preamble and header dictionary without the element type's check: `descr` receives the type text
/// (e.g. "<f8") and `item` its size in bytes.
inline NpyLayout npy_layout_untyped(std::string_view head, const std::string& file, std::string& descr_out, std::size_t item,
                                    std::string_view want);
template <class T>
NpyLayout npy_layout(std::string_view head, const std::string& file) {
  std::string descr;
  return npy_layout_untyped(head, file, descr, sizeof(T), npy_type<T>());
}
inline NpyLayout npy_layout_untyped(std::string_view head, const std::string& file, std::string& descr_out, std::size_t item,
                                    std::string_view want) {
  auto fail = [&](const std::string& what) -> void { throw Error(file, 0, "cannot read .npy: " + what); };
  if (head.size() < 10 || head.substr(0, 6) != "\x93NUMPY") fail("not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(head[6]);
  if (major < 1 || major > 3) fail("unsupported format version " + std::to_string(major));
  const std::size_t len_bytes = major == 1 ? 2 : 4;
  if (head.size() < 8 + len_bytes) fail("truncated header");
  auto byte = [&](std::size_t i) { return std::size_t{static_cast<unsigned char>(head[i])}; };
  std::size_t header_len = byte(8) | (byte(9) << 8);
  if (major > 1) header_len |= (byte(10) << 16) | (byte(11) << 24);
  if (header_len > (1u << 20)) fail("header length " + std::to_string(header_len) + " is implausible");
  NpyLayout out;
  out.offset = 8 + len_bytes + header_len;
  if (head.size() < out.offset) fail("truncated header");
  const std::string_view header = head.substr(8 + len_bytes, header_len);

  std::string_view descr = npy_field(header, "descr");
  if (descr.size() < 4 || (descr.front() != '\'' && descr.front() != '"') || descr.back() != descr.front())
    fail("header has no element type");
  descr = descr.substr(1, descr.size() - 2);
  const char order = descr[0];
  const std::string_view type = descr.substr(1);
  descr_out = std::string(descr.substr(0, 16));
  if (want.empty()) {  // any type the caller converts: its size decides the payload's
    const int bytes = type.size() == 2 && type[1] >= '1' && type[1] <= '8' ? type[1] - '0' : 0;
    if ((type[0] != 'b' && type[0] != 'i' && type[0] != 'u' && type[0] != 'f') || (bytes != 1 && bytes != 2 && bytes != 4 && bytes != 8) ||
        (type[0] == 'f' && bytes < 4) || (type[0] == 'b' && bytes != 1) || (order == '>' && bytes > 1) ||
        (order != '<' && order != '|' && order != '=' && order != '>'))
      fail("element type is '" + descr_out + "', not a little-endian number (b1, i1-i8, u1-u8, f4, f8)");
    item = static_cast<std::size_t>(bytes);
  } else if (type != want || (order == '>' && item > 1) || (order != '<' && order != '|' && order != '=' && order != '>')) {
    fail("element type is '" + descr_out + "', expected '" + (item == 1 ? "|" : "<") + std::string(want) + "'");
  }
  const std::string_view shape = npy_field(header, "shape");
  if (shape.size() < 2 || shape.front() != '(' || shape.back() != ')') fail("header has no shape");
  auto shown = [&] { return std::string(shape.substr(0, 64)) + (shape.size() > 64 ? "…" : ""); };
  std::size_t n = 1;
  for (std::size_t i = 1; i + 1 < shape.size();) {
    while (i + 1 < shape.size() && (shape[i] == ' ' || shape[i] == ',')) ++i;
    if (i + 1 >= shape.size()) break;
    std::size_t d = 0;
    auto [q, ec] = std::from_chars(shape.data() + i, shape.data() + shape.size() - 1, d);
    if (ec != std::errc()) fail("shape '" + shown() + "' is not a tuple of sizes");
    if (out.shape.size() == 32) fail("shape '" + shown() + "' has more than 32 dimensions");
    if (d != 0 && n > (std::numeric_limits<std::size_t>::max() / item) / d) fail("shape '" + shown() + "' is too large to address");
    out.shape.push_back(d);
    n *= d;
    i = static_cast<std::size_t>(q - shape.data());
  }
  if (npy_field(header, "fortran_order") == "True" && out.shape.size() > 1)
    fail("Fortran-ordered arrays are not supported; save with C order");
  out.count = n;
  return out;
}
inline std::string npy_size_error(std::size_t size, std::size_t expected) {
  return "corrupt or truncated .npy (size does not match its header: " + std::to_string(size) + " bytes, expected " +
         std::to_string(expected) + ")";
}
}  // namespace detail

/// Parses a whole .npy held in memory (format 1.0–3.0, little-endian, C order, element type T). Errors name
/// `file`: wrong type, truncated, trailing bytes, a corrupt header or a shape too large to address.
template <class T>
NpyArray<T> parse_npy(std::string_view bytes, const std::string& file) {
  static_assert(std::endian::native == std::endian::little, "evnerf's .npy reader assumes a little-endian host");
  auto layout = detail::npy_layout<T>(bytes, file);
  if (bytes.size() - layout.offset != layout.count * sizeof(T))  // count * sizeof(T) cannot overflow (checked)
    throw Error(file, 0, detail::npy_size_error(bytes.size(), layout.offset + layout.count * sizeof(T)));
  NpyArray<T> out;
  out.shape = std::move(layout.shape);
  out.data.resize(layout.count);
  if (layout.count) std::memcpy(out.data.data(), bytes.data() + layout.offset, layout.count * sizeof(T));
  return out;
}

/// Parses a whole .npy held in memory whatever its numeric element type (bool, integers, float32/64,
/// little-endian), converted to Out: double (integers above 2^53 lose their low bits) or std::int64_t
/// (exact for integers; floating-point values must be whole and in range). Errors name `file`.
template <class Out = double>
NpyArray<Out> parse_npy_numeric(std::string_view bytes, const std::string& file) {
  std::string descr;
  auto layout = detail::npy_layout_untyped(bytes, file, descr, 0, {});
  const char kind = descr[1];
  const std::size_t item = static_cast<std::size_t>(descr[2] - '0');
  if (bytes.size() - layout.offset != layout.count * item)
    throw Error(file, 0, detail::npy_size_error(bytes.size(), layout.offset + layout.count * item));
  NpyArray<Out> out;
  out.shape = std::move(layout.shape);
  out.data.resize(layout.count);
  const char* p = bytes.data() + layout.offset;
  auto convert = [&]<class T>(T) {
    for (std::size_t i = 0; i < layout.count; ++i) {
      T v;
      std::memcpy(&v, p + i * sizeof(T), sizeof(T));
      if constexpr (std::is_floating_point_v<T> && std::is_integral_v<Out>) {
        if (!(v >= -9.2e18 && v <= 9.2e18) || v != std::floor(v))
          throw Error(file, 0,
                      "element " + std::to_string(i) + " (" + short_number(static_cast<double>(v)) + ") is not a whole number in range");
      } else if constexpr (std::is_same_v<T, std::uint64_t> && std::is_integral_v<Out>) {
        if (v > static_cast<std::uint64_t>(INT64_MAX))
          throw Error(file, 0, "element " + std::to_string(i) + " does not fit a signed 64-bit integer");
      }
      out.data[i] = static_cast<Out>(v);
    }
  };
  if (kind == 'f') item == 4 ? convert(float{}) : convert(double{});
  else if (kind == 'b' || kind == 'u')
    item == 1   ? convert(std::uint8_t{})
    : item == 2 ? convert(std::uint16_t{})
    : item == 4 ? convert(std::uint32_t{})
                : convert(std::uint64_t{});
  else
    item == 1   ? convert(std::int8_t{})
    : item == 2 ? convert(std::int16_t{})
    : item == 4 ? convert(std::int32_t{})
                : convert(std::int64_t{});
  return out;
}

/// Parses a .npy holding one string (numpy's '<U' type, UTF-32; a 0-d array as np.savez writes a str).
/// Characters outside ASCII are refused.
inline std::string parse_npy_string(std::string_view bytes, const std::string& file) {
  auto fail = [&](const std::string& what) -> void { throw Error(file, 0, "cannot read .npy string: " + what); };
  if (bytes.size() < 10 || bytes.substr(0, 6) != "\x93NUMPY") fail("not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(bytes[6]);
  const std::size_t len_bytes = major == 1 ? 2 : 4;
  if ((major < 1 || major > 3) || bytes.size() < 8 + len_bytes) fail("unsupported or truncated header");
  std::size_t header_len = std::size_t{static_cast<unsigned char>(bytes[8])} | (std::size_t{static_cast<unsigned char>(bytes[9])} << 8);
  if (major > 1)
    header_len |= (std::size_t{static_cast<unsigned char>(bytes[10])} << 16) | (std::size_t{static_cast<unsigned char>(bytes[11])} << 24);
  if (header_len > bytes.size() - 8 - len_bytes) fail("truncated header");
  const std::string_view header = bytes.substr(8 + len_bytes, header_len);
  std::string_view descr = detail::npy_field(header, "descr");
  if (descr.size() < 5 || descr.substr(1, 2) != "<U" || descr.back() != descr.front()) fail("not a string ('<U') array");
  std::size_t chars = 0;
  for (char c : descr.substr(3, descr.size() - 4)) {
    if (c < '0' || c > '9' || chars > 1000000) fail("bad string length in '" + std::string(descr.substr(0, 16)) + "'");
    chars = chars * 10 + static_cast<std::size_t>(c - '0');
  }
  if (detail::npy_field(header, "shape") != "()") fail("not a single string (shape ())");
  const std::string_view payload = bytes.substr(8 + len_bytes + header_len);
  if (payload.size() != 4 * chars) fail(detail::npy_size_error(bytes.size(), 8 + len_bytes + header_len + 4 * chars));
  std::string s;
  for (std::size_t i = 0; i < chars; ++i) {
    std::uint32_t c = 0;
    std::memcpy(&c, payload.data() + 4 * i, 4);
    if (c == 0) break;  // numpy pads with NULs
    if (c > 127) fail("a character outside ASCII");
    s += static_cast<char>(c);
  }
  return s;
}

/// Reads a .npy file straight into memory: the header is read and parsed first (npy_layout), the payload
/// once, with no intermediate copies (xtensor's reader copies the file several times, which made cache
/// loads 3× slower). The payload's size is checked against the file's before anything is allocated.
template <class T>
NpyArray<T> load_npy(const std::filesystem::path& path) {
  static_assert(std::endian::native == std::endian::little, "evnerf's .npy reader assumes a little-endian host");
  const std::string file = path.string();
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw Error(file, 0, "cannot open file (missing or unreadable)");
  std::string head(12, '\0');
  head.resize(std::fread(head.data(), 1, 12, f.get()));
  if (head.size() >= 12 && head.substr(0, 6) == "\x93NUMPY") {  // then read the header it announces
    const std::size_t len_bytes = static_cast<unsigned char>(head[6]) == 1 ? 2 : 4;
    std::size_t header_len = std::size_t{static_cast<unsigned char>(head[8])} | (std::size_t{static_cast<unsigned char>(head[9])} << 8);
    if (len_bytes == 4)
      header_len |= (std::size_t{static_cast<unsigned char>(head[10])} << 16) | (std::size_t{static_cast<unsigned char>(head[11])} << 24);
    if (header_len <= (1u << 20)) {
      const std::size_t want = 8 + len_bytes + header_len;
      const std::size_t had = head.size();
      if (want > had) {
        head.resize(want);
        head.resize(had + std::fread(head.data() + had, 1, want - had, f.get()));
      }
    }
  }
  auto layout = detail::npy_layout<T>(head, file);
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec || size < layout.offset || size - layout.offset != layout.count * sizeof(T))
    throw Error(file, 0, detail::npy_size_error(ec ? 0 : size, layout.offset + layout.count * sizeof(T)));
  NpyArray<T> out;
  out.shape = std::move(layout.shape);
  out.data.resize(layout.count);
  if (std::fseek(f.get(), static_cast<long>(layout.offset), SEEK_SET) != 0 ||
      (layout.count > 0 && std::fread(out.data.data(), sizeof(T), layout.count, f.get()) != layout.count))
    throw Error(file, 0, "cannot read .npy: read error in the payload");
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
