// io/rosbag/read.hpp — reading a ROS bag (io/rosbag.hpp): its connections and index (read_bag_index; a bag
// cut short, without an index or with one that lies, is walked record by record to its last whole record),
// its messages topic by topic (for_each_bag_message), its topics (rosbag_topics), and the recording
// (read_rosbag: the topics chosen for each role, BagTopics, and every message gathered, BagGatherer).
// Depends on io/rosbag/messages.hpp, events/ and geometry/.
#pragma once
#include "../../core/types.hpp"
#include "../../events/event_stream.hpp"
#include "../../geometry/bayer.hpp"
#include "../../geometry/camera.hpp"
#include "../../geometry/pose.hpp"
#include "../../geometry/trajectory.hpp"
#include "messages.hpp"

namespace evnerf::io {

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

}  // namespace evnerf::io
