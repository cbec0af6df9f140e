#include <evnerf/core/parallel.hpp>
#include <evnerf/core/progress.hpp>
#include <evnerf/core/rng.hpp>
#include <evnerf/geometry/camera.hpp>
#include <evnerf/geometry/trajectory.hpp>
#include <evnerf/io/colmap.hpp>

#include "common.hpp"

using namespace evnerf;
using namespace evnerf::geometry;

TEST_CASE("rng: counter-based streams are reproducible and roughly uniform") {
  Rng a(42), b(42), c(43);
  CHECK(a.next_u64() == b.next_u64());
  CHECK(a.next_u64() != c.next_u64());
  Rng r(1);
  double sum = 0, sq = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const double u = r.uniform();
    REQUIRE(u >= 0.0);
    REQUIRE(u < 1.0);
    sum += u;
  }
  CHECK(sum / n == doctest::Approx(0.5).epsilon(0.01));
  for (int i = 0; i < n; ++i) sq += r.normal() * 0 + std::pow(r.normal(), 2);
  CHECK(sq / n == doctest::Approx(1.0).epsilon(0.03));
  CHECK(r.split(1).next_u64() != r.split(2).next_u64());
}

TEST_CASE("ReadProgressLine: silent for a short read, then a line a second, and one at the end") {
  double t = 0;
  std::FILE* out = std::tmpfile();
  REQUIRE(out);
  ReadProgressLine line("rec.raw", out, 1.0, 1.0, [&] { return t; });
  const std::uint64_t total = 4'000'000'000ull;
  line(100, total);  // t = 0: within the delay
  t = 0.5, line(1'000'000'000ull, total);
  t = 1.5, line(1'500'000'000ull, total);  // shown
  t = 2.0, line(1'600'000'000ull, total);  // within a second of the last: not shown
  t = 2.6, line(2'000'000'000ull, total);  // shown
  t = 3.0, line(total, total);             // the end: always shown, once
  t = 3.1, line(total, total);
  std::rewind(out);
  std::string got;
  for (int c; (c = std::fgetc(out)) != EOF;) got.push_back(static_cast<char>(c));
  std::fclose(out);
  CHECK(got ==
        "reading rec.raw: 38 % (1.50 of 4.00 GB) 1.5 s, eta 2.5 s\n"
        "reading rec.raw: 50 % (2.00 of 4.00 GB) 2.6 s, eta 2.6 s\n"
        "reading rec.raw: 100 % (4.00 of 4.00 GB) 3.0 s\n");
  // A read done within the delay prints nothing at all.
  t = 0;
  std::FILE* quiet = std::tmpfile();
  ReadProgressLine fast("small.txt", quiet, 1.0, 1.0, [&] { return t; });
  t = 0.2, fast(10, 10);
  CHECK(std::ftell(quiet) == 0);
  std::fclose(quiet);
}

TEST_CASE("parallel_jobs_by_cost: every job once, each thread a contiguous run of about equal cost") {
  auto run = [](int threads, const std::vector<double>& cost) {
    ScopedThreadCount tc(threads);
    std::vector<int> owner(cost.size(), -1), times(cost.size(), 0);
    parallel_jobs_by_cost(
        cost.size(), [&](std::size_t j) { return cost[j]; },
        [&](std::size_t j) {
          owner[j] = omp_get_thread_num();
          ++times[j];  // each job by one thread only: no race
        });
    CHECK(std::all_of(times.begin(), times.end(), [](int n) { return n == 1; }));
    CHECK(std::is_sorted(owner.begin(), owner.end()));  // contiguous runs, in thread order
    return owner;
  };
  // A hash grid's flush: two threads' deferred samples (300 and 100) over 4 levels each.
  const std::vector<double> flush = {300, 300, 300, 300, 100, 100, 100, 100};
  const auto o = run(2, flush);
  double load[2] = {0, 0};
  for (std::size_t j = 0; j < flush.size(); ++j) load[o[j]] += flush[j];
  CHECK(load[0] == 900);  // the first three levels of the first thread's, against 700
  CHECK(load[1] == 700);
  CHECK(run(1, flush) == std::vector<int>(8, 0));
  // Equal costs, and all zero: even counts.
  const auto even = run(2, std::vector<double>(32, 1.0));
  CHECK(std::count(even.begin(), even.end(), 0) == 16);
  const auto zero = run(3, std::vector<double>(9, 0.0));
  CHECK(zero == std::vector<int>{0, 0, 0, 1, 1, 1, 2, 2, 2});
  // Fewer jobs than threads, one job, none.
  CHECK(run(4, {5.0, 1.0}).size() == 2);
  CHECK(run(2, {7.0}) == std::vector<int>{0});
  CHECK(run(2, {}).empty());
  // One job carrying almost everything: the split falls at it.
  CHECK(run(2, {1, 1, 100, 1, 1}) == std::vector<int>{0, 0, 1, 1, 1});
}

TEST_CASE("trajectory: interpolation is linear in translation and slerp in rotation, range policy") {
  Pose a, b;
  b.t = Vec3(2, 0, 0);
  b.q = Quat(Eigen::AngleAxisd(1.0, Vec3::UnitZ()));
  Trajectory tr({1.0, 2.0}, {a, b}, "test");
  const Pose m = tr.pose_at(1.5);
  CHECK(m.t.x() == doctest::Approx(1.0));
  CHECK(Eigen::AngleAxisd(m.q).angle() == doctest::Approx(0.5));
  CHECK(tr.pose_at(1.0).t.x() == doctest::Approx(0.0));
  CHECK(tr.pose_at(2.0).t.x() == doctest::Approx(2.0));
  CHECK_THROWS_WITH_AS(tr.pose_at(0.5), doctest::Contains("outside the poses' range"), Error);
  CHECK(tr.pose_at(2.5, OutOfRange::Clamp).t.x() == doctest::Approx(2.0));
  CHECK_THROWS_AS(Trajectory({1.0, 1.0}, {a, b}), Error);
}

TEST_CASE("camera: distort(undistort(p)) round-trips within 1e-3 px over the whole sensor") {
  // Strong distortion of the IJRR rotation sequences' calibration.
  Camera cam(240, 180, 199.092366542, 198.82882047, 132.192071378, 110.712660011,
             {-0.368436311798, 0.150947243557, -0.000296130534385, -0.000759431726241, 0.0});
  double worst = 0;
  for (int v = 0; v <= 180; v += 3)
    for (int u = 0; u <= 240; u += 3) {
      const Vec2 n = cam.undistort_to_normalized(u, v);
      const Vec2 back = cam.project_normalized(n);
      worst = std::max(worst, (back - Vec2(u, v)).norm());
    }
  CHECK(worst < 1e-3);
}

TEST_CASE("camera: rays go through the pixel they were made from") {
  Camera cam(64, 48, 50, 52, 31.5, 23.5, {0.05, -0.01, 0.001, 0.002, 0});
  Pose p = Pose::look_at(Vec3(1, 2, 3), Vec3(0, 0, 0), Vec3(0, 0, 1));
  const Ray r = cam.ray(p, 10.25, 40.5);
  const Vec3 world = r.origin + 2.7 * r.dir;
  const Vec3 cam_pt = p.inverse().apply(world);
  const Vec2 px = cam.project(cam_pt);
  CHECK(px.x() == doctest::Approx(10.25).epsilon(1e-6));
  CHECK(px.y() == doctest::Approx(40.5).epsilon(1e-6));
  CHECK(cam_pt.z() == doctest::Approx(2.7));  // dir has unit z in camera coordinates
}

TEST_CASE("image-motion axis: along the translation, tangential under a roll, undirected through the fixation depth, zero without motion") {
  const Camera cam(64, 48, 50, 50, 31.5, 23.5);
  const Pose from;
  auto moved = [](Vec3 t) {
    Pose p;
    p.t = t;
    return p;
  };
  const Vec3 d(0.3, -0.2, 1.0);  // a pixel off the principal point, unit z
  // A sideways translation moves every depth's point along x only: the axis is exactly (±1, 0).
  Vec2 a = image_motion_axis(cam, from, moved(Vec3(0.1, 0, 0)), d, 0.5, 3.0);
  CHECK(std::abs(a.x()) == 1.0);
  CHECK(a.y() == 0.0);
  a = image_motion_axis(cam, from, moved(Vec3(0, -0.1, 0)), d, 0.5, 3.0);
  CHECK(std::abs(a.y()) == doctest::Approx(1.0).epsilon(1e-12));
  CHECK(std::abs(a.x()) < 1e-12);
  a = image_motion_axis(cam, from, moved(Vec3(0.1, 0.1, 0)), d, 0.5, 3.0);
  CHECK(std::abs(a.x() - a.y()) < 1e-12);  // the diagonal (fx = fy)
  CHECK(a.norm() == doctest::Approx(1.0));
  // A roll about the optical axis moves the point around the principal point: the axis is tangential.
  Pose roll;
  roll.q = Quat(Eigen::AngleAxisd(0.05, Vec3::UnitZ()));
  a = image_motion_axis(cam, from, roll, d, 0.5, 3.0);
  const Vec2 radial = cam.project(d) - Vec2(cam.cx(), cam.cy());
  CHECK(std::abs(a.dot(radial.normalized())) < 0.05);
  // An arc about a fixation point 1 m ahead: the point at 1 m stays put (no vote), nearer and farther ones
  // move in opposite senses along x; the axis is x either way.
  const Pose l = Pose::look_at(Vec3(-0.1, 0, 0), Vec3(0, 0, 1), Vec3(0, -1, 0)),
             r = Pose::look_at(Vec3(0.1, 0, 0), Vec3(0, 0, 1), Vec3(0, -1, 0));
  a = image_motion_axis(cam, l, r, Vec3(0, 0, 1), 0.25, 4.0, 3);
  CHECK(std::abs(a.x()) == doctest::Approx(1.0).epsilon(1e-9));
  CHECK(std::abs(a.y()) < 1e-9);
  // No motion, or every depth behind the second camera: no axis.
  CHECK(image_motion_axis(cam, from, from, d, 0.5, 3.0) == Vec2::Zero());
  CHECK(image_motion_axis(cam, from, moved(Vec3(0, 0, 10)), d, 0.5, 3.0) == Vec2::Zero());
  // A motion under min_px pixels at every depth does not count either.
  CHECK(image_motion_axis(cam, from, moved(Vec3(1e-6, 0, 0)), d, 0.5, 3.0) == Vec2::Zero());
}

TEST_CASE("poses: OpenGL conversion round-trips and look_at looks along +z") {
  Pose p = Pose::look_at(Vec3(0, 0, -5), Vec3(0, 0, 0), Vec3(0, -1, 0));
  CHECK((p.q * Vec3::UnitZ() - Vec3::UnitZ()).norm() < 1e-12);
  const Pose back = from_opengl(to_opengl(p));
  CHECK((back.matrix() - p.matrix()).norm() < 1e-12);
  const Pose comp = p * p.inverse();
  CHECK((comp.matrix() - Eigen::Matrix4d::Identity()).norm() < 1e-12);
}

TEST_CASE("COLMAP text model: world-to-camera converted to camera-to-world") {
  const std::string cams = "# comment\n1 PINHOLE 640 480 500 501 320 240\n2 OPENCV 100 80 90 90 50 40 0.1 0.01 0 0\n";
  const std::string imgs =
      "# header\n1 0.7071067811865476 0 0.7071067811865476 0 1 2 3 1 a b.png\n10 20 -1\n"
      "2 1 0 0 0 0 0 0 2 c.png\n\n";
  auto cameras = io::parse_colmap_cameras(cams, "cameras.txt");
  REQUIRE(cameras.size() == 2);
  CHECK(cameras.at(1).fy() == 501);
  CHECK(cameras.at(2).distortion()[0] == doctest::Approx(0.1));
  auto images = io::parse_colmap_images(imgs, "images.txt");
  REQUIRE(images.size() == 2);
  CHECK(images[0].name == "a b.png");
  // Camera centre C = −Rᵀ t.
  const Mat3 R = Quat(0.7071067811865476, 0, 0.7071067811865476, 0).toRotationMatrix();
  const Vec3 C = -R.transpose() * Vec3(1, 2, 3);
  CHECK((images[0].c2w.t - C).norm() < 1e-9);
  CHECK_THROWS_WITH(io::parse_colmap_cameras("1 FISHEYE 10 10 1 2 3\n", "cameras.txt"),
                    doctest::Contains("cameras.txt:1: unsupported camera model 'FISHEYE'"));
  CHECK_THROWS_WITH(io::parse_colmap_cameras("1 PINHOLE 10 10 1 2 3\n", "cameras.txt"), doctest::Contains("PINHOLE needs 4 parameters"));
  CHECK_THROWS_WITH(io::parse_colmap_images("1 1 0 0 x 0 0 0 1 a.png\n", "images.txt"), doctest::Contains("images.txt:1:"));
}
