// io/aedat4.hpp — iniVation's AEDAT 4.0 files (DV, dv-processing: DAVIS346, DVXplorer), read and written.
// Layout: the line `#!AER-DAT4.0\r\n`, then the IOHeader as a size-prefixed flatbuffer (a 32-bit little-endian
// length, then the buffer): its fields are the compression of every packet (0 none, 1 LZ4, 2 LZ4 high, 3 Zstd,
// 4 Zstd high), the byte offset of the file's data table (−1: none) and an XML description (infoNode) whose
// nodes `outInfo/<id>/` name each stream's type (`typeIdentifier`: EVTS events, FRME frames, IMUS, TRIG) and,
// in their `info` child, the sensor's `sizeX` and `sizeY`. Then packets: an 8-byte header (stream id, body
// size; int32 each), the body compressed as one LZ4 or Zstd frame, which decompresses to a size-prefixed
// flatbuffer: EventPacket { elements: [Event] }, Event a 16-byte struct (int64 µs, int16 x, int16 y, bool
// polarity), or Frame { timestamp (exposure midpoint, µs), four more times, format (0 grey, 16 BGR, 24 BGRA),
// sizeX, sizeY, positionX, positionY, pixels: [uint8] }. The data table, after the packets, is a
// FileDataTable { Table: [FileDataDefinition { ByteOffset, PacketInfo, NumElements, TimestampStart,
// TimestampEnd }] } compressed as the packets are: a time window then reads only the event packets it
// overlaps. Timestamps are Unix microseconds: the recording's times are seconds from the whole second of its
// first event (Dataset::time_origin), as a bag's are, and a pose file beside it is read in the file's clock.
//
// The flatbuffers are read by the bounded reader below rather than through libflatbuffers: the library's
// accessors do not check offsets unless its verifier runs, and the verifier needs flatc-generated code; four
// small tables are read here with every offset checked, so that a corrupt file is an Error naming its byte
// offset. LZ4 and Zstd frames go through Debian's liblz4 and libzstd. Compiled where CMake found both
// (EVNERF_HAVE_AEDAT4). A file cut short inside its packets (no data table written) is read to its last whole
// packet, with a warning. Depends on io/recording.hpp, io/ijrr.hpp (Frames) and core/.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <lz4frame.h>
#include <zstd.h>

#include "../core/warn.hpp"
#include "../core/fileio.hpp"
#include "ijrr.hpp"
#include "recording.hpp"

namespace evnerf::io {

/// One stream of an AEDAT4 file, as its description names it.
struct Aedat4Stream {
  int id = -1;
  std::string type;  ///< EVTS, FRME, IMUS, TRIG, ...
  std::string name;  ///< originalOutputName (events, frames, imu, triggers)
  int width = 0, height = 0;
};

/// What an AEDAT4 file's header and packets say (inspect shows it).
struct Aedat4Info {
  int compression = 0;  ///< 0 none, 1 LZ4, 2 LZ4 high, 3 Zstd, 4 Zstd high
  std::int64_t table_position = -1;
  bool table_used = false;  ///< the data table was read and agreed with the packets it names
  std::string table_note;   ///< why it was not used, where there is one
  std::vector<Aedat4Stream> streams;
  std::size_t packets = 0, packets_skipped = 0;  ///< packets read; packets of other streams or outside the window
  std::size_t events = 0, frames = 0, frames_skipped = 0;
};

inline const char* aedat4_compression_name(int c) {
  static const char* names[] = {"none", "LZ4", "LZ4 (high)", "Zstd", "Zstd (high)"};
  return c >= 0 && c <= 4 ? names[c] : "unknown";
}

namespace detail {

inline constexpr char kAedat4Magic[] = "#!AER-DAT4.0\r\n";
inline constexpr std::size_t kAedat4MagicLen = 14;
/// No packet of a camera decompresses to this much (a 1280×720 BGRA frame is 3.7 MB): a larger one is a
/// corrupt or hostile file, refused before it is held.
inline constexpr std::size_t kAedat4MaxPacket = std::size_t(1) << 28;
/// The most a packet may decompress to in a batch of read_aedat4 (a larger one is decompressed alone, after
/// the batch's others): with kBatch packets a batch holds at most 32 times this. A variable so that the tests
/// can send every packet down the path alone.
inline std::size_t aedat4_slot_body = std::size_t(4) << 20;

/// A flatbuffer in memory, every read checked against its end; `where` names it in errors.
class FlatBuf {
 public:
  FlatBuf(const unsigned char* p, std::size_t n, std::string where) : p_(p), n_(n), where_(std::move(where)) {}
  [[noreturn]] void bad(const std::string& what) const { throw Error(where_ + ": " + what); }
  void need(std::uint64_t pos, std::uint64_t bytes, const char* what) const {
    if (pos > n_ || bytes > n_ - pos)
      bad(std::string(what) + " at buffer byte " + std::to_string(pos) + " runs past the buffer's " + std::to_string(n_) + " bytes");
  }
  template <class T>
  T get(std::uint64_t pos, const char* what) const {
    need(pos, sizeof(T), what);
    T v;
    std::memcpy(&v, p_ + pos, sizeof(T));  // little-endian hosts only (x86-64, AArch64)
    return v;
  }
  const unsigned char* data() const { return p_; }
  std::size_t size() const { return n_; }

 private:
  const unsigned char* p_;
  std::size_t n_;
  std::string where_;
};

/// A table of a FlatBuf: field i's position through its vtable, 0 when the field is absent (its default).
class FlatTable {
 public:
  FlatTable(const FlatBuf& b, std::uint64_t pos, const char* what) : b_(b), pos_(pos) {
    const auto soff = b.get<std::int32_t>(pos, what);
    const std::int64_t vt = static_cast<std::int64_t>(pos) - soff;
    if (vt < 0) b.bad(std::string(what) + ": its vtable offset points before the buffer");
    vt_ = static_cast<std::uint64_t>(vt);
    vsize_ = b.get<std::uint16_t>(vt_, "a vtable");
    tsize_ = b.get<std::uint16_t>(vt_ + 2, "a vtable");
    if (vsize_ < 4 || vsize_ % 2) b.bad(std::string(what) + ": vtable of " + std::to_string(vsize_) + " bytes");
    b.need(vt_, vsize_, "a vtable");
    b.need(pos_, tsize_, what);
  }
  /// Field i's absolute position (its `bytes` checked to lie in the table), or 0.
  std::uint64_t field(int i, std::size_t bytes) const {
    const std::uint64_t slot = 4 + 2 * static_cast<std::uint64_t>(i);
    if (slot + 2 > vsize_) return 0;
    const auto off = b_.get<std::uint16_t>(vt_ + slot, "a vtable");
    if (!off) return 0;
    if (off + bytes > tsize_) b_.bad("field " + std::to_string(i) + " lies outside its table");
    return pos_ + off;
  }
  template <class T>
  T scalar(int i, T def) const {
    const auto f = field(i, sizeof(T));
    return f ? b_.get<T>(f, "a field") : def;
  }
  /// A vector field: its first element's position and its length (0, 0 when absent), checked to fit.
  std::pair<std::uint64_t, std::uint64_t> vector(int i, std::size_t elem) const {
    const auto f = field(i, 4);
    if (!f) return {0, 0};
    const std::uint64_t at = f + b_.get<std::uint32_t>(f, "a vector offset");
    const std::uint64_t len = b_.get<std::uint32_t>(at, "a vector's length");
    b_.need(at + 4, len * elem, "a vector");
    return {at + 4, len};
  }
  std::string_view string(int i) const {
    const auto [at, len] = vector(i, 1);
    return {reinterpret_cast<const char*>(b_.data() + at), static_cast<std::size_t>(len)};
  }

 private:
  const FlatBuf& b_;
  std::uint64_t pos_, vt_ = 0;
  std::uint16_t vsize_ = 0, tsize_ = 0;
};

/// The root table of a flatbuffer that starts at byte 0 of `b`.
inline FlatTable flat_root(const FlatBuf& b, const char* what) { return FlatTable(b, b.get<std::uint32_t>(0, "the root offset"), what); }

/// A size-prefixed flatbuffer in the `n` bytes at `p`: the buffer after its 32-bit size, checked to fit.
inline FlatBuf size_prefixed(const unsigned char* p, std::size_t n, const std::string& where) {
  if (n < 4) throw Error(where + ": " + std::to_string(n) + " bytes hold no size-prefixed flatbuffer");
  std::uint32_t len;
  std::memcpy(&len, p, 4);
  if (len > n - 4) throw Error(where + ": its flatbuffer claims " + std::to_string(len) + " bytes, " + std::to_string(n - 4) + " follow");
  return FlatBuf(p + 4, len, where);
}

/// Decompresses packet bodies, one after another, into a buffer of its own; the LZ4 and Zstd contexts and the
/// buffer are kept from one packet to the next (one inflater per thread).
class Aedat4Inflater {
 public:
  Aedat4Inflater() = default;
  Aedat4Inflater(const Aedat4Inflater&) = delete;
  Aedat4Inflater& operator=(const Aedat4Inflater&) = delete;
  ~Aedat4Inflater() {
    if (lz4_) LZ4F_freeDecompressionContext(lz4_);
    if (zstd_) ZSTD_freeDCtx(zstd_);
  }
  /// The `n` bytes at `src` decompressed (compression as the IOHeader gives it); false, with nothing
  /// decompressed, where the body would be larger than `limit` bytes. `where` names the packet in errors.
  bool inflate(int compression, const unsigned char* src, std::size_t n, std::size_t limit, const std::string& where) {
    size_ = 0;
    if (compression == 0) {
      if (n > limit) return false;
      reserve(n, 0);
      std::memcpy(buf_.get(), src, n);
      size_ = n;
      return true;
    }
    std::size_t used = 0;
    // The output grows only as bytes arrive, up to the limit.
    auto grow = [&] {
      if (used >= limit) return false;
      reserve(std::min(limit, std::max<std::size_t>({std::size_t(1) << 16, 2 * cap_, 4 * n})), used);
      return true;
    };
    if (compression == 1 || compression == 2) {
      if (!lz4_ && LZ4F_isError(LZ4F_createDecompressionContext(&lz4_, LZ4F_VERSION))) {
        lz4_ = nullptr;
        throw Error(where + ": cannot start LZ4 decompression");
      }
      LZ4F_resetDecompressionContext(lz4_);
      std::size_t in = 0;
      for (;;) {
        if (used == cap_ && !grow()) return false;
        std::size_t dst = cap_ - used, len = n - in;
        const std::size_t r = LZ4F_decompress(lz4_, buf_.get() + used, &dst, src + in, &len, nullptr);
        if (LZ4F_isError(r)) throw Error(where + ": corrupt LZ4 frame (" + LZ4F_getErrorName(r) + ")");
        used += dst, in += len;
        if (r == 0) break;
        if (in == n && dst == 0) throw Error(where + ": the LZ4 frame ends early");
      }
      if (in != n) throw Error(where + ": " + std::to_string(n - in) + " bytes follow its LZ4 frame");
    } else if (compression == 3 || compression == 4) {
      if (!zstd_ && !(zstd_ = ZSTD_createDCtx())) throw Error(where + ": cannot start Zstd decompression");
      ZSTD_DCtx_reset(zstd_, ZSTD_reset_session_only);
      ZSTD_inBuffer in{src, n, 0};
      for (;;) {
        if (used == cap_ && !grow()) return false;
        ZSTD_outBuffer o{buf_.get(), cap_, used};
        const std::size_t r = ZSTD_decompressStream(zstd_, &o, &in);
        if (ZSTD_isError(r)) throw Error(where + ": corrupt Zstd frame (" + ZSTD_getErrorName(r) + ")");
        const bool progressed = o.pos > used;
        used = o.pos;
        if (r == 0) break;
        if (in.pos == in.size && !progressed && used < cap_) throw Error(where + ": the Zstd frame ends early");
      }
      if (in.pos != n) throw Error(where + ": " + std::to_string(n - in.pos) + " bytes follow its Zstd frame");
    } else {
      throw Error(where + ": unknown compression " + std::to_string(compression));
    }
    if (used > limit) return false;
    size_ = used;
    return true;
  }
  /// As inflate, with kAedat4MaxPacket the limit and a larger body an Error.
  void inflate(int compression, const unsigned char* src, std::size_t n, const std::string& where) {
    if (!inflate(compression, src, n, kAedat4MaxPacket, where))
      throw Error(where + ": decompresses to more than " + std::to_string(kAedat4MaxPacket >> 20) + " MiB");
  }
  const unsigned char* data() const { return buf_.get(); }
  std::size_t size() const { return size_; }

 private:
  // At least n bytes, the first `keep` kept. Not value-initialised: only what a frame writes is read.
  void reserve(std::size_t n, std::size_t keep) {
    if (n <= cap_) return;
    std::unique_ptr<unsigned char[]> b(new unsigned char[n]);
    if (keep) std::memcpy(b.get(), buf_.get(), keep);
    buf_ = std::move(b), cap_ = n;
  }
  LZ4F_dctx* lz4_ = nullptr;
  ZSTD_DCtx* zstd_ = nullptr;
  std::unique_ptr<unsigned char[]> buf_;
  std::size_t cap_ = 0, size_ = 0;
};

/// The streams an infoNode XML description names: its `outInfo/<id>/` nodes' attributes.
inline std::vector<Aedat4Stream> aedat4_streams(std::string_view xml, const std::string& where) {
  std::vector<Aedat4Stream> out;
  std::vector<std::string> paths;
  auto attr_of = [](std::string_view tag, std::string_view key) -> std::string {
    const std::string k = std::string(key) + "=\"";
    const auto a = tag.find(k);
    if (a == std::string_view::npos) return {};
    const auto b = tag.find('"', a + k.size());
    return b == std::string_view::npos ? std::string{} : std::string(tag.substr(a + k.size(), b - a - k.size()));
  };
  auto unescape = [](std::string s) {
    static const std::pair<const char*, char> ents[] = {{"&lt;", '<'}, {"&gt;", '>'}, {"&quot;", '"'}, {"&apos;", '\''}, {"&amp;", '&'}};
    for (const auto& [e, c] : ents)
      for (std::size_t p; (p = s.find(e)) != std::string::npos;) s.replace(p, std::strlen(e), 1, c);
    return s;
  };
  std::size_t i = 0;
  while ((i = xml.find('<', i)) != std::string_view::npos) {
    const auto close = xml.find('>', i);
    if (close == std::string_view::npos) break;
    const std::string_view tag = xml.substr(i + 1, close - i - 1);
    i = close + 1;
    if (tag.rfind("node", 0) == 0) {
      if (!tag.ends_with("/")) paths.push_back(attr_of(tag, "path"));
    } else if (tag.rfind("/node", 0) == 0) {
      if (!paths.empty()) paths.pop_back();
    } else if (tag.rfind("attr", 0) == 0 && !tag.ends_with("/") && !paths.empty()) {
      const auto end = xml.find("</attr>", i);
      if (end == std::string_view::npos) break;
      const std::string key = attr_of(tag, "key"), value = unescape(std::string(xml.substr(i, end - i)));
      i = end + 7;
      const std::string& path = paths.back();
      const auto o = path.find("/outInfo/");
      if (o == std::string::npos) continue;
      std::size_t p = o + 9, q = p;
      while (q < path.size() && path[q] >= '0' && path[q] <= '9') ++q;
      if (q == p || q - p > 9) continue;
      const int id = std::stoi(path.substr(p, q - p));
      const bool info = path.compare(q, std::string::npos, "/info/") == 0;
      if (!info && path.compare(q, std::string::npos, "/") != 0) continue;
      auto it = std::find_if(out.begin(), out.end(), [&](const Aedat4Stream& s) { return s.id == id; });
      if (it == out.end()) it = out.insert(out.end(), Aedat4Stream{id, {}, {}, 0, 0});
      auto number = [&]() {
        char* e = nullptr;
        const long v = std::strtol(value.c_str(), &e, 10);
        if (e == value.c_str() || v < 0 || v > 65535)
          throw Error(where + ": stream " + std::to_string(id) + "'s " + key + " is '" +
                      (value.size() > 40 ? value.substr(0, 40) + "…" : value) + "' (a size of 0 to 65535 expected)");
        return static_cast<int>(v);
      };
      if (!info && key == "typeIdentifier") it->type = value;
      if (!info && key == "originalOutputName") it->name = value;
      if (info && key == "sizeX") it->width = number();
      if (info && key == "sizeY") it->height = number();
    }
  }
  std::sort(out.begin(), out.end(), [](const Aedat4Stream& a, const Aedat4Stream& b) { return a.id < b.id; });
  return out;
}

/// A packet as the data table names it.
struct Aedat4Entry {
  std::int64_t offset = 0;
  std::int32_t stream = 0, size = 0;
  std::int64_t t_begin = 0, t_end = 0;
  std::int64_t elements = 0;
};

/// One event packet of a batch (Aedat4Events): its compressed body, its decompressed body and what checking
/// its events found; kept from one batch to the next.
struct Aedat4Slot {
  std::uint64_t pos = 0;  ///< the packet header's byte offset
  int stream = 0;
  std::vector<unsigned char> raw;
  Aedat4Inflater body;
  const unsigned char* events = nullptr;  ///< the first 16-byte Event in `body`
  std::uint64_t n = 0;
  std::exception_ptr error;                    ///< decompressing or parsing failed
  bool oversized = false;                      ///< larger than a batch allows: decompressed again alone
  std::exception_ptr bad_event;                ///< an event out of order or off the sensor (before `examined`)
  std::uint64_t examined = 0, lo = 0, hi = 0;  ///< events looked at; those of the window [lo, hi)
  bool done = false;                           ///< an event at or after the window's end
  std::size_t out = 0;                         ///< where its window's events go in the stream
  std::string where(const std::string& file) const {
    return file + ": byte " + std::to_string(pos) + " (packet of stream " + std::to_string(stream) + ")";
  }
  /// Decompresses the body (up to `limit` bytes; false, and `oversized`, when it needs more, an error at
  /// kAedat4MaxPacket) and finds its events; an error is kept in `error` for the caller to raise in file order.
  bool decode(int compression, const std::string& file, std::size_t limit) {
    try {
      const std::string at = where(file);
      if (!body.inflate(compression, raw.data(), raw.size(), limit, at)) {
        if (limit >= kAedat4MaxPacket) throw Error(at + ": decompresses to more than " + std::to_string(kAedat4MaxPacket >> 20) + " MiB");
        return oversized = true, false;
      }
      const auto fb = size_prefixed(body.data(), body.size(), at);
      const auto [first, count] = flat_root(fb, "an EventPacket").vector(0, 16);
      events = fb.data() + first, n = count;
    } catch (...) {
      error = std::current_exception();
    }
    return true;
  }
};

/// The file an AEDAT4 reader reads, at byte offsets: a read that would run past its end is an Error naming
/// the offset, what was read and the file's size.
class Aedat4File {
 public:
  explicit Aedat4File(const std::filesystem::path& path) : name_(path.string()), f_(std::fopen(path.c_str(), "rb")) {
    if (!f_) throw Error(name_, 0, "cannot open file (missing or unreadable)");
    std::error_code ec;
    size_ = std::filesystem::file_size(path, ec);
    if (ec) throw Error(name_, 0, "cannot read its size");
  }
  const std::string& name() const { return name_; }
  std::uint64_t size() const { return size_; }
  void read_at(std::uint64_t pos, std::size_t n, std::vector<unsigned char>& buf, const char* what) const {
    if (pos > size_ || n > size_ - pos)
      throw Error(name_, 0,
                  "byte " + std::to_string(pos) + ": " + what + " of " + std::to_string(n) + " bytes runs past the end of the file (" +
                      std::to_string(size_) + " bytes)");
    buf.resize(n);
    if (std::fseek(f_.get(), static_cast<long>(pos), SEEK_SET) != 0 || std::fread(buf.data(), 1, n, f_.get()) != n)
      throw Error(name_, 0, "byte " + std::to_string(pos) + ": read error");
  }

 private:
  std::string name_;
  std::unique_ptr<std::FILE, FileCloser> f_;
  std::uint64_t size_ = 0;
};

/// The magic line and the IOHeader into `info` (compression, the data table's position, the streams);
/// returns the byte offset where the packets start.
inline std::uint64_t aedat4_header(const Aedat4File& in, Aedat4Info& info) {
  const std::string& file = in.name();
  std::vector<unsigned char> buf;
  in.read_at(0, std::min<std::uint64_t>(in.size(), kAedat4MagicLen + 4), buf, "the header");
  if (buf.size() < kAedat4MagicLen || std::memcmp(buf.data(), kAedat4Magic, kAedat4MagicLen) != 0)
    throw Error(file, 0, "byte 0: not an AEDAT 4.0 file (it does not start with '#!AER-DAT4.0')");
  if (buf.size() < kAedat4MagicLen + 4) throw Error(file, 0, "byte 14: the file ends before its IOHeader's size");
  std::uint32_t header_size;
  std::memcpy(&header_size, buf.data() + kAedat4MagicLen, 4);
  in.read_at(kAedat4MagicLen + 4, header_size, buf, "the IOHeader");
  const FlatBuf hb(buf.data(), buf.size(), file + ": byte 18 (the IOHeader)");
  const auto h = flat_root(hb, "the IOHeader");
  info.compression = h.scalar<std::int32_t>(0, 0);
  info.table_position = h.scalar<std::int64_t>(1, -1);
  if (info.compression < 0 || info.compression > 4)
    throw Error(file, 0,
                "byte 18 (the IOHeader): unknown compression " + std::to_string(info.compression) + " (known: 0 none … 4 Zstd high)");
  info.streams = aedat4_streams(h.string(2), file + ": the IOHeader's description");
  return kAedat4MagicLen + 4 + std::uint64_t(header_size);
}

/// The packets the data table lists, where it is readable and agrees with the packets between data_start
/// and data_end (info.table_used); otherwise none, and info.table_note says why.
inline std::vector<Aedat4Entry> aedat4_table(const Aedat4File& in, Aedat4Info& info, std::uint64_t data_start, std::uint64_t data_end) {
  std::vector<Aedat4Entry> entries;
  const std::uint64_t file_size = in.size();
  try {
    if (static_cast<std::uint64_t>(info.table_position) < data_start || static_cast<std::uint64_t>(info.table_position) >= file_size)
      throw Error("its position " + std::to_string(info.table_position) + " lies outside the file");
    if (file_size - info.table_position > kAedat4MaxPacket) throw Error("larger than " + std::to_string(kAedat4MaxPacket >> 20) + " MiB");
    std::vector<unsigned char> buf;
    in.read_at(static_cast<std::uint64_t>(info.table_position), file_size - info.table_position, buf, "the data table");
    const std::string where = "byte " + std::to_string(info.table_position) + " (the data table)";
    Aedat4Inflater body;
    body.inflate(info.compression, buf.data(), buf.size(), where);
    const auto fb = size_prefixed(body.data(), body.size(), where);
    const auto t = flat_root(fb, "the data table");
    const auto [at, n] = t.vector(0, 4);
    std::uint64_t prev_end = data_start;
    for (std::uint64_t k = 0; k < n; ++k) {
      const auto ent = FlatTable(fb, at + 4 * k + fb.get<std::uint32_t>(at + 4 * k, "an entry offset"), "an entry");
      Aedat4Entry e;
      e.offset = ent.scalar<std::int64_t>(0, 0);
      if (const auto ph = ent.field(1, 8))
        e.stream = fb.get<std::int32_t>(ph, "a packet header"), e.size = fb.get<std::int32_t>(ph + 4, "a packet header");
      e.elements = ent.scalar<std::int64_t>(2, 0);
      e.t_begin = ent.scalar<std::int64_t>(3, 0);
      e.t_end = ent.scalar<std::int64_t>(4, 0);
      if (e.offset < static_cast<std::int64_t>(prev_end) || e.size < 0 || static_cast<std::uint64_t>(e.offset) + 8 + e.size > data_end)
        throw Error("entry " + std::to_string(k) + " names a packet at byte " + std::to_string(e.offset) +
                    " that is not in the data section");
      prev_end = static_cast<std::uint64_t>(e.offset) + 8 + e.size;
      entries.push_back(e);
    }
    // Its packets' headers must be where it says.
    for (const auto& e : entries) {
      in.read_at(static_cast<std::uint64_t>(e.offset), 8, buf, "a packet header");
      std::int32_t sid, size;
      std::memcpy(&sid, buf.data(), 4), std::memcpy(&size, buf.data() + 4, 4);
      if (sid != e.stream || size != e.size) throw Error("its packet at byte " + std::to_string(e.offset) + " has another header");
    }
    info.table_used = true;
  } catch (const Error& e) {
    entries.clear();
    info.table_note = "data table not used (" + e.message() + "); the packets were walked";
  }
  return entries;
}

/// The packets between data_start and data_end, walked header by header (no usable data table). Packets run
/// to the end of the file where no data table follows them: a recording cut short (the recorder stopped
/// before it wrote the table) ends inside its last packet, which is dropped with a warning.
inline std::vector<Aedat4Entry> aedat4_walk(const Aedat4File& in, std::uint64_t data_start, std::uint64_t data_end) {
  const std::string& file = in.name();
  const bool to_end = data_end == in.size();
  auto cut_short = [&](std::uint64_t pos, const std::string& what) {
    warn(file + ": byte " + std::to_string(pos) + ": " + what + " (a recording cut short); read to the last whole packet, " +
         std::to_string(in.size() - pos) + " bytes dropped");
  };
  std::vector<Aedat4Entry> entries;
  std::vector<unsigned char> buf;
  for (std::uint64_t pos = data_start; pos < data_end;) {
    if (data_end - pos < 8) {
      if (!to_end) throw Error(file, 0, "byte " + std::to_string(pos) + ": the data table starts inside a packet header");
      cut_short(pos, "the file ends inside a packet header");
      break;
    }
    in.read_at(pos, 8, buf, "a packet header");
    Aedat4Entry e;
    e.offset = static_cast<std::int64_t>(pos);
    std::memcpy(&e.stream, buf.data(), 4), std::memcpy(&e.size, buf.data() + 4, 4);
    if (e.size <= 0)
      throw Error(
          file, 0,
          "byte " + std::to_string(pos) + ": packet of stream " + std::to_string(e.stream) + " with size " + std::to_string(e.size));
    if (data_end - pos - 8 < static_cast<std::uint64_t>(e.size)) {
      if (!to_end)
        throw Error(file, 0, "byte " + std::to_string(pos) + ": packet of " + std::to_string(e.size) + " bytes runs into the data table");
      cut_short(pos, "packet of " + std::to_string(e.size) + " bytes runs past the end of the file");
      break;
    }
    e.t_begin = std::numeric_limits<std::int64_t>::min(), e.t_end = std::numeric_limits<std::int64_t>::max();
    entries.push_back(e);
    pos += 8 + static_cast<std::uint64_t>(e.size);
  }
  return entries;
}

/// The event packets of a file, read in file order and decoded in batches: each packet decompressed, parsed
/// and its events checked on its own (on OpenMP's threads), then the batch's events of the window appended
/// in order. Errors are raised in file order, so the result and every message are those of a
/// packet-by-packet read. A batch holds up to kBatch packets of up to aedat4_slot_body bytes decompressed; a
/// larger packet (up to kAedat4MaxPacket) is decompressed again alone. The origin is the whole second at or
/// before the first event.
class Aedat4Events {
 public:
  static constexpr std::size_t kBatch = 32;
  Aedat4Events(const Aedat4File& in, Aedat4Info& info, int width, int height, const LoadOptions& opt, events::EventStream& ev)
      : in_(in), info_(info), w_(width), h_(height), t0_(opt.t_begin), t1_(opt.t_end), progress_(opt.progress), ev_(ev), slots_(kBatch) {
    ev_.width = width, ev_.height = height;
  }
  /// Whether event packet `e` is read: not once an event passed the window's end; the table's times let a
  /// window skip the packets wholly before it, and those after it.
  bool wanted(const Aedat4Entry& e) const {
    return !(done_ || (have_origin_ && info_.table_used &&
                       ((static_cast<double>(e.t_end) - static_cast<double>(origin_us_)) / 1e6 < t0_ ||
                        (static_cast<double>(e.t_begin) - static_cast<double>(origin_us_)) / 1e6 >= t1_)));
  }
  /// Reads event packet `e` into the batch, decoding the batch when it is full.
  void add(const Aedat4Entry& e) {
    auto& s = slots_[m_++];
    s.pos = static_cast<std::uint64_t>(e.offset), s.stream = e.stream;
    in_.read_at(s.pos + 8, static_cast<std::size_t>(e.size), s.raw, "a packet");
    read_to_ = s.pos + 8 + static_cast<std::uint64_t>(e.size);
    batch_bytes_ += s.raw.size();
    // The first packet alone: its first event sets the origin the table's times are compared with.
    if (m_ == kBatch || batch_bytes_ >= aedat4_slot_body || !have_origin_) flush();
  }
  /// Decodes the packets of the batch and appends their events.
  void flush() {
    batch_bytes_ = 0;
    if (!m_) return;
    decompress();
    check();
    const std::size_t used = place();
    copy(used);
    m_ = 0;
    if (progress_) progress_(read_to_, in_.size());
  }
  bool have_origin() const { return have_origin_; }
  std::int64_t origin_us() const { return origin_us_; }

 private:
  /// Every packet decompressed and parsed (an oversized one again alone, in order); the origin from the
  /// first event.
  void decompress() {
    const std::string& file = in_.name();
#pragma omp parallel for schedule(dynamic, 1) if (m_ > 1)
    for (std::size_t k = 0; k < m_; ++k) {
      auto& s = slots_[k];
      s.error = nullptr, s.bad_event = nullptr, s.oversized = false, s.events = nullptr, s.n = 0;
      s.decode(info_.compression, file, aedat4_slot_body);
    }
    for (std::size_t k = 0; k < m_; ++k) {
      auto& s = slots_[k];
      if (s.oversized) s.decode(info_.compression, file, kAedat4MaxPacket);  // alone, with the whole limit
      if (s.error) break;
      if (!have_origin_ && s.n) {
        std::int64_t t;
        std::memcpy(&t, s.events, 8);
        const std::int64_t sec = t / 1000000 - (t % 1000000 < 0 ? 1 : 0);  // the whole second at or before it
        if (sec < std::numeric_limits<std::int64_t>::min() / 1000000)
          throw Error(s.where(file) + ": event 0: time " + std::to_string(t) + " µs is out of range");
        origin_us_ = sec * 1000000;
        have_origin_ = true;
      }
    }
  }
  /// Each packet's events checked, and its share of the window found (times are checked to run forwards
  /// within it, so the window is one range); its last packet the first with an event at or after the end.
  void check() {
    const std::string& file = in_.name();
#pragma omp parallel for schedule(dynamic, 1) if (m_ > 1)
    for (std::size_t k = 0; k < m_; ++k) {
      auto& s = slots_[k];
      s.examined = s.lo = s.hi = 0, s.done = false;
      if (s.error) continue;
      std::int64_t prev = std::numeric_limits<std::int64_t>::min();
      for (std::uint64_t i = 0; i < s.n; ++i) {
        const unsigned char* p = s.events + 16 * i;
        std::int64_t us;
        std::int16_t x, y;
        std::memcpy(&us, p, 8), std::memcpy(&x, p + 8, 2), std::memcpy(&y, p + 10, 2);
        if (us < prev || x < 0 || y < 0 || x >= w_ || y >= h_) [[unlikely]] {
          const std::string at = s.where(file) + ": event " + std::to_string(i);
          s.bad_event = std::make_exception_ptr(
              us < prev ? Error(at + ": time runs backwards (" + std::to_string(us) + " µs after " + std::to_string(prev) + " µs)")
                        : Error(at + " at x " + std::to_string(x) + ", y " + std::to_string(y) + " outside the " + std::to_string(w_) +
                                "x" + std::to_string(h_) + " sensor"));
          break;
        }
        std::int64_t rel;
        if (__builtin_sub_overflow(us, origin_us_, &rel)) [[unlikely]] {
          s.bad_event =
              std::make_exception_ptr(Error(s.where(file) + ": event " + std::to_string(i) + ": time " + std::to_string(us) +
                                            " µs is out of range from the first event's second (" + std::to_string(origin_us_) + " µs)"));
          break;
        }
        prev = us;
        s.examined = i + 1;
        const double t = static_cast<double>(rel) / 1e6;
        if (t >= t1_) {
          s.done = true;
          break;
        }
        if (t < t0_) s.lo = i + 1;
        s.hi = i + 1;
      }
    }
  }
  /// In file order: the first error, the times across packets, each packet's place in the stream, which
  /// grows to hold them. Returns the packets used (those up to the window's end).
  std::size_t place() {
    const std::string& file = in_.name();
    std::size_t used = 0, need = out_;
    for (; used < m_ && !done_; ++used) {
      auto& s = slots_[used];
      if (s.error) std::rethrow_exception(s.error);
      ++info_.packets;
      if (s.n) {
        std::int64_t first;
        std::memcpy(&first, s.events, 8);
        if (first < last_us_)
          throw Error(s.where(file) + ": event 0: time runs backwards (" + std::to_string(first) + " µs after " + std::to_string(last_us_) +
                      " µs)");
      }
      if (s.bad_event) std::rethrow_exception(s.bad_event);
      if (s.examined) std::memcpy(&last_us_, s.events + 16 * (s.examined - 1), 8);
      info_.events += s.examined;
      s.out = need, need += s.hi - s.lo;
      done_ = s.done;
    }
    info_.packets_skipped += m_ - used;
    if (need > ev_.t.capacity()) {  // growing by half at least (huge pages, as RawSink's)
      ev_.reserve(std::max(need, ev_.t.capacity() + ev_.t.capacity() / 2));
      huge_pages(ev_.t), huge_pages(ev_.x), huge_pages(ev_.y), huge_pages(ev_.polarity);
    }
    ev_.t.resize(need), ev_.x.resize(need), ev_.y.resize(need), ev_.polarity.resize(need);
    out_ = need;
    return used;
  }
  /// The window's events of the first `used` packets, each packet to its place.
  void copy(std::size_t used) {
#pragma omp parallel for schedule(dynamic, 1) if (used > 1)
    for (std::size_t k = 0; k < used; ++k) {
      const auto& s = slots_[k];
      for (std::uint64_t i = s.lo, o = s.out; i < s.hi; ++i, ++o) {
        const unsigned char* p = s.events + 16 * i;
        std::int64_t us;
        std::uint16_t x, y;
        std::memcpy(&us, p, 8), std::memcpy(&x, p + 8, 2), std::memcpy(&y, p + 10, 2);
        ev_.t[o] = static_cast<double>(us - origin_us_) / 1e6;
        ev_.x[o] = x, ev_.y[o] = y;
        ev_.polarity[o] = static_cast<std::int8_t>(p[12] != 0 ? 1 : -1);
      }
    }
  }

  const Aedat4File& in_;
  Aedat4Info& info_;
  const int w_, h_;
  const double t0_, t1_;
  const ReadProgress progress_;
  events::EventStream& ev_;
  std::vector<Aedat4Slot> slots_;
  std::size_t m_ = 0, out_ = 0, batch_bytes_ = 0;
  bool have_origin_ = false, done_ = false;
  std::int64_t origin_us_ = 0, last_us_ = std::numeric_limits<std::int64_t>::min();
  std::uint64_t read_to_ = 0;
};

/// Frame packet `e`: appended to `frames` (its time in µs, BGR turned RGB) where it covers the whole
/// width × height sensor, counted in info.frames_skipped where it is a region of interest.
inline void aedat4_frame(const Aedat4File& in, const Aedat4Entry& e, int w, int h, Aedat4Info& info, Frames& frames,
                         std::vector<unsigned char>& raw, Aedat4Inflater& body) {
  const std::uint64_t pos = static_cast<std::uint64_t>(e.offset);
  const std::string where = in.name() + ": byte " + std::to_string(pos) + " (packet of stream " + std::to_string(e.stream) + ")";
  in.read_at(pos + 8, static_cast<std::size_t>(e.size), raw, "a packet");
  body.inflate(info.compression, raw.data(), raw.size(), where);
  const auto fb = size_prefixed(body.data(), body.size(), where);
  const auto t = flat_root(fb, "a Frame");
  ++info.packets;
  const auto ts = t.scalar<std::int64_t>(0, 0);
  const auto format = t.scalar<std::int8_t>(5, 0);
  const int fw = t.scalar<std::int16_t>(6, 0), fh = t.scalar<std::int16_t>(7, 0);
  const int px = t.scalar<std::int16_t>(8, 0), py = t.scalar<std::int16_t>(9, 0);
  const int ch = format == 0 ? 1 : format == 16 ? 3 : format == 24 ? 4 : 0;
  if (!ch) throw Error(where + ": frame format " + std::to_string(format) + " (known: 0 grey, 16 BGR, 24 BGRA)");
  const auto [at, n] = t.vector(10, 1);
  if (fw <= 0 || fh <= 0 || n != static_cast<std::uint64_t>(fw) * fh * ch)
    throw Error(where + ": a " + std::to_string(fw) + "x" + std::to_string(fh) + " frame of " + std::to_string(ch) + " channels holds " +
                std::to_string(n) + " bytes");
  if (fw != w || fh != h || px || py) {  // a region of interest, not the sensor: no evaluation frame
    ++info.frames_skipped;
    return;
  }
  Image im(fw, fh, ch == 1 ? 1 : 3);
  const unsigned char* p = fb.data() + at;
  for (std::size_t q = 0; q < im.pixels(); ++q)
    for (int c = 0; c < im.channels; ++c) im.data[q * im.channels + c] = p[q * ch + (ch == 1 ? 0 : 2 - c)] / 255.f;  // BGR → RGB
  frames.t.push_back(static_cast<double>(ts));
  frames.images.push_back(std::move(im));
  ++info.frames;
}

}  // namespace detail

/// Reads an AEDAT4 file: its events (only LoadOptions' time window, seconds from the whole second of its first
/// event), its first frame stream's frames (grey or RGB, at the sensor's size; others are skipped and
/// counted), the origin in `origin_sec`, and what the header said in `info`.
inline events::EventStream read_aedat4(const std::filesystem::path& path, const LoadOptions& opt, Aedat4Info& info, Frames& frames,
                                       std::int64_t& origin_sec) {
  info = {};
  const detail::Aedat4File in(path);
  const std::string& file = in.name();
  const std::uint64_t data_start = detail::aedat4_header(in, info);
  const Aedat4Stream* evs = nullptr;
  const Aedat4Stream* frs = nullptr;
  for (const auto& s : info.streams) {
    if (s.type == "EVTS" && !evs) evs = &s;
    if (s.type == "FRME" && !frs) frs = &s;
  }
  if (!evs)
    throw Error(file, 0,
                "its description names no event stream (typeIdentifier EVTS): " + std::to_string(info.streams.size()) + " streams");
  int w = opt.width, h = opt.height;
  if (w <= 0 || h <= 0) w = evs->width, h = evs->height;
  if (w <= 0 || h <= 0)
    throw Error(file, 0, "the event stream's description gives no sensor size (sizeX, sizeY): give it with --sensor-size WxH");
  check_sensor_size(w, h, file + " (the event stream's sizeX and sizeY)");
  // The packets end where the data table starts (or at the end of the file); the table lists them where it
  // can, else they are walked.
  const std::uint64_t data_end =
      info.table_position >= static_cast<std::int64_t>(data_start) && static_cast<std::uint64_t>(info.table_position) <= in.size()
          ? static_cast<std::uint64_t>(info.table_position)
          : in.size();
  std::vector<detail::Aedat4Entry> entries;
  if (info.table_position >= 0) entries = detail::aedat4_table(in, info, data_start, data_end);
  if (!info.table_used) entries = detail::aedat4_walk(in, data_start, data_end);
  events::EventStream ev;
  detail::Aedat4Events reader(in, info, w, h, opt, ev);
  // A whole file whose table counts its events: reserved at once, so that the stream is not copied as it
  // grows; never more than an event a byte of its packets (16:1, more than recorded events compress), so that
  // a table's count bounds nothing but the file does.
  if (info.table_used && !std::isfinite(opt.t_begin) && !std::isfinite(opt.t_end)) {
    std::uint64_t count = 0;
    for (const auto& e : entries)
      if (e.stream == evs->id)
        count += std::min<std::uint64_t>(static_cast<std::uint64_t>(std::max<std::int64_t>(e.elements, 0)), std::uint64_t(e.size));
    ev.reserve(static_cast<std::size_t>(count));
    huge_pages(ev.t), huge_pages(ev.x), huge_pages(ev.y), huge_pages(ev.polarity);
  }
  std::vector<unsigned char> frame_raw;
  detail::Aedat4Inflater frame_body;
  for (const auto& e : entries) {
    if (e.stream == evs->id) {
      if (reader.wanted(e)) reader.add(e);
      else ++info.packets_skipped;
    } else if (frs && e.stream == frs->id) {
      reader.flush();  // the packets before it first: the frames stay in file order
      detail::aedat4_frame(in, e, w, h, info, frames, frame_raw, frame_body);
      if (opt.progress) opt.progress(static_cast<std::uint64_t>(e.offset) + 8 + static_cast<std::uint64_t>(e.size), in.size());
    } else {
      ++info.packets_skipped;
    }
  }
  reader.flush();
  if (!reader.have_origin()) throw Error(file, 0, "no events in its event stream " + std::to_string(evs->id));
  origin_sec = reader.origin_us() / 1000000;
  if (ev.t.capacity() > 2 * ev.t.size() + 4096)
    ev.t.shrink_to_fit(), ev.x.shrink_to_fit(), ev.y.shrink_to_fit(), ev.polarity.shrink_to_fit();
  // Frame times in seconds from the origin, in time order.
  for (double& t : frames.t) t = (t - static_cast<double>(reader.origin_us())) / 1e6;
  for (std::size_t k = 1; k < frames.t.size(); ++k)
    if (frames.t[k] < frames.t[k - 1]) throw Error(file, 0, "frame " + std::to_string(k) + "'s time runs backwards");
  return ev;
}

/// Whether a file starts with AEDAT 4.0's version line.
inline bool is_aedat4(const std::filesystem::path& path) {
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  char head[detail::kAedat4MagicLen];
  return f && std::fread(head, 1, sizeof head, f.get()) == sizeof head && std::memcmp(head, detail::kAedat4Magic, sizeof head) == 0;
}

/// Loads an AEDAT4 file as a recording: its events and frames, calib.txt and groundtruth.txt beside it (or
/// the LoadOptions' files; pose times in the file's clock, Unix seconds).
inline Dataset load_aedat4(const std::filesystem::path& path, const LoadOptions& opt) {
  Aedat4Info info;
  Dataset d;
  d.events = read_aedat4(path, opt, info, d.frames, d.time_origin);
  attach_calibration_and_poses(path, opt, d, d.events.width, d.events.height, "an AEDAT4 recording", static_cast<double>(d.time_origin));
  std::string streams;
  for (const auto& s : info.streams)
    streams += (streams.empty() ? "" : ", ") + std::to_string(s.id) + " " + (s.type.empty() ? "?" : s.type) +
               (s.name.empty() ? "" : " (" + s.name + ")");
  char buf[768];
  std::snprintf(
      buf, sizeof buf,
      "aedat4        %s compression, streams: %s; %zu packets read, %zu skipped; %zu events, %zu frames (%zu not of the whole sensor)",
      aedat4_compression_name(info.compression), streams.c_str(), info.packets, info.packets_skipped, info.events, info.frames,
      info.frames_skipped);
  d.notes.push_back(buf);
  d.notes.push_back(info.table_used ? "aedat4        data table read: the time window seeks through it"
                                    : "aedat4        " + (info.table_note.empty() ? std::string("no data table") : info.table_note));
  return d;
}

namespace detail {
/// A minimal flatbuffer writer for the tables above, front to back: a table is written with its offset fields
/// empty (its vtable just before it), and each offset is patched once what it points to is written after it
/// (flatbuffers' offsets point forward). start() reserves the root offset and the file identifier.
class FlatWriter {
 public:
  struct Field {
    std::vector<unsigned char> bytes;  ///< a scalar's or struct's bytes; empty for an absent field
    bool offset = false;               ///< a 4-byte offset, patched later
  };
  struct Table {
    std::size_t pos;
    std::vector<std::size_t> at;  ///< each field's position (0 when absent)
  };
  template <class T>
  static Field scalar(T v) {
    Field f;
    f.bytes.resize(sizeof(T));
    std::memcpy(f.bytes.data(), &v, sizeof(T));
    return f;
  }
  static Field raw(const void* p, std::size_t n) {
    Field f;
    f.bytes.assign(static_cast<const unsigned char*>(p), static_cast<const unsigned char*>(p) + n);
    return f;
  }
  static Field offset() { return Field{{}, true}; }

  void start() { buf_.assign(8, 0); }
  /// A vector of `count` elements of `elem` bytes whose elements start at a multiple of `align`.
  std::size_t vector(const void* elems, std::size_t count, std::size_t elem, std::size_t align) {
    pad_to((std::max<std::size_t>(align, 4) - 4) % std::max<std::size_t>(align, 4), std::max<std::size_t>(align, 4));
    const std::size_t at = buf_.size();
    const auto len = static_cast<std::uint32_t>(count);
    append(&len, 4);
    if (count) append(elems, count * elem);
    return at;
  }
  /// A string: a vector of its bytes with a NUL after them (not counted), as flatbuffers writes strings.
  std::size_t string(std::string_view s) {
    const std::size_t at = vector(s.data(), s.size(), 1, 1);
    buf_.push_back(0);
    return at;
  }
  Table table(const std::vector<Field>& fields) {
    Table t;
    t.at.assign(fields.size(), 0);
    std::vector<std::uint16_t> offs(fields.size(), 0);
    std::size_t tsize = 4;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      const std::size_t n = fields[i].offset ? 4 : fields[i].bytes.size();
      if (!n) continue;
      const std::size_t a = std::min<std::size_t>(n, 8);
      tsize = (tsize + a - 1) / a * a;
      offs[i] = static_cast<std::uint16_t>(tsize);
      tsize += n;
    }
    std::vector<std::uint16_t> vt = {static_cast<std::uint16_t>(4 + 2 * fields.size()), static_cast<std::uint16_t>(tsize)};
    vt.insert(vt.end(), offs.begin(), offs.end());
    // The table starts at a multiple of 8 (its int64 fields aligned), its vtable just before it.
    const std::size_t vbytes = 2 * vt.size();
    pad_to((8 - vbytes % 8) % 8, 8);
    const std::size_t vpos = buf_.size();
    append(vt.data(), vbytes);
    t.pos = buf_.size();
    buf_.resize(t.pos + tsize, 0);
    const auto soff = static_cast<std::int32_t>(t.pos - vpos);
    std::memcpy(&buf_[t.pos], &soff, 4);
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (!offs[i]) continue;
      t.at[i] = t.pos + offs[i];
      if (!fields[i].offset) std::memcpy(&buf_[t.at[i]], fields[i].bytes.data(), fields[i].bytes.size());
    }
    return t;
  }
  /// Points the offset at `slot` to `target` (written after it).
  void patch(std::size_t slot, std::size_t target) {
    const auto rel = static_cast<std::uint32_t>(target - slot);
    std::memcpy(&buf_[slot], &rel, 4);
  }
  /// The bytes of a size-prefixed flatbuffer whose root is `root`, with file identifier `ident`.
  std::vector<unsigned char> finish(std::size_t root, const char* ident) {
    const auto r = static_cast<std::uint32_t>(root);
    std::memcpy(&buf_[0], &r, 4);
    std::memcpy(&buf_[4], ident, 4);
    std::vector<unsigned char> out(4 + buf_.size());
    const auto n = static_cast<std::uint32_t>(buf_.size());
    std::memcpy(out.data(), &n, 4);
    std::copy(buf_.begin(), buf_.end(), out.begin() + 4);
    return out;
  }

 private:
  void append(const void* p, std::size_t n) {
    buf_.insert(buf_.end(), static_cast<const unsigned char*>(p), static_cast<const unsigned char*>(p) + n);
  }
  /// Zero bytes until the size is `rem` modulo `mod`.
  void pad_to(std::size_t rem, std::size_t mod) {
    while (buf_.size() % mod != rem) buf_.push_back(0);
  }
  std::vector<unsigned char> buf_;
};

inline std::vector<unsigned char> aedat4_compress(int compression, const std::vector<unsigned char>& src) {
  if (compression == 0) return src;
  std::vector<unsigned char> out;
  if (compression == 1 || compression == 2) {
    LZ4F_preferences_t pref{};
    pref.compressionLevel = compression == 2 ? 9 : 0;
    out.resize(LZ4F_compressFrameBound(src.size(), &pref));
    const std::size_t n = LZ4F_compressFrame(out.data(), out.size(), src.data(), src.size(), &pref);
    if (LZ4F_isError(n)) throw Error(std::string("LZ4 compression failed: ") + LZ4F_getErrorName(n));
    out.resize(n);
  } else {
    out.resize(ZSTD_compressBound(src.size()));
    const std::size_t n = ZSTD_compress(out.data(), out.size(), src.data(), src.size(), compression == 4 ? 19 : 3);
    if (ZSTD_isError(n)) throw Error(std::string("Zstd compression failed: ") + ZSTD_getErrorName(n));
    out.resize(n);
  }
  return out;
}
}  // namespace detail

/// Writes a recording as an AEDAT4 file: stream 0 the events (packets of up to 4096), stream 1 the frames
/// (grey, or BGR for colour frames), a data table, `compression` one of "none", "lz4", "zstd"; calib.txt
/// and groundtruth.txt beside it (pose times in the file's clock). Times are whole microseconds from the
/// recording's origin; written atomically.
inline void write_aedat4(const std::filesystem::path& path, const Dataset& d, const std::string& compression = "lz4") {
  using W = detail::FlatWriter;
  const int c = compression == "none" ? 0 : compression == "lz4" ? 1 : compression == "zstd" ? 3 : -1;
  if (c < 0) throw Error(path.string(), 0, "AEDAT4 compression '" + compression + "' (known: none, lz4, zstd)");
  const int w = d.camera.width(), h = d.camera.height();
  if (w > 32767 || h > 32767)
    throw Error(path.string(), 0, "AEDAT4 coordinates are 16-bit; the sensor is " + std::to_string(w) + "x" + std::to_string(h));
  const std::int64_t origin_us = d.time_origin * 1000000;
  auto us_of = [&](double t, const std::string& what) {
    const double v = std::nearbyint(t * 1e6);
    if (!std::isfinite(v) || std::fabs(v) > 9e15) throw Error(path.string(), 0, what + " at " + short_number(t) + " s is out of range");
    return origin_us + static_cast<std::int64_t>(v);
  };
  const bool has_frames = d.frames.size() > 0;
  const std::string sx = std::to_string(w), sy = std::to_string(h);
  auto stream_xml = [&](int id, const char* type, const char* name) {
    const std::string p = "/mainloop/Recorder/outInfo/" + std::to_string(id) + "/";
    return "  <node name=\"" + std::to_string(id) + "\" path=\"" + p + "\">\n   <attr key=\"compression\" type=\"string\">" +
           std::string(c == 0   ? "NONE"
                       : c == 1 ? "LZ4"
                                : "ZSTD") +
           "</attr>\n   <attr key=\"originalModuleName\" type=\"string\">evnerf</attr>\n" +
           "   <attr key=\"originalOutputName\" type=\"string\">" + name + "</attr>\n   <attr key=\"typeIdentifier\" type=\"string\">" +
           type + "</attr>\n   <node name=\"info\" path=\"" + p + "info/\">\n    <attr key=\"sizeX\" type=\"int\">" + sx +
           "</attr>\n    <attr key=\"sizeY\" type=\"int\">" + sy +
           "</attr>\n    <attr key=\"source\" type=\"string\">evnerf</attr>\n   </node>\n  </node>\n";
  };
  const std::string xml = "<dv version=\"2.0\">\n <node name=\"outInfo\" path=\"/mainloop/Recorder/outInfo/\">\n" +
                          stream_xml(0, "EVTS", "events") + (has_frames ? stream_xml(1, "FRME", "frames") : std::string()) +
                          " </node>\n</dv>\n";
  // Packets, each with its data-table entry.
  std::vector<unsigned char> data;
  std::vector<detail::Aedat4Entry> entries;
  auto add_packet = [&](std::int32_t stream, const std::vector<unsigned char>& fb, std::int64_t t0, std::int64_t t1, std::size_t count) {
    const auto bytes = detail::aedat4_compress(c, fb);
    detail::Aedat4Entry e{static_cast<std::int64_t>(data.size()), stream, static_cast<std::int32_t>(bytes.size()), t0, t1,
                          static_cast<std::int64_t>(count)};
    data.insert(data.end(), reinterpret_cast<const unsigned char*>(&e.stream), reinterpret_cast<const unsigned char*>(&e.stream) + 4);
    data.insert(data.end(), reinterpret_cast<const unsigned char*>(&e.size), reinterpret_cast<const unsigned char*>(&e.size) + 4);
    data.insert(data.end(), bytes.begin(), bytes.end());
    entries.push_back(e);
  };
  std::size_t f = 0;
  auto flush_frames_before = [&](double t) {
    for (; f < d.frames.size() && d.frames.t[f] <= t; ++f) {
      const Image im = frame_image(d.frames, f);
      const int ch = im.channels == 1 ? 1 : 3;
      std::vector<unsigned char> px(im.pixels() * ch);
      for (std::size_t q = 0; q < im.pixels(); ++q)
        for (int k = 0; k < ch; ++k)
          px[q * ch + k] =
              static_cast<unsigned char>(std::lround(std::clamp(im.data[q * im.channels + (ch == 1 ? 0 : 2 - k)], 0.f, 1.f) * 255.f));
      W fw;
      fw.start();
      const std::int64_t ts = us_of(d.frames.t[f], "frame " + std::to_string(f));
      const auto t =
          fw.table({W::scalar(ts), W::scalar(ts), W::scalar(ts), W::scalar(ts), W::scalar(ts), W::scalar<std::int8_t>(ch == 1 ? 0 : 16),
                    W::scalar(static_cast<std::int16_t>(im.width)), W::scalar(static_cast<std::int16_t>(im.height)),
                    W::scalar<std::int16_t>(0), W::scalar<std::int16_t>(0), W::offset()});
      fw.patch(t.at[10], fw.vector(px.data(), px.size(), 1, 1));
      add_packet(1, fw.finish(t.pos, "FRME"), ts, ts, 1);
    }
  };
  const auto& ev = d.events;
  constexpr std::size_t kPacket = 4096;
  std::vector<unsigned char> el;
  for (std::size_t i = 0; i < ev.size(); i += kPacket) {
    const std::size_t n = std::min(kPacket, ev.size() - i);
    if (has_frames) flush_frames_before(ev.t[i]);
    el.assign(16 * n, 0);
    std::int64_t t0 = 0, t1 = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const std::int64_t us = us_of(ev.t[i + k], "event " + std::to_string(i + k));
      const auto x = static_cast<std::int16_t>(ev.x[i + k]), y = static_cast<std::int16_t>(ev.y[i + k]);
      std::memcpy(&el[16 * k], &us, 8), std::memcpy(&el[16 * k + 8], &x, 2), std::memcpy(&el[16 * k + 10], &y, 2);
      el[16 * k + 12] = ev.polarity[i + k] > 0;
      if (k == 0) t0 = us;
      t1 = us;
    }
    W pw;
    pw.start();
    const auto t = pw.table({W::offset()});
    pw.patch(t.at[0], pw.vector(el.data(), n, 16, 8));
    add_packet(0, pw.finish(t.pos, "EVTS"), t0, t1, n);
  }
  if (has_frames) flush_frames_before(INFINITY);
  // The header, whose size does not depend on the table's position (an int64 always written).
  auto header = [&](std::int64_t table_pos) {
    W hw;
    hw.start();
    const auto t = hw.table({W::scalar<std::int32_t>(c), W::scalar<std::int64_t>(table_pos), W::offset()});
    hw.patch(t.at[2], hw.string(xml));
    return hw.finish(t.pos, "IOHE");
  };
  const std::size_t head = detail::kAedat4MagicLen + header(0).size();
  // The data table: each entry's byte offset is its packet header's in the file.
  W tw;
  tw.start();
  const auto root = tw.table({W::offset()});
  const std::vector<std::uint32_t> slots(entries.size(), 0);
  const std::size_t vec = tw.vector(slots.data(), slots.size(), 4, 4);
  tw.patch(root.at[0], vec);
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const auto& e = entries[k];
    const std::int32_t ph[2] = {e.stream, e.size};
    const auto t = tw.table({W::scalar<std::int64_t>(static_cast<std::int64_t>(head + e.offset)), W::raw(ph, 8),
                             W::scalar<std::int64_t>(e.elements), W::scalar<std::int64_t>(e.t_begin), W::scalar<std::int64_t>(e.t_end)});
    tw.patch(vec + 4 + 4 * k, t.pos);
  }
  const auto table_fb = tw.finish(root.pos, "FTAB");
  const auto table_bytes = detail::aedat4_compress(c, table_fb);
  const auto hdr = header(static_cast<std::int64_t>(head + data.size()));
  std::string out(detail::kAedat4Magic, detail::kAedat4MagicLen);
  out.append(reinterpret_cast<const char*>(hdr.data()), hdr.size());
  out.append(reinterpret_cast<const char*>(data.data()), data.size());
  out.append(reinterpret_cast<const char*>(table_bytes.data()), table_bytes.size());
  write_file_atomic(path, out);
  write_calibration_and_poses_beside(path, d, static_cast<double>(d.time_origin));
}

inline Format aedat4_format() {
  return {"aedat4",
          false,
          kAedat4Description,
          &is_aedat4,
          &load_aedat4,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions& o) { write_aedat4(p, d, o.compression); },
          {".aedat4"}};
}

}  // namespace evnerf::io
