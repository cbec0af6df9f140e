// Events per second read from each recording format, from the same synthetic stream of 2 M events
// (240×180, 10 µs apart on average, as bench_main's text benchmarks) written by evnerf's own writers to files
// in the temporary folder (in the page cache, as a re-read recording is): IJRR events.txt (the reference,
// parsed by the fast text reader, no .npy cache), Prophesee EVT 2.0 and EVT 3.0 .raw (times on whole
// microseconds), event_utils/HQF HDF5, and ROS bags with uncompressed, lz4 and bz2 chunks (1 ms of events per
// dvs_msgs/EventArray, rosbag's 768 kB chunks), and AEDAT4 with LZ4 and Zstd packets (4096 events each).
// bench/formats.sh runs it and prints the medians.
#include <benchmark/benchmark.h>
#include <evnerf/core/rng.hpp>
#include <evnerf/io/dataset.hpp>

#include <filesystem>

using namespace evnerf;
namespace fs = std::filesystem;

namespace {

constexpr std::size_t kEvents = 2000000;

const events::EventStream& stream() {
  static const events::EventStream ev = [] {
    Rng rng(3);
    events::EventStream e;
    e.width = 240;
    e.height = 180;
    double t = 0;
    for (std::size_t i = 0; i < kEvents; ++i) {
      t += rng.uniform() * 1e-5;
      // Times on whole nanoseconds, as every format stores them exactly.
      e.push_back(std::round(t * 1e9) / 1e9, int(rng.below(240)), int(rng.below(180)), rng.below(2) ? 1 : -1);
    }
    return e;
  }();
  return ev;
}
fs::path dir() {
  static const fs::path d = [] {
    auto p = fs::temp_directory_path() / "evnerf_bench_formats";
    fs::create_directories(p);
    return p;
  }();
  return d;
}
const io::Dataset& dataset() {
  static const io::Dataset d = [] {
    io::Dataset r;
    r.camera = geometry::Camera(240, 180, 200, 200, 120, 90);
    r.events = stream();
    return r;
  }();
  return d;
}

void BM_read_text(benchmark::State& st) {
  const auto path = dir() / "ijrr";
  io::write_ijrr(path, dataset());
  for (auto _ : st) benchmark::DoNotOptimize(io::read_events_txt(path / "events.txt", 240, 180));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations() * kEvents));
}
void BM_read_prophesee(benchmark::State& st, const std::string& version) {
  const auto path = dir() / (version == "2.0" ? "events.evt2.raw" : "events.raw");
  io::Dataset us = dataset();
  for (auto& t : us.events.t) t = std::round(t * 1e6) / 1e6;
  io::write_prophesee_raw(path, us, version);
  io::PropheseeInfo info;
  for (auto _ : st) benchmark::DoNotOptimize(io::read_prophesee_events(path, {}, info));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations() * kEvents));
  st.counters["MB"] = static_cast<double>(fs::file_size(path)) / 1e6;
}
#ifdef EVNERF_HAVE_HDF5
void BM_read_hdf5(benchmark::State& st) {
  const auto path = dir() / "events.h5";
  io::write_hdf5(path, stream(), 240, 180, {}, {});
  for (auto _ : st) benchmark::DoNotOptimize(io::read_hdf5(path));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations() * kEvents));
}
#endif
#ifdef EVNERF_HAVE_ROSBAG
void BM_read_rosbag(benchmark::State& st, const std::string& compression) {
  const auto path = dir() / ("events_" + compression + ".bag");
  io::BagWriteOptions o;
  o.compression = compression;
  o.origin_sec = 1600000000;
  io::write_rosbag(path, stream(), dataset().camera, {}, {}, {}, o);
  for (auto _ : st) benchmark::DoNotOptimize(io::read_rosbag(path));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations() * kEvents));
  st.counters["MB"] = static_cast<double>(fs::file_size(path)) / 1e6;
}
#endif
#ifdef EVNERF_HAVE_AEDAT4
void BM_read_aedat4(benchmark::State& st, const std::string& compression) {
  const auto path = dir() / ("events_" + compression + ".aedat4");
  io::Dataset us = dataset();
  for (auto& t : us.events.t) t = std::round(t * 1e6) / 1e6;
  io::write_aedat4(path, us, compression);
  io::Aedat4Info info;
  io::Frames frames;
  std::int64_t origin = 0;
  for (auto _ : st) benchmark::DoNotOptimize(io::read_aedat4(path, {}, info, frames, origin));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations() * kEvents));
  st.counters["MB"] = static_cast<double>(fs::file_size(path)) / 1e6;
}
#endif

}  // namespace

BENCHMARK(BM_read_text)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_read_prophesee, evt2, std::string("2.0"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_read_prophesee, evt3, std::string("3.0"))->Unit(benchmark::kMillisecond)->UseRealTime();
#ifdef EVNERF_HAVE_HDF5
BENCHMARK(BM_read_hdf5)->Unit(benchmark::kMillisecond)->UseRealTime();
#endif
#ifdef EVNERF_HAVE_ROSBAG
BENCHMARK_CAPTURE(BM_read_rosbag, none, std::string("none"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_read_rosbag, lz4, std::string("lz4"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_read_rosbag, bz2, std::string("bz2"))->Unit(benchmark::kMillisecond)->UseRealTime();
#endif
#ifdef EVNERF_HAVE_AEDAT4
BENCHMARK_CAPTURE(BM_read_aedat4, lz4, std::string("lz4"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_read_aedat4, zstd, std::string("zstd"))->Unit(benchmark::kMillisecond)->UseRealTime();
#endif
BENCHMARK_MAIN();
