// The readers of the IJRR text layout (events.txt, calib.txt, groundtruth.txt, images.txt), npy, PNG and
// COLMAP text models; the dataset (the event cache, limits), the format table, the paper's colour geometry;
// the real IJRR chunk where ../shared/data has it.
#include <evnerf/core/rng.hpp>
#include <evnerf/io/colmap.hpp>
#include <evnerf/io/dataset.hpp>
#include <evnerf/io/image_io.hpp>
#include <evnerf/io/inspect.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <set>

#include <omp.h>

#include "common.hpp"
#include "io_helpers.hpp"

using namespace evnerf;
namespace fs = std::filesystem;
using evtest::error_of;
using evtest::temp_dir;
using evtest::write;

TEST_CASE("events.txt: parses t x y p and maps polarity 1/0 to ±1") {
  auto ev = io::parse_events("# comment\n0.5 3 4 1\n\n0.6 0 0 0\n0.6 239 179 1\r\n", "e.txt", 240, 180);
  REQUIRE(ev.size() == 3);
  CHECK(ev.t[0] == 0.5);
  CHECK(ev.x[0] == 3);
  CHECK(ev.y[0] == 4);
  CHECK(ev.polarity[0] == 1);
  CHECK(ev.polarity[1] == -1);
  CHECK(ev.x[2] == 239);
}

TEST_CASE("events.txt: every kind of bad input names the file, the line and what is wrong") {
  auto err = [](const std::string& text) { return error_of([&] { io::parse_events(text, "events.txt", 240, 180); }); };
  CHECK_CONTAINS(err("0.1 1 2 1\n0.2 1 2\n"), "events.txt:2: line is truncated: field 'polarity' is missing");
  CHECK_CONTAINS(err("0.1 1 2 1\nabc 1 2 1\n"), "events.txt:2: field 't' is not a number: 'abc'");
  CHECK_CONTAINS(err("0.1 1.5 2 1\n"), "events.txt:1: field 'x' is not an integer");
  CHECK_CONTAINS(err("0.1 1 2 7\n"), "events.txt:1: unknown polarity code 7");
  CHECK_CONTAINS(err("0.1 240 2 1\n"), "events.txt:1: pixel (240, 2) lies outside the 240x180 sensor");
  CHECK_CONTAINS(err("0.1 1 -1 1\n"), "lies outside");
  CHECK_CONTAINS(err("0.2 1 2 1\n0.1 1 2 1\n"), "events.txt:2: timestamp 0.1 goes back in time (previous 0.2)");
  // Numbers in messages are short: a huge timestamp is not echoed as a 309-digit string.
  const std::string huge = err("1e308 1 2 1\n0.1 1 2 1\n");
  CHECK_CONTAINS(huge, "events.txt:2: timestamp 0.1 goes back in time (previous 1e+308)");
  CHECK(huge.size() < 120);
  CHECK(short_number(1403636581.123456) == "1403636581.12346");
  CHECK(short_number(0.123456789, 4) == "0.1235");
  // A field is echoed at most 40 characters long (a megabyte of digits is not copied into the message).
  const std::string long_field = err("0.1 " + std::string(100000, '7') + "x 2 1\n");
  CHECK_CONTAINS(long_field, "events.txt:1: field 'x' is not an integer: '7777777777777777777777777777777777777777… (100001 characters)'");
  CHECK(long_field.size() < 300);
  const std::string far_pose = error_of([] { io::parse_poses("0 0 0 0 1e100 0 0 1\n", "gt.txt"); });
  CHECK_CONTAINS(far_pose, "quaternion is far from unit length (norm 1e+100)");
  CHECK_CONTAINS(err("nan 1 2 1\n"), "events.txt:1: field 't' is not finite");
  CHECK_CONTAINS(err("inf 1 2 1\n"), "not finite");
  CHECK_CONTAINS(err("0.1 1 2 1 5\n"), "events.txt:1: unexpected extra field '5'");
  CHECK_CONTAINS(err("# only a comment\n"), "events.txt:0: no events in file");
  CHECK_CONTAINS(err(""), "no events");
  CHECK_CONTAINS(error_of([] { io::read_events_txt("/nonexistent/events.txt", 240, 180); }), "/nonexistent/events.txt:0: cannot open file");
}

namespace {
/// A few MB of valid events.txt in every line shape the fast scanner handles: fixed, long (17-digit) and
/// exponent timestamps, tabs and runs of spaces, CRLF, -1 polarity, comments and blank lines.
std::string varied_events_text(std::size_t lines, std::uint64_t seed) {
  Rng rng(seed);
  std::string s = "# t x y p\n";
  char buf[96];
  std::uint64_t us = 0;  // times on a microsecond grid, so every format below prints a value in order
  for (std::size_t i = 0; i < lines; ++i) {
    us += 1 + rng.below(100);
    const double t = static_cast<double>(us) * 1e-6;
    const int x = static_cast<int>(rng.below(240)), y = static_cast<int>(rng.below(180));
    const char* fmt[] = {"%.9f %d %d %d\n", "%.17g %d %d %d\n", "%.6e\t%d\t%d  %d \r\n", "%.6f %03d %d %d\n"};
    const int f = static_cast<int>(rng.below(4));
    const int p = rng.below(2) ? 1 : (rng.below(2) ? 0 : -1);
    std::snprintf(buf, sizeof buf, fmt[f], t, x, y, p);
    s += buf;
    if (rng.below(1000) == 0) s += rng.below(2) ? "\n" : "# a comment\n";
  }
  return s;
}
}  // namespace

TEST_CASE("events.txt: the threaded fast scanner equals the reference parser bit for bit") {
  const int saved = thread_count();
  const std::string text = varied_events_text(120000, 7);  // ~3.5 MB: two pieces on two threads
  const char* b = text.data();
  io::detail::EventChunk whole;
  REQUIRE(io::detail::fast_parse_chunk(b, b + text.size(), 240, 180, whole));  // the fast path really runs
  const auto ref = io::parse_events_reference(text, "e.txt", 240, 180);
  for (int threads : {1, 2, 3}) {
    set_thread_count(threads);
    const auto ev = io::parse_events(text, "e.txt", 240, 180);
    REQUIRE(ev.size() == ref.size());
    CHECK(ev.t == ref.t);
    CHECK(ev.x == ref.x);
    CHECK(ev.y == ref.y);
    CHECK(ev.polarity == ref.polarity);
  }
  // An error deep in the second piece, and one that only shows across the cut between pieces, still name
  // the right line.
  set_thread_count(2);
  std::string bad = text;
  const std::size_t line = static_cast<std::size_t>(std::count(bad.begin(), bad.end(), '\n')) - 10;
  std::size_t pos = 0;
  for (std::size_t i = 0; i < line; ++i) pos = bad.find('\n', pos) + 1;
  bad.insert(pos, "99.0 1 2 9\n");
  CHECK_CONTAINS(error_of([&] { io::parse_events(bad, "e.txt", 240, 180); }),
                 "e.txt:" + std::to_string(line + 1) + ": unknown polarity code 9");
  std::string back = text;
  const std::size_t mid = back.find('\n', back.size() / 2) + 1;
  const std::size_t mid_line = static_cast<std::size_t>(std::count(back.begin(), back.begin() + static_cast<std::ptrdiff_t>(mid), '\n'));
  back.insert(mid, "0.0 1 2 1\n");
  CHECK_CONTAINS(error_of([&] { io::parse_events(back, "e.txt", 240, 180); }),
                 "e.txt:" + std::to_string(mid_line + 1) + ": timestamp 0 goes back in time");
  set_thread_count(saved);
}

TEST_CASE("events.txt: numbers the scanner leaves to from_chars, and cut last lines, parse exactly as the reference does") {
  WarningCollector quiet;  // the cut lines warn
  for (const char* text : {"1. 1 2 1\n", ".5 1 2 1\n", "12345678901234567890.5 1 2 1\n", "-0.5 1 2 1\n", "0.1234567890123456789 1 2 1\n",
                           "5e-1 1 2 1\n", "0.5 1 2 1\r\n  \n", "0.5,1,2,1\n",
                           // a cut last line: dropped by both, after an event and after only a comment
                           "0.5 1 2 1\n0.6 1", "# t x y p\r\n0.0EEE 5 7 : value"}) {
    CAPTURE(text);
    auto outcome = [&](auto parse) {
      try {
        const auto ev = parse(text, "e.txt", 240, 180);
        char buf[64];
        std::snprintf(buf, sizeof buf, "%zu events, t0 = %a, x0 = %d", ev.size(), ev.t[0], int(ev.x[0]));
        return std::string(buf);
      } catch (const Error& e) {
        return std::string(e.what());
      }
    };
    CHECK(outcome([](auto... a) { return io::parse_events(a...); }) == outcome([](auto... a) { return io::parse_events_reference(a...); }));
  }
}

TEST_CASE("calib.txt, groundtruth.txt and images.txt: parsing and bad input") {
  auto cam = io::parse_calib("335.4 335.3 129.9 99.1 -0.13 0.09 -0.0003 0.0001 0.0\n", "calib.txt", 240, 180);
  CHECK(cam.fx() == doctest::Approx(335.4));
  CHECK(cam.distortion()[0] == doctest::Approx(-0.13));
  CHECK(io::parse_calib("200 200 120 90\n", "calib.txt", 240, 180).distorted() == false);
  CHECK_CONTAINS(error_of([] { io::parse_calib("200 200 120 90 0.1\n", "calib.txt", 240, 180); }),
                 "calib.txt:1: calibration needs 4, 8 or 9 numbers (fx fy cx cy [k1 k2 p1 p2 [k3]]), found 5");
  CHECK_CONTAINS(error_of([] { io::parse_calib("", "calib.txt", 240, 180); }), "calibration file is empty");
  CHECK_CONTAINS(error_of([] { io::parse_calib("-1 200 120 90\n", "calib.txt", 240, 180); }), "focal lengths must be positive");

  auto tr = io::parse_poses("0.1 1 2 3 0 0 0 1\n0.2 1 2 3 0 0 0.7071068 0.7071068\n", "gt.txt");
  CHECK(tr.size() == 2);
  CHECK(tr.poses()[1].q.z() == doctest::Approx(0.7071068));
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0\n", "gt.txt"); }), "gt.txt:1: line is truncated: field 'qw' is missing");
  // Found by tests/fuzz (fuzz_colmap): a zero quaternion in images.txt gave a NaN pose.
  CHECK_CONTAINS(error_of([] { io::parse_colmap_images("1 0 0 0 0 7 3.2 1 1 a.png\n\n", "images.txt"); }),
                 "images.txt:1: quaternion is far from unit length (norm 0)");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1\n", "gt.txt"); }),
                 "gt.txt:2: pose timestamps must increase strictly");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0 0\n", "gt.txt"); }), "gt.txt:1: quaternion is far from unit length");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 nan 0 0 0 1\n", "gt.txt"); }), "'pz' is not finite");

  auto fr = io::parse_frames("0.0 images/a.png\n0.1 images/b c.png\n", "images.txt", "/data");
  REQUIRE(fr.size() == 2);
  CHECK(fr.paths[1] == fs::path("/data/images/b c.png"));
  CHECK_CONTAINS(error_of([] { io::parse_frames("0.0\n", "images.txt", "/d"); }),
                 "images.txt:1: line is truncated: field 'image path' is missing");
}

TEST_CASE("npy: round trip, atomic write, and corrupt files are reported") {
  const auto dir = temp_dir("npy");
  std::vector<float> v{1.f, 2.5f, -3.f, 4.f, 5.f, 6.f};
  io::save_npy(dir / "a.npy", v.data(), {2, 3});
  auto back = io::load_npy<float>(dir / "a.npy");
  CHECK(back.shape == std::vector<std::size_t>{2, 3});
  CHECK(back.data == v);
  CHECK_CONTAINS(error_of([&] { io::load_npy<double>(dir / "a.npy"); }), "a.npy:0: cannot read .npy");
  // Truncate the file.
  const std::string bytes = read_file(dir / "a.npy");
  write(dir / "b.npy", bytes.substr(0, bytes.size() - 5));
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "b.npy"); }), "b.npy");
  write(dir / "c.npy", "not an npy file at all");
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "c.npy"); }), "c.npy:0: cannot read .npy: not a .npy file");
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "missing.npy"); }), "missing.npy:0: cannot open file");
  write(dir / "d.npy", bytes + "junk");
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "d.npy"); }), "d.npy:0: corrupt or truncated .npy");
  // A format-2.0 header (4-byte length), as NumPy writes for very wide headers, and a big-endian file.
  auto npy = [](int major, const std::string& dict, const std::string& payload) {
    std::string h = "{" + dict + "}";
    const std::size_t pre = 6 + 2 + (major == 1 ? 2 : 4);
    while ((pre + h.size() + 1) % 16) h += ' ';
    h += '\n';
    std::string f = "\x93NUMPY";
    f += char(major);
    f += char(0);
    for (std::size_t i = 0; i < (major == 1 ? 2u : 4u); ++i) f += char((h.size() >> (8 * i)) & 0xff);
    return f + h + payload;
  };
  const std::string two(reinterpret_cast<const char*>(v.data()), 2 * sizeof(float));
  write(dir / "e.npy", npy(2, "'descr': '<f4', 'fortran_order': False, 'shape': (2,), ", two));
  CHECK(io::load_npy<float>(dir / "e.npy").data == std::vector<float>{1.f, 2.5f});
  write(dir / "f.npy", npy(1, "'descr': '>f4', 'fortran_order': False, 'shape': (2,), ", two));
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "f.npy"); }), "element type is '>f4', expected '<f4'");
  // A shape whose product overflows is refused before allocating (the payload's size check would otherwise
  // compare against a wrapped product); so are 33 dimensions. In memory (parse_npy) as from a file.
  const std::string huge = npy(1, "'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296, 2), ", "");
  CHECK_CONTAINS(error_of([&] { io::parse_npy<float>(huge, "g.npy"); }),
                 "g.npy:0: cannot read .npy: shape '(4294967296, 4294967296, 2)' is too large");
  write(dir / "g.npy", huge);
  CHECK_CONTAINS(error_of([&] { io::load_npy<float>(dir / "g.npy"); }), "is too large to address");
  std::string dims = "(";
  for (int i = 0; i < 33; ++i) dims += "1, ";
  CHECK_CONTAINS(error_of([&] { io::parse_npy<float>(npy(1, "'descr': '<f4', 'shape': " + dims + "), ", "\1\1\1\1"), "h.npy"); }),
                 "has more than 32 dimensions");
  CHECK(io::parse_npy<float>(npy(1, "'descr': '<f4', 'fortran_order': False, 'shape': (2,), ", two), "e.npy").data ==
        std::vector<float>{1.f, 2.5f});
  CHECK_CONTAINS(error_of([&] { io::parse_npy<float>(bytes + "x", "i.npy"); }), "i.npy:0: corrupt or truncated .npy");
  CHECK_CONTAINS(error_of([&] { io::parse_npy<float>(bytes.substr(0, 9), "j.npy"); }), "j.npy:0: cannot read .npy: not a .npy file");
  for (auto& e : fs::directory_iterator(dir)) CHECK(e.path().string().find(".tmp.") == std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("dataset: a folder loads, the event cache is used on the second load and survives corruption") {
  const auto dir = temp_dir("ds");
  write(dir / "events.txt", "0.10 1 2 1\n0.11 3 4 0\n0.12 5 6 1\n");
  write(dir / "calib.txt", "100 100 16 12\n");
  write(dir / "sensor.txt", "32 24\n");
  write(dir / "groundtruth.txt", "0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n");
  io::LoadOptions opt;
  opt.cache_root = dir / "cache";
  auto a = io::load_ijrr(dir, opt);
  CHECK_FALSE(a.from_cache);
  CHECK(a.camera.width() == 32);
  auto b = io::load_ijrr(dir, opt);
  CHECK(b.from_cache);
  CHECK(b.events.t == a.events.t);
  CHECK(b.events.polarity == a.events.polarity);
  // Corrupt the cache: the loader must fall back to the text file, not return garbage.
  for (auto& e : fs::recursive_directory_iterator(dir / "cache"))
    if (e.path().filename() == "t.npy") write(e.path(), "garbage");
  auto c = io::load_ijrr(dir, opt);
  CHECK_FALSE(c.from_cache);
  CHECK(c.events.t == a.events.t);
  CHECK_CONTAINS(error_of([&] { io::load_ijrr(dir / "missing", opt); }), "not a folder");
  fs::remove(dir / "calib.txt");
  CHECK_CONTAINS(error_of([&] { io::load_ijrr(dir, opt); }), "calib.txt:0: cannot open file");
  fs::remove_all(dir);
}

TEST_CASE("the format table: one name each, --format's list, every writer's output is detected as its format and reads back equal") {
  std::set<std::string> names;
  for (const auto& f : io::formats()) {
    CAPTURE(f.name);
    CHECK(names.insert(f.name).second);
    CHECK(std::string(f.description).size() > 10);
    CHECK((f.load != nullptr) == (f.detect != nullptr));                 // a reader is found by its content
    CHECK((f.load != nullptr) == (std::string(f.unavailable).empty()));  // or the build says why not
  }
  CHECK(io::format_names().size() == names.size());
  CHECK(io::format_list() == "ijrr, eventnerf, robust-e-nerf, evt2, evt3, dat, hdf5, rosbag, aedat4");
  const auto dir = temp_dir("formats");
  fs::create_directories(dir / "rec");
  write(dir / "rec" / "events.txt", "0.10 1 2 1\n0.11 3 4 0\n0.12 5 6 1\n");
  write(dir / "rec" / "calib.txt", "100 100 16 12\n");
  write(dir / "rec" / "sensor.txt", "32 24\n");
  write(dir / "rec" / "groundtruth.txt", "0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n");
  io::LoadOptions opt;
  opt.use_cache = false;
  const auto d = io::load(dir / "rec", opt);
  CHECK(std::string(io::detect_format(dir / "rec").name) == "ijrr");
  int written = 0;
  for (const auto& f : io::formats()) {
    if (!f.write) continue;
    CAPTURE(f.name);
    const fs::path out = dir / (std::string("out_") + f.name + (f.extensions.empty() ? "" : f.extensions.front()));
    CHECK(io::convert(out, d) == f.name);
    CHECK(std::string(io::detect_format(out).name) == f.name);
    const auto back = io::load(out, opt);
    CHECK(back.events.t == d.events.t);
    CHECK(back.events.x == d.events.x);
    CHECK(back.events.polarity == d.events.polarity);
    ++written;
  }
  CHECK(written >= 1);
  CHECK_CONTAINS(error_of([&] { io::detect_format(dir / "rec", "bag"); }),
                 "unknown format 'bag' (known: ijrr, eventnerf, robust-e-nerf, evt2, evt3, dat, hdf5, rosbag, aedat4)");
  // A format of the user's own (tests/parts.sh registers one end to end) must bring a new name, a detection
  // and a reader; a refused one leaves the table as it was.
  io::Format mine = io::formats()[3];
  CHECK_CONTAINS(error_of([&] { io::register_format(mine); }), "register_format: there is already a format 'evt2'");
  mine.name = "mine";
  mine.load = nullptr;
  CHECK_CONTAINS(error_of([&] { io::register_format(mine); }), "register_format: format 'mine' needs `detect` and `load`");
  mine.name = "";
  CHECK_CONTAINS(error_of([&] { io::register_format(mine); }), "a format needs a name and a description");
  CHECK(io::format_names().size() == names.size());
  fs::remove_all(dir);
}

/// An IJRR folder of `n` events on a 32 × 24 sensor, 10 µs apart, read back (no cache): the recording the
/// whole-file tests write in every format.
static io::Dataset many_events_folder(const fs::path& folder, int n) {
  fs::create_directories(folder);
  std::string text;
  for (int k = 0; k < n; ++k)
    text += std::to_string(0.1 + 1e-5 * k).substr(0, 9) + " " + std::to_string(k % 32) + " " + std::to_string(k % 24) +
            (k % 3 ? " 1\n" : " 0\n");
  write(folder / "events.txt", text);
  write(folder / "calib.txt", "100 100 16 12\n");
  write(folder / "sensor.txt", "32 24\n");
  io::LoadOptions plain;
  plain.use_cache = false;
  return io::load(folder, plain);
}

TEST_CASE("a whole-file read reports its progress: monotonic, in the file's bytes, to the end") {
  // 150 000 events: several of the Prophesee reader's 64 KiB blocks, of AEDAT4's packets and of a bag's chunks.
  const auto dir = temp_dir("progress");
  io::LoadOptions plain;
  plain.use_cache = false;
  const auto d = many_events_folder(dir / "rec", 150000);
  // The readers that report (those evnerf also writes: Prophesee DAT reports through the same block reader
  // as EVT 2.0 and 3.0; HDF5 through its read in a child process and its own), and the file whose bytes they count.
  const std::set<std::string> reporting = {"ijrr", "evt2", "evt3", "rosbag", "aedat4", "hdf5"};
  int checked = 0;
  for (const auto& f : io::formats()) {
    const std::string name = f.name;
    if (!reporting.count(name) || !f.load) continue;
    CAPTURE(name);
    fs::path out = dir / "rec", counted = dir / "rec" / "events.txt";
    if (name != "ijrr") {
      out = counted = dir / ("out_" + name + (f.extensions.empty() ? "" : f.extensions.front()));
      const bool writes = f.write != nullptr;
      REQUIRE(writes);
      io::convert(out, d);
    }
    std::vector<std::pair<std::uint64_t, std::uint64_t>> calls;
    io::LoadOptions opt = plain;
    opt.progress = [&](std::uint64_t done, std::uint64_t total) { calls.emplace_back(done, total); };
    const auto back = io::load(out, opt);
    CHECK(back.events.size() == d.events.size());
    REQUIRE(!calls.empty());
    const std::uint64_t size = fs::file_size(counted);
    bool monotonic = true, totals = true;
    for (std::size_t k = 0; k < calls.size(); ++k) {
      monotonic = monotonic && calls[k].first <= calls[k].second && (k == 0 || calls[k].first >= calls[k - 1].first);
      totals = totals && calls[k].second == size;
    }
    CHECK(monotonic);
    CHECK(totals);
    // The last report is at the end of the data read: the file's end, or (AEDAT4) its last packet's, before the table.
    CHECK(calls.back().first > size * 9 / 10);
    if (name != "ijrr") CHECK(calls.size() >= 3);
    // A progress function that throws abandons the read with its error.
    opt.progress = [](std::uint64_t done, std::uint64_t) {
      if (done > 0) throw Error("stopped by the caller");
    };
    CHECK_CONTAINS(error_of([&] { io::load(out, opt); }), "stopped by the caller");
    ++checked;
  }
  CHECK(checked >= 4);
  fs::remove_all(dir);
}

TEST_CASE("a recording cut short (a camera that lost power) reads to its last whole event, with one warning naming where") {
  // 200 000 events: several of each writer's packets, chunks (a bag's are 768 KiB) and blocks, so that a cut
  // in the middle leaves some whole.
  const auto dir = temp_dir("cut");
  io::LoadOptions opt;
  opt.use_cache = false;
  const auto d = many_events_folder(dir / "rec", 200000);
  // The formats a camera or a recorder writes as it goes; the others (HDF5, the EventNeRF and Robust e-NeRF
  // layouts) are written whole by a script, and a file of them cut short is refused.
  const std::set<std::string> streamed = {"ijrr", "evt2", "evt3", "rosbag", "aedat4"};
  int checked = 0;
  for (const auto& f : io::formats()) {
    const std::string name = f.name;
    if (!streamed.count(name) || !f.load) continue;
    CAPTURE(name);
    fs::path whole = dir / "rec" / "events.txt";
    if (name != "ijrr") {
      whole = dir / ("whole_" + name + (f.extensions.empty() ? "" : f.extensions.front()));
      io::convert(whole, d);
    }
    const std::string bytes = read_file(whole);
    int warned = 0;
    for (const std::size_t cut : {bytes.size() / 2 + 1, bytes.size() * 9 / 10 + 3, bytes.size() - 3}) {
      CAPTURE(cut);
      // Beside the whole file (its calib.txt serves both), or a folder of its own for IJRR's layout.
      fs::path in = dir / ("cut_" + whole.filename().string()), file = in;
      if (name == "ijrr") {
        fs::create_directories(dir / "cut");
        fs::copy_file(dir / "rec" / "calib.txt", dir / "cut" / "calib.txt", fs::copy_options::overwrite_existing);
        fs::copy_file(dir / "rec" / "sensor.txt", dir / "cut" / "sensor.txt", fs::copy_options::overwrite_existing);
        in = dir / "cut", file = in / "events.txt";
      }
      write(file, bytes.substr(0, cut));
      WarningCollector said;
      const auto back = io::load(in, opt);
      // The events read are the whole file's first ones; a cut in the middle loses the rest.
      REQUIRE(back.events.size() <= d.events.size());
      const auto n = static_cast<std::ptrdiff_t>(back.events.size());
      CHECK(n > 0);
      CHECK(std::equal(back.events.t.begin(), back.events.t.end(), d.events.t.begin()));
      CHECK(std::equal(back.events.x.begin(), back.events.x.end(), d.events.x.begin()));
      CHECK(std::equal(back.events.y.begin(), back.events.y.end(), d.events.y.begin()));
      CHECK(std::equal(back.events.polarity.begin(), back.events.polarity.end(), d.events.polarity.begin()));
      if (cut < bytes.size() * 3 / 4) CHECK(back.events.size() < d.events.size());
      // At most one warning; it names the file, a place in it and what was dropped.
      REQUIRE(said.messages().size() <= 1);
      for (const auto& m : said.messages()) {
        CHECK_CONTAINS(m, file.string() + ":");
        CHECK_CONTAINS(m, "(a recording cut short)");
        CHECK_CONTAINS(m, " dropped");
        ++warned;
      }
    }
    // The cut in the middle falls inside a word, line, packet or record of every one of these writers.
    CHECK(warned >= 1);
    ++checked;
  }
  CHECK(checked == static_cast<int>(streamed.size()));
  // A cut middle line stays an error: only the last line may end early.
  CHECK_CONTAINS(error_of([] { io::parse_events("0.1 1 2 1\n0.2 1 2\n0.3 1 2 1", "e.txt", 8, 8); }), "e.txt:2: line is truncated");
  {
    WarningCollector said;
    CHECK(io::parse_events("0.1 1 2 1\n0.2 1 2 0", "e.txt", 8, 8).size() == 2);  // a whole last line without a line break
    CHECK(io::parse_events("0.1 1 2 1\n# a comment", "e.txt", 8, 8).size() == 1);
    CHECK(said.messages().empty());
    CHECK(io::parse_events("0.1 1 2 1\n0.2 1 2", "e.txt", 8, 8).size() == 1);
    REQUIRE(said.messages().size() == 1);
    CHECK(said.messages()[0] ==
          "e.txt:2: the file ends inside this line (a recording cut short); read to the line before, 7 bytes dropped");
  }
  // A whole last line with a wrong value is an error, not a cut.
  CHECK_CONTAINS(error_of([] { io::parse_events("0.1 1 2 1\n0.2 1 2 7", "e.txt", 8, 8); }), "e.txt:2: unknown polarity code 7");
  fs::remove_all(dir);
}

#ifdef EVNERF_HAVE_AEDAT4
TEST_CASE("AEDAT4: a file of many packets reads the same on one or two threads, whole, through windows and packet by packet") {
  // 300 000 events: 74 of the writer's packets of 4096, several of the reader's batches of 32.
  const auto dir = temp_dir("aedat4_batches");
  fs::create_directories(dir);
  constexpr int kN = 300000;
  io::Dataset d;
  d.camera = geometry::Camera(64, 48, 50, 50, 32, 24);
  d.events.width = 64, d.events.height = 48;
  auto us_of = [](int k) { return 200000 + 10 * std::int64_t(k); };
  for (int k = 0; k < kN; ++k) d.events.push_back(static_cast<double>(us_of(k)) / 1e6, k % 64, (k / 64) % 48, k % 3 ? 1 : -1);
  io::Aedat4Info info;
  io::Frames frames;
  std::int64_t origin = 0;
  auto read = [&](const fs::path& f, io::LoadOptions o = {}) { return io::read_aedat4(f, o, info, frames, origin); };
  auto same = [](const events::EventStream& a, const events::EventStream& b) {
    return a.t == b.t && a.x == b.x && a.y == b.y && a.polarity == b.polarity;
  };
  const int threads_before = omp_get_max_threads();
  for (const std::string c : {"lz4", "none"}) {
    CAPTURE(c);
    const auto f = dir / ("many_" + c + ".aedat4");
    io::write_aedat4(f, d, c);
    omp_set_num_threads(1);
    const auto one = read(f);
    omp_set_num_threads(2);
    const auto two = read(f);
    CHECK(same(one, d.events));
    CHECK(same(two, d.events));
    CHECK(info.events == std::size_t(kN));
    CHECK(info.packets == std::size_t((kN + 4095) / 4096));
    // Windows: exactly the whole read's events in [t0, t1), the packets outside skipped through the table.
    for (const auto& window : std::vector<std::pair<double, double>>{{0.5, 1.7}, {2.0, 2.3}, {0.0, 0.21}, {3.1, 9.0}}) {
      const double t0 = window.first, t1 = window.second;  // not a structured binding: CAPTURE's lambda takes it
      CAPTURE(t0);
      io::LoadOptions o;
      o.t_begin = t0, o.t_end = t1;
      events::EventStream want;
      want.width = 64, want.height = 48;
      for (std::size_t k = 0; k < d.events.size(); ++k)
        if (d.events.t[k] >= t0 && d.events.t[k] < t1) want.push_back(d.events.t[k], d.events.x[k], d.events.y[k], d.events.polarity[k]);
      CHECK(same(read(f, o), want));
      if (t0 > 0.3) CHECK(info.packets_skipped > 0);
    }
    // Every packet larger than a batch allows: each decompressed alone, the same events.
    const auto limit = io::detail::aedat4_slot_body;
    io::detail::aedat4_slot_body = 1000;
    CHECK(same(read(f), d.events));
    io::detail::aedat4_slot_body = limit;
  }
  // Bad events deep in the file: the first in file order is named, on any thread count; a window that ends
  // before them reads.
  const auto clean = dir / "many_none.aedat4";
  std::string bytes;
  {
    std::ifstream in(clean, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto event_at = [&](int k) {  // the 16-byte Event of event k in the uncompressed file
    char e[12];
    const std::int64_t us = us_of(k);
    const std::int16_t x = static_cast<std::int16_t>(k % 64), y = static_cast<std::int16_t>((k / 64) % 48);
    std::memcpy(e, &us, 8), std::memcpy(e + 8, &x, 2), std::memcpy(e + 10, &y, 2);
    const auto at = bytes.find(std::string(e, 12));
    REQUIRE(at != std::string::npos);
    return at;
  };
  auto corrupt = [&](const std::string& name, const std::vector<std::pair<int, std::int64_t>>& times, int off_sensor) {
    std::string b = bytes;
    for (const auto& [k, us] : times) std::memcpy(&b[event_at(k)], &us, 8);
    if (off_sensor >= 0) {
      const std::int16_t x = 64;
      std::memcpy(&b[event_at(off_sensor) + 8], &x, 2);
    }
    write(dir / name, b);
    return dir / name;
  };
  // Event 200 000 is event 3392 of packet 48, off the sensor; event 250 000 (packet 61) runs backwards.
  const auto both = corrupt("both.aedat4", {{250000, 0}}, 200000);
  for (int threads : {1, 2}) {
    omp_set_num_threads(threads);
    CHECK_CONTAINS(error_of([&] { read(both); }), "(packet of stream 0): event 3392 at x 64, y 5 outside the 64x48 sensor");
  }
  io::LoadOptions early;
  early.t_begin = 0.3, early.t_end = 1.0;
  CHECK(read(both, early).size() == std::size_t(70000));
  // The first event of packet 61 before the last of packet 60: named as its packet's event 0.
  const auto across = corrupt("across.aedat4", {{61 * 4096, us_of(61 * 4096 - 5)}}, -1);
  CHECK_CONTAINS(error_of([&] { read(across); }), "(packet of stream 0): event 0: time runs backwards (" +
                                                      std::to_string(us_of(61 * 4096 - 5)) + " µs after " +
                                                      std::to_string(us_of(61 * 4096 - 1)) + " µs)");
  // Within a packet, after the batch's first.
  const auto within = corrupt("within.aedat4", {{40 * 4096 + 7, us_of(40 * 4096 + 5)}}, -1);
  CHECK_CONTAINS(error_of([&] { read(within); }), "event 7: time runs backwards");
  // Times further apart than int64 microseconds hold (a fuzzer's input): refused, not wrapped.
  const auto far = corrupt("far.aedat4", {{0, -4899916394580000000}, {kN - 1, 6557241057451452165}}, -1);
  CHECK_CONTAINS(error_of([&] { read(far); }), "µs is out of range from the first event's second (-4899916394580000000 µs)");
  omp_set_num_threads(threads_before);
  fs::remove_all(dir);
}
#endif

TEST_CASE("EVT 3.0: a whole file decoded in parallel parts gives the serial read's events, counts and errors") {
  // Words of the test's own: time-high words across two 24-bit wraps, time-low and row words, single events,
  // vector bases with VECT_12 and VECT_8 masks (some runs of them longer than a part), triggers and words of
  // the types evnerf skips, and events before the first time high and row (which have no time or row, and
  // are dropped). `want` holds the events a reader must give.
  const auto dir = temp_dir("evt3_parts");
  fs::create_directories(dir);
  std::vector<std::uint16_t> words;
  events::EventStream want;
  want.width = 640, want.height = 480;
  std::mt19937 rng(7);
  auto u = [&](unsigned n) { return static_cast<unsigned>(rng() % n); };
  words.push_back(0x2000 | 5);  // no time high and no row yet
  words.push_back(0x8000 | 3);  // a time high, still no row
  words.push_back(0x3000 | 10), words.push_back(0x4000 | 0x0F0);
  std::size_t triggers = 0, other = 0;
  std::int64_t us = 3 << 12, high = 3;
  for (int g = 0; g < 30000; ++g) {
    us += u(4) == 0 ? u(18000) : u(40);
    for (; high != us >> 12; words.push_back(static_cast<std::uint16_t>(0x8000 | (high & 0xFFF))))
      high = std::min(us >> 12, high + 0x7FF);  // steps of under half the 12-bit range
    words.push_back(static_cast<std::uint16_t>(0x6000 | (us & 0xFFF)));
    const unsigned y = u(480);
    words.push_back(static_cast<std::uint16_t>(y));
    if (u(3) == 0) {
      const unsigned x = u(640), on = u(2);
      words.push_back(static_cast<std::uint16_t>(0x2000 | on << 11 | x));
      want.push_back(static_cast<double>(us) / 1e6, static_cast<int>(x), static_cast<int>(y), on ? 1 : -1);
    } else {
      const bool run = u(20) == 0;  // a run of vector words longer than a part of the smallest blocks
      unsigned base = run ? u(40) : u(560);
      const unsigned on = u(2);
      words.push_back(static_cast<std::uint16_t>(0x3000 | on << 11 | base));
      for (unsigned v = run ? 48 : 1 + u(4); v--;) {
        const bool twelve = u(2) != 0;
        const unsigned len = twelve ? 12 : 8, mask = u(1u << len);
        words.push_back(static_cast<std::uint16_t>((twelve ? 0x4000 : 0x5000) | mask));
        for (unsigned b = 0; b < len; ++b)
          if (mask >> b & 1) want.push_back(static_cast<double>(us) / 1e6, static_cast<int>(base + b), static_cast<int>(y), on ? 1 : -1);
        base += len;
      }
    }
    if (u(50) == 0) words.push_back(static_cast<std::uint16_t>(0xA000 | u(4096))), ++triggers;
    if (u(70) == 0) {  // a word of a type evnerf skips: 1, 7, 9, 11–15
      const unsigned kinds[] = {0x1, 0x7, 0x9, 0xB, 0xC, 0xD, 0xE, 0xF};
      words.push_back(static_cast<std::uint16_t>(kinds[u(8)] << 12 | u(4096))), ++other;
    }
  }
  REQUIRE(us > 2 * (std::int64_t(1) << 24));  // two wraps
  auto write_words = [&](const std::string& name, const std::vector<std::uint16_t>& w) {
    std::string b = "% evt 3.0\n% format EVT3;height=480;width=640\n% end\n";
    for (const auto v : w) b.push_back(static_cast<char>(v & 0xFF)), b.push_back(static_cast<char>(v >> 8));
    write(dir / name, b);
    return dir / name;
  };
  auto same = [](const events::EventStream& a, const events::EventStream& b) {
    return a.t == b.t && a.x == b.x && a.y == b.y && a.polarity == b.polarity;
  };
  io::PropheseeInfo info;
  const auto clean = write_words("clean.raw", words);
  const int threads_before = omp_get_max_threads();
  const auto block = io::detail::evt3_parallel_words;
  io::detail::evt3_blocks_redone = 0;
  for (const std::size_t b : {block, std::size_t(997), std::size_t(64)}) {  // the default block, then many small ones
    CAPTURE(b);
    io::detail::evt3_parallel_words = b;
    for (int threads : {1, 2, 3}) {
      CAPTURE(threads);
      omp_set_num_threads(threads);
      info = {};
      CHECK(same(io::read_prophesee_events(clean, {}, info), want));
      CHECK(info.events == want.size());
      CHECK(info.triggers == triggers);
      CHECK(info.other_words == other);
      CHECK(io::detail::evt3_blocks_redone == 0);  // no block of a clean file is decoded twice
    }
    for (int parts : {5, 64}) {  // more parts than threads: one thread decodes several, in order
      CAPTURE(parts);
      io::detail::evt3_parallel_parts = parts;
      for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        info = {};
        CHECK(same(io::read_prophesee_events(clean, {}, info), want));
        CHECK(info.triggers == triggers);
        CHECK(io::detail::evt3_blocks_redone == 0);
      }
      io::detail::evt3_parallel_parts = 0;
    }
  }
  // Bad words deep in the file: every thread count and block size names the same byte (the serial read's).
  auto bad_at = [&](const std::string& name, std::size_t at, std::vector<std::uint16_t> insert) {
    auto w = words;
    w.insert(w.begin() + static_cast<std::ptrdiff_t>(at), insert.begin(), insert.end());
    return write_words(name, w);
  };
  const std::size_t n = words.size();
  // A time-high word before the last one's (less than half the range back), an event off the sensor, and a
  // time-low word that takes the time back, each followed by an event.
  std::uint16_t last_high = 0;
  for (std::size_t k = 0; k < n * 6 / 10; ++k)
    if (words[k] >> 12 == 8) last_high = words[k];
  const std::vector<std::pair<fs::path, std::string>> bad = {
      {bad_at("high_back.raw", n * 6 / 10, {static_cast<std::uint16_t>(0x8000 | ((last_high - 5) & 0xFFF))}),
       "EVT_TIME_HIGH runs backwards"},
      {bad_at("off_sensor.raw", n * 7 / 10, {0x2000 | 700}), "event at x 700"},
      {bad_at("time_back.raw", n * 8 / 10, {0x6000, 0x2000 | 1, 0x6FFF, 0x2000 | 2}), "time runs backwards"},
  };
  for (const auto& entry : bad) {
    const fs::path file = entry.first;  // not a structured binding: clang's lambdas below cannot capture one
    const std::string& what = entry.second;
    const std::string f = file.filename().string();
    CAPTURE(f);
    io::detail::evt3_parallel_words = block;
    omp_set_num_threads(1);
    const std::string serial = error_of([&] { io::read_prophesee_events(file, {}, info); });
    CHECK_CONTAINS(serial, what);
    for (const std::size_t b : {block, std::size_t(997), std::size_t(64)}) {
      io::detail::evt3_parallel_words = b;
      omp_set_num_threads(2);
      io::detail::evt3_blocks_redone = 0;
      CHECK(error_of([&] { io::read_prophesee_events(file, {}, info); }) == serial);
      CHECK(io::detail::evt3_blocks_redone == 1);  // the block of the bad word, decoded again serially
    }
  }
  io::detail::evt3_parallel_words = block;
  omp_set_num_threads(threads_before);
  fs::remove_all(dir);
}

TEST_CASE("EVT 3.0: runs of vector words, then single events, fill the arrays exactly") {
  // A vector word gives up to 12 events for one word, so the room a block makes (one event a word) runs out
  // inside it: a block of full VECT_12 masks followed by single-event words needs the vectors' room to
  // count the words after them. Every event must arrive (none lost, none written past the arrays).
  const auto dir = temp_dir("evt3_vectors");
  fs::create_directories(dir);
  std::string b = "% evt 3.0\n% format EVT3;height=16;width=2048\n% end\n";
  auto word = [&](unsigned w) { b.push_back(static_cast<char>(w & 0xFF)), b.push_back(static_cast<char>(w >> 8)); };
  events::EventStream want;
  word(0x8000 | 1), word(0x6000 | 7), word(0x0000 | 3);  // time high 1, time low 7, row 3
  const double t = ((1 << 12) | 7) / 1e6;
  for (int g = 0; g < 12; ++g) {
    const int vectors = 40 + 60 * g, singles = 500 + 400 * g;
    word(0x3000 | 0x800 | 0);  // vector base x 0, ON
    for (int v = 0; v < vectors; ++v) {
      word(0x4000 | 0xFFF);
      for (int q = 0; q < 12; ++q) want.push_back(t, 12 * v + q, 3, 1);
      if (12 * (v + 1) % 2040 == 0) break;
    }
    for (int k = 0; k < singles; ++k) {
      word(0x2000 | static_cast<unsigned>(k % 2048));
      want.push_back(t, k % 2048, 3, -1);
    }
  }
  write(dir / "vectors.raw", b);
  for (int threads : {1, 2}) {
    CAPTURE(threads);
    omp_set_num_threads(threads);
    io::PropheseeInfo info;
    const auto got = io::read_prophesee_events(dir / "vectors.raw", {}, info);
    REQUIRE(got.size() == want.size());
    CHECK(got.t == want.t);
    CHECK(got.x == want.x);
    CHECK(got.polarity == want.polarity);
  }
  omp_set_num_threads(1);
  fs::remove_all(dir);
}

TEST_CASE("inspect: a recording of one polarity is named so, not given a threshold ratio") {
  const auto dir = temp_dir("one_polarity");
  fs::create_directories(dir);
  write(dir / "events.txt", "0.10 1 2 1\n0.11 3 4 1\n0.12 5 6 1\n");
  write(dir / "calib.txt", "100 100 16 12\n");
  write(dir / "sensor.txt", "32 24\n");
  io::LoadOptions opt;
  opt.use_cache = false;
  const std::string text = io::format_summary(io::summarize(io::load(dir, opt)));
  CHECK_CONTAINS(text, "warning: the recording has no OFF events");
  CHECK(text.find("C-/C+") == std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("PNG: write then read back, montage and depth colouring have the right shape") {
  const auto dir = temp_dir("png");
  auto good_png_for_lengths = [&] { return read_file(dir / "a.png"); };
  Image img(5, 4, 1);
  for (std::size_t i = 0; i < img.data.size(); ++i) img.data[i] = static_cast<float>(i) / 19.f;
  io::write_png(dir / "a.png", img);
  auto back = io::read_png(dir / "a.png");
  REQUIRE(back.width == 5);
  for (std::size_t i = 0; i < img.data.size(); ++i) CHECK(back.data[i] == doctest::Approx(img.data[i]).epsilon(0.003));
  auto m = io::montage({img, img}, 3);
  CHECK(m.width == 12);
  CHECK(m.channels == 3);
  CHECK(io::colorize(img, 0, 1).channels == 3);
  CHECK_CONTAINS(error_of([&] { io::read_png(dir / "missing.png"); }), "missing.png:0: cannot open");
  // A header announcing 10000 × 10000 pixels (within stb's own limit of 2^30 bytes) is refused before
  // decoding allocates anything.
  std::string png = read_file(dir / "a.png");
  REQUIRE(png.substr(12, 4) == "IHDR");
  for (int k : {16, 20}) {  // width, height: big-endian 10000
    png[k] = 0, png[k + 1] = 0, png[k + 2] = char(0x27), png[k + 3] = char(0x10);
  }
  // Its 27 bytes of compressed pixels cannot hold 10^8 (deflate compresses at most 1032:1) …
  CHECK_CONTAINS(error_of([&] { io::decode_png(png, "big.png"); }),
                 "big.png:0: cannot decode image: truncated or corrupt PNG (27 bytes of compressed pixels cannot hold the 100010000 bytes");
  // … and with 100 kB more of them, the pixel limit refuses it.
  const std::size_t iend = png.rfind("IEND") - 4;
  std::string more(12 + 100000, '\0');
  more[1] = char(0x01), more[2] = char(0x86), more[3] = char(0xa0);  // 100000, big-endian
  more.replace(4, 4, "IDAT");
  png.insert(iend, more);
  CHECK_CONTAINS(error_of([&] { io::decode_png(png, "big.png"); }), "big.png:0: image header announces 10000x10000 pixels");
  CHECK_CONTAINS(error_of([&] { io::decode_png("GIF89a", "x.gif"); }), "x.gif:0: cannot decode image: not a PNG file");
  // Found by tests/fuzz (fuzz_png): 34 bytes that stb_image's TGA decoder spent 10 s on. Only PNG is decoded.
  CHECK_CONTAINS(error_of([&] { io::decode_png(std::string("\x02\x00\x0a\x96\x18\x18\x18\x18", 8) + std::string(26, '\x18'), "t.tga"); }),
                 "t.tga:0: cannot decode image: not a PNG file");
  CHECK_CONTAINS(error_of([&] { io::decode_png("garbage", "x.png"); }), "x.png:0: cannot decode image");
  // Found by tests/fuzz (fuzz_png): an IDAT chunk announcing 1 GB in a small file made stb_image allocate
  // 2 GB before noticing the data was missing: the chunk lengths are checked against the file first.
  std::string liar = good_png_for_lengths();
  const std::size_t idat_at = liar.find("IDAT") - 4;
  liar[idat_at] = 0x40;  // 0x40xxxxxx bytes
  CHECK_CONTAINS(error_of([&] { io::decode_png(liar, "liar.png"); }),
                 "liar.png:0: cannot decode image: truncated or corrupt PNG (a chunk of 10");
  CHECK_CONTAINS(error_of([&] { io::decode_png(good_png_for_lengths().substr(0, 60), "cut.png"); }),
                 "cut.png:0: cannot decode image: truncated or corrupt PNG");
  // Found by tests/fuzz (fuzz_png): an empty IDAT chunk before the data made stb_image call memcpy with a null
  // destination (undefined behaviour; the fuzz build now tolerates only that, in stb's code). Such a file is
  // valid and decodes to the same pixels.
  const std::string good_png = read_file(dir / "a.png");
  const std::size_t idat = good_png.find("IDAT") - 4;
  const std::string empty_idat = good_png.substr(0, idat) + std::string("\0\0\0\0IDAT\x35\xaf\x06\x1e", 12) + good_png.substr(idat);
  CHECK(io::decode_png(empty_idat, "empty_idat.png").data == back.data);
  fs::remove_all(dir);
}

/// An uncompressed 24-bit BMP of w x h pixels, bottom-up rows padded to 4 bytes, pixel (x, y) (y = 0 the
/// top row) of grey level 40 x + 10 y (blue, green and red equal).
static std::string bmp_24(int w, int h, std::uint32_t compression = 0) {
  const int row = (w * 3 + 3) / 4 * 4;
  std::string b(54 + static_cast<std::size_t>(row) * h, '\0');
  auto put = [&](std::size_t at, std::uint32_t v, int n) {
    for (int i = 0; i < n; ++i) b[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
  };
  b[0] = 'B', b[1] = 'M';
  put(2, static_cast<std::uint32_t>(b.size()), 4), put(10, 54, 4), put(14, 40, 4), put(18, w, 4), put(22, h, 4);
  put(26, 1, 2), put(28, 24, 2), put(30, compression, 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) b[54 + static_cast<std::size_t>(row) * (h - 1 - y) + 3 * x + c] = static_cast<char>(40 * x + 10 * y);
  return b;
}

TEST_CASE("BMP textures: an uncompressed one decodes the right way up, a short or compressed one is refused before decoding") {
  const auto img = io::decode_image(bmp_24(3, 2), "skin.bmp", 3);
  REQUIRE(img.width == 3);
  REQUIRE(img.height == 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) CHECK(img.data[3 * (3 * y + x) + 1] == doctest::Approx((40 * x + 10 * y) / 255.0));
  CHECK_CONTAINS(error_of([] { io::decode_image(bmp_24(3, 2).substr(0, 60), "cut.bmp"); }),
                 "cut.bmp:0: cannot decode image: truncated BMP (6 bytes of pixel data for 3x2 pixels)");
  CHECK_CONTAINS(error_of([] { io::decode_image(bmp_24(3, 2, 1), "rle.bmp"); }),
                 "rle.bmp:0: cannot decode image: compressed BMP (compression 1");
  CHECK_CONTAINS(error_of([] { io::decode_image("BM", "tiny.bmp"); }),
                 "tiny.bmp:0: cannot decode image: a BMP header is at least 26 bytes");
  CHECK_CONTAINS(error_of([] { io::decode_image("GIF89a", "x.gif"); }), "x.gif:0: cannot decode image: not a PNG, JPEG, TGA or BMP file");
}

TEST_CASE("real data: IJRR slider_depth chunk loads with the documented counts and warnings") {
  const auto folder = evtest::shared_data("ijrr_slider_depth_chunk");
  if (folder.empty()) {
    MESSAGE("../shared/data absent: skipped");
    return;
  }
  io::LoadOptions opt;
  opt.use_cache = false;
  auto d = io::load_ijrr(folder, opt);
  auto s = io::summarize(d);
  CHECK(s.events == 50000);
  CHECK(s.on == 21147);
  CHECK(s.off == 28853);
  CHECK(s.width == 240);
  CHECK(s.height == 180);
  CHECK(s.frames == 87);
  CHECK(s.poses == 339);
  bool warned = false;
  for (auto& w : s.warnings) warned |= w.find("frame 0 (t = 0.000000 s) precedes the first pose") != std::string::npos;
  CHECK(warned);
  CHECK(d.camera.fx() == doctest::Approx(335.419462958));
  auto frame = io::read_png(d.frames.paths[0]);
  CHECK(frame.width == 240);
  CHECK(frame.height == 180);
}

TEST_CASE("real data: every IJRR event window parses, including float-noise timestamps") {
  const auto root = evtest::shared_data("ijrr_event_windows");
  if (root.empty()) {
    MESSAGE("../shared/data absent: skipped");
    return;
  }
  int n = 0;
  for (auto& e : fs::directory_iterator(root)) {
    if (!e.is_directory()) continue;
    io::LoadOptions opt;
    opt.use_cache = false;
    auto d = io::load_ijrr(e.path(), opt);
    CHECK(d.events.size() >= 20000);
    CHECK(d.camera.distortion()[0] == doctest::Approx(-0.368436311798));
    d.events.validate();
    ++n;
  }
  CHECK(n == 12);
}

TEST_CASE("dataset: an absurd sensor size is refused before anything is allocated for it") {
  const auto dir = temp_dir("huge");
  write(dir / "events.txt", "0.10 1 2 1\n");
  write(dir / "calib.txt", "100 100 16 12\n");
  write(dir / "sensor.txt", "60000 60000\n");
  CHECK_CONTAINS(error_of([&] { io::load_ijrr(dir); }),
                 "sensor.txt:1: sensor size 60000x60000 has more than 67108864 pixels (refused before allocating");
  write(dir / "sensor.txt", "70000 10\n");
  CHECK_CONTAINS(error_of([&] { io::load_ijrr(dir); }), "sensor size 70000x10 out of range (1 to 65535 per side)");
  fs::remove_all(dir);
}

TEST_CASE("COLMAP text model as a recording's pose source: images get the times of the frames of their file names") {
  const auto dir = temp_dir("colsrc");
  write(dir / "events.txt", "0.01 1 1 1\n0.02 2 2 0\n");
  write(dir / "calib.txt", "20 20 4 3\n");
  write(dir / "sensor.txt", "8 6\n");
  write(dir / "images.txt", "0.000 images/frame_0.png\n0.010 images/frame_1.png\n0.020 images/frame_2.png\n");
  fs::create_directories(dir / "sparse");
  // World-to-camera: image b is frame_2 (t = 0.02) translated by (0, 0, 1); a is frame_0 at the identity;
  // c names no frame of the recording and is left out.
  write(dir / "sparse" / "images.txt",
        "# IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME\n1 1 0 0 0 0 0 1 1 frame_2.png\n\n2 1 0 0 0 0 0 0 1 frame_0.png\n\n"
        "3 1 0 0 0 0 0 0 1 other.png\n\n");
  write(dir / "sparse" / "cameras.txt", "1 PINHOLE 8 6 30 31 4 3\n");
  io::LoadOptions o;
  o.poses = dir / "sparse";
  o.calib = dir / "sparse" / "cameras.txt";
  const auto d = io::load(dir, o);
  REQUIRE(d.trajectory.size() == 2);
  CHECK(d.trajectory.times() == std::vector<double>{0.0, 0.02});
  CHECK(d.trajectory.poses()[1].t.z() == doctest::Approx(-1));  // camera-to-world: the inverse of COLMAP's
  CHECK(d.camera.fx() == 30);
  CHECK(d.camera.fy() == 31);
  o.poses = dir / "sparse" / "images.txt";  // the file works as the folder does
  CHECK(io::load(dir, o).trajectory.size() == 2);
  write(dir / "sparse" / "images.txt", "1 1 0 0 0 0 0 1 1 nothing.png\n\n");
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "images.txt:0: 0 of its 1 images match a frame of the recording by file name");
  write(dir / "sparse" / "cameras.txt", "1 PINHOLE 16 12 30 31 4 3\n");
  o.poses.clear();
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "cameras.txt:0: camera of 16x12 for a 8x6 sensor");
  fs::remove_all(dir);
}

TEST_CASE("the paper's colour geometry: site sensors, their cameras and events, upsampling back") {
  // The paper's colour geometry, for every pattern and channel: a channel's first site in each block, a
  // camera for those sites (what site pixel (x', y') sees is what full pixel (2x'+ox, 2y'+oy) sees, through
  // the same distortion), the events moved there, and the upsampling back.
  const geometry::Camera full(13, 9, 20, 22, 6.3, 4.1, {0.05, -0.02, 0.001, -0.002, 0.003});
  io::Dataset rec;
  rec.camera = full;
  rec.events.width = 13;
  rec.events.height = 9;
  for (int i = 0; i < 13 * 9; ++i) rec.events.push_back(0.001 * i, i % 13, i / 13, i % 3 == 0 ? -1 : 1);
  for (const char* name : {"rggb", "bggr", "gbrg", "grbg"}) {
    geometry::BayerPattern p;
    REQUIRE(geometry::BayerPattern::parse(name, p));
    rec.bayer_pattern = name;
    for (int c = 0; c < 3; ++c) {
      CAPTURE(name);
      CAPTURE(c);
      const auto s = geometry::site_of(p, c);
      CHECK(p.at(s.ox, s.oy) == c);
      if (c == 1) CHECK(s.oy == 0);  // green: the block's first green, in its first row for every pattern
      const auto sc = geometry::site_camera(full, s);
      CHECK(sc.width() == (s.ox ? 6 : 7));
      CHECK(sc.height() == (s.oy ? 4 : 5));
      for (int x = 0; x < sc.width(); ++x)
        for (int y = 0; y < sc.height(); ++y) {
          const auto a = sc.ray(geometry::Pose{}, x + 0.5, y + 0.5), b = full.ray(geometry::Pose{}, 2 * x + s.ox + 0.5, 2 * y + s.oy + 0.5);
          CHECK((a.dir - b.dir).norm() < 1e-9);
        }
      const Vec3 point(0.3, -0.2, 2.0);
      const Vec2 u = full.project(point), v = sc.project(point);
      CHECK(v.x() == doctest::Approx((u.x() - s.ox + 0.5) / 2));
      CHECK(v.y() == doctest::Approx((u.y() - s.oy + 0.5) / 2));
      const auto sub = io::channel_dataset(rec, p, c);
      CHECK(sub.camera.width() == sc.width());
      CHECK(sub.events.size() == static_cast<std::size_t>(sc.width() * sc.height()));
      CHECK(sub.bayer_pattern.empty());  // a grey recording
      sub.events.validate("sub");
      for (std::size_t i = 0; i < sub.events.size(); ++i) {  // each event from the site it names
        const int k = static_cast<int>(std::lround(sub.events.t[i] / 0.001));
        CHECK(k % 13 == 2 * sub.events.x[i] + s.ox);
        CHECK(k / 13 == 2 * sub.events.y[i] + s.oy);
        CHECK(sub.events.polarity[i] == rec.events.polarity[static_cast<std::size_t>(k)]);
      }
      // Upsampling: a site keeps its value; a plane in site coordinates stays that plane inside the grid.
      Image img(sc.width(), sc.height());
      for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) img.at(x, y) = 0.5f + 0.25f * x - 0.125f * y;
      const auto up = geometry::upsample_sites(img, s, 13, 9);
      REQUIRE(up.width == 13);
      for (int y = 0; y < 9; ++y)
        for (int x = 0; x < 13; ++x) {
          const double sx = std::clamp((x - s.ox) / 2.0, 0.0, img.width - 1.0), sy = std::clamp((y - s.oy) / 2.0, 0.0, img.height - 1.0);
          CHECK(up.at(x, y) == doctest::Approx(0.5 + 0.25 * sx - 0.125 * sy));
          if ((x & 1) == s.ox && (y & 1) == s.oy) CHECK(up.at(x, y) == img.at(x / 2, y / 2));
        }
    }
    // Green on both its sites: the full sensor, every green event where it fired, the sites marked.
    const auto g = io::channel_dataset(rec, p, 1, io::GreenSites::Both);
    CHECK(g.camera.width() == 13);
    CHECK(g.camera.height() == 9);
    REQUIRE(g.sites.size() == 13u * 9u);
    std::size_t greens = 0;
    for (int y = 0; y < 9; ++y)
      for (int x = 0; x < 13; ++x) {
        CHECK(g.sites[static_cast<std::size_t>(y) * 13 + x] == (p.at(x, y) == 1 ? 1 : 0));
        greens += p.at(x, y) == 1;
      }
    CHECK(g.events.size() == greens);  // one event per pixel in `rec`
    g.events.validate("green");
    for (std::size_t i = 0; i < g.events.size(); ++i) {
      const int k = static_cast<int>(std::lround(g.events.t[i] / 0.001));
      CHECK(k % 13 == g.events.x[i]);
      CHECK(k / 13 == g.events.y[i]);
      CHECK(p.at(g.events.x[i], g.events.y[i]) == 1);
    }
    // Red and blue have one site per block: Both changes nothing for them.
    CHECK(io::channel_dataset(rec, p, 0, io::GreenSites::Both).camera.width() ==
          geometry::site_camera(full, geometry::site_of(p, 0)).width());
    CHECK(io::channel_dataset(rec, p, 0, io::GreenSites::Both).sites.empty());
  }
}
