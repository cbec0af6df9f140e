// The folder layouts of EventNeRF and Robust e-NeRF: fixtures written by numpy and PIL, bad archives
// and folders, times in int64, sensors too large; a folder holding two layouts.
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
#include "io_helpers.hpp"

using namespace evnerf;
namespace fs = std::filesystem;
using evtest::error_of;
using evtest::temp_dir;
using evtest::write;

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

TEST_CASE("io::load: a folder holding two layouts is refused unless --format names one, --format checks what it is given") {
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
  CHECK_CONTAINS(error_of([&] { io::load(dir, o); }),
                 "unknown format 'hdf' (known: ijrr, eventnerf, robust-e-nerf, evt2, evt3, dat, hdf5, rosbag, aedat4)");
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
  fs::copy_file(fx / "eventnerf" / "train" / "pose" / "r_00003.txt", dir / "s" / "train" / "pose" / "r_00003.txt",
                fs::copy_options::overwrite_existing);
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
  CHECK_CONTAINS(error_of([] {
                   io::parse_npy_string(
                       std::string("\x93NUMPY\x01\x00\x36\x00{'descr': '<f8', 'fortran_order': False, 'shape': (), }      \n", 64), "s");
                 }),
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
    write(dir / "s" / "raw_events.npz", npz_of({{"position", npy_of<std::uint16_t>("<u2", "(2, 2)", {1, 2, 3, 4})},
                                                {"timestamp", npy_of<std::int64_t>("<i8", "(2,)", {t0, t1})},
                                                {"polarity", npy_of<std::uint8_t>("|u1", "(2,)", {1, 0})}}));
  };
  auto poses = [&](std::int64_t a, std::int64_t b) {
    write(dir / "s" / "camera_poses.npz", npz_of({{"T_wc_position", npy_of<double>("<f8", "(2, 3)", {0, 0, 0, 0.1, 0, 0})},
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
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }),
                 "camera_poses.npz:0: pose 0: time 9223372036709551616 ns lies more than 104 days from the first event");
  // The same for an event, and for a first event whose whole second lies below int64's range.
  events(first, hi);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }), "raw_events.npz:0: event 1: time 9223372036854775807 ns lies more than 104 days");
  events(lo, lo + 1'000'000);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "s"); }),
                 "raw_events.npz:0: event 0: time -9223372036854775808 ns has no whole second within int64's range");
  fs::remove_all(dir);
}

TEST_CASE("EventNeRF and Robust e-NeRF folders: a sensor too large is refused before anything per pixel, naming what gave its size") {
  const fs::path fx = EVNERF_FIXTURES;
  const auto dir = temp_dir("layout_size");
  // Robust e-NeRF: img_width and img_height of 65535 (each in range, together 4.3 G pixels).
  fs::copy(fx / "robust_e_nerf", dir / "r", fs::copy_options::recursive);
  write(dir / "r" / "camera_calibration.npz", npz_of({{"intrinsics", npy_of<double>("<f8", "(3, 3)", {20, 0, 3.5, 0, 21, 2.5, 0, 0, 1})},
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
  CHECK_CONTAINS(error_of([&] { io::load(dir / "e"); }),
                 "r_00000.png (the first frame, which gives the sensor size):0: sensor size 10000x10000");
  fs::remove_all(dir);
}
