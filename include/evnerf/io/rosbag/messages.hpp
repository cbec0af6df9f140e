// io/rosbag/messages.hpp — ROS messages decoded from their definition text (io/rosbag.hpp), not from
// compiled-in layouts: the definition parsed into types and fields (MsgSchema), a cursor over a message's
// bytes that skips or reads fields by name (numbers, times, strings, arrays), and the layout of an event
// array (EventLayout: any array `events` of fixed-size structs with integer x, y, a time ts and a boolean or
// integer polarity). Depends on io/rosbag/records.hpp.
#pragma once
#include "records.hpp"

namespace evnerf::io::detail {

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

}  // namespace evnerf::io::detail
