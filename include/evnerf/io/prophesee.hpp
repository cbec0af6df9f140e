// io/prophesee.hpp — Prophesee's files: `.raw` in EVT 2.0 (32-bit words) and EVT 3.0 (16-bit words, vectorised),
// and the older `.dat` CD files; writers for EVT 2.0 and EVT 3.0. Each file starts with text lines beginning
// with '%' (`% evt 3.0`, `% format EVT3;height=720;width=1280`, `% geometry 1280x720`, `% plugin_name …`,
// `% Width 640` in .dat); the sensor's size comes from those lines, else from the sensor generation the
// plugin names (Gen3: 640×480, Gen4 / IMX636: 1280×720, GenX320: 320×320), else from --sensor-size.
// Words are little-endian. EVT 2.0: type in bits 31–28; a CD word (0 OFF, 1 ON) holds the 6 low bits of the
// microsecond time (27–22), x (21–11), y (10–0); EVT_TIME_HIGH (8) the time's bits 33–6. EVT 3.0: type in bits
// 15–12; EVT_ADDR_Y (0) sets y, EVT_ADDR_X (2) is one event at x with polarity bit 11, VECT_BASE_X (3) sets a
// base x and polarity, VECT_12 (4) and VECT_8 (5) are events at the base + each set bit of their mask (the base
// then moves on by 12 or 8), EVT_TIME_LOW (6) and EVT_TIME_HIGH (8) set the two 12-bit halves of a 24-bit
// microsecond time that wraps every 16.8 s. External triggers (0xA) and vendor words are skipped and counted.
// .dat: after the header, a byte of event type and a byte of event size (8), then records of a 32-bit
// microsecond time and x (bits 13–0), y (27–14), polarity (31–28). Times are held as integer microseconds and
// given in seconds; a time that runs backwards, a coordinate outside the sensor or an unknown version is an
// Error naming the file and the byte offset; a file that ends inside a word (cut short) is read to its last
// whole word, with a warning. A whole EVT 3.0 file is decoded on OpenMP's threads,
// to the same events and errors as one thread (decode_evt3). A recording in one file takes calib.txt and
// groundtruth.txt beside it (or --calib, --poses). Depends on io/recording.hpp, io/ijrr.hpp and core/warn.hpp.
#pragma once
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "../core/warn.hpp"
#include "ijrr.hpp"
#include "recording.hpp"

namespace evnerf::io {

/// What a Prophesee file's header and words say (inspect shows it).
struct PropheseeInfo {
  std::string kind;  ///< "evt 2.0", "evt 3.0" or "dat"
  int width = 0, height = 0;
  std::string geometry_from;  ///< which header line (or flag) gave the size
  std::size_t header_bytes = 0;
  std::size_t events = 0;                     ///< CD events decoded (up to the time window's end, where the read stops)
  std::size_t triggers = 0, other_words = 0;  ///< trigger words, and words of other types, skipped
};

namespace detail {
/// The '%' lines at the start of a file, as (key, value) pairs split at the first space.
struct PercentHeader {
  std::vector<std::pair<std::string, std::string>> lines;
  std::size_t bytes = 0;
  const std::string* find(const std::string& key) const {
    for (const auto& [k, v] : lines)
      if (k == key) return &v;
    return nullptr;
  }
};

inline PercentHeader read_percent_header(std::FILE* f, const std::string& file) {
  PercentHeader h;
  std::string line;
  for (;;) {
    const int c = std::fgetc(f);
    if (c != '%') {
      if (c != EOF) std::ungetc(c, f);
      break;
    }
    line.clear();
    int d;
    while ((d = std::fgetc(f)) != EOF && d != '\n') {
      line.push_back(static_cast<char>(d));
      if (line.size() > 4096) throw Error(file, 0, "header line at byte " + std::to_string(h.bytes) + " longer than 4096 bytes");
    }
    if (d == EOF) throw Error(file, 0, "header line at byte " + std::to_string(h.bytes) + " runs to the end of the file");
    h.bytes += line.size() + 2;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    const auto a = line.find_first_not_of(' ');
    if (a == std::string::npos) continue;
    const auto sp = line.find(' ', a);
    const auto v = sp == std::string::npos ? std::string::npos : line.find_first_not_of(' ', sp);
    h.lines.emplace_back(line.substr(a, sp == std::string::npos ? std::string::npos : sp - a),
                         v == std::string::npos ? std::string() : line.substr(v));
    if (h.lines.back().first == "end") break;
    if (h.lines.size() > 10000) throw Error(file, 0, "more than 10000 header lines");
  }
  return h;
}

/// An integer header value, or -1.
inline long header_int(const std::string& s) {
  char* end = nullptr;
  const long v = std::strtol(s.c_str(), &end, 10);
  return end != s.c_str() && v > 0 && v <= 65535 ? v : -1;
}

/// The sensor size from the header (format, geometry, Width/Height, sensor generation), or opt's when given.
inline void sensor_geometry(const PercentHeader& h, const LoadOptions& opt, const std::string& file, PropheseeInfo& info) {
  if (opt.width > 0 && opt.height > 0) {
    info.width = opt.width, info.height = opt.height, info.geometry_from = "--sensor-size";
  } else if (const auto* fmt = h.find("format");
             fmt && fmt->find("width=") != std::string::npos && fmt->find("height=") != std::string::npos) {
    info.width = static_cast<int>(header_int(fmt->substr(fmt->find("width=") + 6)));
    info.height = static_cast<int>(header_int(fmt->substr(fmt->find("height=") + 7)));
    info.geometry_from = "the header's format line";
  } else if (const auto* g = h.find("geometry"); g && g->find('x') != std::string::npos) {
    info.width = static_cast<int>(header_int(*g));
    info.height = static_cast<int>(header_int(g->substr(g->find('x') + 1)));
    info.geometry_from = "the header's geometry line";
  } else if (h.find("Width") && h.find("Height")) {
    info.width = static_cast<int>(header_int(*h.find("Width")));
    info.height = static_cast<int>(header_int(*h.find("Height")));
    info.geometry_from = "the header's Width and Height lines";
  } else {
    std::string gen;
    if (const auto* p = h.find("plugin_name")) gen = *p;
    if (const auto* s = h.find("sensor_generation")) gen += " gen" + *s;
    std::transform(gen.begin(), gen.end(), gen.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    gen.erase(std::remove(gen.begin(), gen.end(), '.'), gen.end());
    if (gen.find("genx320") != std::string::npos || gen.find("imx8") != std::string::npos) info.width = 320, info.height = 320;
    else if (gen.find("gen4") != std::string::npos || gen.find("imx636") != std::string::npos) info.width = 1280, info.height = 720;
    else if (gen.find("gen3") != std::string::npos) info.width = 640, info.height = 480;
    info.geometry_from = "the sensor generation of the header's plugin_name";
  }
  if (info.width <= 0 || info.height <= 0)
    throw Error(file, 0,
                "the header gives no sensor size (no format, geometry or Width/Height line and no known sensor generation): "
                "give it with --sensor-size WxH");
  check_sensor_size(info.width, info.height, file + " (the sensor size of its header)");
}

/// Collects decoded events: times in microseconds (as the file holds them) into seconds, only those of the
/// window; checks order and coordinates. `done` once a time passes the window's end. room(n) before a block
/// that may add up to n events; finish() gives back what room() reserved beyond them. The events go through
/// raw pointers into the stream's arrays (sized ahead by room()), so that a store does not re-read a vector's
/// end; the arrays hold their final size only after finish().
class RawSink {
 public:
  RawSink(events::EventStream& ev, const LoadOptions& opt, const std::string& file, int w, int h, std::uint64_t file_bytes = 0)
      : ev_(ev), file_(file), w_(static_cast<unsigned>(w)), h_(static_cast<unsigned>(h)), t0_(opt.t_begin), t1_(opt.t_end),
        progress_(opt.progress), bytes_(file_bytes), n_(ev.t.size()) {
    bind();
  }
  /// After a block: the file is read up to byte `offset` (LoadOptions::progress).
  void read_to(std::size_t offset) const {
    if (progress_) progress_(std::min<std::uint64_t>(offset, bytes_), bytes_);
  }
  /// Capacity for n events in all, allocated but not touched (a whole file's estimate).
  void reserve(std::size_t n) {
    if (n <= ev_.t.capacity()) return;
    ev_.t.resize(n_), ev_.x.resize(n_), ev_.y.resize(n_), ev_.polarity.resize(n_);  // what follows n_ is not copied
    ev_.reserve(n);
    huge_pages(ev_.t), huge_pages(ev_.x), huge_pages(ev_.y), huge_pages(ev_.polarity);
    bind();
  }
  /// Room for n more events: the arrays sized to hold them (only those elements are initialised, just before
  /// the block writes them), the capacity grown by half at least where it runs out.
  void room(std::size_t n) {
    if (n_ + n <= ev_.t.size()) [[likely]]
      return;
    if (n_ + n > ev_.t.capacity()) reserve(std::max(n_ + n, ev_.t.capacity() + ev_.t.capacity() / 2));
    const std::size_t size = std::min(ev_.t.capacity(), n_ + std::max<std::size_t>(n, 4096));  // a vector word's 12 fit
    ev_.t.resize(size), ev_.x.resize(size), ev_.y.resize(size), ev_.polarity.resize(size);
    bind();
  }
  void finish() {
    ev_.t.resize(n_), ev_.x.resize(n_), ev_.y.resize(n_), ev_.polarity.resize(n_);
    if (ev_.t.capacity() > 2 * ev_.t.size() + 4096)
      ev_.t.shrink_to_fit(), ev_.x.shrink_to_fit(), ev_.y.shrink_to_fit(), ev_.polarity.shrink_to_fit();
  }
  // Small enough to be inlined into each decoder's loop; the messages are built out of line.
  [[gnu::always_inline]] void add(std::int64_t us, unsigned x, unsigned y, int on, std::size_t offset) {
    if (us < last_ || x >= w_ || y >= h_) [[unlikely]]
      refuse(us, x, y, offset);
    last_ = us;
    ++count_;
    const double t = static_cast<double>(us) / 1e6;
    if (t >= t1_) [[unlikely]] {
      done_ = true;
      return;
    }
    if (t < t0_) return;
    // room() sized the arrays for it. The polarity's store (a char, which may alias anything) comes last.
    const std::size_t i = n_++;
    t_[i] = t;
    x_[i] = static_cast<std::uint16_t>(x);
    y_[i] = static_cast<std::uint16_t>(y);
    p_[i] = static_cast<std::int8_t>(on ? 1 : -1);
  }
  [[noreturn]] void bad(std::size_t offset, const std::string& what) const {
    throw Error(file_, 0, "byte " + std::to_string(offset) + ": " + what);
  }
  [[noreturn, gnu::noinline, gnu::cold]] void refuse(std::int64_t us, unsigned x, unsigned y, std::size_t offset) const {
    if (us < last_) bad(offset, "time runs backwards (" + std::to_string(us) + " µs after " + std::to_string(last_) + " µs)");
    bad(offset, "event at x " + std::to_string(x) + ", y " + std::to_string(y) + " outside the " + std::to_string(w_) + "x" +
                    std::to_string(h_) + " sensor");
  }
  bool done() const { return done_; }
  std::size_t count() const { return count_; }
  /// The parallel decoders' interface: whether only a time window is kept, the events held, the last time,
  /// the sensor's size; ahead(n) the arrays' places for the next n events (written by the caller, then
  /// taken with commit(n, the last one's time), all of them checked as add() checks each).
  bool windowed() const { return std::isfinite(t0_) || std::isfinite(t1_); }
  std::size_t size() const { return n_; }
  std::int64_t last() const { return last_; }
  std::uint64_t file_bytes() const { return bytes_; }
  unsigned width() const { return w_; }
  unsigned height() const { return h_; }
  struct Arrays {
    double* t;
    std::uint16_t *x, *y;
    std::int8_t* p;
  };
  Arrays ahead(std::size_t n) {
    room(n);
    return {t_ + n_, x_ + n_, y_ + n_, p_ + n_};
  }
  void commit(std::size_t n, std::int64_t last_us) {
    n_ += n, count_ += n;
    if (n) last_ = last_us;
  }

 private:
  void bind() { t_ = ev_.t.data(), x_ = ev_.x.data(), y_ = ev_.y.data(), p_ = ev_.polarity.data(); }
  events::EventStream& ev_;
  std::string file_;
  unsigned w_, h_;
  double t0_, t1_;
  std::int64_t last_ = 0;
  std::size_t count_ = 0;
  bool done_ = false;
  const ReadProgress& progress_;
  std::uint64_t bytes_;
  std::size_t n_;
  double* t_ = nullptr;
  std::uint16_t *x_ = nullptr, *y_ = nullptr;
  std::int8_t* p_ = nullptr;
};

/// Reads `f` from its position in blocks of whole words of `word` bytes, calling `block(words, n, offset)`
/// until it returns false or the file ends (and the sink's progress after each). A file that ends inside a
/// word is a recording cut short (a camera that lost power, a recorder that crashed): its whole words are
/// read, and one warning names the byte offset and the bytes dropped.
/// Blocks are `block_bytes` long (a multiple of the word).
template <class Block>
void read_words(std::FILE* f, std::size_t word, std::size_t offset, const std::string& file, const RawSink& sink, std::size_t block_bytes,
                Block&& block) {
  // Not value-initialised: a small file touches only the pages it reads into.
  const std::size_t kBlock = block_bytes;
  const std::unique_ptr<unsigned char[]> buf(new unsigned char[kBlock]);
  std::size_t keep = 0;
  for (;;) {
    const std::size_t got = std::fread(buf.get() + keep, 1, kBlock - keep, f) + keep;
    if (std::ferror(f)) throw Error(file, 0, "read error after byte " + std::to_string(offset));
    const std::size_t whole = got / word * word;
    if (whole && !block(buf.get(), whole / word, offset)) return;
    offset += whole;
    sink.read_to(offset);
    keep = got - whole;
    if (got < kBlock) {
      if (keep)
        warn(file + ": byte " + std::to_string(offset) + ": the file ends " + std::to_string(keep) + " byte" + (keep == 1 ? "" : "s") +
             " into a " + std::to_string(word) + "-byte word (a recording cut short); read to the last whole word, " +
             std::to_string(keep) + " byte" + (keep == 1 ? "" : "s") + " dropped");
      return;
    }
    std::memmove(buf.get(), buf.get() + whole, keep);
  }
}

/// The block of the serial decoders: it stays in the first-level cache's reach.
inline constexpr std::size_t kWordBlock = std::size_t(1) << 16;
/// Words of EVT 3.0 a whole-file read on several threads decodes per block (tests lower it to cross many
/// blocks and parts).
inline std::size_t evt3_parallel_words = std::size_t(1) << 19;
/// Parts the parallel EVT 3.0 decode cuts a block into: 0 for one a thread. Tests and the fuzzer set it to run
/// the two-pass decode, in that many parts, on one thread.
inline int evt3_parallel_parts = 0;
/// Blocks the parallel EVT 3.0 decode handed back to the serial one (a clean file has none; tests look).
inline std::atomic<std::size_t> evt3_blocks_redone{0};

inline std::uint32_t le32(const unsigned char* p) { return p[0] | p[1] << 8 | p[2] << 16 | static_cast<std::uint32_t>(p[3]) << 24; }
inline std::uint16_t le16(const unsigned char* p) { return static_cast<std::uint16_t>(p[0] | p[1] << 8); }

inline void decode_evt2(std::FILE* f, std::size_t offset, RawSink& sink, PropheseeInfo& info, const std::string& file) {
  std::int64_t high = -1;  // the time's bits 33–6 (with wraps past 2^34 µs added); -1 before the first
  read_words(f, 4, offset, file, sink, kWordBlock, [&](const unsigned char* p, std::size_t n, std::size_t at) {
    sink.room(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t w = le32(p + 4 * i);
      const unsigned type = w >> 28;
      if (type <= 1) {
        if (high < 0) continue;  // before the first time base: its time is unknown
        sink.add(high << 6 | (w >> 22 & 63), w >> 11 & 0x7FF, w & 0x7FF, static_cast<int>(type), at + 4 * i);
        if (sink.done()) return false;
      } else if (type == 8) {
        std::int64_t h = w & 0x0FFFFFFF;
        if (high >= 0) {
          h += high >> 28 << 28;
          if (h < high) {
            if (high - h < std::int64_t(1) << 27) sink.bad(at + 4 * i, "EVT_TIME_HIGH runs backwards");
            h += std::int64_t(1) << 28;  // the 34-bit time wrapped (after 4 h 46 min)
          }
        }
        high = h;
      } else if (type == 0xA) {
        ++info.triggers;
      } else {
        ++info.other_words;
      }
    }
    return true;
  });
}

/// EVT 3.0's decoding state: the time's high half (bits 23–12, with the 24-bit wraps added; -1 before the
/// first EVT_TIME_HIGH), its low half, the row, the vector base and its polarity.
struct Evt3State {
  std::int64_t high = -1, low = 0;
  unsigned y = 0, base = 0;
  int pol = 0;
  bool have_y = false;
};

/// EVT 3.0's state machine over the `n` words at `p` (the first at byte `at`): out.add(us, x, y, on, offset)
/// takes each event and returns false to stop (then so does this), out.room(k) comes before a vector word's
/// events (k: its 12 and one for each word after it in the run), out.bad(offset, what) a time-high word that
/// runs backwards. Triggers and other words are counted.
template <class Out>
bool evt3_words(const unsigned char* p, std::size_t n, std::size_t at, Evt3State& state, std::size_t& triggers, std::size_t& other,
                Out& out) {
  // The state in locals: the words are read through a char pointer, which may alias anything held in memory.
  Evt3State s = state;
  std::size_t trig = 0, oth = 0;
  const bool go = [&] {
    for (std::size_t i = 0; i < n; ++i) {
      const unsigned w = le16(p + 2 * i), type = w >> 12;
      switch (type) {
        case 0x0:
          s.y = w & 0x7FF, s.have_y = true;
          break;
        case 0x2:
          if (s.high < 0 || !s.have_y) break;
          if (!out.add(s.high << 12 | s.low, w & 0x7FF, s.y, w >> 11 & 1, at + 2 * i)) return false;
          break;
        case 0x3:
          s.base = w & 0x7FF, s.pol = w >> 11 & 1;
          break;
        case 0x4:
        case 0x5: {
          const unsigned mask = type == 0x4 ? w & 0xFFF : w & 0xFF, len = type == 0x4 ? 12 : 8;
          out.room(12 + (n - i - 1));  // its 12, and one for each word after it (the block's room() counted one a word)
          if (s.high >= 0 && s.have_y)
            for (unsigned m = mask; m; m &= m - 1)
              if (!out.add(s.high << 12 | s.low, s.base + static_cast<unsigned>(__builtin_ctz(m)), s.y, s.pol, at + 2 * i)) return false;
          s.base += len;
          break;
        }
        case 0x6:
          s.low = w & 0xFFF;
          break;
        case 0x8: {
          std::int64_t h = w & 0xFFF;
          if (s.high >= 0) {
            h += s.high >> 12 << 12;
            if (h < s.high) {
              if (s.high - h < 0x800) {
                out.bad(at + 2 * i, "EVT_TIME_HIGH runs backwards");
                return false;
              }
              h += 0x1000;  // the 24-bit time wrapped (every 16.8 s)
            }
          }
          s.high = h;
          break;
        }
        case 0xA:
          ++trig;
          break;
        default:
          ++oth;
      }
    }
    return true;
  }();
  state = s, triggers += trig, other += oth;
  return go;
}

/// What a run of EVT 3.0 words does to any state it starts from (the first pass of the parallel decode): the
/// events it gives, and the state it leaves, as functions of the state it is given.
struct Evt3Summary {
  bool has_high = false, has_low = false, has_y = false, has_base = false, bad = false;
  std::int64_t first_high = 0, last_high = 0;  // the first time-high word's 12 bits; the last high, from it
  unsigned low = 0, y = 0, base = 0;           // base: after the last VECT_BASE_X, or the vectors' sum of lengths
  int pol = 0;
  std::size_t events = 0;                       // events once the run has given a time high and a row of its own
  std::size_t before[2][2] = {{0, 0}, {0, 0}};  // events before that, by [time high given][row given]
  std::size_t triggers = 0, other = 0;

  /// Sums up the `n` words at `p`.
  void scan(const unsigned char* p, std::size_t n) {
    Evt3Summary u = *this;  // in locals: see evt3_words
    u.scan_here(p, n);
    *this = u;
  }
  void scan_here(const unsigned char* p, std::size_t n) {
    // Up to the run's own time high and row: word by word, as the state machine goes.
    std::size_t i = 0;
    for (; i < n && !(has_high && has_y); ++i) {
      const unsigned w = le16(p + 2 * i), type = w >> 12;
      if (type == 0x0) has_y = true;
      else if (type == 0x2) count(1);
      else if (type == 0x4) count(static_cast<unsigned>(__builtin_popcount(w & 0xFFF)));
      else if (type == 0x5) count(static_cast<unsigned>(__builtin_popcount(w & 0xFF)));
      else if (type == 0x8) time_high(w);
      else if (type == 0xA) ++triggers;
      else if (type != 0x3 && type != 0x6) ++other;
    }
    // Then in chunks, without a branch on a word's type (which stalls the state machine), so that the compiler
    // can vectorise it: the events each word gives (a popcount of the vector words' masks), the words skipped,
    // the vector bases and lengths; a chunk that holds time-high words is gone through again for them.
    std::size_t bases = 0, lens = 0;
    for (std::size_t j = 0; j < i; ++j) {
      const unsigned type = le16(p + 2 * j) >> 12;
      bases += type == 0x3, lens += type == 0x4 ? 12 : type == 0x5 ? 8 : 0;
    }
    constexpr std::size_t kChunk = 512;
    for (std::size_t len = 0; i < n; i += len) {
      len = std::min(kChunk, n - i);
      const unsigned char* q = p + 2 * i;
      unsigned ev = 0, trig = 0, oth = 0, nb = 0, nl = 0, highs = 0;
      for (std::size_t j = 0; j < len; ++j) {
        const unsigned w = le16(q + 2 * j), type = w >> 12;
        unsigned c = w & (type == 0x4 ? 0xFFFu : type == 0x5 ? 0xFFu : 0u);
        c = c - (c >> 1 & 0x5555u);
        c = (c & 0x3333u) + (c >> 2 & 0x3333u);
        c = (c + (c >> 4)) & 0x0F0Fu;
        c = (c + (c >> 8)) & 0x1Fu;
        ev += c + (type == 0x2);
        trig += type == 0xA;
        oth += 0xFA82u >> type & 1u;  // types 1, 7, 9 and 11–15
        nb += type == 0x3;
        nl += type == 0x4 ? 12u : type == 0x5 ? 8u : 0u;
        highs += type == 0x8;
      }
      events += ev, triggers += trig, other += oth, bases += nb, lens += nl;
      if (highs)
        for (std::size_t j = 0; j < len; ++j)
          if (le16(q + 2 * j) >> 12 == 0x8) time_high(le16(q + 2 * j));
    }
    // The last row, time low and vector base, from the end (the base moved on by the vectors after it).
    for (std::size_t j = n; j-- > 0;)
      if (const unsigned w = le16(p + 2 * j); w >> 12 == 0x0) {
        y = w & 0x7FF, has_y = true;
        break;
      }
    for (std::size_t j = n; j-- > 0;)
      if (const unsigned w = le16(p + 2 * j); w >> 12 == 0x6) {
        low = w & 0xFFF, has_low = true;
        break;
      }
    unsigned moved = 0;
    for (std::size_t j = n; j-- > 0 && bases;) {
      const unsigned w = le16(p + 2 * j), type = w >> 12;
      if (type == 0x3) {
        base = (w & 0x7FF) + moved, pol = w >> 11 & 1, has_base = true;
        break;
      }
      moved += type == 0x4 ? 12 : type == 0x5 ? 8 : 0;
    }
    if (!has_base) base = static_cast<unsigned>(lens);  // the vectors' lengths, all of them
  }
  void time_high(unsigned w) {
    std::int64_t h = w & 0xFFF;
    if (!has_high) {
      first_high = last_high = h, has_high = true;
      return;
    }
    h += last_high >> 12 << 12;
    if (h < last_high) {
      if (last_high - h < 0x800) bad = true;
      h += 0x1000;
    }
    last_high = h;
  }
  [[gnu::always_inline]] void count(unsigned k) {
    if (has_high && has_y) [[likely]] {
      events += k;
      return;
    }
    for (int hi = 0; hi < 2; ++hi)
      for (int yy = 0; yy < 2; ++yy)
        if ((hi || has_high) && (yy || has_y)) before[hi][yy] += k;
  }
  /// The events the run gives from state `s`, and `s` moved to the run's end; false where the run's first
  /// time-high word runs backwards from s's (the serial decode names it).
  bool apply(Evt3State& s, std::size_t& n) const {
    n = events + before[s.high >= 0][s.have_y];
    if (has_high) {
      std::int64_t h = first_high;
      if (s.high >= 0) {
        h += s.high >> 12 << 12;
        if (h < s.high) {
          if (s.high - h < 0x800) return false;
          h += 0x1000;
        }
      }
      s.high = h + (last_high - first_high);
    }
    if (has_low) s.low = low;
    if (has_y) s.y = y, s.have_y = true;
    if (has_base) s.base = base, s.pol = pol;
    else s.base += base;
    return true;
  }
};

/// Writes one part's events of the parallel decode into arrays sized for them; any event out of order or
/// outside the sensor marks the part, whose block is then decoded again by the serial path (which names it).
struct Evt3PartOut {
  double* t;
  std::uint16_t *x, *y;
  std::int8_t* p;
  std::size_t n = 0, cap = 0;
  unsigned w = 0, h = 0;
  std::int64_t first = 0, last = std::numeric_limits<std::int64_t>::min();
  bool wrong = false;
  [[gnu::always_inline]] bool add(std::int64_t us, unsigned xx, unsigned yy, int on, std::size_t) {
    if (us < last || xx >= w || yy >= h || n == cap) [[unlikely]] {
      wrong = true;
      return false;
    }
    if (n == 0) first = us;
    last = us;
    std::memcpy(t + n, &us, sizeof us);  // the microseconds: seconds() turns them into seconds, all at once
    x[n] = static_cast<std::uint16_t>(xx);
    y[n] = static_cast<std::uint16_t>(yy);
    p[n] = static_cast<std::int8_t>(on ? 1 : -1);
    ++n;
    return true;
  }
  void room(std::size_t) {}
  void bad(std::size_t, const char*) { wrong = true; }
  /// The times written as microseconds, in seconds: a loop the compiler vectorises, where a scalar division
  /// per event would hold up the decoding loop.
  void seconds() const {
    for (std::size_t i = 0; i < n; ++i) {
      std::int64_t us;
      std::memcpy(&us, t + i, sizeof us);
      t[i] = static_cast<double>(us) / 1e6;
    }
  }
};

/// The serial path's output: the sink, which checks each event against the window and names any error.
struct Evt3SinkOut {
  RawSink& sink;
  [[gnu::always_inline]] bool add(std::int64_t us, unsigned x, unsigned y, int on, std::size_t off) {
    sink.add(us, x, y, on, off);
    return !sink.done();
  }
  void room(std::size_t n) { sink.room(n); }
  [[noreturn]] void bad(std::size_t off, const char* what) { sink.bad(off, what); }
};

/// EVT 3.0. A whole-file read on more than one thread decodes each block of words in two passes: the first
/// sums up what each part of the block does to the state (Evt3Summary), which gives every part its starting
/// state and its place in the arrays; the second decodes the parts side by side. A block in which any part
/// finds something wrong is decoded again by the serial state machine, from the same state, so that the
/// events, the counts and every error are those of a serial read.
inline void decode_evt3(std::FILE* f, std::size_t offset, RawSink& sink, PropheseeInfo& info, const std::string& file) {
  Evt3State s;
  Evt3SinkOut serial{sink};
  int threads = 1;
#ifdef _OPENMP
  threads = omp_get_max_threads();
#endif
  const int parts = std::min(evt3_parallel_parts > 0 ? evt3_parallel_parts : threads, 64);
  [[maybe_unused]] const int team = std::min(parts, threads);  // the threads that decode the parts
  const bool parallel = parts > 1 && !sink.windowed() && evt3_parallel_words > 0;
  if (!parallel) {
    read_words(f, 2, offset, file, sink, kWordBlock, [&](const unsigned char* p, std::size_t n, std::size_t at) {
      sink.room(n);  // one event per word; a vector word makes room for its 12 and the words after it
      return evt3_words(p, n, at, s, info.triggers, info.other_words, serial);
    });
    return;
  }
  std::vector<Evt3Summary> sum(static_cast<std::size_t>(parts));
  std::vector<Evt3State> from(static_cast<std::size_t>(parts));
  std::vector<std::size_t> first(static_cast<std::size_t>(parts) + 1);
  std::vector<Evt3PartOut> out(static_cast<std::size_t>(parts));
  // Blocks of a sixteenth of the file at least, so that progress is reported as often as in the serial read.
  const std::size_t block =
      std::min<std::uint64_t>(2 * evt3_parallel_words, std::max<std::uint64_t>(kWordBlock, sink.file_bytes() / 16 & ~std::uint64_t(1)));
  read_words(f, 2, offset, file, sink, block, [&](const unsigned char* p, std::size_t n, std::size_t at) {
    const std::size_t step = (n + static_cast<std::size_t>(parts) - 1) / static_cast<std::size_t>(parts);
    auto lo = [&](int k) { return std::min(n, step * static_cast<std::size_t>(k)); };
#pragma omp parallel for schedule(static, 1) num_threads(team)
    for (int k = 0; k < parts; ++k) {
      sum[k] = {};
      sum[k].scan(p + 2 * lo(k), lo(k + 1) - lo(k));
    }
    bool ok = true;
    Evt3State at_end = s;
    first[0] = sink.size();
    for (int k = 0; k < parts && ok; ++k) {
      from[k] = at_end;
      std::size_t m = 0;
      ok = !sum[k].bad && sum[k].apply(at_end, m);
      first[k + 1] = first[k] + m;
    }
    if (ok) {
      const auto a = sink.ahead(first[parts] - first[0]);
#pragma omp parallel for schedule(static, 1) num_threads(team)
      for (int k = 0; k < parts; ++k) {
        const std::size_t i = first[k] - first[0];
        // In locals, and each part's result in out[k] only at its end: see evt3_words.
        Evt3PartOut o{a.t + i, a.x + i, a.y + i, a.p + i, 0, first[k + 1] - first[k], sink.width(), sink.height()};
        Evt3State st = from[k];
        std::size_t trig = 0, other = 0;
        evt3_words(p + 2 * lo(k), lo(k + 1) - lo(k), at + 2 * lo(k), st, trig, other, o);
        if (o.n != o.cap) o.wrong = true;
        o.seconds();
        out[k] = o;
      }
      std::int64_t last = sink.last();
      for (int k = 0; k < parts && ok; ++k) {
        if (out[k].wrong || (out[k].n && out[k].first < last)) ok = false;
        if (out[k].n) last = out[k].last;
      }
      if (ok) {
        sink.commit(first[parts] - first[0], last);
        for (const auto& u : sum) info.triggers += u.triggers, info.other_words += u.other;
        s = at_end;
        return true;
      }
    }
    ++evt3_blocks_redone;
    sink.room(n);
    return evt3_words(p, n, at, s, info.triggers, info.other_words, serial);
  });
}

inline void decode_dat(std::FILE* f, std::size_t offset, RawSink& sink, const std::string& file) {
  unsigned char ts[2];
  if (std::fread(ts, 1, 2, f) != 2) throw Error(file, 0, "byte " + std::to_string(offset) + ": no event type and size after the header");
  if (ts[1] != 8)
    throw Error(
        file, 0,
        "byte " + std::to_string(offset + 1) + ": event size " + std::to_string(ts[1]) + " (a .dat file of CD events has 8-byte records)");
  std::int64_t wraps = 0, last = -1;
  read_words(f, 8, offset + 2, file, sink, kWordBlock, [&](const unsigned char* p, std::size_t n, std::size_t at) {
    sink.room(n);
    for (std::size_t i = 0; i < n; ++i) {
      std::int64_t t = le32(p + 8 * i);
      const std::uint32_t w = le32(p + 8 * i + 4);
      if (last >= 0 && t + wraps < last && last - (t + wraps) > (std::int64_t(1) << 31)) wraps += std::int64_t(1) << 32;
      t += wraps;
      last = t;
      sink.add(t, w & 0x3FFF, w >> 14 & 0x3FFF, (w >> 28) != 0, at + 8 * i);
      if (sink.done()) return false;
    }
    return true;
  });
}

/// Opens a Prophesee file and reads its header: the kind ("evt 2.0", "evt 3.0", "dat") or "" when it is none.
inline std::string prophesee_kind(const PercentHeader& h) {
  std::string v;
  if (const auto* e = h.find("evt")) v = *e;
  if (const auto* fmt = h.find("format")) {
    const auto s = fmt->substr(0, fmt->find(';'));
    v = s == "EVT2" ? "2.0" : s == "EVT3" ? "3.0" : s == "EVT21" ? "2.1" : s;
  }
  if (!v.empty()) return "evt " + v;
  return h.find("Width") || h.find("Version") || h.find("Date") ? "dat" : "";
}
}  // namespace detail

/// Reads a Prophesee .raw (EVT 2.0, 3.0) or .dat file's events (only LoadOptions' time window; reading stops
/// past its end); `info` gets what the header and words said.
inline events::EventStream read_prophesee_events(const std::filesystem::path& path, const LoadOptions& opt, PropheseeInfo& info) {
  const std::string file = path.string();
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) throw Error(file, 0, "cannot open file (missing or unreadable)");
  const auto h = detail::read_percent_header(f.get(), file);
  info.kind = detail::prophesee_kind(h);
  info.header_bytes = h.bytes;
  if (info.kind != "evt 2.0" && info.kind != "evt 3.0" && info.kind != "dat")
    throw Error(file, 0,
                "Prophesee " + (info.kind.empty() ? std::string("file of no known kind") : info.kind) +
                    ": evnerf reads EVT 2.0 and EVT 3.0 .raw files and .dat CD files");
  detail::sensor_geometry(h, opt, file, info);
  events::EventStream ev;
  ev.width = info.width;
  ev.height = info.height;
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  detail::RawSink sink(ev, opt, file, info.width, info.height, ec ? 0 : bytes);
  if (!std::isfinite(opt.t_begin) && !std::isfinite(opt.t_end)) {                                // the whole file: about an event per word
    if (!ec && bytes > h.bytes) sink.reserve((bytes - h.bytes) / (info.kind == "dat" ? 8 : 4));  // EVT 3.0: two words an event
  }
  if (info.kind == "evt 2.0") detail::decode_evt2(f.get(), h.bytes, sink, info, file);
  else if (info.kind == "evt 3.0") detail::decode_evt3(f.get(), h.bytes, sink, info, file);
  else detail::decode_dat(f.get(), h.bytes, sink, file);
  sink.finish();
  info.events = sink.count();
  return ev;
}

/// Whether a file's '%' header says `kind`: "evt 2.0", "evt 3.0", "dat", or "evt 3.0+" for any EVT version but
/// 2.0 (a version evnerf does not read goes to the EVT 3.0 entry, whose reader names it).
inline bool is_prophesee(const std::filesystem::path& path, const char* kind) {
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) return false;
  try {
    const auto k = detail::prophesee_kind(detail::read_percent_header(f.get(), path.string()));
    return std::string(kind) == "evt 3.0+" ? k.rfind("evt", 0) == 0 && k != "evt 2.0" : k == kind;
  } catch (const Error&) {
    return false;
  }
}

/// Loads a Prophesee file as a recording: its events, calib.txt and groundtruth.txt beside it (or the
/// LoadOptions' files). Without a calibration, an Error, unless LoadOptions::calibration_optional (inspect).
inline Dataset load_prophesee(const std::filesystem::path& path, const LoadOptions& opt) {
  PropheseeInfo info;
  Dataset d;
  d.events = read_prophesee_events(path, opt, info);
  attach_calibration_and_poses(path, opt, d, info.width, info.height, "a Prophesee recording");
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "prophesee     %s, %dx%d (from %s), %zu header bytes, %zu events in the file, %zu trigger words, %zu other words",
                info.kind.c_str(), info.width, info.height, info.geometry_from.c_str(), info.header_bytes, info.events, info.triggers,
                info.other_words);
  d.notes.push_back(buf);
  return d;
}

/// Writes the events as an EVT 2.0 (`version` "2.0") or EVT 3.0 (one EVT_ADDR_X word per event) .raw file,
/// with calib.txt and groundtruth.txt beside it as io::load reads them back. Times are rounded to whole
/// microseconds and must lie in [0, 2^34) µs.
inline void write_prophesee_raw(const std::filesystem::path& path, const Dataset& d, const std::string& version) {
  const auto& ev = d.events;
  const int w = d.camera.width(), h = d.camera.height();
  if (w > 2048 || h > 2048)
    throw Error(path.string(), 0, "EVT words hold coordinates below 2048; the sensor is " + std::to_string(w) + "x" + std::to_string(h));
  std::string out = "% evt " + version + "\n% format EVT" + (version == "2.0" ? "2" : "3") + ";height=" + std::to_string(h) +
                    ";width=" + std::to_string(w) + "\n% geometry " + std::to_string(w) + "x" + std::to_string(h) +
                    "\n% integrator_name evnerf\n% end\n";
  auto put = [&](std::uint64_t v, int bytes) {
    for (int k = 0; k < bytes; ++k) out.push_back(static_cast<char>(v >> (8 * k) & 0xFF));
  };
  std::int64_t high = -1, low = -1;
  int y = -1;
  out.reserve(out.size() + ev.size() * (version == "2.0" ? 4 : 4));
  for (std::size_t i = 0; i < ev.size(); ++i) {
    const double tu = std::nearbyint(ev.t[i] * 1e6);
    if (!(tu >= 0 && tu < 17179869184.0))
      throw Error(path.string(), 0, "event " + std::to_string(i) + " at " + short_number(ev.t[i]) + " s: EVT times lie in [0, 2^34) µs");
    const auto us = static_cast<std::int64_t>(tu);
    const unsigned on = ev.polarity[i] > 0, x = ev.x[i], yy = ev.y[i];
    if (version == "2.0") {
      if (us >> 6 != high) put(0x80000000u | static_cast<std::uint32_t>((high = us >> 6) & 0x0FFFFFFF), 4);
      put(on << 28 | static_cast<std::uint32_t>(us & 63) << 22 | x << 11 | yy, 4);
      continue;
    }
    const std::int64_t full = us >> 12;
    if (full != high) {
      // Steps of less than half the 12-bit range, so that a reader tells each wrap of the 24-bit time.
      while (high >= 0 && full - high >= 0x800) put(0x8000u | ((high += 0x7FF) & 0xFFF), 2);
      put(0x8000u | ((high = full) & 0xFFF), 2);
      low = -1;
    }
    if ((us & 0xFFF) != low) put(0x6000u | static_cast<unsigned>(low = us & 0xFFF), 2);
    if (static_cast<int>(yy) != y) put(yy, 2), y = static_cast<int>(yy);
    put(0x2000u | on << 11 | x, 2);
  }
  write_file_atomic(path, out);
  write_calibration_and_poses_beside(path, d);
}

/// The formats' entries in io::formats(): an EVT 2.0 file is written for an output ending in .evt2.raw, EVT 3.0
/// (what today's sensors write) for any other .raw.
inline Format evt2_format() {
  return {"evt2",
          false,
          "a Prophesee .raw file in EVT 2.0 (Gen3 and older sensors; '% evt 2.0' in its header)",
          [](const std::filesystem::path& p) { return is_prophesee(p, "evt 2.0"); },
          &load_prophesee,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions&) { write_prophesee_raw(p, d, "2.0"); },
          {".evt2.raw"}};
}
inline Format evt3_format() {
  return {"evt3",
          false,
          "a Prophesee .raw file in EVT 3.0 (IMX636, Gen4, GenX320; '% evt 3.0' in its header)",
          [](const std::filesystem::path& p) { return is_prophesee(p, "evt 3.0+"); },
          &load_prophesee,
          [](const std::filesystem::path& p, const Dataset& d, const WriteOptions&) { write_prophesee_raw(p, d, "3.0"); },
          {".raw"}};
}
inline Format dat_format() {
  return {"dat", false, "a Prophesee .dat file of CD events ('%' header lines, then 8-byte records)",
          [](const std::filesystem::path& p) { return is_prophesee(p, "dat"); }, &load_prophesee};
}

}  // namespace evnerf::io
