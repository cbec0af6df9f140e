// io/rosbag.hpp — event recordings in ROS bags (format 2.0), read from the published format specification
// without ROS: records (a header of `name=value` fields, then data), connection records (topic, type and the
// full message definition), chunks (uncompressed, bz2 or lz4 frames, through Debian's libbz2 and liblz4),
// and the index at the end (chunk infos: which chunk holds messages of which connection).
//
// Messages are decoded from their definition text, not from compiled-in layouts: any event message whose
// definition has an array `events` of fixed-size structs with integer `x`, `y`, a `time ts` and a
// boolean or integer `polarity` is read (dvs_msgs/EventArray, prophesee_event_msgs/EventArray, ...), and
// the fields of sensor_msgs/Image, sensor_msgs/CameraInfo, geometry_msgs/PoseStamped,
// geometry_msgs/TransformStamped and nav_msgs/Odometry are found by name. Topics are chosen
// automatically when one topic has the role, by name (BagOptions) otherwise.
//
// Times: ROS time (seconds since 1970) loses its nanoseconds in a double, so every time read is relative
// to `origin_sec`, the whole second of the first time decoded, and is the double nearest the exact number
// of nanoseconds (as a text reader of the time with nine decimals gets it). Memory: one chunk at a time (a few MB),
// plus what is kept (events, frames in memory, poses). Every error names the file and the record, chunk,
// topic or message. A bag cut short (a recorder that crashed or lost power: no index, or an index that lies or
// runs past the end of the file) is read to its last whole record, with a warning. Compiled only where CMake found libbz2
// and liblz4 (EVNERF_HAVE_ROSBAG).
// Its line of the format table is rosbag_format(). Depends on core/, geometry/, events/ and io/ only.
#pragma once
#include <bzlib.h>
#include <lz4frame.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"
#include "../core/warn.hpp"
#include "../events/event_stream.hpp"
#include "../core/fileio.hpp"
#include "../geometry/bayer.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "../geometry/trajectory.hpp"
#include "recording.hpp"

namespace evnerf::io {

inline constexpr std::size_t kBagMaxRecordHeader = std::size_t{1} << 20;  ///< a record header (fields)
inline constexpr std::uint64_t kBagMaxChunk = std::uint64_t{1} << 31;     ///< a chunk, uncompressed
inline constexpr std::string_view kBagMagic = "#ROSBAG V2.0\n";

/// One topic of a bag: its message type and how many messages it has.
struct BagTopic {
  std::string topic, type;
  std::uint64_t messages = 0;
  std::uint32_t connections = 0;
};

/// Which topics to read. Empty: the one topic that has the role (an error names the candidates when
/// there are several); "none": skip the role (not for events).
struct BagOptions {
  std::string events_topic, images_topic, camera_info_topic, poses_topic;
  ReadProgress progress;  ///< called after each chunk (or record of an unindexed bag) the read visits
};

/// What a bag holds, times in seconds after `origin_sec` (ROS time, whole seconds).
struct BagRecording {
  std::int64_t origin_sec = 0;
  events::EventStream events;             ///< width/height 0: events::EventStream's size is set by the caller
  std::int64_t max_x = -1, max_y = -1;    ///< the largest pixel coordinates among the events
  int array_width = 0, array_height = 0;  ///< the event messages' own `width`/`height` fields (0: absent)
  std::vector<double> frame_times;
  std::vector<Image> frames;   ///< float in [0, 1]; Bayer mosaics demosaiced to RGB
  std::string frame_encoding;  ///< the frames' encoding (mono8, bgr8, bayer_rggb8, ...)
  bool has_camera_info = false;
  int info_width = 0, info_height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion{0, 0, 0, 0, 0};  ///< k1 k2 p1 p2 k3
  std::vector<double> pose_times;
  std::vector<geometry::Pose> poses;
  std::string events_topic, images_topic, camera_info_topic, poses_topic;  ///< the topics read ("" none)
};

namespace detail {

/// A name from the file (topic, type, field) as errors show it: at most 48 characters.
inline std::string bag_shown(std::string_view s) { return s.size() <= 48 ? std::string(s) : std::string(s.substr(0, 45)) + "..."; }

// ---- bytes ------------------------------------------------------------------------------------------

inline std::uint32_t bag_u32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
inline std::uint64_t bag_u64(const unsigned char* p) { return std::uint64_t(bag_u32(p)) | std::uint64_t(bag_u32(p + 4)) << 32; }

/// A bag file read at offsets, bounds-checked against its size.
class BagFile {
 public:
  explicit BagFile(const std::filesystem::path& path) : name_(path.string()) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw Error(name_, 0, "cannot open file (missing or not a file)");
    size_ = std::filesystem::file_size(path, ec);
    if (ec) throw Error(name_, 0, "cannot read the file's size: " + ec.message());
    f_ = std::fopen(name_.c_str(), "rb");
    if (!f_) throw Error(name_, 0, std::string("cannot open: ") + std::strerror(errno));
  }
  ~BagFile() {
    if (f_) std::fclose(f_);
  }
  BagFile(const BagFile&) = delete;
  BagFile& operator=(const BagFile&) = delete;
  const std::string& name() const { return name_; }
  std::uint64_t size() const { return size_; }
  void read(std::uint64_t off, void* dst, std::uint64_t n, const std::string& what) {
    if (off > size_ || n > size_ - off)
      throw Error(
          name_, 0,
          what + " at byte " + std::to_string(off) + " runs past the end of the file (" + std::to_string(size_) + " bytes; truncated?)");
    if (n == 0) return;
    if (fseeko(f_, static_cast<off_t>(off), SEEK_SET) != 0 || std::fread(dst, 1, n, f_) != n)
      throw Error(name_, 0, "read error at byte " + std::to_string(off) + ": " + std::strerror(errno));
  }

 private:
  std::string name_;
  std::uint64_t size_ = 0;
  std::FILE* f_ = nullptr;
};

/// A record header: `name=value` fields, each preceded by its length.
struct BagHeader {
  std::vector<std::pair<std::string_view, std::string_view>> fields;
  const std::string_view* find(std::string_view name) const {
    for (const auto& [k, v] : fields)
      if (k == name) return &v;
    return nullptr;
  }
};

inline BagHeader parse_bag_header(std::string_view bytes, const std::string& where) {
  BagHeader h;
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    if (bytes.size() - pos < 4) throw Error(where + ": header ends inside a field's length");
    const std::uint32_t len = bag_u32(reinterpret_cast<const unsigned char*>(bytes.data() + pos));
    pos += 4;
    if (len > bytes.size() - pos)
      throw Error(where + ": header field of " + std::to_string(len) + " bytes runs past the header (" +
                  std::to_string(bytes.size() - pos) + " left)");
    const std::string_view field = bytes.substr(pos, len);
    pos += len;
    const auto eq = field.find('=');
    if (eq == std::string_view::npos) throw Error(where + ": header field without '=' (not a bag record?)");
    h.fields.emplace_back(field.substr(0, eq), field.substr(eq + 1));
  }
  return h;
}

inline std::string_view bag_field(const BagHeader& h, std::string_view name, std::size_t size, const std::string& where) {
  const auto* v = h.find(name);
  if (!v) throw Error(where + ": header has no '" + std::string(name) + "' field");
  if (size && v->size() != size)
    throw Error(where + ": header field '" + std::string(name) + "' has " + std::to_string(v->size()) + " bytes, expected " +
                std::to_string(size));
  return *v;
}
inline std::uint32_t bag_field_u32(const BagHeader& h, std::string_view name, const std::string& where) {
  return bag_u32(reinterpret_cast<const unsigned char*>(bag_field(h, name, 4, where).data()));
}
inline std::uint64_t bag_field_u64(const BagHeader& h, std::string_view name, const std::string& where) {
  return bag_u64(reinterpret_cast<const unsigned char*>(bag_field(h, name, 8, where).data()));
}
inline int bag_op(const BagHeader& h, const std::string& where) { return static_cast<unsigned char>(bag_field(h, "op", 1, where)[0]); }

enum BagOp : int {
  kBagMessage = 0x02,
  kBagFileHeader = 0x03,
  kBagIndexData = 0x04,
  kBagChunk = 0x05,
  kBagChunkInfo = 0x06,
  kBagConnection = 0x07
};

/// One record of a buffer (a chunk's contents): its header and data; false at the buffer's end.
inline bool next_bag_record(std::string_view buf, std::size_t& pos, BagHeader& h, std::string_view& data, const std::string& where) {
  if (pos == buf.size()) return false;
  const std::string at = where + ", record at offset " + std::to_string(pos);
  if (buf.size() - pos < 4) throw Error(at + ": ends inside the header length");
  const std::uint32_t hl = bag_u32(reinterpret_cast<const unsigned char*>(buf.data() + pos));
  if (hl > buf.size() - pos - 4) throw Error(at + ": header of " + std::to_string(hl) + " bytes runs past the end");
  h = parse_bag_header(buf.substr(pos + 4, hl), at);  // views into `buf`
  pos += 4 + std::size_t{hl};
  if (buf.size() - pos < 4) throw Error(at + ": ends inside the data length");
  const std::uint32_t dl = bag_u32(reinterpret_cast<const unsigned char*>(buf.data() + pos));
  if (dl > buf.size() - pos - 4) throw Error(at + ": data of " + std::to_string(dl) + " bytes runs past the end");
  data = buf.substr(pos + 4, dl);
  pos += 4 + std::size_t{dl};
  return true;
}

/// A record of the file at `off`: header parsed into `hb`/`h`; returns the data's offset and length
/// (the data itself is read by the caller, only when needed).
inline std::pair<std::uint64_t, std::uint32_t> read_bag_record(BagFile& f, std::uint64_t off, std::string& hb, BagHeader& h) {
  const std::string at = f.name() + ": record at byte " + std::to_string(off);
  unsigned char len[4];
  f.read(off, len, 4, "record header length");
  const std::uint32_t hl = bag_u32(len);
  if (hl > kBagMaxRecordHeader || hl > f.size() - off - 4)
    throw Error(at + ": header length " + std::to_string(hl) + " is larger than the rest of the file or the limit (" +
                std::to_string(kBagMaxRecordHeader) + " bytes)");
  hb.resize(hl);
  f.read(off + 4, hb.data(), hl, "record header");
  h = parse_bag_header(hb, at);
  f.read(off + 4 + hl, len, 4, "record data length");
  const std::uint32_t dl = bag_u32(len);
  const std::uint64_t data_off = off + 8 + hl;
  if (dl > f.size() - data_off)
    throw Error(at + ": data of " + std::to_string(dl) + " bytes runs past the end of the file (" + std::to_string(f.size() - data_off) +
                " bytes left; truncated?)");
  return {data_off, dl};
}

/// An LZ4 frame decompression context, kept from chunk to chunk (creating one per chunk costs allocations
/// of its block buffers).
class Lz4Context {
 public:
  Lz4Context() = default;
  ~Lz4Context() {
    if (ctx_) LZ4F_freeDecompressionContext(ctx_);
  }
  Lz4Context(const Lz4Context&) = delete;
  Lz4Context& operator=(const Lz4Context&) = delete;
  /// A context ready for a new frame.
  LZ4F_dctx* fresh(const std::string& where) {
    if (!ctx_) {
      if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx_, LZ4F_VERSION))) throw Error(where + ": cannot start lz4 decompression");
    } else {
      LZ4F_resetDecompressionContext(ctx_);
    }
    return ctx_;
  }

 private:
  LZ4F_dctx* ctx_ = nullptr;
};

/// A chunk's records, decompressed. The output grows only as decompressed bytes arrive (a header that
/// claims gigabytes for a few compressed bytes allocates nothing for them).
inline std::string_view decompress_bag_chunk(std::string_view compression, std::string_view src, std::uint64_t size, std::vector<char>& out,
                                             const std::string& where, Lz4Context& lz4) {
  if (size > kBagMaxChunk)
    throw Error(where + ": chunk claims " + std::to_string(size) + " uncompressed bytes (limit " + std::to_string(kBagMaxChunk) + ")");
  if (compression == "none") {
    if (src.size() != size)
      throw Error(where + ": uncompressed chunk holds " + std::to_string(src.size()) + " bytes, its header says " + std::to_string(size));
    return src;
  }
  out.clear();
  auto grow = [&](std::size_t produced) {
    const std::size_t want = std::min<std::size_t>(size, std::max<std::size_t>({std::size_t{1} << 16, 2 * out.size(), produced + 1}));
    out.resize(want);
  };
  std::size_t produced = 0;
  if (compression == "bz2") {
    bz_stream s{};
    if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) throw Error(where + ": cannot start bz2 decompression");
    struct End {
      bz_stream* s;
      ~End() { BZ2_bzDecompressEnd(s); }
    } end{&s};
    s.next_in = const_cast<char*>(src.data());
    s.avail_in = static_cast<unsigned>(src.size());
    for (;;) {
      if (produced == out.size()) {
        if (out.size() == size) {  // full: only the stream's end may follow
          char extra;
          s.next_out = &extra;
          s.avail_out = 1;
          const int rc = BZ2_bzDecompress(&s);
          if (rc == BZ_STREAM_END && s.avail_out == 1) break;
          throw Error(where + ": bz2 chunk decompresses to more than its header's " + std::to_string(size) + " bytes");
        }
        grow(produced);
      }
      s.next_out = out.data() + produced;
      s.avail_out = static_cast<unsigned>(out.size() - produced);
      const int rc = BZ2_bzDecompress(&s);
      produced = out.size() - s.avail_out;
      if (rc == BZ_STREAM_END) break;
      if (rc != BZ_OK) throw Error(where + ": corrupt bz2 chunk (libbz2 error " + std::to_string(rc) + ")");
      if (s.avail_in == 0 && s.avail_out != 0) throw Error(where + ": bz2 chunk ends before its stream does (truncated?)");
    }
  } else if (compression == "lz4") {
    // LZ4 expands at most 255-fold: a buffer of the claimed size within that bound is allocated at once,
    // so that whole blocks decompress straight into it.
    out.resize(static_cast<std::size_t>(std::min<std::uint64_t>(size, 255 * std::uint64_t{src.size()} + 65536)));
    LZ4F_dctx* ctx = lz4.fresh(where);
    std::size_t consumed = 0;
    bool finished = false;
    while (!finished) {
      if (produced == out.size()) {
        if (out.size() == size) {
          if (consumed == src.size()) break;  // input fully used; the frame must have ended (checked below)
          char extra[16];
          std::size_t n_out = sizeof extra, n_in = src.size() - consumed;
          const std::size_t rc = LZ4F_decompress(ctx, extra, &n_out, src.data() + consumed, &n_in, nullptr);
          if (LZ4F_isError(rc)) throw Error(where + ": corrupt lz4 chunk (" + LZ4F_getErrorName(rc) + ")");
          if (n_out) throw Error(where + ": lz4 chunk decompresses to more than its header's " + std::to_string(size) + " bytes");
          consumed += n_in;
          if (rc == 0) break;
          if (n_in == 0) throw Error(where + ": lz4 chunk ends before its frame does (truncated?)");
          continue;
        }
        grow(produced);
      }
      std::size_t n_out = out.size() - produced, n_in = src.size() - consumed;
      const std::size_t rc = LZ4F_decompress(ctx, out.data() + produced, &n_out, src.data() + consumed, &n_in, nullptr);
      if (LZ4F_isError(rc)) throw Error(where + ": corrupt lz4 chunk (" + LZ4F_getErrorName(rc) + ")");
      produced += n_out;
      consumed += n_in;
      if (rc == 0) finished = true;
      else if (n_in == 0 && n_out == 0) throw Error(where + ": lz4 chunk ends before its frame does (truncated?)");
    }
    if (!finished && produced != size) throw Error(where + ": lz4 chunk ends before its frame does (truncated?)");
  } else {
    throw Error(where + ": unknown chunk compression '" + std::string(compression.substr(0, 40)) + "' (this reader knows none, bz2, lz4)");
  }
  if (produced != size)
    throw Error(where + ": chunk decompresses to " + std::to_string(produced) + " bytes, its header says " + std::to_string(size));
  return {out.data(), produced};
}

// ---- message definitions ------------------------------------------------------------------------

enum class Prim : std::uint8_t {
  Bool,
  Int8,
  UInt8,
  Int16,
  UInt16,
  Int32,
  UInt32,
  Int64,
  UInt64,
  Float32,
  Float64,
  String,
  Time,
  Duration,
  Struct
};

constexpr int prim_size(Prim p) {
  switch (p) {
    case Prim::Bool:
    case Prim::Int8:
    case Prim::UInt8:
      return 1;
    case Prim::Int16:
    case Prim::UInt16:
      return 2;
    case Prim::Int32:
    case Prim::UInt32:
    case Prim::Float32:
      return 4;
    case Prim::Int64:
    case Prim::UInt64:
    case Prim::Float64:
    case Prim::Time:
    case Prim::Duration:
      return 8;
    default:
      return -1;
  }
}
constexpr bool prim_integer(Prim p) { return p <= Prim::UInt64; }

struct MsgField {
  std::string name;
  Prim prim = Prim::Struct;
  std::string type_name;  ///< Struct: the referenced type as written, resolved into `type`
  int type = -1;
  std::int64_t array = 0;  ///< 0 scalar, -1 variable length, n > 0 fixed length n
};
struct MsgType {
  std::string name;  ///< "pkg/Name"
  std::vector<MsgField> fields;
  std::int64_t fixed = -2;  ///< bytes when every field has a fixed size, -1 when not; -2 not yet known
};

/// A message type and every type it uses, parsed from a connection's `message_definition`.
struct MsgSchema {
  std::vector<MsgType> types;  ///< types[0] is the connection's own type
  std::string where;           ///< the connection, for errors
  const MsgType& root() const { return types[0]; }
  const MsgField* field(int type, std::string_view name) const {
    for (const auto& f : types[static_cast<std::size_t>(type)].fields)
      if (f.name == name) return &f;
    return nullptr;
  }
};

inline bool parse_prim(std::string_view t, Prim& p) {
  static constexpr std::pair<std::string_view, Prim> table[] = {
      {"bool", Prim::Bool},       {"int8", Prim::Int8},     {"byte", Prim::Int8},     {"uint8", Prim::UInt8},
      {"char", Prim::UInt8},      {"int16", Prim::Int16},   {"uint16", Prim::UInt16}, {"int32", Prim::Int32},
      {"uint32", Prim::UInt32},   {"int64", Prim::Int64},   {"uint64", Prim::UInt64}, {"float32", Prim::Float32},
      {"float64", Prim::Float64}, {"string", Prim::String}, {"time", Prim::Time},     {"duration", Prim::Duration}};
  for (const auto& [name, prim] : table)
    if (t == name) {
      p = prim;
      return true;
    }
  return false;
}

inline std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

inline std::int64_t msg_fixed_size(MsgSchema& s, int type, int depth = 0);

/// Parses ROS's .msg text: the root type's fields, then sections "MSG: pkg/Name" after lines of '='.
inline MsgSchema parse_msg_definition(std::string_view root_type, std::string_view text, const std::string& where) {
  MsgSchema s;
  s.where = where;
  s.types.push_back({std::string(root_type), {}, -2});
  std::size_t pos = 0;
  bool expect_name = false;
  while (pos <= text.size()) {
    const auto nl = text.find('\n', pos);
    std::string_view line = text.substr(pos, nl == std::string_view::npos ? std::string_view::npos : nl - pos);
    pos = nl == std::string_view::npos ? text.size() + 1 : nl + 1;
    line = trim(line);
    if (line.size() >= 3 && line.find_first_not_of('=') == std::string_view::npos) {
      expect_name = true;
      continue;
    }
    if (expect_name) {
      if (line.empty()) continue;
      if (line.substr(0, 4) != "MSG:") throw Error(where + ": message definition: expected 'MSG: pkg/Name' after a line of '='");
      s.types.push_back({std::string(trim(line.substr(4))), {}, -2});
      if (s.types.size() > 4096) throw Error(where + ": message definition has more than 4096 types");
      expect_name = false;
      continue;
    }
    if (const auto hash = line.find('#'); hash != std::string_view::npos) line = trim(line.substr(0, hash));
    if (line.empty()) continue;
    const auto sp = line.find_first_of(" \t");
    if (sp == std::string_view::npos)
      throw Error(where + ": message definition line '" + std::string(line.substr(0, 60)) + "' has no field name");
    std::string_view type = line.substr(0, sp), name = trim(line.substr(sp));
    if (name.find('=') != std::string_view::npos) continue;  // a constant: no bytes in the message
    if (name.find_first_of(" \t") != std::string_view::npos)
      throw Error(where + ": message definition line '" + std::string(line.substr(0, 60)) + "' is not 'type name'");
    MsgField f;
    f.name = std::string(name);
    if (const auto br = type.find('['); br != std::string_view::npos) {
      if (type.back() != ']') throw Error(where + ": message definition: bad array type '" + std::string(type.substr(0, 60)) + "'");
      const std::string_view n = type.substr(br + 1, type.size() - br - 2);
      if (n.empty()) {
        f.array = -1;
      } else {
        std::int64_t v = 0;
        for (char c : n) {
          if (c < '0' || c > '9' || v > (std::int64_t{1} << 31))
            throw Error(where + ": message definition: bad array length in '" + std::string(type.substr(0, 60)) + "'");
          v = v * 10 + (c - '0');
        }
        if (v == 0) throw Error(where + ": message definition: array of length 0 in '" + std::string(type) + "'");
        f.array = v;
      }
      type = type.substr(0, br);
    }
    if (!parse_prim(type, f.prim)) {
      f.prim = Prim::Struct;
      f.type_name = type == "Header" ? "std_msgs/Header" : std::string(type);
    }
    s.types.back().fields.push_back(std::move(f));
  }
  // Resolve the referenced types: "pkg/Name" exactly, else "Name" in the referring type's package, else
  // the one section whose short name matches.
  for (std::size_t t = 0; t < s.types.size(); ++t) {
    const std::string& owner = s.types[t].name;
    const std::string pkg = owner.substr(0, owner.find('/'));
    for (auto& f : s.types[t].fields) {
      if (f.prim != Prim::Struct) continue;
      auto find = [&](const std::string& full) {
        for (std::size_t k = 0; k < s.types.size(); ++k)
          if (s.types[k].name == full) return static_cast<int>(k);
        return -1;
      };
      int k = find(f.type_name);
      if (k < 0 && f.type_name.find('/') == std::string::npos) {
        k = find(pkg + "/" + f.type_name);
        if (k < 0)
          for (std::size_t j = 0; j < s.types.size(); ++j) {
            const auto& n = s.types[j].name;
            const auto slash = n.find('/');
            if (slash != std::string::npos && n.substr(slash + 1) == f.type_name) {
              if (k >= 0) throw Error(where + ": message definition: type '" + bag_shown(f.type_name) + "' is ambiguous");
              k = static_cast<int>(j);
            }
          }
      }
      if (k < 0)
        throw Error(where + ": message definition: field '" + bag_shown(f.name) + "' of " + bag_shown(owner) + " has type '" +
                    bag_shown(f.type_name) + "', whose definition is not included");
      f.type = k;
    }
  }
  for (std::size_t t = 0; t < s.types.size(); ++t) msg_fixed_size(s, static_cast<int>(t));
  return s;
}

/// The size of a type when all its fields have fixed sizes, else -1; a type that contains itself is refused.
inline std::int64_t msg_fixed_size(MsgSchema& s, int type, int depth) {
  auto& t = s.types[static_cast<std::size_t>(type)];
  if (t.fixed != -2) return t.fixed;
  if (depth > 64) throw Error(s.where + ": message definition: type " + bag_shown(t.name) + " contains itself");
  std::int64_t total = 0;
  for (const auto& f : t.fields) {
    std::int64_t one = f.prim == Prim::Struct ? msg_fixed_size(s, f.type, depth + 1) : prim_size(f.prim);
    if (one < 0 || f.array < 0) return t.fixed = -1;
    total += one * (f.array > 0 ? f.array : 1);
    if (total > (std::int64_t{1} << 40)) throw Error(s.where + ": message definition: type " + bag_shown(t.name) + " is absurdly large");
  }
  return t.fixed = total;
}

/// A position in a message being decoded; every read is bounds-checked.
struct MsgCursor {
  const unsigned char* p;
  const unsigned char* end;
  const std::string* where;  ///< names the message, for errors
  void need(std::uint64_t n) const {
    if (n > static_cast<std::uint64_t>(end - p))
      throw Error(*where + ": message ends early (needs " + std::to_string(n) + " more bytes, has " + std::to_string(end - p) + ")");
  }
  std::uint32_t u32() {
    need(4);
    const auto v = bag_u32(p);
    p += 4;
    return v;
  }
};

inline void msg_skip_type(const MsgSchema& s, int type, MsgCursor& c, int depth);

inline void msg_skip_field(const MsgSchema& s, const MsgField& f, MsgCursor& c, int depth) {
  const std::int64_t elem = f.prim == Prim::Struct ? s.types[static_cast<std::size_t>(f.type)].fixed : prim_size(f.prim);
  std::uint64_t n = 1;
  if (f.array > 0) n = static_cast<std::uint64_t>(f.array);
  if (f.array < 0) n = c.u32();
  if (elem >= 0) {
    c.need(n * static_cast<std::uint64_t>(elem));
    c.p += n * static_cast<std::uint64_t>(elem);
    return;
  }
  // Variable-size elements take at least 4 bytes each (a string's or an array's length): a count larger
  // than that allows is refused before looping over it.
  if (n > static_cast<std::uint64_t>(c.end - c.p) / 4 + 1) c.need(4 * n);
  for (std::uint64_t i = 0; i < n; ++i) {
    if (f.prim == Prim::String) {
      const std::uint32_t len = c.u32();
      c.need(len);
      c.p += len;
    } else {
      msg_skip_type(s, f.type, c, depth + 1);
    }
  }
}

inline void msg_skip_type(const MsgSchema& s, int type, MsgCursor& c, int depth) {
  if (depth > 64) throw Error(*c.where + ": message nests deeper than 64 levels");
  for (const auto& f : s.types[static_cast<std::size_t>(type)].fields) msg_skip_field(s, f, c, depth);
}

/// Calls fn(field, cursor) for each field of `type` in order; fn returns true when it consumed the field,
/// false to have it skipped.
template <class Fn>
void msg_walk(const MsgSchema& s, int type, MsgCursor& c, Fn&& fn) {
  for (const auto& f : s.types[static_cast<std::size_t>(type)].fields)
    if (!fn(f, c)) msg_skip_field(s, f, c, 1);
}

inline double msg_read_number(const MsgField& f, MsgCursor& c) {
  const int n = prim_size(f.prim);
  c.need(static_cast<std::uint64_t>(n));
  const unsigned char* p = c.p;
  c.p += n;
  switch (f.prim) {
    case Prim::Bool:
    case Prim::UInt8:
      return p[0];
    case Prim::Int8:
      return static_cast<std::int8_t>(p[0]);
    case Prim::UInt16:
      return std::uint16_t(p[0] | p[1] << 8);
    case Prim::Int16:
      return static_cast<std::int16_t>(std::uint16_t(p[0] | p[1] << 8));
    case Prim::UInt32:
      return bag_u32(p);
    case Prim::Int32:
      return static_cast<std::int32_t>(bag_u32(p));
    case Prim::UInt64:
      return static_cast<double>(bag_u64(p));
    case Prim::Int64:
      return static_cast<double>(static_cast<std::int64_t>(bag_u64(p)));
    case Prim::Float32: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case Prim::Float64: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
    default:
      throw Error(*c.where + ": field '" + bag_shown(f.name) + "' is not a number");
  }
}

inline bool is_number_field(const MsgField& f) {
  return f.array == 0 && f.prim != Prim::Struct && f.prim != Prim::String && f.prim != Prim::Time && f.prim != Prim::Duration;
}

inline std::int64_t msg_int_at(Prim p, const unsigned char* q) {
  switch (p) {
    case Prim::Bool:
    case Prim::UInt8:
      return q[0];
    case Prim::Int8:
      return static_cast<std::int8_t>(q[0]);
    case Prim::UInt16:
      return std::uint16_t(q[0] | q[1] << 8);
    case Prim::Int16:
      return static_cast<std::int16_t>(std::uint16_t(q[0] | q[1] << 8));
    case Prim::UInt32:
      return bag_u32(q);
    case Prim::Int32:
      return static_cast<std::int32_t>(bag_u32(q));
    case Prim::UInt64:
    case Prim::Int64:
      return static_cast<std::int64_t>(bag_u64(q));
    default:
      return 0;
  }
}

/// ROS time as stored: seconds and nanoseconds.
struct RosTime {
  std::uint32_t sec = 0, nsec = 0;
  bool zero() const { return sec == 0 && nsec == 0; }
};

inline RosTime msg_read_time(const MsgField& f, MsgCursor& c) {
  if (f.prim != Prim::Time || f.array != 0) throw Error(*c.where + ": field '" + f.name + "' is not a time");
  c.need(8);
  RosTime t{bag_u32(c.p), bag_u32(c.p + 4)};
  c.p += 8;
  return t;
}

/// Reads an array of float64 (fixed length `n`, or any length when n < 0) at a field.
inline std::vector<double> msg_read_f64s(const MsgField& f, MsgCursor& c, std::int64_t n, const std::string& type) {
  if (f.prim != Prim::Float64 || f.array == 0 || (n >= 0 && f.array != n))
    throw Error(*c.where + ": field '" + bag_shown(f.name) + "' of " + type + " is not float64[" + (n >= 0 ? std::to_string(n) : "") + "]");
  const std::uint64_t count = f.array > 0 ? static_cast<std::uint64_t>(f.array) : c.u32();
  c.need(8 * count);
  std::vector<double> v(count);
  if (count) std::memcpy(v.data(), c.p, 8 * count);  // (an empty vector's data() may be null)
  c.p += 8 * count;
  return v;
}

inline std::string msg_read_string(const MsgField& f, MsgCursor& c, std::size_t keep = 256) {
  if (f.prim != Prim::String || f.array != 0) throw Error(*c.where + ": field '" + f.name + "' is not a string");
  const std::uint32_t len = c.u32();
  c.need(len);
  std::string s(reinterpret_cast<const char*>(c.p), std::min<std::size_t>(len, keep));
  c.p += len;
  return s;
}

/// Where in an event message's `events` array the fields of one event lie.
struct EventLayout {
  std::int64_t stride = 0, ox = 0, oy = 0, ots = 0, op = 0;
  Prim px = Prim::UInt16, py = Prim::UInt16, pp = Prim::Bool;
};

/// Whether a message type is an array of events (see the file's comment); `why` says what is missing.
inline bool event_layout(const MsgSchema& s, EventLayout& L, std::string& why) {
  const MsgField* ev = s.field(0, "events");
  if (!ev) return why = "it has no field 'events'", false;
  if (ev->prim != Prim::Struct || ev->array != -1) return why = "its field 'events' is not a variable-length array of structs", false;
  const auto& t = s.types[static_cast<std::size_t>(ev->type)];
  if (t.fixed <= 0) return why = "its events (" + bag_shown(t.name) + ") have no fixed size", false;
  L.stride = t.fixed;
  bool got[4] = {false, false, false, false};
  std::int64_t off = 0;
  for (const auto& f : t.fields) {
    const std::int64_t size =
        (f.prim == Prim::Struct ? s.types[static_cast<std::size_t>(f.type)].fixed : prim_size(f.prim)) * (f.array > 0 ? f.array : 1);
    if (f.array == 0) {
      if (f.name == "x" && prim_integer(f.prim)) L.ox = off, L.px = f.prim, got[0] = true;
      if (f.name == "y" && prim_integer(f.prim)) L.oy = off, L.py = f.prim, got[1] = true;
      if (f.name == "ts" && f.prim == Prim::Time) L.ots = off, got[2] = true;
      if (f.name == "polarity" && prim_integer(f.prim)) L.op = off, L.pp = f.prim, got[3] = true;
    }
    off += size;
  }
  if (!(got[0] && got[1] && got[2] && got[3]))
    return why = "its events (" + bag_shown(t.name) + ") lack integer 'x', 'y', 'polarity' or a 'time ts'", false;
  return true;
}

struct BagConnection {
  std::uint32_t id = 0;
  std::string topic, type, md5, definition;
};
struct BagChunkInfo {
  std::uint64_t pos = 0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> counts;  ///< connection, messages
};

/// The file header and the index at the end (connections, chunk infos); `indexed` is false for a bag
/// whose index was never written (a recording that did not close) or was cut off, which is then scanned up to
/// `records_end`, the end of its last whole record.
struct BagIndex {
  std::uint64_t first_record = 0, index_pos = 0, records_end = 0;
  bool indexed = false;
  std::map<std::uint32_t, BagConnection> conns;
  std::vector<BagChunkInfo> chunks;
};

inline BagConnection parse_bag_connection(const BagHeader& h, std::string_view data, const std::string& where) {
  BagConnection c;
  c.id = bag_field_u32(h, "conn", where);
  c.topic = std::string(bag_field(h, "topic", 0, where));
  const BagHeader d = parse_bag_header(data, where + " (connection data)");
  c.type = std::string(bag_field(d, "type", 0, where + " (connection data)"));
  if (const auto* md5 = d.find("md5sum")) c.md5 = std::string(*md5);
  c.definition = std::string(bag_field(d, "message_definition", 0, where + " (connection data)"));
  if (c.topic.empty() || c.type.empty()) throw Error(where + ": connection with an empty topic or type");
  return c;
}

inline void add_bag_connection(BagIndex& idx, BagConnection c, const std::string& where) {
  const auto it = idx.conns.find(c.id);
  if (it != idx.conns.end()) {
    if (it->second.topic != c.topic || it->second.type != c.type)
      throw Error(where + ": connection " + std::to_string(c.id) + " is defined twice, differently");
    return;
  }
  if (idx.conns.size() >= 65536) throw Error(where + ": more than 65536 connections");
  idx.conns.emplace(c.id, std::move(c));
}

/// Why the record at `off` runs past the end of the file (a file cut short), or "" when it is whole or wrong
/// in another way (read_bag_record names that).
inline std::string bag_record_cut(BagFile& f, std::uint64_t off) {
  const std::uint64_t rest = f.size() - off;
  unsigned char len[4];
  if (rest < 4) return "the file ends inside a record's header length";
  f.read(off, len, 4, "record header length");
  const std::uint32_t hl = bag_u32(len);
  if (hl > kBagMaxRecordHeader) return "";
  if (hl > rest - 4) return "a record header of " + std::to_string(hl) + " bytes runs past the end of the file";
  if (rest - 4 - hl < 4) return "the file ends inside a record's data length";
  f.read(off + 4 + hl, len, 4, "record data length");
  if (bag_u32(len) > rest - 8 - hl) return "a record of " + std::to_string(bag_u32(len)) + " data bytes runs past the end of the file";
  return "";
}

/// Reads the bag header and the index. A bag without an index (never closed), or whose index lies past the end
/// of the file or runs past it (cut short), is scanned: its records are walked here, headers only, to the last
/// whole one, and what runs past the end of the file is dropped with one warning naming its byte offset.
inline BagIndex read_bag_index(BagFile& f) {
  BagIndex idx;
  char magic[13] = {};
  if (f.size() < kBagMagic.size()) throw Error(f.name(), 0, "not a ROS bag (shorter than the '#ROSBAG V2.0' line)");
  f.read(0, magic, 13, "bag magic");
  if (std::string_view(magic, 13) != kBagMagic) {
    if (std::string_view(magic, 9) == "#ROSBAG V") {
      const std::string_view v(magic + 9, 4);
      throw Error(
          f.name(), 0,
          "ROS bag version '" + bag_shown(v.substr(0, v.find('\n'))) + "' is not read (only 2.0; 'rosbag fix' converts older bags)");
    }
    throw Error(f.name(), 0, "not a ROS bag (no '#ROSBAG V2.0' line at its start)");
  }
  std::string hb;
  BagHeader h;
  const auto [data_off, dl] = read_bag_record(f, 13, hb, h);
  const std::string where = f.name() + ": bag header record at byte 13";
  if (bag_op(h, where) != kBagFileHeader) throw Error(where + ": the first record is not the bag header (op 0x03)");
  idx.index_pos = bag_field_u64(h, "index_pos", where);
  const std::uint32_t conn_count = bag_field_u32(h, "conn_count", where), chunk_count = bag_field_u32(h, "chunk_count", where);
  idx.first_record = data_off + dl;
  if (idx.index_pos != 0 && idx.index_pos < idx.first_record)
    throw Error(where + ": index position " + std::to_string(idx.index_pos) + " lies before the file's records (at byte " +
                std::to_string(idx.first_record) + "); 'rosbag reindex' rebuilds it");
  // Never closed, or cut short: the records are walked (headers only) to `limit` or to the last whole one, and
  // read_rosbag scans them. `cut` says what was cut short, for the one warning.
  auto scanned = [&](std::uint64_t limit, std::string cut) {
    idx.index_pos = 0, idx.indexed = false;
    idx.conns.clear(), idx.chunks.clear();
    std::uint64_t off = idx.first_record;
    while (off < limit) {
      const std::string why = bag_record_cut(f, off);
      if (!why.empty()) {
        cut += (cut.empty() ? "byte " : "; at byte ") + std::to_string(off) + ": " + why;
        break;
      }
      const auto [doff, len] = read_bag_record(f, off, hb, h);
      off = doff + len;
    }
    idx.records_end = off;
    if (!cut.empty())
      warn(f.name() + ": " + cut + " (a recording cut short); its records are read to the last whole one, " +
           std::to_string(f.size() - off) + " bytes dropped" + (limit < f.size() ? " (the index only)" : ""));
    return idx;
  };
  if (idx.index_pos == 0) return scanned(f.size(), "");
  if (idx.index_pos >= f.size())
    return scanned(f.size(), "the bag header places its index at byte " + std::to_string(idx.index_pos) + ", past the end of the file (" +
                                 std::to_string(f.size()) + " bytes)");
  std::uint64_t off = idx.index_pos;
  std::string data;
  while (off < f.size()) {
    if (const std::string why = bag_record_cut(f, off); !why.empty())
      return scanned(idx.index_pos,
                     "the index, at byte " + std::to_string(idx.index_pos) + ", is cut short at byte " + std::to_string(off) + ": " + why);
    const auto [doff, len] = read_bag_record(f, off, hb, h);
    const std::string at = f.name() + ": index record at byte " + std::to_string(off);
    const int op = bag_op(h, at);
    if (op == kBagConnection) {
      data.resize(len);
      f.read(doff, data.data(), len, "connection record");
      add_bag_connection(idx, parse_bag_connection(h, data, at), at);
    } else if (op == kBagChunkInfo) {
      if (bag_field_u32(h, "ver", at) != 1) throw Error(at + ": chunk info version is not 1");
      BagChunkInfo ci;
      ci.pos = bag_field_u64(h, "chunk_pos", at);
      const std::uint32_t count = bag_field_u32(h, "count", at);
      if (std::uint64_t{count} * 8 != len)
        throw Error(at + ": chunk info lists " + std::to_string(count) + " connections in " + std::to_string(len) + " bytes");
      if (ci.pos < idx.first_record || ci.pos >= idx.index_pos)
        throw Error(at + ": chunk position " + std::to_string(ci.pos) + " lies outside the chunks");
      data.resize(len);
      f.read(doff, data.data(), len, "chunk info record");
      for (std::uint32_t i = 0; i < count; ++i) {
        const auto* p = reinterpret_cast<const unsigned char*>(data.data()) + 8 * i;
        ci.counts.emplace_back(bag_u32(p), bag_u32(p + 4));
      }
      if (idx.chunks.size() >= chunk_count) throw Error(at + ": more chunk infos than the bag header's " + std::to_string(chunk_count));
      idx.chunks.push_back(std::move(ci));
    } else {
      throw Error(at + ": unexpected record (op " + std::to_string(op) + ") in the index; 'rosbag reindex' rebuilds it");
    }
    off = doff + len;
  }
  if (idx.conns.size() != conn_count || idx.chunks.size() != chunk_count)
    throw Error(where + ": the index holds " + std::to_string(idx.conns.size()) + " connections and " + std::to_string(idx.chunks.size()) +
                " chunk infos, the header says " + std::to_string(conn_count) + " and " + std::to_string(chunk_count) +
                "; 'rosbag reindex' rebuilds it");
  std::sort(idx.chunks.begin(), idx.chunks.end(), [](const auto& a, const auto& b) { return a.pos < b.pos; });
  idx.indexed = true;
  idx.records_end = idx.index_pos;
  return idx;
}

/// Visits every message record of the bag (in file order) as fn(connection id, record time, data, where):
/// the chunks the index lists when `want` says the chunk holds a wanted connection, or every record when
/// the bag has no index (connection records met on the way are added to `idx`).
template <class Want, class Fn>
void for_each_bag_message(BagFile& f, BagIndex& idx, Want&& want, Fn&& fn, const ReadProgress& progress = {}) {
  std::string hb, data;
  std::vector<char> raw;
  Lz4Context lz4;
  BagHeader h;
  auto chunk = [&](std::uint64_t pos, const BagHeader& ch, std::uint64_t doff, std::uint32_t len) {
    const std::string at = f.name() + ": chunk at byte " + std::to_string(pos);
    const std::string_view compression = bag_field(ch, "compression", 0, at);
    const std::uint64_t size = bag_field_u32(ch, "size", at);
    data.resize(len);
    f.read(doff, data.data(), len, "chunk");
    const std::string_view records = decompress_bag_chunk(compression, data, size, raw, at, lz4);
    std::size_t p = 0;
    BagHeader rh;
    std::string_view body;
    for (;;) {
      const std::size_t start = p;
      if (!next_bag_record(records, p, rh, body, at)) break;
      const std::string rat = at + ", record at offset " + std::to_string(start);
      const int op = bag_op(rh, rat);
      if (op == kBagConnection) {
        add_bag_connection(idx, parse_bag_connection(rh, body, rat), rat);
      } else if (op == kBagMessage) {
        const std::uint32_t conn = bag_field_u32(rh, "conn", rat);
        const std::uint64_t time = bag_field_u64(rh, "time", rat);
        if (!idx.conns.count(conn)) throw Error(rat + ": message of connection " + std::to_string(conn) + ", which the bag never defines");
        if (want(conn)) fn(conn, RosTime{static_cast<std::uint32_t>(time), static_cast<std::uint32_t>(time >> 32)}, body, rat);
      } else {
        throw Error(rat + ": unexpected record (op " + std::to_string(op) + ") inside a chunk");
      }
    }
  };
  if (idx.indexed) {
    for (const auto& ci : idx.chunks) {
      bool any = false;
      for (const auto& [conn, n] : ci.counts) any = any || (n > 0 && want(conn));
      if (!any) continue;
      const auto [doff, len] = read_bag_record(f, ci.pos, hb, h);
      const std::string at = f.name() + ": chunk at byte " + std::to_string(ci.pos);
      if (bag_op(h, at) != kBagChunk) throw Error(at + ": the index points at a record that is not a chunk; 'rosbag reindex' rebuilds it");
      chunk(ci.pos, h, doff, len);
      if (progress) progress(doff + len, f.size());
    }
    return;
  }
  std::uint64_t off = idx.first_record;
  while (off < idx.records_end) {
    const auto [doff, len] = read_bag_record(f, off, hb, h);
    const std::string at = f.name() + ": record at byte " + std::to_string(off);
    const int op = bag_op(h, at);
    if (op == kBagChunk) {
      chunk(off, h, doff, len);
    } else if (op == kBagConnection) {
      data.resize(len);
      f.read(doff, data.data(), len, "connection record");
      add_bag_connection(idx, parse_bag_connection(h, data, at), at);
    } else if (op == kBagMessage) {
      const std::uint32_t conn = bag_field_u32(h, "conn", at);
      const std::uint64_t time = bag_field_u64(h, "time", at);
      if (!idx.conns.count(conn)) throw Error(at + ": message of connection " + std::to_string(conn) + ", which the bag never defines");
      if (want(conn)) {
        data.resize(len);
        f.read(doff, data.data(), len, "message record");
        fn(conn, RosTime{static_cast<std::uint32_t>(time), static_cast<std::uint32_t>(time >> 32)}, std::string_view(data), at);
      }
    } else if (op != kBagIndexData && op != kBagChunkInfo) {
      throw Error(at + ": unknown record (op " + std::to_string(op) + ")");
    }
    off = doff + len;
    if (progress && op == kBagChunk) progress(off, f.size());
  }
}

}  // namespace detail

/// Whether the file starts like a ROS bag ("#ROSBAG V").
inline bool is_rosbag(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.string().c_str(), "rb");
  if (!f) return false;
  char b[9] = {};
  const bool ok = std::fread(b, 1, 9, f) == 9 && std::string_view(b, 9) == "#ROSBAG V";
  std::fclose(f);
  return ok;
}

/// The bag's topics with their types and message counts (from the index; a bag without one is scanned).
inline std::vector<BagTopic> rosbag_topics(const std::filesystem::path& path) {
  detail::BagFile f(path);
  auto idx = detail::read_bag_index(f);
  std::map<std::uint32_t, std::uint64_t> counts;
  if (idx.indexed) {
    for (const auto& ci : idx.chunks)
      for (const auto& [conn, n] : ci.counts) counts[conn] += n;
  } else {
    detail::for_each_bag_message(
        f, idx, [](std::uint32_t) { return true; },
        [&](std::uint32_t conn, detail::RosTime, std::string_view, const std::string&) { ++counts[conn]; });
  }
  std::map<std::string, BagTopic> topics;
  for (const auto& [id, c] : idx.conns) {
    auto& t = topics[c.topic];
    if (!t.type.empty() && t.type != c.type)
      throw Error(f.name(), 0,
                  "topic " + detail::bag_shown(c.topic) + " carries two types (" + detail::bag_shown(t.type) + ", " +
                      detail::bag_shown(c.type) + ")");
    t.topic = c.topic;
    t.type = c.type;
    t.messages += counts[id];
    ++t.connections;
  }
  std::vector<BagTopic> out;
  for (auto& [name, t] : topics) out.push_back(std::move(t));
  return out;
}

namespace detail {

/// Position and orientation of a PoseStamped, Odometry, PoseWithCovarianceStamped or TransformStamped.
struct PoseRead {
  bool has_pos = false, has_rot = false, has_stamp = false;
  double p[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1};  // x y z w
  RosTime stamp;
};

inline void msg_read_xyzw(const MsgSchema& s, const MsgField& f, MsgCursor& c, double* out, bool quat) {
  bool got[4] = {false, false, false, !quat};
  msg_walk(s, f.type, c, [&](const MsgField& g, MsgCursor& cc) {
    if (g.name.size() != 1 || !is_number_field(g)) return false;
    const int k = g.name[0] == 'x' ? 0 : g.name[0] == 'y' ? 1 : g.name[0] == 'z' ? 2 : g.name[0] == 'w' && quat ? 3 : -1;
    if (k < 0) return false;
    out[k] = msg_read_number(g, cc);
    got[k] = true;
    return true;
  });
  if (!(got[0] && got[1] && got[2] && got[3]))
    throw Error(*c.where + ": field '" + bag_shown(f.name) + "' lacks x, y, z" + (quat ? ", w" : ""));
}

inline RosTime msg_read_header_stamp(const MsgSchema& s, const MsgField& f, MsgCursor& c, bool& got) {
  RosTime t;
  msg_walk(s, f.type, c, [&](const MsgField& g, MsgCursor& cc) {
    if (g.name != "stamp" || g.prim != Prim::Time || g.array != 0) return false;
    t = msg_read_time(g, cc);
    got = true;
    return true;
  });
  return t;
}

inline void msg_read_pose(const MsgSchema& s, int type, MsgCursor& c, PoseRead& r, int depth) {
  msg_walk(s, type, c, [&](const MsgField& f, MsgCursor& cc) {
    if (f.prim != Prim::Struct || f.array != 0) return false;
    if (depth == 0 && f.name == "header") {
      r.stamp = msg_read_header_stamp(s, f, cc, r.has_stamp);
      return true;
    }
    if (f.name == "position" || f.name == "translation") {
      msg_read_xyzw(s, f, cc, r.p, false);
      r.has_pos = true;
      return true;
    }
    if (f.name == "orientation" || f.name == "rotation") {
      msg_read_xyzw(s, f, cc, r.q, true);
      r.has_rot = true;
      return true;
    }
    if ((f.name == "pose" || f.name == "transform") && depth < 4) {
      msg_read_pose(s, f.type, cc, r, depth + 1);
      return true;
    }
    return false;
  });
}

/// A sensor_msgs/Image's pixels as a float image in [0, 1] (Bayer mosaics demosaiced to RGB).
inline Image bag_image(std::uint64_t w, std::uint64_t h, const std::string& enc, bool big_endian, std::uint64_t step,
                       const unsigned char* data, std::uint64_t len, const std::string& where) {
  if (w < 1 || h < 1 || w > 65535 || h > 65535 || w * h > (std::uint64_t{1} << 26))
    throw Error(where + ": image size " + std::to_string(w) + "x" + std::to_string(h) + " out of range");
  int channels = 1, bytes = 1;
  bool bgr = false, alpha = false;
  geometry::BayerPattern bayer;
  bool mosaic = false;
  if (enc == "mono8" || enc == "8UC1") {
  } else if (enc == "mono16" || enc == "16UC1") {
    bytes = 2;
  } else if (enc == "rgb8" || enc == "bgr8" || enc == "rgba8" || enc == "bgra8") {
    channels = 3;
    bgr = enc[0] == 'b';
    alpha = enc.size() == 5;
  } else if (enc.size() >= 11 && enc.substr(0, 6) == "bayer_" && geometry::BayerPattern::parse(std::string_view(enc).substr(6, 4), bayer) &&
             (enc.substr(10) == "8" || enc.substr(10) == "16")) {
    mosaic = true;
    bytes = enc.substr(10) == "16" ? 2 : 1;
  } else {
    throw Error(where + ": unknown image encoding '" + enc.substr(0, 40) +
                "' (read: mono8, mono16, rgb8, bgr8, rgba8, bgra8, bayer_{rggb,bggr,gbrg,grbg}{8,16})");
  }
  const std::uint64_t px_bytes = std::uint64_t(bytes) * (channels == 3 ? (alpha ? 4 : 3) : 1);
  if (step < w * px_bytes) throw Error(where + ": row step " + std::to_string(step) + " is shorter than a row of " + enc + " pixels");
  if (len < step * (h - 1) + w * px_bytes)
    throw Error(where + ": image data holds " + std::to_string(len) + " bytes, " + std::to_string(h) + " rows of step " +
                std::to_string(step) + " need " + std::to_string(step * (h - 1) + w * px_bytes));
  Image img(static_cast<int>(w), static_cast<int>(h), channels);
  const float full = bytes == 2 ? 65535.f : 255.f;  // divided, as the PNG and HDF5 readers do: the same floats
  for (std::uint64_t y = 0; y < h; ++y) {
    const unsigned char* row = data + y * step;
    for (std::uint64_t x = 0; x < w; ++x)
      for (int k = 0; k < channels; ++k) {
        const unsigned char* q = row + x * px_bytes + static_cast<std::uint64_t>((bgr ? 2 - k : k) * bytes);
        const unsigned v = bytes == 1 ? q[0] : big_endian ? unsigned(q[0]) << 8 | q[1] : unsigned(q[1]) << 8 | q[0];
        img.data[(y * w + x) * static_cast<std::uint64_t>(channels) + static_cast<std::uint64_t>(k)] = static_cast<float>(v) / full;
      }
  }
  return mosaic ? geometry::demosaic(img, bayer) : img;
}

inline std::string join_topics(const std::vector<std::string>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size() && i < 5; ++i) s += (i ? ", " : "") + v[i];
  if (v.size() > 5) s += ", ... (" + std::to_string(v.size()) + " in all)";
  return s;
}

/// A bag's topics: the connections of each, their message definitions (parsed when first asked for), and
/// the choice of the topic that plays each role of a recording.
class BagTopics {
 public:
  BagTopics(const BagFile& f, const BagIndex& idx) : name_(f.name()), idx_(idx) {
    for (const auto& [id, c] : idx.conns) {
      auto& v = conns_[c.topic];
      if (!v.empty() && idx.conns.at(v.front()).type != c.type)
        throw Error(name_, 0,
                    "topic " + bag_shown(c.topic) + " carries two types (" + bag_shown(idx.conns.at(v.front()).type) + ", " +
                        bag_shown(c.type) + ")");
      v.push_back(id);
    }
    for (const auto& [topic, ids] : conns_) listing_.push_back(bag_shown(topic) + " (" + bag_shown(idx.conns.at(ids.front()).type) + ")");
  }
  /// A topic's connections (one or more, all of one type).
  const std::vector<std::uint32_t>& connections(const std::string& topic) const { return conns_.at(topic); }
  std::string type_of(const std::string& topic) const { return idx_.conns.at(conns_.at(topic).front()).type; }
  /// A connection's message definition, parsed; null where it does not parse (schema_error says why).
  const MsgSchema* schema(std::uint32_t id) {
    if (auto it = schemas_.find(id); it != schemas_.end()) return &it->second;
    if (schema_errors_.count(id)) return nullptr;
    const auto& c = idx_.conns.at(id);
    try {
      return &schemas_
                  .emplace(id, parse_msg_definition(c.type, c.definition,
                                                    name_ + ": topic " + bag_shown(c.topic) + " (" + bag_shown(c.type) + ")"))
                  .first->second;
    } catch (const Error& e) {
      schema_errors_[id] = e.what();
      return nullptr;
    }
  }
  const std::string& schema_error(std::uint32_t id) const { return schema_errors_.at(id); }
  /// Whether a topic's messages are arrays of events (x, y, ts, polarity); `why` says why not.
  bool fits_events(const std::string& topic, std::string& why) {
    const auto* s = schema(conns_.at(topic).front());
    if (!s) return why = schema_errors_.at(conns_.at(topic).front()), false;
    EventLayout L;
    return event_layout(*s, L, why);
  }
  /// A test of a topic's type against `types`, for choose.
  auto of_type(std::initializer_list<std::string_view> types) const {
    return [this, types = std::vector<std::string_view>(types)](const std::string& topic, std::string& why) {
      const std::string t = type_of(topic);
      for (auto k : types)
        if (t == k) return true;
      why = "its type is not ";
      for (std::size_t i = 0; i < types.size(); ++i) why += (i ? " or " : "") + std::string(types[i]);
      return false;
    };
  }
  /// The topic that plays `role`: the one `requested` (its flag), which must fit; else the one topic that
  /// fits; empty where none does and the role is not required, or where 'none' is requested.
  template <class Fits>
  std::string choose(const std::string& role, const std::string& flag, const std::string& requested, Fits&& fits, bool required) {
    if (requested == "none") {
      if (required) throw Error(name_, 0, "the " + role + " topic cannot be 'none'");
      return std::string();
    }
    std::string why;
    if (!requested.empty()) {
      if (!conns_.count(requested))
        throw Error(name_, 0, "no topic '" + bag_shown(requested) + "' (" + flag + "); the bag's topics: " + join_topics(listing_));
      if (!fits(requested, why))
        throw Error(name_, 0,
                    "topic " + bag_shown(requested) + " (" + bag_shown(type_of(requested)) + ") cannot be the " + role + ": " + why);
      return requested;
    }
    std::vector<std::string> c, shown;
    for (const auto& [topic, ids] : conns_)
      if (fits(topic, why)) c.push_back(topic), shown.push_back(bag_shown(topic));
    if (c.size() > 1)
      throw Error(name_, 0,
                  "several topics could be the " + role + " (" + join_topics(shown) + "): choose one with " + flag +
                      (required ? "" : " (or 'none')"));
    if (c.empty()) {
      if (required) {
        std::string unread;  // definitions that could not be parsed may hide the topic looked for
        if (!schema_errors_.empty()) unread = "; " + schema_errors_.begin()->second;
        throw Error(
            name_, 0,
            "no " + role + " topic (an array of events with x, y, ts, polarity); the bag's topics: " + join_topics(listing_) + unread);
      }
      return std::string();
    }
    return c.front();
  }

 private:
  std::string name_;
  const BagIndex& idx_;
  std::map<std::string, std::vector<std::uint32_t>> conns_;
  std::vector<std::string> listing_;
  std::map<std::uint32_t, MsgSchema> schemas_;
  std::map<std::uint32_t, std::string> schema_errors_;
};

/// What read_rosbag gathers from its topics' messages, one member function per kind of message, and the
/// times on one clock: seconds from the first time read (rec.origin_sec).
struct BagGatherer {
  BagRecording& rec;
  std::uint64_t event_messages = 0;  ///< from the index: to size the event arrays after the first message
  std::uint64_t file_size = 0;
  bool have_origin = false;
  bool unsorted = false;  ///< event messages out of time order
  std::vector<std::pair<double, Image>> frames;
  std::vector<std::pair<double, geometry::Pose>> poses;

  BagGatherer(BagRecording& r, std::uint64_t bytes) : rec(r), file_size(bytes) {}

  /// Whole nanoseconds divided by 1e9: the double nearest the exact time, the same a text reader gets
  /// from the time printed with nine decimals (exact below 2^53 ns, 104 days, from the origin).
  double rel(RosTime t) {
    if (!have_origin) rec.origin_sec = t.sec, have_origin = true;
    return static_cast<double>((static_cast<std::int64_t>(t.sec) - rec.origin_sec) * 1000000000 + static_cast<std::int64_t>(t.nsec)) / 1e9;
  }
  /// An array of events (the layout event_layout finds), appended to rec.events.
  void events(const MsgSchema& s, MsgCursor& c, const std::string& where) {
    auto& ev = rec.events;
    EventLayout L;
    std::string why;
    event_layout(s, L, why);
    msg_walk(s, 0, c, [&](const MsgField& fl, MsgCursor& cc) {
      if ((fl.name == "width" || fl.name == "height") && is_number_field(fl)) {
        const double v = msg_read_number(fl, cc);
        if (v < 0 || v > 65535)
          throw Error(where + ": field '" + bag_shown(fl.name) + "' is " + short_number(v) + " (expected 0 to 65535)");
        (fl.name == "width" ? rec.array_width : rec.array_height) = static_cast<int>(v);
        return true;
      }
      if (fl.name != "events") return false;
      const std::uint64_t n = cc.u32();
      cc.need(n * static_cast<std::uint64_t>(L.stride));
      const std::size_t base = ev.size();
      if (base + n > ev.t.capacity()) {  // grown rarely: every reallocation copies the stream
        std::size_t want = std::max<std::size_t>(base + n, ev.t.capacity() + ev.t.capacity() / 2);
        if (base == 0 && event_messages > 1)  // the index's message count times this message's events, and a margin
          want = std::max<std::size_t>(want, std::min<std::uint64_t>(n * event_messages + n * event_messages / 4,
                                                                     file_size / static_cast<std::uint64_t>(L.stride) + 1));
        ev.reserve(want);
      }
      ev.t.resize(base + n);
      ev.x.resize(base + n);
      ev.y.resize(base + n);
      ev.polarity.resize(base + n);
      double last = base ? ev.t[base - 1] : -INFINITY;
      const unsigned char* q = cc.p;
      for (std::uint64_t i = 0; i < n; ++i, q += L.stride) {
        const std::int64_t x = msg_int_at(L.px, q + L.ox), y = msg_int_at(L.py, q + L.oy);
        const double t = rel(RosTime{bag_u32(q + L.ots), bag_u32(q + L.ots + 4)});
        if (x < 0 || y < 0 || x > 65535 || y > 65535)
          throw Error(where + ", event " + std::to_string(i) + ": pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                      ") out of range");
        if (t < last) {
          if (i > 0)
            throw Error(where + ", event " + std::to_string(i) + ": time goes back (" + short_number(t) + " s after " + short_number(last) +
                        " s, relative to " + std::to_string(rec.origin_sec) + " s)");
          unsorted = true;  // messages out of order: sorted below
        }
        last = t;
        rec.max_x = std::max(rec.max_x, x);
        rec.max_y = std::max(rec.max_y, y);
        ev.t[base + i] = t;
        ev.x[base + i] = static_cast<std::uint16_t>(x);
        ev.y[base + i] = static_cast<std::uint16_t>(y);
        ev.polarity[base + i] = msg_int_at(L.pp, q + L.op) > 0 ? 1 : -1;
      }
      cc.p = q;
      return true;
    });
  }
  /// A sensor_msgs/Image, at its header stamp (else the record time).
  void image(const MsgSchema& s, MsgCursor& c, const std::string& where, RosTime record_time) {
    bool stamped = false;
    RosTime stamp;
    std::uint64_t w = 0, h = 0, step = 0, len = 0;
    bool big = false;
    std::string enc;
    const unsigned char* data = nullptr;
    msg_walk(s, 0, c, [&](const MsgField& fl, MsgCursor& cc) {
      if (fl.name == "header" && fl.prim == Prim::Struct && fl.array == 0) return stamp = msg_read_header_stamp(s, fl, cc, stamped), true;
      if (fl.name == "encoding" && fl.prim == Prim::String) return enc = msg_read_string(fl, cc, 64), true;
      if (fl.name == "data" && fl.array == -1 && (fl.prim == Prim::UInt8 || fl.prim == Prim::Int8)) {
        len = cc.u32();
        cc.need(len);
        data = cc.p;
        cc.p += len;
        return true;
      }
      if (!is_number_field(fl)) return false;
      if (fl.name == "width") return w = static_cast<std::uint64_t>(std::max(0.0, msg_read_number(fl, cc))), true;
      if (fl.name == "height") return h = static_cast<std::uint64_t>(std::max(0.0, msg_read_number(fl, cc))), true;
      if (fl.name == "step") return step = static_cast<std::uint64_t>(std::max(0.0, msg_read_number(fl, cc))), true;
      if (fl.name == "is_bigendian") return big = msg_read_number(fl, cc) != 0, true;
      return false;
    });
    if (!data) throw Error(where + ": image without a 'data' array");
    Image img = bag_image(w, h, enc, big, step, data, len, where);
    if (!frames.empty() && (img.width != frames.front().second.width || img.height != frames.front().second.height ||
                            img.channels != frames.front().second.channels))
      throw Error(where + ": frame of " + std::to_string(img.width) + "x" + std::to_string(img.height) + "x" +
                  std::to_string(img.channels) + " after frames of " + std::to_string(frames.front().second.width) + "x" +
                  std::to_string(frames.front().second.height) + "x" + std::to_string(frames.front().second.channels));
    if (rec.frame_encoding.empty()) rec.frame_encoding = enc;
    frames.emplace_back(rel(stamped && !stamp.zero() ? stamp : record_time), std::move(img));
  }
  /// The first sensor_msgs/CameraInfo: intrinsics and distortion (the others are skipped).
  void camera_info(const MsgSchema& s, MsgCursor& c, const std::string& where) {
    if (rec.has_camera_info) return;  // the first is used
    std::string model;
    std::vector<double> D, K;
    double binx = 0, biny = 0;
    msg_walk(s, 0, c, [&](const MsgField& fl, MsgCursor& cc) {
      if (fl.name == "distortion_model" && fl.prim == Prim::String) return model = msg_read_string(fl, cc, 64), true;
      if (fl.name == "D") return D = msg_read_f64s(fl, cc, -1, "sensor_msgs/CameraInfo"), true;
      if (fl.name == "K") return K = msg_read_f64s(fl, cc, 9, "sensor_msgs/CameraInfo"), true;
      if (!is_number_field(fl)) return false;
      if (fl.name == "width") return rec.info_width = static_cast<int>(std::clamp(msg_read_number(fl, cc), 0.0, 1e6)), true;
      if (fl.name == "height") return rec.info_height = static_cast<int>(std::clamp(msg_read_number(fl, cc), 0.0, 1e6)), true;
      if (fl.name == "binning_x") return binx = msg_read_number(fl, cc), true;
      if (fl.name == "binning_y") return biny = msg_read_number(fl, cc), true;
      return false;
    });
    if (K.size() != 9) throw Error(where + ": camera info without K (float64[9])");
    if (!(K[0] > 0) || !(K[4] > 0) || !std::isfinite(K[0]) || !std::isfinite(K[4]) || !std::isfinite(K[2]) || !std::isfinite(K[5]))
      throw Error(where + ": camera info K has no positive, finite focal lengths (fx " + short_number(K[0]) + ", fy " + short_number(K[4]) +
                  ")");
    if (binx > 1 || biny > 1)
      throw Error(where + ": binned camera info (binning " + short_number(binx) + "x" + short_number(biny) + ") is not read");
    for (double v : D)
      if (!std::isfinite(v)) throw Error(where + ": camera info D holds a value that is not finite");
    const bool zero = std::all_of(D.begin(), D.end(), [](double v) { return v == 0; });
    std::array<double, 5> k{0, 0, 0, 0, 0};
    if (model == "plumb_bob" || model == "rational_polynomial" || (zero && D.size() <= 14)) {
      if (!zero && model == "plumb_bob" && D.size() != 5 && D.size() != 4)
        throw Error(where + ": plumb_bob distortion with " + std::to_string(D.size()) + " coefficients (expected 5)");
      for (std::size_t i = 0; i < D.size() && i < 5; ++i) k[i] = D[i];
      for (std::size_t i = 5; i < D.size(); ++i)
        if (D[i] != 0)
          throw Error(where + ": rational_polynomial distortion with k4..k6 not zero is not read (the camera model has k1 k2 p1 p2 k3)");
    } else {
      throw Error(where + ": distortion model '" + model + "' is not read (plumb_bob, or rational_polynomial with k4..k6 zero)");
    }
    rec.has_camera_info = true;
    rec.fx = K[0], rec.fy = K[4], rec.cx = K[2], rec.cy = K[5];
    rec.distortion = k;
  }
  /// A pose message of `type`, at its stamp (else the record time).
  void pose(const MsgSchema& s, MsgCursor& c, const std::string& where, RosTime record_time, const std::string& type) {
    PoseRead p;
    msg_read_pose(s, 0, c, p, 0);
    if (!p.has_pos || !p.has_rot) throw Error(where + ": no position and orientation in a " + type);
    for (double v : {p.p[0], p.p[1], p.p[2], p.q[0], p.q[1], p.q[2], p.q[3]})
      if (!std::isfinite(v)) throw Error(where + ": pose holds a value that is not finite");
    const double n = std::sqrt(p.q[0] * p.q[0] + p.q[1] * p.q[1] + p.q[2] * p.q[2] + p.q[3] * p.q[3]);
    if (n < 0.5 || n > 1.5) throw Error(where + ": quaternion is far from unit length (norm " + short_number(n) + ")");
    geometry::Pose pose;
    pose.t = Vec3(p.p[0], p.p[1], p.p[2]);
    pose.q = Quat(p.q[3] / n, p.q[0] / n, p.q[1] / n, p.q[2] / n);
    poses.emplace_back(rel(p.has_stamp && !p.stamp.zero() ? p.stamp : record_time), pose);
  }
  /// The events, frames and poses in time order, into rec.
  void finish() {
    auto& ev = rec.events;
    if (unsorted) {  // messages out of time order (two connections, or a recorder that reordered them)
      std::vector<std::size_t> order(ev.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ev.t[a] < ev.t[b]; });
      events::EventStream sorted;
      sorted.reserve(ev.size());
      for (auto i : order) sorted.push_back(ev.t[i], ev.x[i], ev.y[i], ev.polarity[i]);
      ev = std::move(sorted);
    }
    if (ev.t.capacity() > ev.size() + ev.size() / 2) {  // only a wasteful estimate is worth a copy
      ev.t.shrink_to_fit();
      ev.x.shrink_to_fit();
      ev.y.shrink_to_fit();
      ev.polarity.shrink_to_fit();
    }
    // Frames and poses in time order (stable: by time, then as read). Sorted through an index: a stable
    // sort's temporary buffer would not respect the alignment of Eigen's types.
    auto by_time = [](const auto& v) {
      std::vector<std::size_t> order(v.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(),
                [&](std::size_t a, std::size_t b) { return v[a].first != v[b].first ? v[a].first < v[b].first : a < b; });
      return order;
    };
    for (auto i : by_time(frames)) {
      rec.frame_times.push_back(frames[i].first);
      rec.frames.push_back(std::move(frames[i].second));
    }
    for (auto i : by_time(poses)) {
      if (!rec.pose_times.empty() && poses[i].first == rec.pose_times.back()) continue;  // a repeated stamp: the first pose stands
      rec.pose_times.push_back(poses[i].first);
      rec.poses.push_back(poses[i].second);
    }
  }
};

}  // namespace detail

/// Reads a bag: the events of one topic (required), and where the bag has them, frames, the first camera
/// info, and poses. See the file's comment for topics and times.
inline BagRecording read_rosbag(const std::filesystem::path& path, const BagOptions& opt = {}) {
  using namespace detail;
  BagFile f(path);
  BagIndex idx = read_bag_index(f);
  if (!idx.indexed)  // connections first (they may be anywhere in the chunks), then the messages
    for_each_bag_message(
        f, idx, [](std::uint32_t) { return false; }, [](std::uint32_t, RosTime, std::string_view, const std::string&) {});
  if (idx.conns.empty()) throw Error(f.name(), 0, "the bag has no connections (no topics)");

  BagTopics topics(f, idx);
  BagRecording rec;
  rec.events_topic = topics.choose(
      "events", "--events-topic", opt.events_topic, [&](const std::string& t, std::string& why) { return topics.fits_events(t, why); },
      true);
  rec.images_topic = topics.choose("frames", "--images-topic", opt.images_topic, topics.of_type({"sensor_msgs/Image"}), false);
  rec.camera_info_topic =
      topics.choose("camera info", "--camera-info-topic", opt.camera_info_topic, topics.of_type({"sensor_msgs/CameraInfo"}), false);
  rec.poses_topic = topics.choose("poses", "--poses-topic", opt.poses_topic,
                                  topics.of_type({"geometry_msgs/PoseStamped", "nav_msgs/Odometry", "geometry_msgs/TransformStamped",
                                                  "geometry_msgs/PoseWithCovarianceStamped"}),
                                  false);

  enum Role : int { kNone, kEvents, kImages, kInfo, kPoses };
  std::map<std::uint32_t, Role> role;
  for (const auto& [topic, r] :
       {std::pair{rec.events_topic, kEvents}, {rec.images_topic, kImages}, {rec.camera_info_topic, kInfo}, {rec.poses_topic, kPoses}})
    if (!topic.empty())
      for (auto id : topics.connections(topic)) {
        if (!topics.schema(id)) throw Error(topics.schema_error(id));
        role[id] = r;
      }
  BagGatherer gather(rec, f.size());
  for (const auto& ci : idx.chunks)
    for (const auto& [conn, n] : ci.counts)
      if (auto it = role.find(conn); it != role.end() && it->second == kEvents) gather.event_messages += n;

  std::uint64_t counts[5] = {0, 0, 0, 0, 0};
  for_each_bag_message(
      f, idx, [&](std::uint32_t conn) { return role.count(conn) > 0; },
      [&](std::uint32_t conn, RosTime record_time, std::string_view body, const std::string& at) {
        const Role r = role.at(conn);
        const MsgSchema& s = *topics.schema(conn);
        const std::string where = at + " (topic " + bag_shown(idx.conns.at(conn).topic) + ", message " + std::to_string(counts[r]) + ")";
        ++counts[r];
        MsgCursor c{reinterpret_cast<const unsigned char*>(body.data()), reinterpret_cast<const unsigned char*>(body.data()) + body.size(),
                    &where};
        if (r == kEvents) gather.events(s, c, where);
        else if (r == kImages) gather.image(s, c, where, record_time);
        else if (r == kInfo) gather.camera_info(s, c, where);
        else if (r == kPoses) gather.pose(s, c, where, record_time, idx.conns.at(conn).type);
      },
      opt.progress);
  if (rec.events.empty())
    throw Error(f.name(), 0,
                "topic " + bag_shown(rec.events_topic) + " holds no events (" + std::to_string(counts[kEvents]) + " messages)");
  gather.finish();
  return rec;
}

// ---- writing -------------------------------------------------------------------------------------

/// How write_rosbag lays out a bag.
struct BagWriteOptions {
  std::string compression = "lz4";       ///< "none", "bz2" or "lz4"
  std::int64_t origin_sec = 0;           ///< added to every time (ROS time must not be negative)
  std::size_t chunk_bytes = 768 * 1024;  ///< a chunk is closed once it holds this much (rosbag's default)
  double events_per_message = 1e-3;      ///< seconds of events per EventArray message
};

namespace detail {

inline void bag_put_u32(std::string& s, std::uint32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8), static_cast<unsigned char>(v >> 16),
                              static_cast<unsigned char>(v >> 24)};
  s.append(reinterpret_cast<const char*>(b), 4);
}
inline void bag_put_u64(std::string& s, std::uint64_t v) {
  bag_put_u32(s, static_cast<std::uint32_t>(v));
  bag_put_u32(s, static_cast<std::uint32_t>(v >> 32));
}
inline std::string bag_u32s(std::uint32_t v) {
  std::string s;
  bag_put_u32(s, v);
  return s;
}
inline std::string bag_u64s(std::uint64_t v) {
  std::string s;
  bag_put_u64(s, v);
  return s;
}
/// A record: header fields (name, value bytes), then the data.
inline void bag_put_record(std::string& out, std::initializer_list<std::pair<std::string_view, std::string_view>> fields,
                           std::string_view data) {
  std::string h;
  for (const auto& [k, v] : fields) {
    bag_put_u32(h, static_cast<std::uint32_t>(k.size() + 1 + v.size()));
    h.append(k);
    h += '=';
    h.append(v);
  }
  bag_put_u32(out, static_cast<std::uint32_t>(h.size()));
  out += h;
  bag_put_u32(out, static_cast<std::uint32_t>(data.size()));
  out.append(data);
}

/// The message types write_rosbag writes: ROS's definitions (without their comments) and MD5 sums.
struct BagType {
  const char* name;
  const char* md5;
  const char* definition;
};
inline constexpr const char* kBagHeaderDef =
    "================================================================================\nMSG: std_msgs/Header\n"
    "uint32 seq\ntime stamp\nstring frame_id\n";
inline const BagType kBagEventArray{"dvs_msgs/EventArray", "5e8beee5a6c107e504c2e78903c224b8",
                                    "Header header\nuint32 height\nuint32 width\nEvent[] events\n"};
inline const BagType kBagCameraInfo{"sensor_msgs/CameraInfo", "c9a58c1b0b154e0e6da7578cb991d214",
                                    "Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] D\nfloat64[9] K\n"
                                    "float64[9] R\nfloat64[12] P\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n"};
inline const BagType kBagImage{
    "sensor_msgs/Image", "060021388200f6f0f447d0fcd9c64743",
    "Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n"};
inline const BagType kBagPoseStamped{"geometry_msgs/PoseStamped", "d3812c3cbc69362b77dc0b19b345f8f5", "Header header\nPose pose\n"};
inline std::string bag_definition(const BagType& t) {
  std::string d = std::string(t.definition) + kBagHeaderDef;
  const std::string sep = "================================================================================\n";
  if (&t == &kBagEventArray) d += sep + "MSG: dvs_msgs/Event\nuint16 x\nuint16 y\ntime ts\nbool polarity\n";
  if (&t == &kBagCameraInfo)
    d += sep + "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n";
  if (&t == &kBagPoseStamped)
    d += sep + "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n" + sep +
         "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + sep +
         "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
  return d;
}

/// Builds a bag in memory: chunks with their index data, then connections and chunk infos.
class BagWriter {
 public:
  BagWriter(std::string compression, std::size_t chunk_bytes) : compression_(std::move(compression)), chunk_bytes_(chunk_bytes) {
    if (compression_ != "none" && compression_ != "bz2" && compression_ != "lz4")
      throw Error("write_rosbag: unknown compression '" + compression_ + "' (none, bz2, lz4)");
    out_ = std::string(kBagMagic);
    header_at_ = out_.size();
    put_file_header();
  }
  std::uint32_t connect(const std::string& topic, const BagType& type) {
    const auto id = static_cast<std::uint32_t>(conns_.size());
    std::string data;
    bag_put_record(data, {{"topic", topic}, {"type", type.name}, {"md5sum", type.md5}, {"message_definition", bag_definition(type)}}, "");
    // The connection data is a header's fields without the record's lengths around them.
    conns_.push_back({topic, data.substr(4, data.size() - 8)});
    return id;
  }
  /// Appends one message (its stamp in ns of ROS time).
  void write(std::uint32_t conn, std::uint64_t ns, std::string_view body) {
    if (std::find(chunk_conns_.begin(), chunk_conns_.end(), conn) == chunk_conns_.end()) {
      chunk_conns_.push_back(conn);
      bag_put_record(chunk_, {{"op", "\x07"}, {"conn", bag_u32s(conn)}, {"topic", conns_[conn].topic}}, conns_[conn].data);
    }
    const std::uint64_t t = ros_time(ns);
    index_[conn].emplace_back(t, static_cast<std::uint32_t>(chunk_.size()));
    bag_put_record(chunk_, {{"op", "\x02"}, {"conn", bag_u32s(conn)}, {"time", bag_u64s(t)}}, body);
    start_ = std::min(start_, ns);
    end_ = std::max(end_, ns);
    if (chunk_.size() >= chunk_bytes_) close_chunk();
  }
  /// The whole bag (closes the last chunk, appends the index, fills in the file header).
  std::string finish() {
    close_chunk();
    const std::uint64_t index_pos = out_.size();
    for (std::uint32_t c = 0; c < conns_.size(); ++c)
      bag_put_record(out_, {{"op", "\x07"}, {"conn", bag_u32s(c)}, {"topic", conns_[c].topic}}, conns_[c].data);
    for (const auto& ci : infos_) {
      std::string data;
      for (const auto& [conn, n] : ci.counts) {
        bag_put_u32(data, conn);
        bag_put_u32(data, n);
      }
      bag_put_record(out_,
                     {{"op", "\x06"},
                      {"ver", bag_u32s(1)},
                      {"chunk_pos", bag_u64s(ci.pos)},
                      {"start_time", bag_u64s(ci.start)},
                      {"end_time", bag_u64s(ci.end)},
                      {"count", bag_u32s(static_cast<std::uint32_t>(ci.counts.size()))}},
                     data);
    }
    index_pos_ = index_pos;
    const std::size_t at = header_at_;
    std::string tail = out_.substr(at + 4096 + 8);
    out_.resize(at);
    put_file_header();
    out_ += tail;
    return std::move(out_);
  }

 private:
  struct Conn {
    std::string topic, data;
  };
  struct Info {
    std::uint64_t pos, start, end;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> counts;
  };
  /// The file header record, padded (as rosbag does) so that its header and data take 4096 bytes.
  void put_file_header() {
    std::string h;
    bag_put_record(h,
                   {{"op", "\x03"},
                    {"index_pos", bag_u64s(index_pos_)},
                    {"conn_count", bag_u32s(static_cast<std::uint32_t>(conns_.size()))},
                    {"chunk_count", bag_u32s(static_cast<std::uint32_t>(infos_.size()))}},
                   "");
    const std::size_t header_len = h.size() - 8;
    out_ += h.substr(0, h.size() - 4);
    bag_put_u32(out_, static_cast<std::uint32_t>(4096 - header_len));
    out_.append(4096 - header_len, ' ');
  }
  static std::uint64_t ros_time(std::uint64_t ns) { return (ns / 1000000000) | (ns % 1000000000) << 32; }
  void close_chunk() {
    if (chunk_.empty()) return;
    std::string packed;
    if (compression_ == "none") {
      packed = chunk_;
    } else if (compression_ == "bz2") {
      unsigned int n = static_cast<unsigned int>(chunk_.size() + chunk_.size() / 100 + 600);
      packed.resize(n);
      if (BZ2_bzBuffToBuffCompress(packed.data(), &n, chunk_.data(), static_cast<unsigned int>(chunk_.size()), 9, 0, 0) != BZ_OK)
        throw Error("write_rosbag: bz2 compression failed");
      packed.resize(n);
    } else {
      LZ4F_preferences_t prefs{};
      prefs.frameInfo.blockSizeID = LZ4F_max1MB;  // as roslz4 writes: 1 MB independent blocks, a content checksum
      prefs.frameInfo.blockMode = LZ4F_blockIndependent;
      prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
      packed.resize(LZ4F_compressFrameBound(chunk_.size(), &prefs));
      const std::size_t n = LZ4F_compressFrame(packed.data(), packed.size(), chunk_.data(), chunk_.size(), &prefs);
      if (LZ4F_isError(n)) throw Error(std::string("write_rosbag: lz4 compression failed: ") + LZ4F_getErrorName(n));
      packed.resize(n);
    }
    Info info{out_.size(), ros_time(start_), ros_time(end_), {}};
    bag_put_record(out_, {{"op", "\x05"}, {"compression", compression_}, {"size", bag_u32s(static_cast<std::uint32_t>(chunk_.size()))}},
                   packed);
    for (const auto& [conn, entries] : index_) {
      std::string data;
      for (const auto& [t, off] : entries) {
        bag_put_u64(data, t);
        bag_put_u32(data, off);
      }
      bag_put_record(
          out_,
          {{"op", "\x04"}, {"ver", bag_u32s(1)}, {"conn", bag_u32s(conn)}, {"count", bag_u32s(static_cast<std::uint32_t>(entries.size()))}},
          data);
      info.counts.emplace_back(conn, static_cast<std::uint32_t>(entries.size()));
    }
    infos_.push_back(std::move(info));
    chunk_.clear();
    chunk_conns_.clear();
    index_.clear();
    start_ = UINT64_MAX;
    end_ = 0;
  }

  std::string compression_;
  std::size_t chunk_bytes_;
  std::string out_, chunk_;
  std::size_t header_at_ = 0;
  std::uint64_t index_pos_ = 0;
  std::vector<Conn> conns_;
  std::vector<std::uint32_t> chunk_conns_;
  std::map<std::uint32_t, std::vector<std::pair<std::uint64_t, std::uint32_t>>> index_;
  std::vector<Info> infos_;
  std::uint64_t start_ = UINT64_MAX, end_ = 0;
};

inline void bag_put_header(std::string& m, std::uint32_t seq, std::uint64_t ns) {
  bag_put_u32(m, seq);
  bag_put_u32(m, static_cast<std::uint32_t>(ns / 1000000000));
  bag_put_u32(m, static_cast<std::uint32_t>(ns % 1000000000));
  bag_put_u32(m, 0);  // frame_id ""
}
inline void bag_put_f64(std::string& m, double v) { m.append(reinterpret_cast<const char*>(&v), 8); }

}  // namespace detail

/// Writes a recording as a ROS bag in the layout of DAVIS recordings: /dvs/events (dvs_msgs/EventArray,
/// one message per `events_per_message` seconds), /dvs/camera_info (once, plumb_bob), /dvs/image_raw
/// (mono8 or rgb8) and /optitrack/davis (geometry_msgs/PoseStamped), stamped at origin_sec + t, atomically.
/// read_rosbag reads it back with its times relative to the whole second of the first event.
inline void write_rosbag(const std::filesystem::path& path, const events::EventStream& ev, const geometry::Camera& cam,
                         const geometry::Trajectory& poses, const std::vector<double>& frame_times, const std::vector<Image>& frames,
                         const BagWriteOptions& opt = {}) {
  using namespace detail;
  const std::string file = path.string();
  auto ns_of = [&](double t, const char* what) {  // ROS time: 0 to 2^32 s
    const double s = static_cast<double>(opt.origin_sec) + t;
    if (!(s >= 0 && s < 4294967295.0))
      throw Error(file, 0,
                  std::string("write_rosbag: ") + what + " at " + short_number(t) + " s after the origin " +
                      std::to_string(opt.origin_sec) + " s lies outside ROS time (0 to 2^32 s)");
    return static_cast<std::uint64_t>(opt.origin_sec * 1000000000 + std::llround(t * 1e9));
  };
  require(frames.size() == frame_times.size(), file + ": write_rosbag: frames and times differ in number");
  BagWriter w(opt.compression, opt.chunk_bytes);
  const auto c_info = w.connect("/dvs/camera_info", kBagCameraInfo);
  const auto c_events = w.connect("/dvs/events", kBagEventArray);
  const auto c_images = frames.empty() ? 0u : w.connect("/dvs/image_raw", kBagImage);
  const auto c_poses = poses.empty() ? 0u : w.connect("/optitrack/davis", kBagPoseStamped);
  // Messages in time order across the topics, as a recorder writes them.
  struct Item {
    std::uint64_t ns;
    int kind;  // 0 camera info, 1 events, 2 frame, 3 pose
    std::size_t a, b;
  };
  std::vector<Item> items;
  const std::uint64_t first = ev.empty() ? ns_of(0, "time 0") : ns_of(ev.t.front(), "the first event");
  items.push_back({first, 0, 0, 0});
  for (std::size_t i = 0; i < ev.size();) {
    const double until = ev.t[i] + opt.events_per_message;
    std::size_t j = i + 1;
    while (j < ev.size() && ev.t[j] < until && j - i < 100000) ++j;
    items.push_back({ns_of(ev.t[j - 1], "an event"), 1, i, j});
    i = j;
  }
  for (std::size_t i = 0; i < frames.size(); ++i) items.push_back({ns_of(frame_times[i], "a frame"), 2, i, 0});
  for (std::size_t i = 0; i < poses.size(); ++i) items.push_back({ns_of(poses.times()[i], "a pose"), 3, i, 0});
  std::stable_sort(items.begin(), items.end(), [](const Item& x, const Item& y) { return x.ns < y.ns; });
  std::string m;
  std::uint32_t seq[4] = {0, 0, 0, 0};
  for (const auto& it : items) {
    m.clear();
    bag_put_header(m, seq[it.kind]++, it.ns);
    if (it.kind == 0) {
      bag_put_u32(m, static_cast<std::uint32_t>(cam.height()));
      bag_put_u32(m, static_cast<std::uint32_t>(cam.width()));
      bag_put_u32(m, 9);
      m += "plumb_bob";
      bag_put_u32(m, 5);
      for (double k : cam.distortion()) bag_put_f64(m, k);
      for (double v : {cam.fx(), 0.0, cam.cx(), 0.0, cam.fy(), cam.cy(), 0.0, 0.0, 1.0}) bag_put_f64(m, v);
      for (double v : {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}) bag_put_f64(m, v);
      for (double v : {cam.fx(), 0.0, cam.cx(), 0.0, 0.0, cam.fy(), cam.cy(), 0.0, 0.0, 0.0, 1.0, 0.0}) bag_put_f64(m, v);
      for (int k = 0; k < 6; ++k) bag_put_u32(m, 0);  // binning_x, binning_y, roi x_offset y_offset height width
      m += '\0';                                      // roi do_rectify
      w.write(c_info, it.ns, m);
    } else if (it.kind == 1) {
      bag_put_u32(m, static_cast<std::uint32_t>(cam.height()));
      bag_put_u32(m, static_cast<std::uint32_t>(cam.width()));
      bag_put_u32(m, static_cast<std::uint32_t>(it.b - it.a));
      m.reserve(m.size() + 13 * (it.b - it.a));
      for (std::size_t k = it.a; k < it.b; ++k) {
        const std::uint64_t ns = ns_of(ev.t[k], "an event");
        const unsigned char xy[4] = {static_cast<unsigned char>(ev.x[k]), static_cast<unsigned char>(ev.x[k] >> 8),
                                     static_cast<unsigned char>(ev.y[k]), static_cast<unsigned char>(ev.y[k] >> 8)};
        m.append(reinterpret_cast<const char*>(xy), 4);
        bag_put_u32(m, static_cast<std::uint32_t>(ns / 1000000000));
        bag_put_u32(m, static_cast<std::uint32_t>(ns % 1000000000));
        m += ev.polarity[k] > 0 ? '\1' : '\0';
      }
      w.write(c_events, it.ns, m);
    } else if (it.kind == 2) {
      const Image& im = frames[it.a];
      require(im.channels == 1 || im.channels == 3, file + ": write_rosbag: frames must have 1 or 3 channels");
      bag_put_u32(m, static_cast<std::uint32_t>(im.height));
      bag_put_u32(m, static_cast<std::uint32_t>(im.width));
      const std::string enc = im.channels == 1 ? "mono8" : "rgb8";
      bag_put_u32(m, static_cast<std::uint32_t>(enc.size()));
      m += enc;
      m += '\0';
      bag_put_u32(m, static_cast<std::uint32_t>(im.width * im.channels));
      bag_put_u32(m, static_cast<std::uint32_t>(im.data.size()));
      for (float v : im.data) m += static_cast<char>(static_cast<unsigned char>(std::lround(std::clamp(v, 0.f, 1.f) * 255.f)));
      w.write(c_images, it.ns, m);
    } else {
      const auto& p = poses.poses()[it.a];
      for (double v : {p.t.x(), p.t.y(), p.t.z(), p.q.x(), p.q.y(), p.q.z(), p.q.w()}) bag_put_f64(m, v);
      w.write(c_poses, it.ns, m);
    }
  }
  write_file_atomic(path, w.finish());
}

/// Loads a ROS bag (io/rosbag.hpp). The sensor size is the one given, else the camera info's, else the
/// event messages' own, else the first frame's, else the events' extent. Calibration: LoadOptions::calib,
/// else the camera info, else calib.txt beside the bag. Poses: LoadOptions::poses, else the pose topic,
/// else groundtruth.txt beside the bag (when present); a pose file's times are read in the bag's clock
/// (ROS time, seconds) and moved to the recording's origin like the bag's own.
inline Dataset load_rosbag(const std::filesystem::path& path, const LoadOptions& opt = {}) {
  namespace fs = std::filesystem;
  auto rec = read_rosbag(path, BagOptions{opt.events_topic, opt.images_topic, opt.camera_info_topic, opt.poses_topic, opt.progress});
  const std::string file = path.string();
  int w = opt.width, h = opt.height;
  std::string from = "the size given";
  if (w <= 0 || h <= 0) {
    if (rec.has_camera_info && rec.info_width > 0 && rec.info_height > 0)
      w = rec.info_width, h = rec.info_height, from = "the camera info on " + rec.camera_info_topic;
    else if (rec.array_width > 0 && rec.array_height > 0)
      w = rec.array_width, h = rec.array_height, from = "the event messages on " + rec.events_topic;
    else if (!rec.frames.empty()) w = rec.frames[0].width, h = rec.frames[0].height, from = "the first frame on " + rec.images_topic;
    else w = static_cast<int>(rec.max_x + 1), h = static_cast<int>(rec.max_y + 1), from = "the events' extent";
  }
  check_sensor_size(w, h, file + " (" + from + ")");
  if (rec.max_x >= w || rec.max_y >= h) {
    for (std::size_t i = 0; i < rec.events.size(); ++i)
      if (rec.events.x[i] >= w || rec.events.y[i] >= h)
        throw Error(file, 0,
                    "event " + std::to_string(i) + " of topic " + rec.events_topic + ": pixel (" + std::to_string(rec.events.x[i]) + ", " +
                        std::to_string(rec.events.y[i]) + ") lies outside the " + std::to_string(w) + "x" + std::to_string(h) +
                        " sensor (" + from + ")");
  }
  Dataset d;
  d.folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  d.time_origin = rec.origin_sec;
  // Frames in a Bayer encoding come through the colour filter the events do (CED's Color-DAVIS346).
  if (rec.frame_encoding.rfind("bayer_", 0) == 0) d.bayer_pattern = rec.frame_encoding.substr(6, 4);
  if (!opt.calib.empty()) {
    d.camera = read_calib_source(opt.calib, w, h);
  } else if (rec.has_camera_info) {
    d.camera = geometry::Camera(w, h, rec.fx, rec.fy, rec.cx, rec.cy, rec.distortion);
  } else {
    const fs::path calib = d.folder / "calib.txt";
    if (!fs::exists(calib))
      throw Error(
          file, 0,
          "no camera info topic and no " + calib.string() + " beside the bag: give the calibration (fx fy cx cy [k1 k2 p1 p2 [k3]])");
    d.camera = read_calib_txt(calib, w, h);
  }
  d.frames.t = rec.frame_times;
  if (!opt.poses.empty()) {
    d.trajectory = read_pose_source(opt.poses, d.frames, static_cast<double>(rec.origin_sec));
  } else if (!rec.poses.empty()) {
    d.trajectory = geometry::Trajectory(std::move(rec.pose_times), std::move(rec.poses), file + " (topic " + rec.poses_topic + ")");
  } else if (fs::exists(d.folder / "groundtruth.txt")) {
    d.trajectory = read_pose_source(d.folder / "groundtruth.txt", d.frames, static_cast<double>(rec.origin_sec));
  }
  rec.events.width = w;
  rec.events.height = h;
  d.events = std::move(rec.events);
  d.frames.t = std::move(rec.frame_times);
  d.frames.images = std::move(rec.frames);
  return d;
}

/// Writes a recording as a ROS bag (io::write_rosbag: DAVIS topics, `compression` chunks), stamped at the
/// recording's time origin, so that io::load reads it back.
inline void write_rosbag_recording(const std::filesystem::path& path, const Dataset& d, const std::string& compression = "lz4") {
  std::vector<Image> frames;
  for (std::size_t f = 0; f < d.frames.size(); ++f) frames.push_back(frame_image(d.frames, f));
  BagWriteOptions o;
  o.compression = compression;
  o.origin_sec = d.time_origin;
  write_rosbag(path, d.events, d.camera, d.trajectory, d.frames.t, frames, o);
}

/// inspect's lines for a bag: its topics with their message counts and types.
inline std::string rosbag_summary(const std::filesystem::path& path) {
  std::string out = "ROS bag topics (messages, type):\n";
  for (const auto& t : rosbag_topics(path)) {
    char line[512];
    std::snprintf(line, sizeof line, "  %-32s %9llu  %s\n", t.topic.c_str(), static_cast<unsigned long long>(t.messages), t.type.c_str());
    out += line;
  }
  return out;
}

/// The format's line in io::formats(): written for an output ending in .bag; inspect lists its topics.
inline Format rosbag_format() {
  return {"rosbag",
          false,
          kRosbagDescription,
          &is_rosbag,
          &load_rosbag,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions& o) { write_rosbag_recording(p, d, o.compression); },
          {".bag"},
          &rosbag_summary};
}

}  // namespace evnerf::io
