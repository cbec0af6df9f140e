// io/checkpoint.hpp — the checkpoint format's one parser. A checkpoint is
//   "EVNERFCK" | u64 version | str variant name | u64 parameter count | u64 slices | i64 step |
//   f64×6 box (centre, scale, near, far) | f64 density length (v ≥ 3) | str loss (v ≥ 4) |
//   str architecture (v ≥ 5) |
//   f32 parameters | f32 Adam m | f32 Adam v |
//   u64 average count (0 or the parameter count) + f64 its decay + f32 average (v ≥ 6) |
//   str occupancy grid (v ≥ 2) | str caller's metadata | u64 FNV-1a of everything before it
// (u64/i64/f64 little-endian as stored by this machine; str = u64 length + bytes). Versions: 2 added the
// occupancy grid, 3 the density length, 4 the loss, 5 the architecture (the model's types: encodings,
// networks, sampler; the variant's name is then only a label), 6 the parameter average the model renders
// with (nn::ParameterAverage; count 0 when it keeps none). write_checkpoint writes it (EvNerf::serialize
// fills it in); EvNerf::deserialize and the command line (which variant wrote this file?) read it through
// this header. Depends on core/ only.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "../core/error.hpp"
#include "../core/fileio.hpp"

namespace evnerf::io {

inline constexpr std::uint64_t kCheckpointVersion = 6;

/// Bounds-checked reading of a checkpoint's bytes; every error names the file.
class CheckpointReader {
 public:
  /// Checks the magic and the checksum.
  CheckpointReader(const std::string& bytes, std::string file) : b_(bytes), file_(std::move(file)) {
    if (b_.size() < 16 || std::memcmp(b_.data(), "EVNERFCK", 8) != 0) fail("not an evnerf checkpoint");
    std::uint64_t sum = 0;
    std::memcpy(&sum, b_.data() + b_.size() - 8, 8);
    if (sum != fnv1a64(std::string_view(b_).substr(0, b_.size() - 8))) fail("checksum mismatch (truncated or damaged)");
    pos_ = 8;
  }
  [[noreturn]] void fail(const std::string& why) const { throw Error(file_, 0, "corrupt or mismatched checkpoint: " + why); }
  void get(void* p, std::size_t n) {
    if (n > b_.size() - 8 || pos_ > b_.size() - 8 - n) fail("truncated");
    std::memcpy(p, b_.data() + pos_, n);
    pos_ += n;
  }
  std::uint64_t u64() {
    std::uint64_t v = 0;
    get(&v, 8);
    return v;
  }
  std::string str() {
    const auto n = u64();
    if (n > b_.size()) fail("bad string length");
    std::string s(n, '\0');
    get(s.data(), n);
    return s;
  }
  const std::string& file() const { return file_; }
  /// Bytes left before the checksum.
  std::size_t remaining() const { return b_.size() - 8 - pos_; }

 private:
  const std::string& b_;
  std::string file_;
  std::size_t pos_ = 0;
};

/// Everything before the parameters.
struct CheckpointHeader {
  std::uint64_t version = 0;
  std::string name;  ///< the variant's name as the writer gave it
  std::uint64_t n_params = 0, n_slices = 0;
  std::int64_t step = 0;
  double box[6] = {0, 0, 0, 1, 0, 1};  ///< centre x y z, scale, near, far
  double density_length = 1.0;         ///< versions 1 and 2 measured density per world unit
  std::string loss;                    ///< empty before version 4
  std::string architecture;            ///< empty before version 5
};

/// Reads the header; the reader is left at the parameters.
inline CheckpointHeader read_checkpoint_header(CheckpointReader& r) {
  CheckpointHeader h;
  h.version = r.u64();
  if (h.version < 1 || h.version > kCheckpointVersion) r.fail("unsupported version " + std::to_string(h.version));
  h.name = r.str();
  h.n_params = r.u64();
  h.n_slices = r.u64();
  r.get(&h.step, 8);
  r.get(h.box, sizeof h.box);
  if (h.version >= 3) {
    r.get(&h.density_length, 8);
    if (!(h.density_length > 0) || !std::isfinite(h.density_length)) r.fail("density length is not a positive number");
  }
  if (h.version >= 4) h.loss = r.str();
  if (h.version >= 5) h.architecture = r.str();
  return h;
}

/// What a checkpoint holds besides its header: the parameters with Adam's two moments (n floats each),
/// the parameter average (n floats, or null for none) and its decay, the sampler's state and the caller's
/// metadata.
struct CheckpointBody {
  const float *params = nullptr, *adam_m = nullptr, *adam_v = nullptr;
  std::size_t n = 0;
  const float* average = nullptr;
  double average_decay = 0;
  std::string sampler_state, extra;
};

/// The bytes of a checkpoint of the current version (header.version and n_params are set from here).
inline std::string write_checkpoint(const CheckpointHeader& h, const CheckpointBody& body) {
  std::string b;
  auto put = [&](const void* p, std::size_t n) { b.append(static_cast<const char*>(p), n); };
  auto put_u64 = [&](std::uint64_t v) { put(&v, 8); };
  auto put_str = [&](const std::string& s) {
    put_u64(s.size());
    put(s.data(), s.size());
  };
  put("EVNERFCK", 8);
  put_u64(kCheckpointVersion);
  put_str(h.name);
  put_u64(body.n);
  put_u64(h.n_slices);
  put(&h.step, 8);
  put(h.box, sizeof h.box);
  put(&h.density_length, 8);
  put_str(h.loss);
  put_str(h.architecture);
  put(body.params, body.n * 4);
  put(body.adam_m, body.n * 4);
  put(body.adam_v, body.n * 4);
  put_u64(body.average ? body.n : 0);
  const double decay = body.average ? body.average_decay : 0.0;
  put(&decay, 8);
  if (body.average) put(body.average, body.n * 4);
  put_str(body.sampler_state);
  put_str(body.extra);
  put_u64(fnv1a64(b));
  return b;
}

/// The header of a checkpoint file (the whole file is read and its checksum checked).
inline CheckpointHeader peek_checkpoint(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  CheckpointReader r(bytes, path.string());
  return read_checkpoint_header(r);
}

}  // namespace evnerf::io
