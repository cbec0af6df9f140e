// io/dataset.hpp — the formats evnerf reads and writes, as one table (formats()): an IJRR-layout folder,
// an EventNeRF scene, a Robust e-NeRF sequence, Prophesee .raw (EVT 2.0, 3.0) and .dat files, an event HDF5
// file, a ROS bag, an AEDAT4 file. io::load picks the reader from the content (or LoadOptions::format), io::convert the
// writer from the output's name; --format, inspect, convert and the error texts that list formats come from
// the table. A new format of evnerf's is one header (its reader, `<name>_format()` returning its Format) and
// one line in the table; a format of your own is registered from your own header (register_format), with no
// edit here. Depends on io/.
#pragma once
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "eventnerf.hpp"
#include "ijrr_layout.hpp"
#include "prophesee.hpp"
#include "recording.hpp"
#include "robust_e_nerf.hpp"
#ifdef EVNERF_HAVE_HDF5
#include "hdf5.hpp"
#endif
#ifdef EVNERF_HAVE_ROSBAG
#include "rosbag.hpp"
#endif
#ifdef EVNERF_HAVE_AEDAT4
#include "aedat4.hpp"
#endif

namespace evnerf::io {

namespace detail {
/// The table io::formats() shows: evnerf's formats, then those registered (register_format).
inline std::vector<Format>& format_table() {
  static std::vector<Format> table = {
      ijrr_format(),   eventnerf_format(), robust_e_nerf_format(), evt2_format(), evt3_format(), dat_format(),
#ifdef EVNERF_HAVE_HDF5
      hdf5_format(),
#else
      unavailable_format("hdf5", kHdf5Description, {".h5", ".hdf5"},
                         "this build of evnerf has no HDF5 support (install libhdf5-dev and rebuild)"),
#endif
#ifdef EVNERF_HAVE_ROSBAG
      rosbag_format(),
#else
      unavailable_format("rosbag", kRosbagDescription, {".bag"},
                         "this build of evnerf has no ROS bag support (install libbz2-dev and liblz4-dev and rebuild)"),
#endif
#ifdef EVNERF_HAVE_AEDAT4
      aedat4_format(),
#else
      unavailable_format("aedat4", kAedat4Description, {".aedat4"},
                         "this build of evnerf has no AEDAT4 support (install liblz4-dev and libzstd-dev and rebuild)"),
#endif
  };
  return table;
}
}  // namespace detail

/// The formats, in the order detection tries them (the folder layouts first; a folder that holds none of
/// them is read as IJRR's, whose reader names what is missing), then the formats registered, in the order
/// they were.
inline const std::vector<Format>& formats() { return detail::format_table(); }

/// Adds a format of your own to the table: `io::load`, `convert` and every command (inspect, train, eval,
/// convert, --format NAME) then read it, detected by its `detect` after evnerf's own formats, and write it
/// when it has a writer and extensions (examples/parts/csv_events.hpp). Register before the first read, not
/// while another thread reads. Returns true, so that a header can register at static initialisation
/// (`inline const bool registered = io::register_format(...)`). An Error when the name is taken or the
/// entry has no name, description, detection or reader.
inline bool register_format(Format f) {
  require(f.name && *f.name && f.description && *f.description, "register_format: a format needs a name and a description");
  require(f.detect && f.load, std::string("register_format: format '") + f.name + "' needs `detect` and `load`");
  for (const auto& g : detail::format_table())
    require(std::string_view(g.name) != f.name, std::string("register_format: there is already a format '") + f.name + "'");
  f.unavailable = "";
  detail::format_table().push_back(std::move(f));
  return true;
}

/// The formats' names, as --format takes them.
inline std::vector<std::string> format_names() {
  std::vector<std::string> n;
  for (const auto& f : formats()) n.push_back(f.name);
  return n;
}
/// The names joined by ", ".
inline std::string format_list() {
  std::string s;
  for (const auto& f : formats()) s.append(s.empty() ? "" : ", ").append(f.name);
  return s;
}
/// The format called `name`; an Error naming `where` and every format when there is none.
inline const Format& format_named(const std::string& name, const std::filesystem::path& where) {
  for (const auto& f : formats())
    if (name == f.name) return f;
  throw Error(where.string(), 0, "unknown format '" + name + "' (known: " + format_list() + ")");
}
/// The format of the recording at `path` (LoadOptions::format, else its content); an Error naming the path
/// when it is none of them, a folder holds several layouts, or this build cannot read it.
inline const Format& detect_format(const std::filesystem::path& path, const std::string& format = {}) {
  namespace fs = std::filesystem;
  if (!format.empty()) {
    const Format& f = format_named(format, path);
    if (f.folder != fs::is_directory(path))
      throw Error(path.string(), 0,
                  "format '" + format + "' is " + (f.folder ? "a folder" : "a file") + ", and this is " +
                      (fs::exists(path) ? (f.folder ? "a file" : "a folder") : "missing"));
    if (!f.load) throw Error(path.string(), 0, std::string("format '") + f.name + "': " + f.unavailable);
    return f;
  }
  std::string kinds, missing;
  for (const auto& f : formats()) {
    kinds.append(kinds.empty() ? "" : "; ").append(f.description);
    if (!f.load) missing += std::string(" ") + f.unavailable + ".";
  }
  if (fs::is_directory(path)) {
    std::vector<const Format*> found;
    for (const auto& f : formats())
      if (f.folder && f.detect && f.load && f.detect(path)) found.push_back(&f);
    if (found.size() > 1) {
      std::string list;
      for (const auto* f : found) list.append(list.empty() ? "" : ", ").append(f->name);
      throw Error(path.string(), 0, "the folder holds several layouts (" + list + "): choose one with --format");
    }
    return found.empty() ? formats().front() : *found.front();
  }
  if (!fs::exists(path)) throw Error(path.string(), 0, "no such recording (expected " + kinds + ")");
  for (const auto& f : formats())
    if (!f.folder && f.detect && f.load && f.detect(path)) return f;
  throw Error(path.string(), 0, "not a recording evnerf reads (" + kinds + ")." + missing);
}

/// Loads a recording whatever its format (all its events; io::load applies LoadOptions' time window): the
/// reader is picked from the content, not the name (detect_format).
inline Dataset load_whole(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  return detect_format(path, opt.format).load(path, opt);
}

/// Writes a recording in the format `out`'s name chooses: the file format with the longest extension its
/// name ends in (`.evt2.raw` before `.raw`), else (a folder) the IJRR layout. Returns the format's name.
inline std::string convert(const std::filesystem::path& out, const Dataset& d, const WriteOptions& opt = {}) {
  const std::string name = out.filename().string();
  const Format* best = nullptr;
  std::size_t best_len = 0;
  for (const auto& f : formats())
    for (const auto& ext : f.extensions)
      if (name.size() > ext.size() && name.ends_with(ext) && ext.size() > best_len) best = &f, best_len = ext.size();
  if (best) {
    if (!best->write)
      throw Error(out.string(), 0, std::string("format '") + best->name + "': " + (*best->unavailable ? best->unavailable : "no writer"));
    best->write(out, d, opt);
    return best->name;
  }
  for (const auto& f : formats())
    if (f.folder && f.write) {
      f.write(out, d, opt);
      return f.name;
    }
  throw Error(out.string(), 0, "no format writes this");
}

/// load_whole, then only the events of the time window LoadOptions names (an error when none are left).
inline Dataset load(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  if (!(opt.t_begin < opt.t_end))
    throw Error(path.string(), 0, "time window [" + short_number(opt.t_begin) + ", " + short_number(opt.t_end) + ") s is empty");
  auto d = load_whole(path, opt);
  if (std::isfinite(opt.t_begin) || std::isfinite(opt.t_end)) {
    d.events.keep_time_window(opt.t_begin, opt.t_end);
    if (d.events.empty())
      throw Error(path.string(), 0, "no events in the time window [" + short_number(opt.t_begin) + ", " + short_number(opt.t_end) + ") s");
  }
  return d;
}

}  // namespace evnerf::io
