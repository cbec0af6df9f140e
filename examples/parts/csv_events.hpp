// A file format of your own (examples/custom_parts.cpp): events as comma-separated values, the layout many
// lab scripts and spreadsheets write. A header line names the columns, in any order: t (seconds; or
// timestamp), x, y and p (or polarity: 1 / 0 or 1 / -1); then one event a line. The sensor's size comes from
// --sensor-size or a sensor.txt beside the file ("width height"), the calibration and poses from calib.txt
// and groundtruth.txt beside it (or --calib, --poses), as for any recording held in one file. Registered with
// io::register_format, it is read by inspect, train, eval and convert, chosen by --format csv, and written by
// convert for an output ending in .csv: nothing under include/ changed.
#pragma once
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <tuple>

#include <evnerf/io/dataset.hpp>

namespace mylab {

namespace csv {
namespace fs = std::filesystem;

/// The column of each of t, x, y, p in a header line, or false when the line is not such a header.
inline bool header_columns(std::string_view line, std::array<int, 4>& col) {
  col = {-1, -1, -1, -1};
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  int k = 0;
  for (std::size_t b = 0;; ++k) {
    const std::size_t e = std::min(line.find(',', b), line.size());
    std::string_view name = line.substr(b, e - b);
    while (!name.empty() && name.front() == ' ') name.remove_prefix(1);
    while (!name.empty() && name.back() == ' ') name.remove_suffix(1);
    const int which = name == "t" || name == "timestamp"  ? 0
                      : name == "x"                       ? 1
                      : name == "y"                       ? 2
                      : name == "p" || name == "polarity" ? 3
                                                          : -1;
    if (which < 0 || col[static_cast<std::size_t>(which)] >= 0) return false;
    col[static_cast<std::size_t>(which)] = k;
    if (e == line.size()) break;
    b = e + 1;
  }
  return k == 3 && std::all_of(col.begin(), col.end(), [](int c) { return c >= 0; });
}

/// A file ending in .csv whose first line is such a header.
inline bool detect(const fs::path& p) {
  if (p.extension() != ".csv" || !fs::is_regular_file(p)) return false;
  std::ifstream in(p);
  std::string first;
  std::array<int, 4> col;
  return std::getline(in, first) && header_columns(first, col);
}

inline evnerf::io::Dataset load(const fs::path& p, const evnerf::io::LoadOptions& opt) {
  using evnerf::Error;
  const std::string file = p.string();
  const std::string text = evnerf::read_file(p, opt.progress);
  const fs::path folder = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  int w = opt.width, h = opt.height;
  if (w <= 0 || h <= 0) {
    if (!fs::exists(folder / "sensor.txt"))
      throw Error(file, 0, "the sensor's size is not known: give --sensor-size WxH or a sensor.txt beside the file ('width height')");
    std::tie(w, h) = evnerf::io::parse_sensor_size(evnerf::read_file(folder / "sensor.txt"), (folder / "sensor.txt").string());
  }
  evnerf::io::check_sensor_size(w, h, file + " (the sensor size)");
  evnerf::io::Dataset d;
  d.events.width = w, d.events.height = h;
  std::array<int, 4> col;
  std::size_t pos = 0, line_no = 0;
  double last = -INFINITY;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1, ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line_no == 1) {
      if (!header_columns(line, col)) throw Error(file, 1, "the first line must name the columns t, x, y, p (in any order)");
      continue;
    }
    if (line.empty()) continue;
    std::array<double, 4> v{};  // t, x, y, p
    std::size_t b = 0;
    for (int k = 0; k < 4; ++k) {
      const std::size_t e = std::min(line.find(',', b), line.size());
      if (b > line.size() || (k < 3 && e == line.size()))
        throw Error(file, line_no, "expected 4 comma-separated values, found " + std::to_string(k + 1));
      const char* first = line.data() + b;
      while (first < line.data() + e && *first == ' ') ++first;
      double x = 0;
      const auto r = std::from_chars(first, line.data() + e, x);
      if (r.ec != std::errc() || r.ptr != line.data() + e || !std::isfinite(x))
        throw Error(file, line_no, "value " + std::to_string(k + 1) + " is not a finite number");
      for (int c = 0; c < 4; ++c)
        if (col[static_cast<std::size_t>(c)] == k) v[static_cast<std::size_t>(c)] = x;
      b = e + 1;
    }
    if (b <= line.size()) throw Error(file, line_no, "more than 4 values");
    const auto [t, x, y, pol] = v;
    if (t < last)
      throw Error(file, line_no, "time " + evnerf::short_number(t) + " s goes back (previous " + evnerf::short_number(last) + " s)");
    if (x != std::floor(x) || y != std::floor(y) || x < 0 || y < 0 || x >= w || y >= h)
      throw Error(file, line_no,
                  "pixel (" + evnerf::short_number(x) + ", " + evnerf::short_number(y) + ") is not one of the " + std::to_string(w) + "x" +
                      std::to_string(h) + " sensor's");
    if (pol != 1 && pol != 0 && pol != -1)
      throw Error(file, line_no, "polarity " + evnerf::short_number(pol) + " (expected 1 and 0, or 1 and -1)");
    d.events.push_back(t, static_cast<int>(x), static_cast<int>(y), pol > 0 ? 1 : -1);
    last = t;
  }
  if (d.events.empty()) throw Error(file, 0, "no events");
  evnerf::io::attach_calibration_and_poses(p, opt, d, w, h, "a CSV file of events");
  d.notes.push_back("csv           " + std::to_string(d.events.size()) + " events, " + std::to_string(w) + "x" + std::to_string(h));
  return d;
}

inline void write(const fs::path& p, const evnerf::io::Dataset& d, const evnerf::io::WriteOptions&) {
  std::string out = "t,x,y,p\n";
  char buf[96];
  for (std::size_t i = 0; i < d.events.size(); ++i) {
    const int n =
        std::snprintf(buf, sizeof buf, "%.9f,%d,%d,%d\n", d.events.t[i], d.events.x[i], d.events.y[i], d.events.polarity[i] > 0 ? 1 : 0);
    out.append(buf, static_cast<std::size_t>(n));
  }
  evnerf::write_file_atomic(p, out);
  const fs::path folder = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  evnerf::write_file_atomic(folder / "sensor.txt", std::to_string(d.camera.width()) + " " + std::to_string(d.camera.height()) + "\n");
  evnerf::io::write_calibration_and_poses_beside(p, d);
}
}  // namespace csv

/// The format's entry in the table.
inline evnerf::io::Format csv_format() {
  return {"csv",        false,      "a CSV file of events (a header naming t, x, y, p; sensor.txt and calib.txt beside it)",
          &csv::detect, &csv::load, &csv::write,
          {".csv"}};
}

}  // namespace mylab
