// Writes the harnesses' seed corpora, one folder each, from evnerf's own writers: a tiny simulated
// recording (events, calibration, sensor size, frame list, poses, frames as PNG, depth as .npy), the
// scene descriptions (built-in and random), a checkpoint of the checkpoint harness's model, and
// hand-written variants each format allows (comments, CRLF, TUM headers, distortion, COLMAP models).
// Usage: make_seeds OUT_FOLDER
#include <cstdio>
#include <filesystem>
#include <string>

#include <evnerf/evnerf.hpp>
#include <evnerf/io/ply.hpp>
#include <evnerf/sim/random_scene.hpp>
#include <stb_image_write.h>

#include "fuzz_model.hpp"

namespace fs = std::filesystem;
using namespace evnerf;

namespace {
fs::path root;
int written = 0;
void put(const std::string& corpus, const std::string& name, const std::string& bytes) {
  write_file_atomic(root / corpus / name, bytes);
  ++written;
}
std::string head_lines(const std::string& text, int lines) {
  std::size_t p = 0;
  for (int i = 0; i < lines && p != std::string::npos; ++i) p = text.find('\n', p + 1);
  return p == std::string::npos ? text : text.substr(0, p + 1);
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT_FOLDER\n");
    return 2;
  }
  root = argv[1];
  const fs::path rec_dir = root / "recording";
  {
    auto spec = sim::parse_scene("plane 0 0 1.5 0 0 -1 1 0 0 0 0 checker 2\npath slider -0.1 0 0 0.1 0 0 0 0 1 0.5\n", "tiny.txt");
    sim::SensorConfig sc;
    sc.width = 32;
    sc.height = 24;
    sc.fx = sc.fy = 30;
    sc.cx = sc.cy = -1;
    sc.frame_rate = 12;
    sim::write_recording(rec_dir, sim::Simulator(spec, sc).run());
  }
  const std::string events = read_file(rec_dir / "events.txt");
  put("events", "simulated", head_lines(events, 200));
  put("events", "comments_crlf", "# t x y p\r\n0.000100000 5 7 1\r\n\r\n0.000200 6 7 0\r\n# end\r\n");
  put("events", "signed_polarity", "1e-4 0 0 -1\n2.5e-4 239 179 1\n2.5e-4,1,2,1\n");
  put("calib", "simulated", read_file(rec_dir / "calib.txt"));
  put("calib", "four", "199.092366 198.643274 132.192548 110.712803\n");
  put("calib", "eight", "199.092366 198.643274 132.192548 110.712803 -0.368436 0.150947 -0.000296 -0.000759\n");
  put("calib", "sensor", read_file(rec_dir / "sensor.txt"));
  put("frame", "recorded", "pose=1,0,0,0.25,0,0.98,-0.2,0,0,0.2,0.98,1.5&scale=2&show=depth");
  put("frame", "identity", "pose=1,0,0,0,0,1,0,0,0,0,1,0");
  put("images", "simulated", read_file(rec_dir / "images.txt"));
  put("images", "spaces", "# timestamp filename\n1468938.000000 images/frame 00.png\n1468938.05 images/f01.png  \n");
  const std::string poses = read_file(rec_dir / "groundtruth.txt");
  put("poses", "ijrr", head_lines(poses, 20));
  put("poses", "tum",
      "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
      "1305031102.1858 1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189\n");
  put("colmap", "cameras",
      "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "1 PINHOLE 240 180 199.1 198.6 132.2 110.7\n2 SIMPLE_PINHOLE 346 260 250 173 130\n"
      "3 SIMPLE_RADIAL 346 260 250 173 130 -0.1\n4 RADIAL 346 260 250 173 130 -0.1 0.01\n"
      "5 OPENCV 240 180 199.1 198.6 132.2 110.7 -0.36 0.15 -0.0003 -0.0008\n");
  put("colmap", "images",
      "# Image list with two lines of data per image:\n"
      "1 0.851773 0.0165051 0.503764 -0.142941 -0.737434 1.02973 3.74354 1 frame_000.png\n"
      "2394.03 1000.29 -1 181.3 71.8 42\n"
      "2 0.9 0.1 0.3 -0.1 -0.7 1.0 3.7 1 frame_001.png\n\n");
  {
    const auto depth = read_file(rec_dir / "depth" / "frame_00000000.npy");
    put("npy", "depth_f4", depth);
    std::vector<std::uint16_t> xs{1, 2, 3, 65535};
    std::vector<std::int8_t> ps{1, -1, 1};
    std::vector<double> ts{0.5, 0.25};
    auto dump = [](auto& v) { return xt::dump_npy(xt::adapt(v.data(), v.size(), xt::no_ownership(), std::vector<std::size_t>{v.size()})); };
    put("npy", "x_u2", dump(xs));
    put("npy", "p_i1", dump(ps));
    put("npy", "t_f8", dump(ts));
    // Format 2.0: a 4-byte header length.
    std::string v2 = "\x93NUMPY\x02";
    v2 += '\0';
    std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 1), }";
    header.append(64 - (12 + header.size() + 1) % 64, ' ');
    header += '\n';
    const std::uint32_t len = static_cast<std::uint32_t>(header.size());
    v2.append(reinterpret_cast<const char*>(&len), 4);
    v2 += header;
    const float two[2] = {1.5f, -2.f};
    v2.append(reinterpret_cast<const char*>(two), 8);
    put("npy", "v2_f4", v2);
  }
  put("png", "frame", read_file(rec_dir / "images" / "frame_00000000.png"));
  for (int ch : {1, 2, 3, 4}) {
    std::vector<unsigned char> px(5 * 3 * static_cast<std::size_t>(ch));
    for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<unsigned char>(i * 37);
    std::string png;
    auto sink = [](void* ctx, void* data, int size) {
      static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), static_cast<std::size_t>(size));
    };
    stbi_write_png_to_func(sink, &png, 5, 3, ch, px.data(), 5 * ch);
    put("png", "channels" + std::to_string(ch), png);
  }
  for (const auto& name : sim::builtin_scenes()) put("scene", name, sim::builtin_scene_text(name));
  for (std::uint64_t seed = 1; seed <= 6; ++seed) put("scene", "random" + std::to_string(seed), sim::random_scene_text(seed));
  {
    evfuzz::FuzzModel model(3, render::SceneBox{}, 7);
    // The run of a 3-slice recording on a 32 x 24 sensor: its camera and four boundaries.
    io::CheckpointRun run;
    run.recording = "fuzz";
    run.camera = geometry::Camera(32, 24, 30, 30, 16, 12);
    for (int i = 0; i < 4; ++i) {
      run.times.push_back(0.1 * i);
      run.poses.push_back(geometry::Pose{});
      run.poses.back().t = Vec3(0.01 * i, 0, 0);
    }
    for (const char* kind : {"", "_average"}) {  // without and with the parameter average
      if (*kind) model.set_average(0.99);
      const std::string ck = model.serialize("fuzz", run);
      put("checkpoint", std::string("raw") + kind, std::string(1, '\0') + ck);
      put("checkpoint", std::string("checksummed") + kind, std::string(1, '\1') + ck.substr(0, ck.size() - 8));
    }
  }
  {
    // Prophesee files from the simulated recording: EVT 2.0, EVT 3.0 (evnerf's writers), and a .dat file.
    io::LoadOptions lo;
    lo.use_cache = false;
    auto d = io::load(rec_dir, lo);
    for (auto& t : d.events.t) t = std::round(t * 1e6) / 1e6;
    for (const char* v : {"2.0", "3.0"}) {
      const fs::path f = root / "prophesee_tmp" / (std::string("seed") + v + ".raw");
      io::write_prophesee_raw(f, d, v);
      put("prophesee", std::string("evt") + v, read_file(f));
    }
    std::string dat = "% Date 2020-01-01 00:00:00\n% Version 2\n% Width 32\n% Height 24\n";
    dat += std::string{'\x0c', '\x08'};
    for (std::size_t i = 0; i < d.events.size() && i < 300; ++i) {
      const auto t = static_cast<std::uint32_t>(std::llround(d.events.t[i] * 1e6));
      const std::uint32_t w = d.events.x[i] | std::uint32_t(d.events.y[i]) << 14 | std::uint32_t(d.events.polarity[i] > 0) << 28;
      for (int k = 0; k < 4; ++k) dat.push_back(static_cast<char>(t >> (8 * k)));
      for (int k = 0; k < 4; ++k) dat.push_back(static_cast<char>(w >> (8 * k)));
    }
    put("prophesee", "dat", dat);
#ifdef EVNERF_HAVE_AEDAT4
    // AEDAT4 files: the first 300 events and two frames, in each compression evnerf writes.
    auto small = d;
    if (small.events.size() > 300) small.events.keep_time_window(-INFINITY, small.events.t[300]);
    small.frames.t.resize(std::min<std::size_t>(2, small.frames.t.size()));
    if (!small.frames.paths.empty()) small.frames.paths.resize(small.frames.t.size());
    if (!small.frames.images.empty()) small.frames.images.resize(small.frames.t.size());
    for (const char* c : {"none", "lz4", "zstd"}) {
      const fs::path f = root / "prophesee_tmp" / (std::string("seed_") + c + ".aedat4");
      io::write_aedat4(f, small, c);
      put("aedat4", c, read_file(f));
    }
#endif
    fs::remove_all(root / "prophesee_tmp");
  }
  {
    // PLY files as export writes them: floats with colour bytes, a triangle over them, floats alone, and no
    // vertex at all.
    io::PlyVertices v;
    v.names = {"x", "y", "z", "luminance"};
    v.floats = {0.f, 1.f, 2.f, 0.5f, -1.f, 0.25f, 3.f, 1e-3f, 2.f, 2.f, 2.f, 0.f};
    v.colour = true;
    v.rgb = {10, 20, 30, 200, 100, 0, 1, 2, 3};
    const fs::path f = root / "ply_tmp" / "seed.ply";
    io::write_ply(f, v, {"seed"});
    put("ply", "points", read_file(f));
    v.faces = {{0, 1, 2}, {2, 1, 0}};
    io::write_ply(f, v);
    put("ply", "mesh", read_file(f));
    v.faces.clear();
    v.colour = false;
    v.rgb.clear();
    io::write_ply(f, v);
    put("ply", "floats", read_file(f));
    v.floats.clear();
    io::write_ply(f, v);
    put("ply", "empty", read_file(f));
    fs::remove_all(root / "ply_tmp");
  }
  fs::remove_all(rec_dir);
  std::printf("wrote %d seeds under %s\n", written, root.c_str());
  return 0;
}
