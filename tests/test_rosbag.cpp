// The ROS bag reader: bags written by python3-rosbag, topics, unindexed bags, damaged bags, message
// definitions and image encodings.
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

TEST_CASE("ROS bag: topics by name when two could serve, colour and Bayer frames, Odometry poses, calibration beside") {
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
  CHECK(m.at(2, 2, 0) == doctest::Approx(raw(2, 2)));                                            // R site
  CHECK(m.at(2, 2, 1) == doctest::Approx((raw(1, 2) + raw(3, 2) + raw(2, 1) + raw(2, 3)) / 4));  // G: 4 neighbours
  CHECK(m.at(2, 2, 2) == doctest::Approx((raw(1, 1) + raw(3, 1) + raw(1, 3) + raw(3, 3)) / 4));  // B: 4 diagonals

  o.images_topic = "none";
  CHECK(io::load(fx / "colour.bag", o).frames.size() == 0);
  o.events_topic = "/vicon/odom";
  CHECK_CONTAINS(error_of([&] { io::load(fx / "colour.bag", o); }),
                 "topic /vicon/odom (nav_msgs/Odometry) cannot be the events: it has no field 'events'");
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
  // An index position past the end (a bag cut short after it was closed) is scanned, and said so once.
  std::string bad = good;
  const std::uint64_t past = bad.size() + 10;
  std::memcpy(bad.data() + at, &past, 8);
  write(dir / "badidx.bag", bad);
  {
    WarningCollector said;
    const auto c = io::load(dir / "badidx.bag");
    CHECK(c.events.t == a.events.t);
    REQUIRE(said.messages().size() == 1);
    CHECK_CONTAINS(said.messages()[0],
                   "badidx.bag: the bag header places its index at byte " + std::to_string(past) + ", past the end of the file");
  }
  {
    // inspect lists the topics and reads the bag: the listing leaves the one warning to the read.
    WarningCollector said;
    CHECK_CONTAINS(io::rosbag_summary(dir / "badidx.bag"), "/dvs/events");
    CHECK(said.messages().empty());
  }
  // One before the first record is refused: nothing cut short puts it there.
  const std::uint64_t before = 20;
  std::memcpy(bad.data() + at, &before, 8);
  write(dir / "badidx.bag", bad);
  CHECK_CONTAINS(error_of([&] { io::load(dir / "badidx.bag"); }), "index position 20 lies before the file's records");
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
  const std::string header = bag_record({{"op", "\x03"},
                                         {"index_pos", bytes_of<std::uint64_t>(0)},
                                         {"conn_count", bytes_of<std::uint32_t>(0)},
                                         {"chunk_count", bytes_of<std::uint32_t>(0)}},
                                        std::string(100, ' '));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header), "the bag has no connections");
  CHECK_CONTAINS(
      err("#ROSBAG V2.0\n" + header + bag_record({{"op", "\x05"}, {"compression", "zstd"}, {"size", bytes_of<std::uint32_t>(3)}}, "abc")),
      "chunk at byte " + std::to_string(13 + header.size()) + ": unknown chunk compression 'zstd'");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header +
                     bag_record({{"op", "\x05"}, {"compression", "bz2"}, {"size", bytes_of<std::uint32_t>(1000)}}, "BZh9garbage")),
                 "chunk at byte " + std::to_string(13 + header.size()) + ": corrupt bz2 chunk");
  CHECK_CONTAINS(
      err("#ROSBAG V2.0\n" + header + bag_record({{"op", "\x05"}, {"compression", "none"}, {"size", bytes_of<std::uint32_t>(7)}}, "abc")),
      "uncompressed chunk holds 3 bytes, its header says 7");
  // A header that claims 2 GB for a few compressed bytes allocates nothing for them.
  CHECK_CONTAINS(
      err("#ROSBAG V2.0\n" + header +
          bag_record({{"op", "\x05"}, {"compression", "lz4"}, {"size", bytes_of<std::uint32_t>(0x7fffffff)}}, "\x04\x22\x4d\x18garbage")),
      "corrupt lz4 chunk");
  // A connection whose definition lacks a type it uses; an event message that ends early.
  const std::string conn_data =
      bag_record({{"topic", "/e"}, {"type", "my/Events"}, {"md5sum", "x"}, {"message_definition", "Ev[] events\n"}}, "");
  const std::string conn =
      bag_record({{"op", "\x07"}, {"conn", bytes_of<std::uint32_t>(0)}, {"topic", "/e"}}, conn_data.substr(4, conn_data.size() - 8));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn), "no events topic");
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn), "field 'events' of my/Events has type 'Ev', whose definition is not included");
  const std::string def = "Ev[] events\n================\nMSG: my/Ev\nuint16 x\nuint16 y\ntime ts\nbool polarity\n";
  const std::string conn2_data = bag_record({{"topic", "/e"}, {"type", "my/Events"}, {"md5sum", "x"}, {"message_definition", def}}, "");
  const std::string conn2 =
      bag_record({{"op", "\x07"}, {"conn", bytes_of<std::uint32_t>(0)}, {"topic", "/e"}}, conn2_data.substr(4, conn2_data.size() - 8));
  const std::string short_msg = bag_record({{"op", "\x02"}, {"conn", bytes_of<std::uint32_t>(0)}, {"time", bytes_of<std::uint64_t>(5)}},
                                           bytes_of<std::uint32_t>(3) + std::string(20, '\0'));
  CHECK_CONTAINS(err("#ROSBAG V2.0\n" + header + conn2 + short_msg),
                 "(topic /e, message 0): message ends early (needs 39 more bytes, has 20)");
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
  std::string one =
      bytes_of<std::uint16_t>(300) + bytes_of<std::uint16_t>(1) + bytes_of<std::uint32_t>(10) + bytes_of<std::uint32_t>(5) + '\1';
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
  CHECK_CONTAINS(error_of([&] { bag_image(2, 1, "rgb8", false, 5, rgb, sizeof rgb, where); }),
                 "img: row step 5 is shorter than a row of rgb8 pixels");
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
