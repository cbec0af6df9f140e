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
#include <set>

#include "common.hpp"

using namespace evnerf;
namespace fs = std::filesystem;

namespace {
fs::path temp_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / ("evnerf_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
void write(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

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
  auto err = [](const std::string& text) {
    return error_of([&] { io::parse_events(text, "events.txt", 240, 180); });
  };
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

TEST_CASE("events.txt: numbers the scanner leaves to from_chars parse exactly as the reference does") {
  for (const char* text : {"1. 1 2 1\n", ".5 1 2 1\n", "12345678901234567890.5 1 2 1\n", "-0.5 1 2 1\n",
                           "0.1234567890123456789 1 2 1\n", "5e-1 1 2 1\n", "0.5 1 2 1\r\n  \n", "0.5,1,2,1\n"}) {
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
    CHECK(outcome([](auto... a) { return io::parse_events(a...); }) ==
          outcome([](auto... a) { return io::parse_events_reference(a...); }));
  }
}

TEST_CASE("calib.txt, groundtruth.txt and images.txt: parsing and bad input") {
  auto cam = io::parse_calib("335.4 335.3 129.9 99.1 -0.13 0.09 -0.0003 0.0001 0.0\n", "calib.txt", 240, 180);
  CHECK(cam.fx() == doctest::Approx(335.4));
  CHECK(cam.distortion()[0] == doctest::Approx(-0.13));
  CHECK(io::parse_calib("200 200 120 90\n", "calib.txt", 240, 180).distorted() == false);
  CHECK_CONTAINS(error_of([] { io::parse_calib("200 200 120 90 0.1\n", "calib.txt", 240, 180); }), "calib.txt:1: calibration needs 4, 8 or 9 numbers (fx fy cx cy [k1 k2 p1 p2 [k3]]), found 5");
  CHECK_CONTAINS(error_of([] { io::parse_calib("", "calib.txt", 240, 180); }), "calibration file is empty");
  CHECK_CONTAINS(error_of([] { io::parse_calib("-1 200 120 90\n", "calib.txt", 240, 180); }), "focal lengths must be positive");

  auto tr = io::parse_poses("0.1 1 2 3 0 0 0 1\n0.2 1 2 3 0 0 0.7071068 0.7071068\n", "gt.txt");
  CHECK(tr.size() == 2);
  CHECK(tr.poses()[1].q.z() == doctest::Approx(0.7071068));
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0\n", "gt.txt"); }), "gt.txt:1: line is truncated: field 'qw' is missing");
  // Found by tests/fuzz (fuzz_colmap): a zero quaternion in images.txt gave a NaN pose.
  CHECK_CONTAINS(error_of([] { io::parse_colmap_images("1 0 0 0 0 7 3.2 1 1 a.png\n\n", "images.txt"); }),
                 "images.txt:1: quaternion is far from unit length (norm 0)");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1\n", "gt.txt"); }), "gt.txt:2: pose timestamps must increase strictly");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 3 0 0 0 0\n", "gt.txt"); }), "gt.txt:1: quaternion is far from unit length");
  CHECK_CONTAINS(error_of([] { io::parse_poses("0.1 1 2 nan 0 0 0 1\n", "gt.txt"); }), "'pz' is not finite");

  auto fr = io::parse_frames("0.0 images/a.png\n0.1 images/b c.png\n", "images.txt", "/data");
  REQUIRE(fr.size() == 2);
  CHECK(fr.paths[1] == fs::path("/data/images/b c.png"));
  CHECK_CONTAINS(error_of([] { io::parse_frames("0.0\n", "images.txt", "/d"); }), "images.txt:1: line is truncated: field 'image path' is missing");
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
  CHECK_CONTAINS(error_of([&] { io::parse_npy<float>(huge, "g.npy"); }), "g.npy:0: cannot read .npy: shape '(4294967296, 4294967296, 2)' is too large");
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

TEST_CASE("the format table: one name each, --format's list; every writer's output is detected as its format and reads back equal") {
  std::set<std::string> names;
  for (const auto& f : io::formats()) {
    CAPTURE(f.name);
    CHECK(names.insert(f.name).second);
    CHECK(std::string(f.description).size() > 10);
    CHECK((f.load != nullptr) == (f.detect != nullptr));           // a reader is found by its content
    CHECK((f.load != nullptr) == (std::string(f.unavailable).empty()));  // or the build says why not
  }
  CHECK(io::format_names().size() == names.size());
  CHECK(io::format_list() == "ijrr, eventnerf, robust-e-nerf, hdf5, rosbag");
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
  CHECK_CONTAINS(error_of([&] { io::detect_format(dir / "rec", "bag"); }), "unknown format 'bag' (known: ijrr, eventnerf, robust-e-nerf, hdf5, rosbag)");
  fs::remove_all(dir);
}

TEST_CASE("PNG: write then read back; montage and depth colouring have the right shape") {
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
  // 2 GB before noticing the data was missing. The chunk lengths are now checked against the file first.
  std::string liar = good_png_for_lengths();
  const std::size_t idat_at = liar.find("IDAT") - 4;
  liar[idat_at] = 0x40;  // 0x40xxxxxx bytes
  CHECK_CONTAINS(error_of([&] { io::decode_png(liar, "liar.png"); }), "liar.png:0: cannot decode image: truncated or corrupt PNG (a chunk of 10");
  CHECK_CONTAINS(error_of([&] { io::decode_png(good_png_for_lengths().substr(0, 60), "cut.png"); }), "cut.png:0: cannot decode image: truncated or corrupt PNG");
  // Found by tests/fuzz (fuzz_png): an empty IDAT chunk before the data made stb_image call memcpy with a null
  // destination (undefined behaviour; the fuzz build now tolerates only that, in stb's code). Such a file is
  // valid and decodes to the same pixels.
  const std::string good_png = read_file(dir / "a.png");
  const std::size_t idat = good_png.find("IDAT") - 4;
  const std::string empty_idat = good_png.substr(0, idat) + std::string("\0\0\0\0IDAT\x35\xaf\x06\x1e", 12) + good_png.substr(idat);
  CHECK(io::decode_png(empty_idat, "empty_idat.png").data == back.data);
  fs::remove_all(dir);
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

#ifdef EVNERF_HAVE_HDF5
// ---- HDF5: fixtures written by h5py (tests/fixtures/make_h5.py), bad files written here with the C API ----
namespace {
/// Writes a one-dimensional dataset of `type` (creating its groups).
template <class T>
void h5_put(hid_t f, const char* name, hid_t type, const std::vector<T>& v) {
  const hsize_t n[1] = {v.size()};
  const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
  H5Pset_create_intermediate_group(lcpl, 1);
  const hid_t space = H5Screate_simple(1, n, nullptr);
  const hid_t set = H5Dcreate2(f, name, type, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Dclose(set);
  H5Sclose(space);
  H5Pclose(lcpl);
}
/// An event_utils file of the given columns.
void h5_events(const fs::path& p, const std::vector<std::int16_t>& x, const std::vector<std::int16_t>& y, const std::vector<double>& t,
               const std::vector<std::int8_t>& pol) {
  const hid_t f = H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  h5_put(f, "events/xs", H5T_NATIVE_INT16, x);
  h5_put(f, "events/ys", H5T_NATIVE_INT16, y);
  h5_put(f, "events/ts", H5T_NATIVE_DOUBLE, t);
  h5_put(f, "events/ps", H5T_NATIVE_INT8, pol);
  H5Fclose(f);
}
}  // namespace

TEST_CASE("HDF5: the event_utils/HQF and DSEC layouts written by h5py read back exactly") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto hqf = io::read_hdf5(fx / "hqf.h5");
  CHECK(hqf.layout == "event_utils");
  CHECK(hqf.width == 8);  // from sensor_resolution = (6, 8)
  CHECK(hqf.height == 6);
  const auto dsec = io::read_hdf5(fx / "dsec.h5");
  CHECK(dsec.layout == "dsec");
  CHECK(dsec.width == 8);  // no size in the file: the largest coordinates + 1
  CHECK(dsec.height == 6);
  for (const auto* r : {&hqf, &dsec}) {
    REQUIRE(r->events.size() == 40);
    const double t0 = r == &dsec ? 5.0 : 0.0;  // DSEC: t_offset = 5 000 000 µs
    for (std::size_t k = 0; k < 40; ++k) {
      CHECK(r->events.x[k] == k % 8);
      CHECK(r->events.y[k] == k % 6);
      CHECK(r->events.polarity[k] == (k % 2 == 0 ? 1 : -1));
      CHECK(r->events.t[k] == doctest::Approx(t0 + 1e-4 * double(k)).epsilon(1e-12));
    }
  }
  CHECK(dsec.events_read == 40);
  // A time window: the events of [1.15, 2.45) ms (events 12 to 24); the DSEC file is read through its
  // ms_to_idx (entries 1 and 3: events 10 to 29, one more on each side), the HQF file whole.
  const auto wd = io::read_hdf5(fx / "dsec.h5", 0, 0, 5.00115, 5.00245), wh = io::read_hdf5(fx / "hqf.h5", 0, 0, 0.00115, 0.00245);
  CHECK(wd.events_read == 22);
  CHECK(wh.events_read == 40);
  for (const auto* r : {&wd, &wh}) {
    REQUIRE(r->events.size() == 13);
    CHECK(r->events.x.front() == 12 % 8);
    CHECK(r->events.x.back() == 24 % 8);
  }
  CHECK(io::read_hdf5_checked(fx / "dsec.h5", 0, 0, 5.00115, 5.00245).events.t == wd.events.t);
  CHECK(io::read_hdf5(fx / "dsec.h5", 0, 0, 4.0, 5.00005).events.size() == 1);     // before the index: from event 0
  CHECK(io::read_hdf5(fx / "dsec.h5", 0, 0, 5.00385, 9.0).events.size() == 1);     // after it: to the last event
  CHECK(io::read_hdf5(fx / "dsec.h5", 0, 0, 6.0, 7.0).events.empty());
  REQUIRE(hqf.frames.size() == 2);
  CHECK(hqf.frame_times == std::vector<double>{0.0, 0.002});
  CHECK(hqf.frames[1].width == 8);
  CHECK(hqf.frames[1].data[5] == doctest::Approx(10 / 255.0));
  CHECK(dsec.frames.empty());

  // io::load picks the reader from the content; calibration and poses come from beside the file.
  const auto dir = temp_dir("h5");
  fs::copy_file(fx / "hqf.h5", dir / "recording.h5");
  CHECK_CONTAINS(error_of([&] { io::load(dir / "recording.h5"); }), "calib.txt:0: missing: an HDF5 recording takes its calibration");
  write(dir / "calib.txt", "10 10 4 3\n");
  write(dir / "groundtruth.txt", "0 0 0 0 0 0 0 1\n0.01 0.1 0 0 0 0 0 1\n");
  const auto d = io::load(dir / "recording.h5");
  CHECK(d.camera.width() == 8);
  CHECK(d.events.size() == 40);
  CHECK(d.trajectory.size() == 2);
  CHECK(d.frames.size() == 2);
  CHECK(io::frame_image(d.frames, 1).data == hqf.frames[1].data);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "calib.txt"); }), "calib.txt:0: not a recording evnerf reads");
  CHECK_CONTAINS(error_of([&] { io::load(dir / "nothing"); }), "nothing:0: no such recording");
  fs::remove_all(dir);
}

TEST_CASE("HDF5: bad files are refused with the file, the dataset and what is wrong") {
  const auto dir = temp_dir("h5bad");
  auto err = [&](const fs::path& p) { return error_of([&] { io::read_hdf5(p); }); };
  const std::string good = read_file(fs::path(EVNERF_FIXTURES) / "hqf.h5");
  write(dir / "cut.h5", good.substr(0, good.size() / 3));
  CHECK_CONTAINS(err(dir / "cut.h5"), "cut.h5:0: ");
  write(dir / "text.h5", "t x y p\n");
  CHECK_CONTAINS(err(dir / "text.h5"), "text.h5:0: not an HDF5 file");
  {
    const hid_t f = H5Fcreate((dir / "empty.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    h5_put(f, "other", H5T_NATIVE_INT, std::vector<int>{1});
    H5Fclose(f);
  }
  CHECK_CONTAINS(err(dir / "empty.h5"), "empty.h5:0: no events: expected datasets events/xs");
  h5_events(dir / "back.h5", {1, 2, 3}, {1, 1, 1}, {0.1, 0.3, 0.2}, {1, 0, 1});
  CHECK_CONTAINS(err(dir / "back.h5"), "dataset 'events/ts', event 2: time 0.2 s goes back (previous 0.3 s)");
  h5_events(dir / "pol.h5", {1, 2}, {1, 1}, {0.1, 0.2}, {1, 5});
  CHECK_CONTAINS(err(dir / "pol.h5"), "dataset 'events/ps', event 1: unknown polarity 5");
  h5_events(dir / "neg.h5", {1, -2}, {1, 1}, {0.1, 0.2}, {1, 0});
  CHECK_CONTAINS(err(dir / "neg.h5"), "event 1: pixel (-2, 1) lies outside");
  h5_events(dir / "short.h5", {1, 2}, {1}, {0.1, 0.2}, {1, 0});
  CHECK_CONTAINS(err(dir / "short.h5"), "the event datasets differ in length (events/xs 2, events/ys 1");
  h5_events(dir / "nan.h5", {1, 2}, {1, 1}, {0.1, NAN}, {1, 0});
  CHECK_CONTAINS(err(dir / "nan.h5"), "event 1: time is not finite");
  {
    const hid_t f = H5Fcreate((dir / "float.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    h5_put(f, "events/xs", H5T_NATIVE_FLOAT, std::vector<float>{1.5f});
    h5_put(f, "events/ys", H5T_NATIVE_INT16, std::vector<std::int16_t>{1});
    h5_put(f, "events/ts", H5T_NATIVE_DOUBLE, std::vector<double>{0.1});
    h5_put(f, "events/ps", H5T_NATIVE_INT8, std::vector<std::int8_t>{1});
    H5Fclose(f);
  }
  CHECK_CONTAINS(err(dir / "float.h5"), "dataset 'events/xs' holds floating-point values");
  // Found by tests/fuzz (fuzz_hdf5): a sensor_resolution of 6.3e16 was cast to int (undefined behaviour).
  h5_events(dir / "res.h5", {1}, {1}, {0.1}, {1});
  {
    const hid_t f = H5Fopen((dir / "res.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hsize_t two[1] = {2};
    const double res[2] = {6.3e16, 8};
    const hid_t space = H5Screate_simple(1, two, nullptr);
    const hid_t attr = H5Acreate2(f, "sensor_resolution", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(attr, H5T_NATIVE_DOUBLE, res);
    H5Aclose(attr);
    H5Sclose(space);
    H5Fclose(f);
  }
  CHECK_CONTAINS(err(dir / "res.h5"), "res.h5:0: attribute 'sensor_resolution' (6.3e+16, 8) is not a height and width");
  // Checked in a child first (what io::load does): the same result, the same refusals, and a crash of the
  // library (here forced in the child) is an Error in this process.
  const auto checked = io::read_hdf5_checked(fs::path(EVNERF_FIXTURES) / "hqf.h5");
  CHECK(checked.events.t == io::read_hdf5(fs::path(EVNERF_FIXTURES) / "hqf.h5").events.t);
  CHECK(error_of([&] { io::read_hdf5_checked(dir / "back.h5"); }) == err(dir / "back.h5"));
  io::detail::hdf5_probe_hook() = [] { std::raise(SIGKILL); };  // no handler (the test framework's) can intercept it
  const std::string crashed = error_of([&] { io::read_hdf5_checked(fs::path(EVNERF_FIXTURES) / "hqf.h5"); });
  io::detail::hdf5_probe_hook() = nullptr;
  CHECK_CONTAINS(crashed, "hqf.h5:0: the HDF5 library crashed (signal 9, ");
  CHECK_CONTAINS(crashed, "nothing was loaded");
  // A sensor size given by the caller bounds the pixels.
  h5_events(dir / "wide.h5", {1, 9}, {1, 1}, {0.1, 0.2}, {1, 0});
  CHECK_CONTAINS(error_of([&] { io::read_hdf5(dir / "wide.h5", 8, 6); }), "event 1: pixel (9, 1) lies outside the 8x6 sensor");
  fs::remove_all(dir);
}
#endif

#ifdef EVNERF_HAVE_ROSBAG
// ---- ROS bags: fixtures written by Debian's python3-rosbag (tests/fixtures/make_bag.py); damaged and
// hand-made bags written here ----
namespace {
/// One record: header fields ("name", bytes) then data.
std::string bag_record(const std::vector<std::pair<std::string, std::string>>& fields, const std::string& data) {
  auto u32 = [](std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  std::string h;
  for (const auto& [k, v] : fields) h += u32(static_cast<std::uint32_t>(k.size() + 1 + v.size())) + k + "=" + v;
  return u32(static_cast<std::uint32_t>(h.size())) + h + u32(static_cast<std::uint32_t>(data.size())) + data;
}
template <class T>
std::string bytes_of(T v) {
  return std::string(reinterpret_cast<const char*>(&v), sizeof v);
}
/// The offset of the bag header's index_pos value (the fixture's first record).
std::size_t index_pos_offset(const std::string& bag) { return bag.find("index_pos=") + 10; }
}  // namespace

TEST_CASE("ROS bag: the fixtures written by rosbag (none, bz2, lz4 chunks) read back exactly") {
  const fs::path fx = EVNERF_FIXTURES;
  std::vector<double> first_times;
  for (const char* name : {"davis.bag", "davis_bz2.bag", "davis_lz4.bag"}) {
    CAPTURE(name);
    CHECK(io::is_rosbag(fx / name));
    const auto topics = io::rosbag_topics(fx / name);
    REQUIRE(topics.size() == 4);
    CHECK(topics[1].topic == "/dvs/events");
    CHECK(topics[1].type == "dvs_msgs/EventArray");
    CHECK(topics[1].messages == 4);
    CHECK(topics[3].topic == "/optitrack/davis");
    CHECK(topics[3].messages == 5);
    const auto d = io::load(fx / name);
    CHECK(d.time_origin == 1500000000);
    CHECK(d.camera.width() == 8);  // from the camera info
    CHECK(d.camera.height() == 6);
    CHECK(d.camera.fx() == 20);
    CHECK(d.camera.fy() == 21);
    CHECK(d.camera.cx() == 3.5);
    CHECK(d.camera.cy() == 2.5);
    CHECK(d.camera.distortion() == std::array<double, 5>{0.1, -0.05, 0.001, 0.002, 0.01});
    REQUIRE(d.events.size() == 40);  // the events of make_h5.py, 0.25 s after the origin
    for (std::size_t k = 0; k < 40; ++k) {
      CHECK(d.events.x[k] == k % 8);
      CHECK(d.events.y[k] == k % 6);
      CHECK(d.events.polarity[k] == (k % 2 == 0 ? 1 : -1));
      CHECK(d.events.t[k] == doctest::Approx(0.25 + 1e-4 * double(k)).epsilon(1e-13));
    }
    REQUIRE(d.frames.size() == 2);
    CHECK(d.frames.t[1] == doctest::Approx(0.252));
    const auto f1 = io::frame_image(d.frames, 1);
    CHECK(f1.channels == 1);
    CHECK(f1.data[5] == doctest::Approx(10 / 255.0));
    REQUIRE(d.trajectory.size() == 5);
    const auto& p3 = d.trajectory.poses()[3];
    CHECK(d.trajectory.times()[3] == doctest::Approx(0.253));
    CHECK(p3.t.x() == doctest::Approx(0.3));
    CHECK(p3.t.z() == doctest::Approx(1.03));
    CHECK(p3.q.z() == doctest::Approx(std::sin(0.075)));
    CHECK(p3.q.w() == doctest::Approx(std::cos(0.075)));
    first_times.push_back(d.events.t[7]);
  }
  CHECK(first_times[0] == first_times[1]);
  CHECK(first_times[0] == first_times[2]);
}

TEST_CASE("ROS bag: topics by name when two could serve; colour and Bayer frames; Odometry poses; calibration beside") {
  const fs::path fx = EVNERF_FIXTURES;
  io::LoadOptions o;
  o.calib = fx / "colour_calib.txt";
  CHECK_CONTAINS(error_of([&] { io::load(fx / "colour.bag", o); }),
                 "colour.bag:0: several topics could be the frames (/dvs/image_color, /dvs/image_raw): choose one with --images-topic");
  o.images_topic = "/dvs/image_color";  // bgr8: pixel (x, y) holds b = 10 x, g = 20 y, r = 100 + frame
  auto d = io::load(fx / "colour.bag", o);
  REQUIRE(d.frames.size() == 2);
  const auto c = io::frame_image(d.frames, 1);
  CHECK(c.channels == 3);
  CHECK(c.at(5, 4, 0) == doctest::Approx(101 / 255.0));
  CHECK(c.at(5, 4, 1) == doctest::Approx(80 / 255.0));
  CHECK(c.at(5, 4, 2) == doctest::Approx(50 / 255.0));
  CHECK(d.camera.fx() == 20);
  CHECK(!d.camera.distorted());
  REQUIRE(d.trajectory.size() == 5);  // nav_msgs/Odometry
  CHECK(d.trajectory.poses()[4].t.x() == doctest::Approx(0.4));
  CHECK(d.trajectory.poses()[4].q.z() == doctest::Approx(std::sin(0.1)));

  CHECK(d.bayer_pattern.empty());     // bgr8 frames say nothing of a mosaic
  o.images_topic = "/dvs/image_raw";  // bayer_rggb8, value (7 (x + 8 y) + frame) mod 256: demosaiced
  d = io::load(fx / "colour.bag", o);
  CHECK(d.bayer_pattern == "rggb");
  const auto m = io::frame_image(d.frames, 0);
  REQUIRE(m.channels == 3);
  auto raw = [](int x, int y) { return static_cast<float>((7 * (x + 8 * y)) % 256) / 255.f; };
  CHECK(m.at(2, 2, 0) == doctest::Approx(raw(2, 2)));                                          // R site
  CHECK(m.at(2, 2, 1) == doctest::Approx((raw(1, 2) + raw(3, 2) + raw(2, 1) + raw(2, 3)) / 4));  // G: 4 neighbours
  CHECK(m.at(2, 2, 2) == doctest::Approx((raw(1, 1) + raw(3, 1) + raw(1, 3) + raw(3, 3)) / 4));  // B: 4 diagonals

  o.images_topic = "none";
  CHECK(io::load(fx / "colour.bag", o).frames.size() == 0);
  o.events_topic = "/vicon/odom";
  CHECK_CONTAINS(error_of([&] { io::load(fx / "colour.bag", o); }), "topic /vicon/odom (nav_msgs/Odometry) cannot be the events: it has no field 'events'");
  o.events_topic = "/dvs/nothing";
  CHECK_CONTAINS(error_of([&] { io::load(fx / "colour.bag", o); }),
                 "no topic '/dvs/nothing' (--events-topic); the bag's topics: /dvs/events (dvs_msgs/EventArray), /dvs/image_color");
  // Without camera info or a calibration given: calib.txt beside the bag, else a clear error.
  const auto dir = temp_dir("bagcal");
  fs::copy_file(fx / "colour.bag", dir / "c.bag");
  io::LoadOptions plain;
  plain.images_topic = "none";
  CHECK_CONTAINS(error_of([&] { io::load(dir / "c.bag", plain); }), "c.bag:0: no camera info topic and no ");
  write(dir / "calib.txt", "30 30 4 3\n");
  // A pose file beside the bag is in the bag's clock and moves to the recording's origin.
  write(dir / "groundtruth.txt", "1500000000.25 0 0 0 0 0 0 1\n1500000000.26 1 0 0 0 0 0 1\n");
  plain.poses_topic = "none";
  d = io::load(dir / "c.bag", plain);
  CHECK(d.camera.fx() == 30);
  REQUIRE(d.trajectory.size() == 2);
  CHECK(d.trajectory.times()[1] == doctest::Approx(0.26));
  fs::remove_all(dir);
}

TEST_CASE("ROS bag: a bag without its index (a recording that never closed) is scanned and reads the same") {
  const std::string good = read_file(fs::path(EVNERF_FIXTURES) / "davis_lz4.bag");
  std::string cut = good;
  const std::size_t at = index_pos_offset(cut);
  std::uint64_t index_pos = 0;
  std::memcpy(&index_pos, cut.data() + at, 8);
  REQUIRE(index_pos > 4096);
  REQUIRE(index_pos < cut.size());
  cut.resize(index_pos);  // no index records
  std::memset(cut.data() + at, 0, 8);
  const auto dir = temp_dir("bagidx");
  write(dir / "open.bag", cut);
  const auto a = io::load(fs::path(EVNERF_FIXTURES) / "davis_lz4.bag"), b = io::load(dir / "open.bag");
  CHECK(a.events.t == b.events.t);
  CHECK(a.events.x == b.events.x);
  CHECK(a.events.polarity == b.events.polarity);
  CHECK(a.trajectory.times() == b.trajectory.times());
  CHECK(a.frames.t == b.frames.t);
  const auto topics = io::rosbag_topics(dir / "open.bag");
  REQUIRE(topics.size() == 4);
  CHECK(topics[1].messages == 4);
  // An index position past the end is refused (not scanned silently): the index was damaged.
  std::string bad = good;
  const std::uint64_t past = bad.size() + 10;
  std::memcpy(bad.data() + at, &past, 8);
  write(dir / "badidx.bag", bad);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "badidx.bag"); }), "lies outside the file's records");
  fs::remove_all(dir);
}

TEST_CASE("ROS bag: damaged and strange bags are refused with the file and the record, never a crash") {
  const auto dir = temp_dir("bagbad");
  auto err = [&](const std::string& bytes) {
    write(dir / "b.bag", bytes);
    return error_of([&] { io::load(dir / "b.bag"); });
  };
  CHECK_CONTAINS(err("#ROSBAG V1.2\nxxxx"), "b.bag:0: ROS bag version '1.2' is not read (only 2.0");
  CHECK_CONTAINS(err("#ROSBAG V9999"), "b.bag:0: ROS bag version '9999' is not read");  // no newline (found by fuzz_rosbag)
  CHECK_CONTAINS(err("#ROSBAG V2.0\n"), "record header length at byte 13 runs past the end of the file");
  const std::string header = bag_record({{"op", "\x03"}, {"index_pos", bytes_of<std::uint64_t>(0)}, {"conn_count", bytes_of<std::uint32_t>(0)},
                                         {"chunk_count", bytes_of<std::uint32_t>(0)}},
                                        std::string(100, ' '));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header), "the bag has no connections");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + bag_record({{"op", "\x05"}, {"compression", "zstd"}, {"size", bytes_of<std::uint32_t>(3)}}, "abc")),
                 "chunk at byte " + std::to_string(13 + header.size()) + ": unknown chunk compression 'zstd'");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + bag_record({{"op", "\x05"}, {"compression", "bz2"}, {"size", bytes_of<std::uint32_t>(1000)}}, "BZh9garbage")),
                 "chunk at byte " + std::to_string(13 + header.size()) + ": corrupt bz2 chunk");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + bag_record({{"op", "\x05"}, {"compression", "none"}, {"size", bytes_of<std::uint32_t>(7)}}, "abc")),
                 "uncompressed chunk holds 3 bytes, its header says 7");
  // A header that claims 2 GB for a few compressed bytes allocates nothing for them.
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header +
                     bag_record({{"op", "\x05"}, {"compression", "lz4"}, {"size", bytes_of<std::uint32_t>(0x7fffffff)}}, "\x04\x22\x4d\x18garbage")),
                 "corrupt lz4 chunk");
  // A connection whose definition lacks a type it uses; an event message that ends early.
  const std::string conn_data = bag_record({{"topic", "/e"}, {"type", "my/Events"}, {"md5sum", "x"}, {"message_definition", "Ev[] events\n"}}, "");
  const std::string conn = bag_record({{"op", "\x07"}, {"conn", bytes_of<std::uint32_t>(0)}, {"topic", "/e"}},
                                      conn_data.substr(4, conn_data.size() - 8));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn), "no events topic");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn), "field 'events' of my/Events has type 'Ev', whose definition is not included");
  const std::string def = "Ev[] events\n================\nMSG: my/Ev\nuint16 x\nuint16 y\ntime ts\nbool polarity\n";
  const std::string conn2_data = bag_record({{"topic", "/e"}, {"type", "my/Events"}, {"md5sum", "x"}, {"message_definition", def}}, "");
  const std::string conn2 = bag_record({{"op", "\x07"}, {"conn", bytes_of<std::uint32_t>(0)}, {"topic", "/e"}},
                                       conn2_data.substr(4, conn2_data.size() - 8));
  const std::string short_msg = bag_record({{"op", "\x02"}, {"conn", bytes_of<std::uint32_t>(0)}, {"time", bytes_of<std::uint64_t>(5)}},
                                           bytes_of<std::uint32_t>(3) + std::string(20, '\0'));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn2 + short_msg), "(topic /e, message 0): message ends early (needs 39 more bytes, has 20)");
  // Events that go back in time inside one message; a message of a connection never defined.
  std::string two;
  two += bytes_of<std::uint16_t>(1) + bytes_of<std::uint16_t>(1) + bytes_of<std::uint32_t>(10) + bytes_of<std::uint32_t>(5) + '\1';
  two += bytes_of<std::uint16_t>(2) + bytes_of<std::uint16_t>(1) + bytes_of<std::uint32_t>(10) + bytes_of<std::uint32_t>(4) + '\0';
  const std::string back = bag_record({{"op", "\x02"}, {"conn", bytes_of<std::uint32_t>(0)}, {"time", bytes_of<std::uint64_t>(5)}},
                                      bytes_of<std::uint32_t>(2) + two);
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn2 + back), "(topic /e, message 0), event 1: time goes back");
  const std::string orphan = bag_record({{"op", "\x02"}, {"conn", bytes_of<std::uint32_t>(9)}, {"time", bytes_of<std::uint64_t>(5)}}, "");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn2 + orphan), "message of connection 9, which the bag never defines");
  // Pixels outside the sensor given; no calibration anywhere.
  std::string one = bytes_of<std::uint16_t>(300) + bytes_of<std::uint16_t>(1) + bytes_of<std::uint32_t>(10) + bytes_of<std::uint32_t>(5) + '\1';
  const std::string wide = bag_record({{"op", "\x02"}, {"conn", bytes_of<std::uint32_t>(0)}, {"time", bytes_of<std::uint64_t>(5)}},
                                      bytes_of<std::uint32_t>(1) + one);
  write(dir / "calib.txt", "10 10 4 3\n");
  io::LoadOptions o;
  o.width = 240;
  o.height = 180;
  write(dir / "w.bag", "#ROSBAG V2.0\n" + header + conn2 + wide);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "w.bag", o); }), "event 0 of topic /e: pixel (300, 1) lies outside the 240x180 sensor");
  CHECK(io::load(dir / "w.bag").camera.width() == 301);  // no size anywhere: the events' extent

  // Every truncation and many single-byte changes of a real bag: a result or an evnerf::Error.
  const std::string good = read_file(fs::path(EVNERF_FIXTURES) / "davis_bz2.bag");
  int refused = 0, read = 0;
  for (std::size_t n = 0; n < good.size(); n += 61) {
    write(dir / "t.bag", good.substr(0, n));
    try {
      io::load(dir / "t.bag");
      ++read;
    } catch (const Error& e) {
      ++refused;
      CHECK_CONTAINS(std::string(e.what()), "t.bag");
    }
  }
  CHECK(refused > 0);
  for (std::size_t i = 13; i < good.size(); i += 37) {
    std::string flipped = good;
    flipped[i] = static_cast<char>(flipped[i] ^ 0x5a);
    write(dir / "f.bag", flipped);
    try {
      io::load(dir / "f.bag");
      ++read;
    } catch (const Error& e) {
      ++refused;
    }
  }
  CHECK(read > 0);
  fs::remove_all(dir);
}

TEST_CASE("ROS bag: message definitions (constants, arrays, nested and implicit types) and image encodings") {
  using namespace io::detail;
  const auto s = parse_msg_definition("pkg/Top",
                                      "# comment\nint32 A=5  # a constant\nstring NAME=x=y\nHeader header\nInner[3] fixed\nInner[] var\n"
                                      "float64[9] K\n=====\nMSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
                                      "=====\nMSG: pkg/Inner\nuint8 a\nduration d\n",
                                      "w");
  REQUIRE(s.root().fields.size() == 4);
  CHECK(s.root().fields[0].name == "header");
  CHECK(s.types[static_cast<std::size_t>(s.root().fields[1].type)].name == "pkg/Inner");
  CHECK(s.root().fields[1].array == 3);
  CHECK(s.root().fields[2].array == -1);
  CHECK(s.types[static_cast<std::size_t>(s.root().fields[1].type)].fixed == 9);
  CHECK(s.root().fixed == -1);
  CHECK_CONTAINS(error_of([] { parse_msg_definition("a/B", "a/B self\n", "w"); }), "contains itself");
  CHECK_CONTAINS(error_of([] { parse_msg_definition("a/B", "uint8[x] v\n", "w"); }), "bad array length");

  // An empty variable-length array (a CameraInfo's D without distortion; found by fuzz_rosbag).
  const std::string msg_where = "msg";
  const unsigned char zero_count[4] = {0, 0, 0, 0};
  MsgField d_field;
  d_field.name = "D";
  d_field.prim = Prim::Float64;
  d_field.array = -1;
  MsgCursor cur{zero_count, zero_count + 4, &msg_where};
  CHECK(msg_read_f64s(d_field, cur, -1, "sensor_msgs/CameraInfo").empty());
  CHECK(cur.p == zero_count + 4);

  const std::string where = "img";
  const unsigned char rgb[] = {10, 20, 30, 40, 50, 60, 0, 0};  // 2x1 rgb8, step 8 (padding)
  auto im = bag_image(2, 1, "rgb8", false, 8, rgb, sizeof rgb, where);
  CHECK(im.channels == 3);
  CHECK(im.at(1, 0, 2) == doctest::Approx(60 / 255.0));
  const unsigned char m16[] = {0x12, 0x34, 0xff, 0xff};  // 2x1 mono16, big-endian
  im = bag_image(2, 1, "mono16", true, 4, m16, sizeof m16, where);
  CHECK(im.at(0, 0) == doctest::Approx(0x1234 / 65535.0));
  CHECK_CONTAINS(error_of([&] { bag_image(2, 1, "rgb8", false, 5, rgb, sizeof rgb, where); }), "img: row step 5 is shorter than a row of rgb8 pixels");
  CHECK_CONTAINS(error_of([&] { bag_image(2, 2, "rgb8", false, 8, rgb, sizeof rgb, where); }), "image data holds 8 bytes");
  CHECK_CONTAINS(error_of([&] { bag_image(2, 1, "yuv422", false, 8, rgb, sizeof rgb, where); }), "unknown image encoding 'yuv422'");

  // Demosaicing a uniform colour gives that colour everywhere, for every pattern.
  for (const char* name : {"rggb", "bggr", "gbrg", "grbg"}) {
    geometry::BayerPattern p;
    REQUIRE(geometry::BayerPattern::parse(name, p));
    CHECK(p.name() == name);
    Image mosaic(5, 4);
    const float colour[3] = {0.2f, 0.5f, 0.9f};
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 5; ++x) mosaic.at(x, y) = colour[p.at(x, y)];
    const auto rgb_img = geometry::demosaic(mosaic, p);
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 5; ++x)
        for (int c = 0; c < 3; ++c) CHECK(rgb_img.at(x, y, c) == doctest::Approx(colour[c]));
  }
  geometry::BayerPattern q;
  CHECK(!geometry::BayerPattern::parse("rgbg", q));
  CHECK(!geometry::BayerPattern::parse("rggbx", q));
}
#endif

// ---- EventNeRF's layout: fixtures written by numpy and PIL (tests/fixtures/make_eventnerf.py) ----
TEST_CASE("EventNeRF layout: events from .npz (deflated or stored), poses spread over the events' time, frames, intrinsics") {
  const fs::path fx = EVNERF_FIXTURES;
  CHECK(io::is_eventnerf(fx / "eventnerf"));
  CHECK(!io::is_eventnerf(fx));
  const auto d = io::load(fx / "eventnerf");
  CHECK(d.camera.width() == 8);  // the frames' size
  CHECK(d.camera.height() == 6);
  CHECK(d.camera.fx() == 20);
  CHECK(d.camera.fy() == 21);
  CHECK(d.camera.cx() == 3.5);
  CHECK(d.camera.cy() == 2.5);
  CHECK(!d.camera.distorted());
  REQUIRE(d.events.size() == 40);
  for (std::size_t k = 0; k < 40; ++k) {
    CHECK(d.events.x[k] == k % 8);
    CHECK(d.events.y[k] == k % 6);
    CHECK(d.events.polarity[k] == (k % 2 == 0 ? 1 : -1));
    CHECK(d.events.t[k] == 1e-4 * double(k));
  }
  REQUIRE(d.trajectory.size() == 5);  // view i at i / 4 · max(t)
  CHECK(d.trajectory.times()[2] == doctest::Approx(0.5 * 0.0039));
  CHECK(d.trajectory.times()[4] == d.events.t.back());
  const auto& p2 = d.trajectory.poses()[2];
  CHECK(p2.t.x() == doctest::Approx(0.2));
  CHECK(p2.t.z() == doctest::Approx(1.02));
  CHECK(std::abs(p2.q.y()) == doctest::Approx(std::sin(0.05)));
  CHECK(std::abs(p2.q.w()) == doctest::Approx(std::cos(0.05)));
  REQUIRE(d.frames.size() == 5);
  CHECK(d.frames.t == d.trajectory.times());
  CHECK(io::frame_image(d.frames, 1).data[5] == doctest::Approx(10 / 255.0));

  // Stored members, bool polarities, no frames (the sensor is EventNeRF's 346x260), and a division-model
  // distortion turned into radial coefficients that move every pixel where EventNeRF's model does.
  const auto e = io::load(fx / "eventnerf_dist");
  CHECK(e.camera.width() == 346);
  CHECK(e.events.polarity == d.events.polarity);
  CHECK(e.events.t == d.events.t);
  CHECK(e.frames.size() == 0);
  REQUIRE(e.camera.distorted());
  double worst = 0;
  for (double u : {0.0, 100.0, 345.0})
    for (double v : {0.0, 130.0, 259.0}) {
      const double xd = (u - 173) / 250, yd = (v - 130) / 250, r2 = xd * xd + yd * yd, D = 1 - 0.1 * r2 + 0.02 * r2 * r2;
      const Vec2 back = e.camera.project_normalized({xd / D, yd / D});
      worst = std::max({worst, std::abs(back.x() - u), std::abs(back.y() - v)});
    }
  CHECK(worst < 0.05);
}

TEST_CASE("io::load: a folder holding two layouts is refused unless --format names one; --format checks what it is given") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto dir = temp_dir("twolayouts");
  fs::copy(fx / "eventnerf", dir, fs::copy_options::recursive);
  const auto enf = io::load(dir);  // one layout: read from the content
  io::write_ijrr(dir, enf);        // now an IJRR folder too
  CHECK_CONTAINS(error_of([&] { io::load(dir); }), "the folder holds several layouts (ijrr, eventnerf): choose one with --format");
  io::LoadOptions o;
  o.use_cache = false;
  o.format = "eventnerf";
  const auto a = io::load(dir, o);
  CHECK(a.events.t == enf.events.t);
  CHECK(a.trajectory.size() == 5);
  o.format = "ijrr";
  const auto b = io::load(dir, o);
  CHECK(b.events.x == enf.events.x);
  CHECK(b.events.size() == 40);
  o.format = "hdf5";
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "format 'hdf5' is a file, and this is a folder");
  o.format = "ijrr";
  CHECK_CONTAINS(error_of([&] { io::load(fx / "davis.bag", o); }), "davis.bag:0: format 'ijrr' is a folder, and this is a file");
#ifdef EVNERF_HAVE_ROSBAG
  o.format = "rosbag";
  CHECK(io::load(fx / "davis.bag", o).events.size() > 0);
#endif
  o.format = "hdf";
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "unknown format 'hdf' (known: ijrr, eventnerf, robust-e-nerf, hdf5, rosbag)");
  // A time window, for every reader: only the events inside it, and an error when none are.
  o.format = "eventnerf";
  o.t_begin = 0.00115;
  o.t_end = 0.00245;
  const auto w = io::load(dir, o);
  REQUIRE(w.events.size() == 13);
  CHECK(w.events.t.front() == enf.events.t[12]);
  CHECK(w.trajectory.size() == 5);  // poses and frames stay whole
  o.t_begin = 1.0;
  o.t_end = 2.0;
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "no events in the time window [1, 2) s");
  o.t_end = 1.0;
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }), "time window [1, 1) s is empty");
  fs::remove_all(dir);
}

TEST_CASE("EventNeRF layout and .npz: bad archives and folders are refused with the file and what is wrong") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto dir = temp_dir("enf");
  fs::copy(fx / "eventnerf", dir / "s", fs::copy_options::recursive);
  const auto npz = dir / "s" / "train" / "events" / "events.npz";
  const std::string good = read_file(npz);
  auto err = [&] { return error_of([&] { io::load(dir / "s"); }); };
  // Every truncation and many single-byte changes of the archive: an evnerf::Error, never a crash.
  int refused = 0;
  for (std::size_t n = 0; n < good.size(); n += 7) {
    write(npz, good.substr(0, n));
    refused += err().find("events.npz:0: ") != std::string::npos;
  }
  CHECK(refused == static_cast<int>((good.size() + 6) / 7));
  for (std::size_t i = 0; i < good.size(); i += 3) {
    std::string f = good;
    f[i] = static_cast<char>(f[i] ^ 0x20);
    write(npz, f);
    const std::string e = err();
    CHECK((e == "no error" || e.find("events.npz") != std::string::npos));
  }
  // A flipped byte inside a deflated member is caught by deflate or by the CRC.
  std::string f = good;
  const std::size_t data = f.find("x.npy") + 5 + 20;
  f[data] = static_cast<char>(f[data] ^ 0x01);
  write(npz, f);
  CHECK_CONTAINS(err(), "events.npz:0: cannot read .npz: member 'x.npy'");
  write(npz, good);
  fs::copy_file(npz, npz.parent_path() / "more.npz");
  CHECK_CONTAINS(err(), "expected one .npz archive of events, found 2");
  fs::remove(npz.parent_path() / "more.npz");
  write(dir / "s" / "train" / "pose" / "r_00003.txt", "1 0 0 0\n0 2 0 0\n0 0 1 0\n0 0 0 1\n");
  CHECK_CONTAINS(err(), "r_00003.txt:0: the upper-left 3x3 is not a rotation");
  fs::copy_file(fx / "eventnerf" / "train" / "pose" / "r_00003.txt", dir / "s" / "train" / "pose" / "r_00003.txt", fs::copy_options::overwrite_existing);
  write(dir / "s" / "train" / "intrinsics" / "r_00002.txt", "21 0 3.5 0\n0 21 2.5 0\n0 0 1 0\n0 0 0 1\n");
  CHECK_CONTAINS(err(), "r_00002.txt:0: differs from r_00000.txt (one camera is read)");
  fs::remove(dir / "s" / "train" / "rgb" / "r_00004.png");
  CHECK_CONTAINS(err(), "rgb:0: 4 frames for 5 poses");
  fs::remove_all(dir);
}

// ---- Robust e-NeRF's layout: a fixture written by numpy (tests/fixtures/make_robust_e_nerf.py) ----
TEST_CASE("Robust e-NeRF layout: events, poses and calibration from its numpy archives, times exact in ns") {
  const fs::path fx = EVNERF_FIXTURES;
  CHECK(io::is_robust_e_nerf(fx / "robust_e_nerf"));
  const auto d = io::load(fx / "robust_e_nerf");
  CHECK(d.time_origin == 1600000000);
  CHECK(d.bayer_pattern == "rggb");
  CHECK(d.camera.width() == 8);
  CHECK(d.camera.height() == 6);
  CHECK(d.camera.fx() == 20);
  CHECK(d.camera.cy() == 2.5);
  CHECK(d.camera.distortion()[0] == doctest::Approx(0.1));
  CHECK(d.camera.distortion()[3] == doctest::Approx(0.002));
  REQUIRE(d.events.size() == 40);
  for (std::size_t k = 0; k < 40; ++k) {
    CHECK(d.events.x[k] == k % 8);
    CHECK(d.events.y[k] == k % 6);
    CHECK(d.events.polarity[k] == (k % 2 == 0 ? 1 : -1));
    CHECK(d.events.t[k] == static_cast<double>(250000000 + 100000 * k) / 1e9);  // exact: integers all the way
  }
  REQUIRE(d.trajectory.size() == 5);
  CHECK(d.trajectory.times()[3] == 0.253);
  CHECK(d.trajectory.poses()[4].t.x() == doctest::Approx(0.4));
  CHECK(d.trajectory.poses()[4].q.z() == doctest::Approx(std::sin(0.1)).epsilon(1e-6));

  // Damaged: a missing array, an unreadable model string, a time that goes back.
  const auto dir = temp_dir("ren");
  fs::copy(fx / "robust_e_nerf", dir / "s", fs::copy_options::recursive);
  const auto bad = dir / "s" / "raw_events.npz";
  std::string zip = read_file(bad);
  const auto at = zip.rfind("polarity.npy");  // the central directory's name of the member
  REQUIRE(at != std::string::npos);
  zip.replace(at, 8, "polarizd");
  write(bad, zip);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }), "raw_events.npz:0: no array 'polarity'");
  CHECK(io::parse_npy_string(std::string("\x93NUMPY\x01\x00\x36\x00{'descr': '<U2', 'fortran_order': False, 'shape': (), }      \n", 64) +
                                 std::string("o\0\0\0k\0\0\0", 8),
                             "s") == "ok");
  CHECK_CONTAINS(error_of([] { io::parse_npy_string(std::string("\x93NUMPY\x01\x00\x36\x00{'descr': '<f8', 'fortran_order': False, 'shape': (), }      \n", 64), "s"); }),
                 "not a string ('<U') array");
  fs::remove_all(dir);
}

namespace {
/// One .npy (format 1.0) of little-endian values: `descr` such as "<i8", `shape` as numpy prints it.
template <class T>
std::string npy_of(const std::string& descr, const std::string& shape, const std::vector<T>& v) {
  std::string dict = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
  dict.append(63 - (10 + dict.size()) % 64, ' ');
  dict += '\n';
  std::string out = "\x93NUMPY\x01";
  out += '\0';
  out += static_cast<char>(dict.size() & 0xFF);
  out += static_cast<char>(dict.size() >> 8);
  out += dict;
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  return out;
}
/// A .npz as numpy's savez writes it: a zip of stored members "<name>.npy", with CRC-32s.
std::string npz_of(const std::vector<std::pair<std::string, std::string>>& members) {
  auto le = [](std::string& s, std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) s += static_cast<char>((v >> (8 * i)) & 0xFF);
  };
  std::string body, dir;
  for (const auto& [key, bytes] : members) {
    const std::string name = key + ".npy";
    const auto crc = io::detail::zip_crc32(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
    const std::uint64_t local = body.size();
    body += "PK\x03\x04";
    le(body, 20, 2), le(body, 0, 2), le(body, 0, 2), le(body, 0, 4), le(body, crc, 4);
    le(body, bytes.size(), 4), le(body, bytes.size(), 4), le(body, name.size(), 2), le(body, 0, 2);
    body += name + bytes;
    dir += "PK\x01\x02";
    le(dir, 20, 2), le(dir, 20, 2), le(dir, 0, 2), le(dir, 0, 2), le(dir, 0, 4), le(dir, crc, 4);
    le(dir, bytes.size(), 4), le(dir, bytes.size(), 4), le(dir, name.size(), 2), le(dir, 0, 2), le(dir, 0, 2);
    le(dir, 0, 2), le(dir, 0, 2), le(dir, 0, 4), le(dir, local, 4);
    dir += name;
  }
  std::string out = body + dir + "PK\x05\x06";
  le(out, 0, 4), le(out, members.size(), 2), le(out, members.size(), 2), le(out, dir.size(), 4), le(out, body.size(), 4), le(out, 0, 2);
  return out;
}
}  // namespace

TEST_CASE("Robust e-NeRF layout: times anywhere in int64 are refused or read exactly, never wrapped") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto dir = temp_dir("ren_range");
  fs::copy(fx / "robust_e_nerf", dir / "s", fs::copy_options::recursive);
  auto events = [&](std::int64_t t0, std::int64_t t1) {
    write(dir / "s" / "raw_events.npz",
          npz_of({{"position", npy_of<std::uint16_t>("<u2", "(2, 2)", {1, 2, 3, 4})},
                  {"timestamp", npy_of<std::int64_t>("<i8", "(2,)", {t0, t1})},
                  {"polarity", npy_of<std::uint8_t>("|u1", "(2,)", {1, 0})}}));
  };
  auto poses = [&](std::int64_t a, std::int64_t b) {
    write(dir / "s" / "camera_poses.npz",
          npz_of({{"T_wc_position", npy_of<double>("<f8", "(2, 3)", {0, 0, 0, 0.1, 0, 0})},
                  {"T_wc_orientation", npy_of<double>("<f8", "(2, 4)", {0, 0, 0, 1, 0, 0, 0, 1})},
                  {"T_wc_timestamp", npy_of<std::int64_t>("<i8", "(2,)", {a, b})}}));
  };
  constexpr std::int64_t lo = std::numeric_limits<std::int64_t>::min(), hi = std::numeric_limits<std::int64_t>::max();
  // The helpers write what the reader reads: far from the ends of int64, exactly.
  events(1'600'000'000'250'000'000, 1'600'000'000'251'000'000);
  poses(1'600'000'000'000'000'000, 1'600'000'001'000'000'000);
  const auto d = io::load(dir / "s");
  CHECK(d.time_origin == 1'600'000'000);
  REQUIRE(d.events.size() == 2);
  CHECK(d.events.t[1] == 0.251);
  CHECK(d.trajectory.times() == std::vector<double>{0.0, 1.0});
  // 1.8e19 ns (584 years) after the first event: int64 arithmetic would wrap it to 1 s before it.
  const std::int64_t first = -9'223'372'036'000'000'000;
  events(first, first + 1'000'000);
  poses(9'223'372'036'709'551'616, first + 2'000'000'000);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }), "camera_poses.npz:0: pose 0: time 9223372036709551616 ns lies more than 104 days from the first event");
  // The same for an event, and for a first event whose whole second lies below int64's range.
  events(first, hi);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }), "raw_events.npz:0: event 1: time 9223372036854775807 ns lies more than 104 days");
  events(lo, lo + 1'000'000);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }), "raw_events.npz:0: event 0: time -9223372036854775808 ns has no whole second within int64's range");
  fs::remove_all(dir);
}

TEST_CASE("EventNeRF and Robust e-NeRF folders: a sensor too large is refused before anything per pixel, naming what gave its size") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto dir = temp_dir("layout_size");
  // Robust e-NeRF: img_width and img_height of 65535 (each in range, together 4.3 G pixels).
  fs::copy(fx / "robust_e_nerf", dir / "r", fs::copy_options::recursive);
  write(dir / "r" / "camera_calibration.npz",
        npz_of({{"intrinsics", npy_of<double>("<f8", "(3, 3)", {20, 0, 3.5, 0, 21, 2.5, 0, 0, 1})},
                {"img_height", npy_of<std::uint16_t>("<u2", "()", {65535})},
                {"img_width", npy_of<std::uint16_t>("<u2", "()", {65535})}}));
  CHECK_CONTAINS(error_of([&] { io::load(dir / "r"); }),
                 "camera_calibration.npz (its img_width and img_height):0: sensor size 65535x65535 has more than 67108864 pixels");
  io::LoadOptions given;
  given.width = given.height = 9000;
  CHECK_CONTAINS(error_of([&] { io::load(dir / "r", given); }), "r (the sensor size given):0: sensor size 9000x9000 has more than");
  // EventNeRF: the first frame's header says 10000 x 10000 (stb_image reads only the header for the size).
  fs::copy(fx / "eventnerf", dir / "e", fs::copy_options::recursive);
  std::string png = "\x89PNG\r\n\x1a\n";
  png += std::string("\0\0\0\x0dIHDR", 8);
  png += std::string("\0\0\x27\x10\0\0\x27\x10\x08\0\0\0\0", 13);
  png += std::string("\0\0\0\0", 4);  // the CRC, which the header read does not check
  write(dir / "e" / "train" / "rgb" / "r_00000.png", png);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "e"); }), "r_00000.png (the first frame, which gives the sensor size):0: sensor size 10000x10000");
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
    CHECK(io::channel_dataset(rec, p, 0, io::GreenSites::Both).camera.width() == geometry::site_camera(full, geometry::site_of(p, 0)).width());
    CHECK(io::channel_dataset(rec, p, 0, io::GreenSites::Both).sites.empty());
  }
}
