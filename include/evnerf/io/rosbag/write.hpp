// io/rosbag/write.hpp — writing a ROS bag 2.0 in the layout of DAVIS recordings (io/rosbag.hpp): records,
// chunks and the index, the message definitions and their md5 sums of the types written. Depends on
// io/rosbag/records.hpp, events/ and geometry/.
#pragma once
#include "../../events/event_stream.hpp"
#include "../../geometry/camera.hpp"
#include "../../geometry/pose.hpp"
#include "../../geometry/trajectory.hpp"
#include "records.hpp"

namespace evnerf::io {

/// How write_rosbag lays out a bag.
struct BagWriteOptions {
  std::string compression = "lz4";       ///< "none", "bz2" or "lz4"
  std::int64_t origin_sec = 0;           ///< added to every time (ROS time must not be negative)
  std::size_t chunk_bytes = 768 * 1024;  ///< a chunk is closed once it holds this much (rosbag's default)
  double events_per_message = 1e-3;      ///< seconds of events per EventArray message
  bool camera_info = true;               ///< the camera info message (off: a recording whose calibration is not known)
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
  const auto c_info = opt.camera_info ? w.connect("/dvs/camera_info", kBagCameraInfo) : 0u;
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
  if (opt.camera_info) items.push_back({first, 0, 0, 0});
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

}  // namespace evnerf::io
