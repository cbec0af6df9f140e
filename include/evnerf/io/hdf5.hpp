// io/hdf5.hpp — event recordings in HDF5, through the HDF5 C library (Debian's libhdf5-dev). Two layouts:
//   event_utils / HQF:  events/xs, events/ys (integers), events/ts (seconds), events/ps (0/1 or ±1 or bool);
//                       frames images/imageNNNNNNNNN (H×W or H×W×C, uint8) with a `timestamp` attribute in
//                       seconds; the root attribute `sensor_resolution` = (height, width) when present.
//   DSEC:               events/x, events/y, events/t (µs, added to the root dataset `t_offset` when present),
//                       events/p; `ms_to_idx` (the first event of every millisecond) is checked when present.
// Events are read in blocks of kHdf5Block, converted and checked as they come, into vectors sized once from
// the dataset's extent: the peak memory is the stream itself plus one block, whatever the file's size. A
// whole-file read reports its progress after each dataset's part of a block, as the share of the events'
// elements read times the file's size (the datasets are not laid out in the file in reading order).
// Compressed datasets are read through HDF5's filter plugins: DSEC ships its events compressed with Blosc
// (filter 32001), which Debian's hdf5-filter-plugin-blosc-serial provides; a filter the library cannot load
// is an Error naming it and the package. Every error names the file and the dataset. Compiled only where
// CMake found HDF5 (EVNERF_HAVE_HDF5).
// Its line of the format table is hdf5_format(). Depends on core/, geometry/, events/ and io/ only.
#pragma once
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "../events/event_stream.hpp"
#include "ijrr.hpp"
#include "recording.hpp"

namespace evnerf::io {

inline constexpr std::size_t kHdf5Block = std::size_t{1} << 20;

/// What an event HDF5 file holds.
struct Hdf5Recording {
  std::string layout;  ///< "event_utils" or "dsec"
  events::EventStream events;
  int width = 0, height = 0;        ///< from `sensor_resolution` or the frames; 0 when the file does not say
  std::vector<double> frame_times;  ///< seconds
  std::vector<Image> frames;        ///< float in [0, 1]
  std::size_t events_read = 0;      ///< events read from the file (fewer than it holds when a time window
                                    ///< and DSEC's ms_to_idx let the reader skip the rest)
};

namespace detail {

/// An HDF5 identifier closed on scope exit.
class H5Id {
 public:
  H5Id(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~H5Id() {
    if (id_ >= 0) close_(id_);
  }
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

/// HDF5's own error printing off for a scope (our errors say what went wrong), restored after.
class H5Quiet {
 public:
  H5Quiet() {
    H5Eget_auto2(H5E_DEFAULT, &fn_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~H5Quiet() { H5Eset_auto2(H5E_DEFAULT, fn_, data_); }
  H5Quiet(const H5Quiet&) = delete;
  H5Quiet& operator=(const H5Quiet&) = delete;

 private:
  H5E_auto2_t fn_ = nullptr;
  void* data_ = nullptr;
};

/// Whether every component of `path` ("a/b/c") exists as a link.
inline bool h5_exists(hid_t file, const std::string& path) {
  std::size_t pos = 0;
  while (true) {
    pos = path.find('/', pos + 1);
    const std::string part = path.substr(0, pos);
    if (H5Lexists(file, part.c_str(), H5P_DEFAULT) <= 0) return false;
    if (pos == std::string::npos) return true;
  }
}

/// Where Debian installs HDF5's filter plugins (hdf5-filter-plugin-blosc-serial: Blosc, DSEC's compression;
/// hdf5-filter-plugin: LZ4, BZip2, Bitshuffle). Debian's libhdf5 searches it by default; HDF5_PLUGIN_PATH
/// replaces that default, so the folder is put first in the search path once, where it exists (first:
/// libhdf5 1.10 ends its search at a folder of the path that does not exist).
inline constexpr const char* kDebianHdf5Plugins = "/usr/lib/x86_64-linux-gnu/hdf5/serial/plugins";
inline void use_debian_plugins() {
  static const bool done = [] {
    std::error_code ec;
    if (!std::filesystem::is_directory(kDebianHdf5Plugins, ec)) return true;
    unsigned n = 0;
    if (H5PLsize(&n) < 0) return true;
    for (unsigned i = 0; i < n; ++i) {
      char dir[4096] = {0};
      if (H5PLget(i, dir, sizeof dir) > 0 && std::string(dir) == kDebianHdf5Plugins) return true;
    }
    H5PLprepend(kDebianHdf5Plugins);
    return true;
  }();
  (void)done;
}

/// The Debian package that provides the HDF5 filter `id`, as advice for an Error.
inline std::string filter_package(H5Z_filter_t id) {
  switch (id) {
    case 32001:
      return "install Debian's hdf5-filter-plugin-blosc-serial";
    case 307:
    case 32004:
    case 32008:
      return "install Debian's hdf5-filter-plugin";
    case 32013:
      return "install Debian's hdf5-filter-plugin-zfp-serial";
    default:
      return "put its plugin in a folder that HDF5_PLUGIN_PATH names";
  }
}

/// A one-dimensional numeric dataset, read block by block.
class H5Vector {
 public:
  H5Vector(hid_t file, const std::string& name, const std::string& where)
      : where_(where + ": dataset '" + name + "'"), set_(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose),
        space_(set_.ok() ? H5Dget_space(set_.get()) : -1, H5Sclose) {
    if (!set_.ok()) throw Error(where_ + " cannot be opened");
    if (!space_.ok()) throw Error(where_ + " has no readable shape");
    // Every filter of its pipeline must be loadable, or the first read fails without saying why.
    const H5Id dcpl(H5Dget_create_plist(set_.get()), H5Pclose);
    const int filters = dcpl.ok() ? H5Pget_nfilters(dcpl.get()) : 0;
    for (int i = 0; i < filters; ++i) {
      unsigned flags = 0, config = 0;
      std::size_t values = 0;
      char name[80] = {0};
      const H5Z_filter_t id =
          H5Pget_filter2(dcpl.get(), static_cast<unsigned>(i), &flags, &values, nullptr, sizeof name - 1, name, &config);
      if (id < 0) throw Error(where_ + " has an unreadable filter pipeline");
      if (H5Zfilter_avail(id) <= 0)
        throw Error(where_ + " is compressed with HDF5 filter " + std::to_string(id) +
                    (name[0] ? std::string(" ('") + name + "')" : std::string()) + ", which this HDF5 library cannot load (searched " +
                    kDebianHdf5Plugins + " and HDF5_PLUGIN_PATH): " + filter_package(id));
      if (id == 32001) blosc_ = i;
      else if (id != H5Z_FILTER_SHUFFLE) size_changing_ = true;
    }
    const int rank = H5Sget_simple_extent_ndims(space_.get());
    hsize_t dims[2] = {0, 0};
    if (rank < 1 || rank > 2 || H5Sget_simple_extent_dims(space_.get(), dims, nullptr) < 0 || (rank == 2 && dims[1] != 1))
      throw Error(where_ + " is not a one-dimensional array");
    size_ = dims[0];
    const H5Id type(H5Dget_type(set_.get()), H5Tclose);
    const H5T_class_t cls = type.ok() ? H5Tget_class(type.get()) : H5T_NO_CLASS;
    if (cls != H5T_INTEGER && cls != H5T_FLOAT && cls != H5T_ENUM)  // h5py stores bool as an enum of int8
      throw Error(where_ + " does not hold numbers");
    floating_ = cls == H5T_FLOAT;
    const std::size_t element = H5Tget_size(type.get());  // a corrupt type can claim gigabytes per element
    if (element == 0 || element > 8)
      throw Error(where_ + " has elements of " + std::to_string(element) + " bytes (numbers of 1 to 8 expected)");
    if (cls == H5T_INTEGER) {
      // Padding bits (fewer significant bits than the element holds, or an offset) are legal HDF5 that no event
      // file uses; on a corrupt type (16 bits at bit 246 of a 2-byte element) libhdf5 1.10 converts the same
      // elements to other values for another selection of them.
      const std::size_t bits = H5Tget_precision(type.get());
      const int at = H5Tget_offset(type.get());
      if (at != 0 || bits != 8 * element)
        throw Error(where_ + " has integers of " + std::to_string(bits) + " bits at bit " + std::to_string(at) + " of " +
                    std::to_string(element) + "-byte elements (whole-byte integers expected)");
    }
    if (blosc_ >= 0 && !size_changing_) {
      // Blosc alone (or with HDF5's shuffle, which keeps the size): each stored chunk's Blosc header must say
      // it decompresses to a whole chunk (chunk_check).
      hsize_t chunk[2] = {0, 0};
      const int crank = dcpl.ok() ? H5Pget_chunk(dcpl.get(), 2, chunk) : -1;
      if (crank == rank && chunk[0] > 0) {
        chunk_ = chunk[0];
        chunk_bytes_ = chunk[0] * (rank == 2 ? chunk[1] : 1) * element;
        char path[4096] = {0};
        if (H5Fget_name(file, path, sizeof path - 1) > 0) path_ = path;
      }
    }
    if (cls == H5T_ENUM) {
      const H5Id base(H5Tget_super(type.get()), H5Tclose);
      if (!base.ok() || H5Tget_size(base.get()) != 1) throw Error(where_ + " is an enumeration other than h5py's bool");
      byte_enum_ = true;
    }
  }
  std::size_t size() const { return static_cast<std::size_t>(size_); }
  bool floating() const { return floating_; }
  const std::string& where() const { return where_; }
  /// Elements [begin, begin + n) converted to T by HDF5 (integers are range-checked by the caller).
  template <class T>
  void read(std::size_t begin, std::size_t n, T* out) const {
    if (n == 0) return;
    if (chunk_) chunk_check(begin, n);
    const hsize_t start[1] = {begin}, count[1] = {n};
    const int rank = H5Sget_simple_extent_ndims(space_.get());
    hsize_t start2[2] = {begin, 0}, count2[2] = {n, 1};
    if (H5Sselect_hyperslab(space_.get(), H5S_SELECT_SET, rank == 2 ? start2 : start, nullptr, rank == 2 ? count2 : count, nullptr) < 0)
      throw Error(where_ + ": cannot select elements " + std::to_string(begin) + " … " + std::to_string(begin + n));
    const H5Id mem(H5Screate_simple(1, count, nullptr), H5Sclose);
    if (byte_enum_) {  // h5py's bool: the enumeration's one-byte values as stored, then widened
      std::vector<signed char> raw(n);
      const H5Id type(H5Dget_type(set_.get()), H5Tclose);
      if (H5Dread(set_.get(), type.get(), mem.get(), space_.get(), H5P_DEFAULT, raw.data()) < 0)
        throw Error(where_ + ": read error at elements " + std::to_string(begin) + " … " + std::to_string(begin + n));
      for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<T>(raw[i]);
      return;
    }
    if (H5Dread(set_.get(), native<T>(), mem.get(), space_.get(), H5P_DEFAULT, out) < 0)
      throw Error(where_ + ": read error at elements " + std::to_string(begin) + " … " + std::to_string(begin + n) +
                  " (truncated or corrupt file?)");
  }
  /// The Blosc chunks holding elements [begin, begin + n), checked before the library decompresses them:
  /// Debian's Blosc filter plugin decompresses to the size its chunk's header gives, and libhdf5 1.10 then
  /// copies a whole chunk from that buffer (a heap over-read on a corrupt header); Blosc itself reads as many
  /// compressed bytes as the header says. A header that disagrees with the chunk is an Error.
  void chunk_check(std::size_t begin, std::size_t n) const {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(path_.empty() ? nullptr : std::fopen(path_.c_str(), "rb"), &std::fclose);
    if (!f) throw Error(where_ + ": cannot open the file again to check its Blosc chunks");
    for (std::uint64_t c = begin / chunk_; c * chunk_ < begin + n; ++c) {
      hsize_t offset[2] = {c * chunk_, 0};
      unsigned mask = 0;
      haddr_t addr = HADDR_UNDEF;
      hsize_t bytes = 0;
      if (H5Dget_chunk_info_by_coord(set_.get(), offset, &mask, &addr, &bytes) < 0)
        throw Error(where_ + ": the chunk at element " + std::to_string(offset[0]) + " cannot be located (corrupt chunk index?)");
      if (addr == HADDR_UNDEF || (mask >> blosc_ & 1)) continue;  // not written (fill value), or stored without Blosc
      unsigned char h[16];
      const std::string at = where_ + ": the Blosc chunk at element " + std::to_string(offset[0]) + " (byte " + std::to_string(addr) + ")";
      if (bytes < 16 || fseeko(f.get(), static_cast<off_t>(addr), SEEK_SET) != 0 || std::fread(h, 1, 16, f.get()) != 16)
        throw Error(at + ": its 16-byte header cannot be read (" + std::to_string(bytes) + " bytes stored)");
      const std::uint32_t nbytes = h[4] | h[5] << 8 | h[6] << 16 | static_cast<std::uint32_t>(h[7]) << 24;
      const std::uint32_t cbytes = h[12] | h[13] << 8 | h[14] << 16 | static_cast<std::uint32_t>(h[15]) << 24;
      if (nbytes != chunk_bytes_)
        throw Error(at + " says it decompresses to " + std::to_string(nbytes) + " bytes, not the chunk's " + std::to_string(chunk_bytes_) +
                    " (corrupt file?)");
      if (cbytes > bytes)
        throw Error(at + " says it holds " + std::to_string(cbytes) + " compressed bytes, " + std::to_string(bytes) +
                    " are stored (corrupt file?)");
    }
  }
  template <class T>
  static hid_t native() {
    if constexpr (std::is_same_v<T, double>) return H5T_NATIVE_DOUBLE;
    else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_NATIVE_INT64;
    else if constexpr (std::is_same_v<T, std::uint64_t>) return H5T_NATIVE_UINT64;
    else static_assert(sizeof(T) == 0, "H5Vector::read: double, int64 or uint64");
  }

 private:
  std::string where_;
  H5Id set_, space_;
  hsize_t size_ = 0;
  bool floating_ = false, byte_enum_ = false;
  int blosc_ = -1;                       // the Blosc filter's place in the pipeline
  bool size_changing_ = false;           // another filter that changes the size
  hsize_t chunk_ = 0, chunk_bytes_ = 0;  // elements and bytes a chunk holds; 0: no Blosc check
  std::string path_;
};

/// A numeric attribute of `object` with up to `max` elements, as doubles; empty when absent.
inline std::vector<double> h5_attribute(hid_t object, const char* name, std::size_t max = 16) {
  if (H5Aexists(object, name) <= 0) return {};
  const H5Id attr(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
  if (!attr.ok()) return {};
  const H5Id space(H5Aget_space(attr.get()), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  if (n <= 0 || static_cast<std::size_t>(n) > max) return {};
  std::vector<double> v(static_cast<std::size_t>(n));
  if (H5Aread(attr.get(), H5T_NATIVE_DOUBLE, v.data()) < 0) return {};
  return v;
}

}  // namespace detail

/// Whether `path` starts with the HDF5 signature (at offset 0; files with a user block are not recognised).
inline bool is_hdf5(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return false;
  char sig[8] = {};
  const bool ok = std::fread(sig, 1, 8, f) == 8 && std::memcmp(sig, "\x89HDF\r\n\x1a\n", 8) == 0;
  std::fclose(f);
  return ok;
}

namespace detail {

/// The frames of an event_utils file (images/image*, each with a `timestamp` attribute), in name order,
/// into rec.frames and rec.frame_times.
inline void h5_frames(hid_t f, const std::string& file, Hdf5Recording& rec) {
  const H5Id group(H5Gopen2(f, "images", H5P_DEFAULT), H5Gclose);
  hsize_t count = 0;
  if (!group.ok() || H5Gget_num_objs(group.get(), &count) < 0) throw Error(file, 0, "group 'images' cannot be read");
  std::vector<std::pair<double, std::string>> named;
  for (hsize_t i = 0; i < count; ++i) {
    char name[256] = {};
    if (H5Gget_objname_by_idx(group.get(), i, name, sizeof name) <= 0) continue;
    if (std::strncmp(name, "image", 5) != 0) continue;
    const std::string full = std::string("images/") + name;
    const H5Id set(H5Dopen2(f, full.c_str(), H5P_DEFAULT), H5Dclose);
    if (!set.ok()) throw Error(file, 0, "dataset '" + full + "' cannot be opened");
    const auto ts = h5_attribute(set.get(), "timestamp", 1);
    if (ts.size() != 1 || !std::isfinite(ts[0])) throw Error(file, 0, "dataset '" + full + "' has no numeric 'timestamp' attribute");
    named.emplace_back(ts[0], full);
  }
  std::sort(named.begin(), named.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  for (const auto& [t, full] : named) {
    const H5Id set(H5Dopen2(f, full.c_str(), H5P_DEFAULT), H5Dclose);
    const H5Id space(H5Dget_space(set.get()), H5Sclose);
    const int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[3] = {0, 0, 1};
    if (rank < 2 || rank > 3 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
      throw Error(file, 0, "dataset '" + full + "' is not an H×W or H×W×C image");
    const H5Id type(H5Dget_type(set.get()), H5Tclose);
    if (!type.ok() || H5Tget_class(type.get()) != H5T_INTEGER || H5Tget_size(type.get()) != 1)
      throw Error(file, 0, "dataset '" + full + "' is not an 8-bit image");
    if (dims[0] == 0 || dims[1] == 0 || dims[0] > 65535 || dims[1] > 65535 || dims[0] * dims[1] > std::uint64_t{1} << 26 ||
        (dims[2] != 1 && dims[2] != 3))
      throw Error(file, 0,
                  "dataset '" + full + "' has an unusable image shape (" + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                      std::to_string(dims[2]) + ")");
    if (!rec.frame_times.empty() && t < rec.frame_times.back())
      throw Error(file, 0, "dataset '" + full + "': frame timestamps go back in time");
    std::vector<unsigned char> px8(dims[0] * dims[1] * dims[2]);
    if (H5Dread(set.get(), H5T_NATIVE_UCHAR, H5S_ALL, H5S_ALL, H5P_DEFAULT, px8.data()) < 0)
      throw Error(file, 0, "dataset '" + full + "': read error (an image must hold 8-bit values)");
    Image img(static_cast<int>(dims[1]), static_cast<int>(dims[0]), static_cast<int>(dims[2]));
    for (std::size_t i = 0; i < px8.size(); ++i) img.data[i] = px8[i] / 255.f;
    rec.frame_times.push_back(t);
    rec.frames.push_back(std::move(img));
  }
}

/// The sensor's size into rec: the caller's (width, height > 0), else the file's `sensor_resolution`
/// attribute, else its first frame's; left 0 where none gives it (the events then do).
inline void h5_sensor_size(hid_t f, const std::string& file, int width, int height, Hdf5Recording& rec) {
  if (const auto res = h5_attribute(f, "sensor_resolution", 2); res.size() == 2) {
    for (double v : res)
      if (!(v >= 1 && v <= 65535) || v != std::floor(v))
        throw Error(file, 0,
                    "attribute 'sensor_resolution' (" + short_number(res[0]) + ", " + short_number(res[1]) +
                        ") is not a height and width of 1 to 65535 pixels");
    rec.height = static_cast<int>(res[0]);
    rec.width = static_cast<int>(res[1]);
  } else if (!rec.frames.empty()) {
    rec.width = rec.frames[0].width;
    rec.height = rec.frames[0].height;
  }
  if (width > 0 && height > 0) rec.width = width, rec.height = height;
}

/// DSEC's `t_offset` (µs the event times count from), 0 where the file has none.
inline double h5_t_offset(hid_t f, const std::string& file) {
  if (!h5_exists(f, "t_offset")) return 0;
  const H5Id set(H5Dopen2(f, "t_offset", H5P_DEFAULT), H5Dclose);
  const H5Id type(set.ok() ? H5Dget_type(set.get()) : -1, H5Tclose);
  const H5Id space(set.ok() ? H5Dget_space(set.get()) : -1, H5Sclose);
  std::int64_t v = 0;
  if (!set.ok() || !type.ok() || H5Tget_class(type.get()) != H5T_INTEGER || H5Tget_size(type.get()) > 8 || !space.ok() ||
      H5Sget_simple_extent_npoints(space.get()) != 1 || H5Dread(set.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, &v) < 0)
    throw Error(file, 0, "dataset 't_offset' cannot be read as an integer (microseconds)");
  return static_cast<double>(v);
}

/// DSEC's `ms_to_idx` (entry k: the first event at or after k ms of the raw times), checked to run forwards
/// within the n events; empty where the file has none.
inline std::vector<std::uint64_t> h5_ms_index(hid_t f, const std::string& file, std::size_t n, std::uint64_t bytes) {
  std::vector<std::uint64_t> ms_index;
  if (!h5_exists(f, "ms_to_idx")) return ms_index;
  const H5Vector idx(f, "ms_to_idx", file);
  if (idx.size() > 16 * static_cast<std::size_t>(bytes))
    throw Error(file, 0,
                "dataset 'ms_to_idx' claims " + std::to_string(idx.size()) + " entries in a file of " + std::to_string(bytes) + " bytes");
  ms_index.resize(idx.size());
  idx.read(0, ms_index.size(), ms_index.data());
  for (std::size_t k = 0; k < ms_index.size(); ++k)
    if (ms_index[k] > n || (k > 0 && ms_index[k] < ms_index[k - 1]))
      throw Error(file, 0, "dataset 'ms_to_idx' disagrees with the events at millisecond " + std::to_string(k));
  return ms_index;
}

/// The four event datasets of either layout and how their times read (seconds = (t + t_offset) · t_scale).
struct H5EventSets {
  H5Vector xs, ys, ts, ps;
  std::string pt, pp;  ///< the times' and polarities' dataset names
  double t_offset = 0, t_scale = 1;
};

/// Events [i0, i1) of the datasets into rec.events (in blocks of kHdf5Block, each event checked: finite
/// times running forwards, pixels on the sensor, polarities 0/1 or ±1), rec's size from the events where
/// it has none. `progress` hears of the elements read, in the file's bytes.
inline void h5_read_events(const H5EventSets& d, const std::string& file, std::size_t i0, std::size_t i1, std::uint64_t bytes,
                           const ReadProgress& progress, Hdf5Recording& rec) {
  auto& ev = rec.events;
  const std::size_t count = i1 - i0;
  rec.events_read = count;
  ev.t.resize(count);
  ev.x.resize(count);
  ev.y.resize(count);
  ev.polarity.resize(count);
  std::vector<std::int64_t> bx(std::min(count, kHdf5Block)), by(bx.size()), bp(bx.size());
  std::vector<double> bt(bx.size());
  std::int64_t max_x = -1, max_y = -1;
  const std::int64_t lim_x = rec.width > 0 ? rec.width : 65535, lim_y = rec.height > 0 ? rec.height : 65535;
  double last = -INFINITY;
  // After `parts` of the block at b (four datasets each), the share of the elements read, in the file's bytes.
  auto report = [&](std::size_t b, std::size_t m, int parts) {
    if (!progress || count == 0) return;
    const double share = (4.0 * static_cast<double>(b - i0) + parts * static_cast<double>(m)) / (4.0 * static_cast<double>(count));
    progress(static_cast<std::uint64_t>(share * static_cast<double>(bytes)), bytes);
  };
  for (std::size_t b = i0; b < i1; b += kHdf5Block) {
    const std::size_t m = std::min(kHdf5Block, i1 - b);
    d.xs.read(b, m, bx.data());
    report(b, m, 1);
    d.ys.read(b, m, by.data());
    report(b, m, 2);
    d.ps.read(b, m, bp.data());
    report(b, m, 3);
    if (d.ts.floating()) {
      d.ts.read(b, m, bt.data());
    } else {  // integer timestamps (DSEC's µs): read exactly, then scale
      std::vector<std::int64_t> ti(m);
      d.ts.read(b, m, ti.data());
      for (std::size_t i = 0; i < m; ++i) bt[i] = static_cast<double>(ti[i]);
    }
    report(b, m, 4);
    for (std::size_t i = 0; i < m; ++i) {
      const std::size_t k = b + i;
      const double t = (bt[i] + d.t_offset) * d.t_scale;
      if (!std::isfinite(t)) throw Error(file, 0, "dataset '" + d.pt + "', event " + std::to_string(k) + ": time is not finite");
      if (t < last)
        throw Error(file, 0,
                    "dataset '" + d.pt + "', event " + std::to_string(k) + ": time " + short_number(t) + " s goes back (previous " +
                        short_number(last) + " s)");
      if (bx[i] < 0 || by[i] < 0 || bx[i] >= lim_x || by[i] >= lim_y)
        throw Error(file, 0,
                    "event " + std::to_string(k) + ": pixel (" + std::to_string(bx[i]) + ", " + std::to_string(by[i]) +
                        ") lies outside the " + std::to_string(lim_x) + "x" + std::to_string(lim_y) + " sensor");
      if (bp[i] != 0 && bp[i] != 1 && bp[i] != -1)
        throw Error(file, 0,
                    "dataset '" + d.pp + "', event " + std::to_string(k) + ": unknown polarity " + std::to_string(bp[i]) +
                        " (expected 0/1 or -1/1)");
      last = t;
      max_x = std::max(max_x, bx[i]);
      max_y = std::max(max_y, by[i]);
      ev.t[k - i0] = t;
      ev.x[k - i0] = static_cast<std::uint16_t>(bx[i]);
      ev.y[k - i0] = static_cast<std::uint16_t>(by[i]);
      ev.polarity[k - i0] = static_cast<std::int8_t>(bp[i] == 1 ? 1 : -1);
    }
  }
  if (rec.width <= 0 || rec.height <= 0) {
    rec.width = static_cast<int>(max_x + 1);
    rec.height = static_cast<int>(max_y + 1);
  }
  ev.width = rec.width;
  ev.height = rec.height;
}

/// Refuses a ms_to_idx that disagrees with events [i0, i1) of n as read (entries pointing at events this
/// read skipped are checked only for order, which h5_ms_index did).
inline void h5_check_ms_index(const std::vector<std::uint64_t>& ms_index, const events::EventStream& ev, double t_offset, std::size_t i0,
                              std::size_t i1, std::size_t n, const std::string& file) {
  if (ms_index.empty()) return;
  if (i0 == 0 && i1 == n && ms_index.size() > n + 1 + static_cast<std::size_t>(std::max(0.0, (ev.t.back() - t_offset * 1e-6) * 1e3)) + 1)
    throw Error(file, 0, "dataset 'ms_to_idx' has " + std::to_string(ms_index.size()) + " entries, more than the events' milliseconds");
  auto raw_ms = [&](std::size_t j) { return (ev.t[j - i0] - t_offset * 1e-6) * 1e3; };
  for (std::size_t k = 0; k < ms_index.size(); ++k) {
    const std::size_t v = ms_index[k];
    const bool bad = (v >= i0 && v < i1 && raw_ms(v) < double(k) - 1e-6) || (v > i0 && v <= i1 && raw_ms(v - 1) >= double(k) + 1e-6);
    if (bad) throw Error(file, 0, "dataset 'ms_to_idx' disagrees with the events at millisecond " + std::to_string(k));
  }
}

}  // namespace detail

/// Reads an event HDF5 file of either layout. `width`/`height` (when > 0) bound the pixel coordinates;
/// otherwise the file's `sensor_resolution` or first frame does, else the largest coordinate + 1.
/// `progress` (where set) hears of the events read, in bytes of the file (see the header's comment).
inline Hdf5Recording read_hdf5(const std::filesystem::path& path, int width = 0, int height = 0, double t_begin = -INFINITY,
                               double t_end = INFINITY, const ReadProgress& progress = {}) {
  const std::string file = path.string();
  const detail::H5Quiet quiet;
  if (!std::filesystem::is_regular_file(path)) throw Error(file, 0, "cannot open file (missing or not a file)");
  if (!is_hdf5(path)) throw Error(file, 0, "not an HDF5 file (no HDF5 signature at its start)");
  detail::use_debian_plugins();
  const detail::H5Id h5(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!h5.ok()) throw Error(file, 0, "the HDF5 library cannot open this file (truncated or corrupt?)");
  const hid_t f = h5.get();
  Hdf5Recording rec;
  const bool eu = detail::h5_exists(f, "events/xs"), dsec = detail::h5_exists(f, "events/x");
  if (!eu && !dsec)
    throw Error(file, 0,
                "no events: expected datasets events/xs, events/ys, events/ts, events/ps (event_utils, HQF) or "
                "events/x, events/y, events/t, events/p (DSEC)");
  rec.layout = eu ? "event_utils" : "dsec";
  const std::string px = eu ? "events/xs" : "events/x", py = eu ? "events/ys" : "events/y", pt = eu ? "events/ts" : "events/t",
                    pp = eu ? "events/ps" : "events/p";
  for (const auto& name : {py, pt, pp})
    if (!detail::h5_exists(f, name)) throw Error(file, 0, "dataset '" + name + "' is missing (" + rec.layout + " layout)");
  if (eu && detail::h5_exists(f, "images")) detail::h5_frames(f, file, rec);
  detail::h5_sensor_size(f, file, width, height, rec);

  const detail::H5EventSets d{detail::H5Vector(f, px, file),
                              detail::H5Vector(f, py, file),
                              detail::H5Vector(f, pt, file),
                              detail::H5Vector(f, pp, file),
                              pt,
                              pp,
                              dsec ? detail::h5_t_offset(f, file) : 0.0,
                              eu ? 1.0 : 1e-6};
  for (const auto* v : {&d.xs, &d.ys, &d.ps})
    if (v->floating()) throw Error(v->where() + " holds floating-point values (pixel coordinates and polarities are integers)");
  const std::size_t n = d.xs.size();
  if (d.ys.size() != n || d.ts.size() != n || d.ps.size() != n)
    throw Error(file, 0,
                "the event datasets differ in length (" + px + " " + std::to_string(n) + ", " + py + " " + std::to_string(d.ys.size()) +
                    ", " + pt + " " + std::to_string(d.ts.size()) + ", " + pp + " " + std::to_string(d.ps.size()) + ")");
  if (n == 0) throw Error(file, 0, "no events (the event datasets are empty)");
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  if (ec || n > 16 * static_cast<std::size_t>(bytes))  // refuse an absurd extent before allocating for it
    throw Error(file, 0, "dataset '" + px + "' claims " + std::to_string(n) + " events in a file of " + std::to_string(bytes) + " bytes");

  // DSEC: with a time window, ms_to_idx bounds the events to read: those from ms_to_idx[floor] to
  // ms_to_idx[ceil] of the window's ends, one more on each side so that the entries used are checked
  // against the events like the others.
  const std::vector<std::uint64_t> ms_index = dsec ? detail::h5_ms_index(f, file, n, bytes) : std::vector<std::uint64_t>{};
  std::size_t i0 = 0, i1 = n;
  if (!ms_index.empty() && (std::isfinite(t_begin) || std::isfinite(t_end))) {
    const double ms0 = t_begin * 1e3 - d.t_offset * 1e-3, ms1 = t_end * 1e3 - d.t_offset * 1e-3;
    const double last_k = static_cast<double>(ms_index.size() - 1);
    if (std::isfinite(t_begin) && ms0 > 0) i0 = ms_index[static_cast<std::size_t>(std::min(std::floor(ms0), last_k))];
    if (std::isfinite(t_end) && std::ceil(ms1) <= last_k) i1 = ms_index[static_cast<std::size_t>(std::max(0.0, std::ceil(ms1)))];
    i0 = i0 > 0 ? i0 - 1 : 0;
    i1 = std::min(n, std::max(i1, i0) + 1);
  }
  detail::h5_read_events(d, file, i0, i1, bytes, progress, rec);
  detail::h5_check_ms_index(ms_index, rec.events, d.t_offset, i0, i1, n, file);
  if (std::isfinite(t_begin) || std::isfinite(t_end)) rec.events.keep_time_window(t_begin, t_end);
  return rec;
}

namespace detail {
/// Called in the probing child before it reads (tests make it crash on purpose); null otherwise.
inline void (*&hdf5_probe_hook())() {
  static void (*hook)() = nullptr;
  return hook;
}
}  // namespace detail

/// read_hdf5, but first in a child process (fork): the HDF5 library (Debian's 1.10.8) crashes on some corrupt
/// files, inside its own metadata code, where no check of ours can reach. When the child dies by a signal
/// the file is refused with an Error saying so, and this process is untouched; when the child refuses the
/// file, its Error is rethrown here; when it reads the file, this process reads it again (the same calls on
/// the same bytes). The cost is a second read of the file; the child's memory is gone before this one's
/// read begins, so the peak memory is unchanged. `progress` hears of both reads, each as half the file's
/// bytes (the child's through the pipe); where it throws, the child is stopped and the read abandoned.
inline Hdf5Recording read_hdf5_checked(const std::filesystem::path& path, int width = 0, int height = 0, double t_begin = -INFINITY,
                                       double t_end = INFINITY, const ReadProgress& progress = {}) {
  const std::string file = path.string();
  int fds[2];
  if (::pipe(fds) != 0) throw Error(file, 0, "cannot create a pipe to check the HDF5 file in a child process");
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error(file, 0, "cannot fork to check the HDF5 file in a child process");
  }
  if (pid == 0) {  // the child: only report
    ::close(fds[0]);
    // A fault ends the child by its signal, whatever handlers the program installed (a fuzzer's, a
    // sanitizer's): the parent reads the signal from the exit status.
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) std::signal(sig, SIG_DFL);
    // What the child sends: 'P' and the bytes done (8 bytes, this machine's order) for each progress report,
    // then 'E' and an Error's message, if it refuses the file.
    auto send = [&](const char* data, std::size_t n) {
      for (std::size_t off = 0; off < n;) {
        const ssize_t w = ::write(fds[1], data + off, n - off);
        if (w <= 0) return;
        off += static_cast<std::size_t>(w);
      }
    };
    ReadProgress report;
    if (progress)
      report = [&](std::uint64_t done, std::uint64_t) {
        char r[9] = {'P'};
        std::memcpy(r + 1, &done, 8);
        send(r, 9);
      };
    int code = 0;
    try {
      if (detail::hdf5_probe_hook()) detail::hdf5_probe_hook()();
      read_hdf5(path, width, height, t_begin, t_end, report);
    } catch (const Error& e) {
      const std::string m = std::string("E") + e.what();
      send(m.data(), m.size());
      code = 3;
    } catch (...) {
      code = 4;
    }
    ::_exit(code);
  }
  ::close(fds[1]);
  std::error_code size_error;
  std::uint64_t total = std::filesystem::file_size(path, size_error);
  if (size_error) total = 0;
  std::string in, message;
  bool refused = false;  // after 'E': the rest is the message
  char buf[4096];
  try {
    for (ssize_t k; (k = ::read(fds[0], buf, sizeof buf)) != 0;) {
      if (k < 0 && errno == EINTR) continue;
      if (k < 0) break;
      (refused ? message : in).append(buf, static_cast<std::size_t>(k));
      std::size_t at = 0;
      for (; !refused && at < in.size(); at += 9) {
        if (in[at] == 'E') {
          refused = true;
          message = in.substr(at + 1);
          break;
        }
        if (in.size() - at < 9) break;
        std::uint64_t done = 0;
        std::memcpy(&done, in.data() + at + 1, 8);
        if (progress) progress(std::min(done, total) / 2, total);
      }
      in.erase(0, refused ? in.size() : at);
    }
  } catch (...) {  // the caller's progress function abandons the read
    ::kill(pid, SIGKILL);
    ::close(fds[0]);
    while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {}
    throw;
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
  if (WIFSIGNALED(status))
    throw Error(file, 0,
                "the HDF5 library crashed (signal " + std::to_string(WTERMSIG(status)) + ", " + strsignal(WTERMSIG(status)) +
                    ") reading this file in a child process: the file is corrupt in a way the library does not check; "
                    "nothing was loaded");
  if (WIFEXITED(status) && WEXITSTATUS(status) == 3) throw Error(message);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw Error(file, 0,
                "reading this HDF5 file in a child process ended with exit status " +
                    std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) +
                    " (a crash a sanitizer reported, or out of memory); nothing was loaded");
  ReadProgress second;
  // The child's read filled [0, total / 2]; this one fills the rest, ending at total.
  if (progress) second = [&](std::uint64_t done, std::uint64_t) { progress(total - (total - std::min(done, total)) / 2, total); };
  return read_hdf5(path, width, height, t_begin, t_end, second);
}

/// Writes events (and frames, 8-bit, with their times) as an event_utils/HQF HDF5 file: events/xs, ys
/// (int16), ts (float64 seconds), ps (int8, 1 ON, 0 OFF), images/imageNNNNNNNNN with a `timestamp`
/// attribute, and the root attribute `sensor_resolution` = (height, width). Written to a temporary file and
/// renamed into place, so `path` is the old file or the complete new one.
inline void write_hdf5(const std::filesystem::path& path, const events::EventStream& ev, int width, int height,
                       const std::vector<double>& frame_times, const std::vector<Image>& frames) {
  const std::string file = path.string();
  require(width > 0 && height > 0 && width <= 32767 && height <= 32767, file + ": write_hdf5 stores pixels as int16 (sides up to 32767)");
  require(frame_times.size() == frames.size(), file + ": write_hdf5: one time per frame");
  const detail::H5Quiet quiet;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  const std::string tmp = file + ".tmp." + std::to_string(::getpid());
  auto fail = [&](const std::string& what) {
    std::filesystem::remove(tmp);
    throw Error(file, 0, "cannot write HDF5: " + what);
  };
  {
    const detail::H5Id f(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    if (!f.ok()) fail("cannot create the file");
    const detail::H5Id lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
    H5Pset_create_intermediate_group(lcpl.get(), 1);
    auto put = [&](const std::string& name, hid_t file_type, hid_t mem_type, const void* data, int rank, const hsize_t* dims) {
      const detail::H5Id space(H5Screate_simple(rank, dims, nullptr), H5Sclose);
      const detail::H5Id set(H5Dcreate2(f.get(), name.c_str(), file_type, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
      if (!set.ok() || H5Dwrite(set.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0) fail("dataset '" + name + "' (disk full?)");
    };
    const std::size_t n = ev.size();
    std::vector<std::int16_t> xs(n), ys(n);
    std::vector<std::int8_t> ps(n);
    for (std::size_t i = 0; i < n; ++i) {
      xs[i] = static_cast<std::int16_t>(ev.x[i]);
      ys[i] = static_cast<std::int16_t>(ev.y[i]);
      ps[i] = ev.polarity[i] > 0 ? 1 : 0;
    }
    const hsize_t dn[1] = {n};
    put("events/xs", H5T_STD_I16LE, H5T_NATIVE_INT16, xs.data(), 1, dn);
    put("events/ys", H5T_STD_I16LE, H5T_NATIVE_INT16, ys.data(), 1, dn);
    put("events/ts", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, ev.t.data(), 1, dn);
    put("events/ps", H5T_STD_I8LE, H5T_NATIVE_INT8, ps.data(), 1, dn);
    for (std::size_t k = 0; k < frames.size(); ++k) {
      const Image& im = frames[k];
      std::vector<unsigned char> px(im.data.size());
      for (std::size_t i = 0; i < px.size(); ++i)
        px[i] = static_cast<unsigned char>(std::lround(std::clamp(std::isfinite(im.data[i]) ? im.data[i] : 0.f, 0.f, 1.f) * 255.f));
      const hsize_t dims[3] = {static_cast<hsize_t>(im.height), static_cast<hsize_t>(im.width), static_cast<hsize_t>(im.channels)};
      char name[64];
      std::snprintf(name, sizeof name, "images/image%09zu", k);
      put(name, H5T_STD_U8LE, H5T_NATIVE_UCHAR, px.data(), im.channels == 1 ? 2 : 3, dims);
      const detail::H5Id set(H5Dopen2(f.get(), name, H5P_DEFAULT), H5Dclose);
      const detail::H5Id scalar(H5Screate(H5S_SCALAR), H5Sclose);
      const detail::H5Id attr(H5Acreate2(set.get(), "timestamp", H5T_IEEE_F64LE, scalar.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
      if (!attr.ok() || H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &frame_times[k]) < 0) fail(std::string("attribute timestamp of ") + name);
    }
    const hsize_t two[1] = {2};
    const std::int64_t res[2] = {height, width};
    const detail::H5Id space(H5Screate_simple(1, two, nullptr), H5Sclose);
    const detail::H5Id attr(H5Acreate2(f.get(), "sensor_resolution", H5T_STD_I64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!attr.ok() || H5Awrite(attr.get(), H5T_NATIVE_INT64, res) < 0) fail("attribute sensor_resolution");
    if (H5Fflush(f.get(), H5F_SCOPE_GLOBAL) < 0) fail("flush (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) fail("cannot rename the temporary file into place: " + ec.message());
}

/// Loads an event HDF5 file (io/hdf5.hpp: event_utils/HQF or DSEC layout) with the calibration and poses
/// LoadOptions names, or calib.txt and groundtruth.txt beside it. Frames, when the file has them, are
/// kept in memory.
inline Dataset load_hdf5(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  auto rec = opt.hdf5_check_in_child ? read_hdf5_checked(path, opt.width, opt.height, opt.t_begin, opt.t_end, opt.progress)
                                     : read_hdf5(path, opt.width, opt.height, opt.t_begin, opt.t_end, opt.progress);
  check_sensor_size(rec.width, rec.height, path.string() + " (the sensor size it gives)");
  Dataset d;
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  attach_calibration_and_poses(path, opt, d, rec.width, rec.height, "an HDF5 recording");
  d.events = std::move(rec.events);
  return d;
}

/// Writes a recording as an event_utils/HQF HDF5 file (write_hdf5) with calib.txt and, when there are
/// poses, groundtruth.txt beside it, so that io::load reads it back.
inline void write_hdf5_recording(const std::filesystem::path& path, const Dataset& d) {
  std::vector<double> times = d.frames.t;
  std::vector<Image> frames;
  for (std::size_t f = 0; f < d.frames.size(); ++f) frames.push_back(frame_image(d.frames, f));
  write_hdf5(path, d.events, d.camera.width(), d.camera.height(), times, frames);
  write_calibration_and_poses_beside(path, d);
}

/// The format's line in io::formats(): written for an output ending in .h5 or .hdf5.
inline Format hdf5_format() {
  return {"hdf5",           false,
          kHdf5Description, &is_hdf5,
          &load_hdf5,       [](const std::filesystem::path& p, const Dataset& d, const WriteOptions&) { write_hdf5_recording(p, d); },
          {".h5", ".hdf5"}};
}

}  // namespace evnerf::io
