// The folder layouts of other projects' datasets, loaded as io::load loads them: Robust e-NeRF's sequence
// (io::load_robust_e_nerf: three .npz archives, times in int64 ns) and EventNeRF's scene (io::load_eventnerf:
// an .npz of events, text matrices for the intrinsics and one pose per view). fuzz_npz explores the archives
// themselves; this harness explores what the readers make of the arrays and matrices inside them.
// Input: one layout byte ('R' or 'E'; anything else reads as 'R' when even, 'E' when odd), then the files,
// separated by "@@next@@":
//   R: camera_calibration.npz, raw_events.npz[, camera_poses.npz]
//   E: train/events/events.npz, train/intrinsics/r_00000.txt, then train/pose/r_NNNNN.txt, one per part
// The files go to a folder in /dev/shm made afresh for each input.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <evnerf/io/dataset.hpp>

#include "fuzz.hpp"

namespace fs = std::filesystem;

namespace {
/// The stream's invariants after a read that succeeded.
void check_events(const evnerf::events::EventStream& ev, int width, int height) {
  evfuzz::expect(ev.size() > 0, "a recording without events was accepted");
  evfuzz::expect(ev.width == width && ev.height == height, "the events' sensor differs from the camera's");
  for (std::size_t i = 0; i < ev.size(); ++i) {
    evfuzz::expect(std::isfinite(ev.t[i]) && (i == 0 || ev.t[i] >= ev.t[i - 1]), "event times not finite and sorted");
    evfuzz::expect(ev.x[i] < width && ev.y[i] < height, "an event outside the sensor");
    evfuzz::expect(ev.polarity[i] == 1 || ev.polarity[i] == -1, "a polarity other than ±1");
  }
}
void check_trajectory(const evnerf::geometry::Trajectory& tr) {
  for (std::size_t i = 0; i < tr.size(); ++i) {
    evfuzz::expect(std::isfinite(tr.times()[i]) && (i == 0 || tr.times()[i] > tr.times()[i - 1]), "pose times not finite and increasing");
    const auto& p = tr.poses()[i];
    evfuzz::expect(p.t.allFinite() && std::abs(p.q.norm() - 1) < 1e-6, "a pose not finite or not a rotation");
  }
}
void check_camera(const evnerf::geometry::Camera& c) {
  evfuzz::expect(c.width() > 0 && c.height() > 0 && c.fx() > 0 && c.fy() > 0 && std::isfinite(c.cx()) && std::isfinite(c.cy()),
                 "a camera without a positive size and focal length");
  evfuzz::expect(static_cast<long long>(c.width()) * c.height() <= evnerf::io::kMaxSensorPixels, "a sensor above the pixel limit");
  for (double k : c.distortion()) evfuzz::expect(std::isfinite(k), "a distortion coefficient not finite");
}
void put(const fs::path& p, std::string_view bytes) {
  fs::create_directories(p.parent_path());
  std::FILE* f = std::fopen(p.c_str(), "wb");
  if (!f) return;
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view in = evfuzz::text(data, size);
  const bool robust = in[0] == 'R' || (in[0] != 'E' && in[0] % 2 == 0);
  std::vector<std::string_view> parts;
  constexpr std::string_view sep = "@@next@@";
  for (std::size_t p = 1;;) {
    const std::size_t q = in.find(sep, p);
    parts.push_back(in.substr(p, q == std::string_view::npos ? std::string_view::npos : q - p));
    if (q == std::string_view::npos || parts.size() == 64) break;
    p = q + sep.size();
  }
  static const fs::path dir = fs::path("/dev/shm") / ("evnerf_fuzz_" + std::to_string(::getpid()) + "_layout");
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  if (ec) return 0;
  if (robust) {
    const char* names[] = {"camera_calibration.npz", "raw_events.npz", "camera_poses.npz"};
    for (std::size_t i = 0; i < parts.size() && i < 3; ++i) put(dir / names[i], parts[i]);
    evfuzz::run([&] {
      const auto s = evnerf::io::load_robust_e_nerf(dir);
      check_camera(s.camera);
      check_events(s.events, s.camera.width(), s.camera.height());
      check_trajectory(s.trajectory);
    });
  } else {
    put(dir / "train" / "events" / "events.npz", parts[0]);
    if (parts.size() > 1) put(dir / "train" / "intrinsics" / "r_00000.txt", parts[1]);
    for (std::size_t i = 2; i < parts.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "r_%05zu.txt", i - 2);
      put(dir / "train" / "pose" / name, parts[i]);
    }
    evfuzz::run([&] {
      const auto s = evnerf::io::load_eventnerf(dir);
      check_camera(s.camera);
      check_events(s.events, s.camera.width(), s.camera.height());
      check_trajectory(s.trajectory);
      evfuzz::expect(s.trajectory.size() + 2 == parts.size(), "a pose file left out");
    });
  }
  return 0;
}
