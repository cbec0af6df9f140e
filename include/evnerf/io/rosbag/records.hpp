// io/rosbag/records.hpp — the bytes of a ROS bag 2.0 (io/rosbag.hpp): little-endian integers, the file read
// at byte offsets (BagFile), records (a header of `name=value` fields, then data) and their fields, and
// chunks decompressed (none, bz2 through Debian's libbz2, lz4 frames through liblz4). Every error names the
// file and the record. Depends on core/ and io/recording.hpp.
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

#include "../../core/error.hpp"
#include "../../core/fileio.hpp"
#include "../../core/warn.hpp"
#include "../recording.hpp"

namespace evnerf::io {

inline constexpr std::size_t kBagMaxRecordHeader = std::size_t{1} << 20;  ///< a record header (fields)
inline constexpr std::uint64_t kBagMaxChunk = std::uint64_t{1} << 31;     ///< a chunk, uncompressed
inline constexpr std::string_view kBagMagic = "#ROSBAG V2.0\n";

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

}  // namespace detail

}  // namespace evnerf::io
