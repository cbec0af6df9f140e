// train/settings.hpp — the training settings, each declared once: train::Config holds them for a run, and
// the table settings() names each one (its name is the command line's --flag with dashes for underscores,
// the Python module's keyword and settings.json's key), says where it lives in Config, which values it
// allows and what it does in one line. The command line's flags and --help, the Python keywords, check()
// and settings.json all come from the table: a new setting is one member and one row.
// Depends on core/, nn/params.hpp (Adam's defaults) and train/group.hpp (nlohmann::json for settings.json).
#pragma once
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "../core/error.hpp"
#include "../nn/params.hpp"
#include "group.hpp"

namespace evnerf::train {

/// Everything a training run is given that does not change the computation's shape (the variant's type
/// does that). These defaults are the library's, the command line's and the Python module's alike (spec §9;
/// Adam's are nn::AdamConfig's, whose lr 5e-3 the hash-grid presets want; pass 5e-4 for the paper's). Each
/// member is a row of settings() but `progress` and `group`, which say how a run is shown and where it runs.
struct Config {
  long iterations = 6000;
  int pixels = 1024;
  std::uint64_t seed = 1;
  int threads = 0;
  double near = 0.3, far = 7.0;
  double lr = nn::AdamConfig{}.lr, lr_decay = nn::AdamConfig{}.decay, lr_decay_steps = nn::AdamConfig{}.decay_steps;
  std::optional<double> tv;  ///< unset: the variant's own weight
  double average = 0.998;
  long checkpoint_every = 500;
  int subslices = 1;
  int holdout = 0;
  bool clamp_poses = false;
  bool keep_hot_pixels = false;
  std::optional<double> refractory;  ///< unset: learned with the field, downward from the recording's bound; given: that period, fixed
  bool density_per_box = false;
  std::optional<double> background;  ///< unset: no background (the last sample stops every ray)
  bool learn_background = true;      ///< a backdrop of unknown brightness, learned with the field (unless `background` is given)
  bool refine_poses = false;         ///< a correction per pose knot, learned with the field (model/poses.hpp)
  double pose_lr_rotation = 5e-4, pose_lr_translation = 2e-4;
  bool learn_time_offset = false;  ///< the clock offset between the events and the poses, learned
  double time_offset_lr = 2e-4;
  double pose_lr_decay_steps = 6000;
  int pose_levels = 8;
  long pose_start = 1000;
  double pose_prior_rotation = 10, pose_prior_translation = 10;
  long collapse_check_every = 250, collapse_check_from = 500;
  bool allow_collapse = false;
  int shards = 0;
  Exchange exchange = Exchange::Auto;
  bool progress = true;
  Group* group = nullptr;  ///< the processes of a data-parallel run (dist/mpi.hpp's MpiGroup; null: this one)
  /// The shards per step this Config gives.
  int shard_count() const { return shards > 0 ? shards : group ? group->size() : 1; }
  /// `group` when it has several processes (one process alone needs no sums), else null.
  Group* processes() const { return group && group->size() > 1 ? group : nullptr; }
};

/// How `exchange` is spelt.
inline const char* exchange_name(Exchange e) { return e == Exchange::Dense ? "dense" : e == Exchange::Sparse ? "sparse" : "auto"; }
inline Exchange parse_exchange(std::string_view s, const std::string& who) {
  for (auto e : {Exchange::Auto, Exchange::Dense, Exchange::Sparse})
    if (s == exchange_name(e)) return e;
  throw Error(who + ": exchange must be auto, dense or sparse, got '" + std::string(s) + "'");
}

/// One row of the table: a setting's name, its member of Config, the values it allows (an interval for
/// numbers, open or closed at either end; flags and the exchange take any of theirs) and its help line.
struct Setting {
  using Member = std::variant<long Config::*, int Config::*, std::uint64_t Config::*, double Config::*, std::optional<double> Config::*,
                              bool Config::*, Exchange Config::*>;
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  const char* name;
  Member member;
  double lo = -kInf, hi = kInf;
  bool lo_open = false, hi_open = false;
  const char* help = "";

  /// The command line's flag: --name with dashes.
  std::string flag() const {
    std::string f = "--";
    for (const char* c = name; *c; ++c) f += *c == '_' ? '-' : *c;
    return f;
  }
  bool numeric() const { return !std::holds_alternative<bool Config::*>(member) && !std::holds_alternative<Exchange Config::*>(member); }
  bool integral() const {
    return std::holds_alternative<long Config::*>(member) || std::holds_alternative<int Config::*>(member) ||
           std::holds_alternative<std::uint64_t Config::*>(member);
  }
  /// Whether a number is allowed (finite and inside the interval).
  bool allows(double v) const { return std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi); }
  /// The interval as words: "> 0", ">= 0", "in [1, 64]", "in [0, 1)", "any" (for --help and errors).
  std::string range_text() const {
    auto num = [](double x) { return short_number(x); };
    if (lo == -kInf && hi == kInf) return "any";
    if (hi == kInf) return std::string(lo_open ? "> " : ">= ") + num(lo);
    if (lo == -kInf) return std::string(hi_open ? "< " : "<= ") + num(hi);
    return std::string("in ") + (lo_open ? "(" : "[") + num(lo) + ", " + num(hi) + (hi_open ? ")" : "]");
  }
  /// The setting's value in `c` as settings.json records it (null: an unset optional).
  nlohmann::json get(const Config& c) const {
    return std::visit(
        [&](auto m) -> nlohmann::json {
          const auto& v = c.*m;
          using V = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<V, std::optional<double>>) return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
          else if constexpr (std::is_same_v<V, Exchange>) return exchange_name(v);
          else return v;
        },
        member);
  }
  /// The number a numeric setting holds in `c` (NaN for an unset optional, which check() lets pass).
  double number(const Config& c) const {
    return std::visit(
        [&](auto m) -> double {
          const auto& v = c.*m;
          using V = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<V, std::optional<double>>) return v ? *v : std::nan("");
          else if constexpr (std::is_same_v<V, Exchange> || std::is_same_v<V, bool>) return 0;
          else return static_cast<double>(v);
        },
        member);
  }
  /// Sets the setting in `c` from JSON (settings.json's value, or a Python keyword's through JSON); an
  /// Error naming `who` and the setting when the value has the wrong type.
  void set(Config& c, const nlohmann::json& j, const std::string& who) const {
    auto wrong = [&](const char* want) { return Error(who + ": " + name + " must be " + want + ", got " + j.dump()); };
    std::visit(
        [&](auto m) {
          auto& v = c.*m;
          using V = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<V, std::optional<double>>) {
            if (j.is_null()) v.reset();
            else if (j.is_number()) v = j.get<double>();
            else throw wrong("a number (or None)");
          } else if constexpr (std::is_same_v<V, Exchange>) {
            if (!j.is_string()) throw wrong("auto, dense or sparse");
            v = parse_exchange(j.get<std::string>(), who);
          } else if constexpr (std::is_same_v<V, bool>) {
            if (!j.is_boolean()) throw wrong("true or false");
            v = j.get<bool>();
          } else if constexpr (std::is_same_v<V, double>) {
            if (!j.is_number()) throw wrong("a number");
            v = j.get<double>();
          } else {
            if (!j.is_number_integer() || (std::is_unsigned_v<V> && !j.is_number_unsigned() && j.get<long long>() < 0))
              throw wrong("an integer");
            v = j.get<V>();
          }
        },
        member);
  }
};

/// The training settings, in the order --help lists them.
inline const std::vector<Setting>& settings() {
  using S = Setting;
  constexpr double inf = S::kInf;
  static const std::vector<Setting> rows = {
      {"iterations", &Config::iterations, 0, inf, true, false, "training steps in total"},
      {"pixels", &Config::pixels, 1, 1 << 22, false, false, "pixels per step, each rendered at its window's two ends"},
      {"seed", &Config::seed, 0, inf, false, false, "random seed (initialisation, windows, pixels, noise, samples)"},
      {"threads", &Config::threads, 0, 4096, false, false, "threads (0 = all)"},
      {"near", &Config::near, 0, inf, true, false, "nearest sample depth (world units)"},
      {"far", &Config::far, 0, inf, true, false, "farthest sample depth (world units), beyond near"},
      {"lr", &Config::lr, 0, inf, true, false, "Adam's learning rate (the paper's model wants 5e-4)"},
      {"lr_decay", &Config::lr_decay, 0, 1, true, false, "the factor the learning rate decays by over lr_decay_steps"},
      {"lr_decay_steps", &Config::lr_decay_steps, 0, inf, true, false, "steps over which the learning rate decays by lr_decay"},
      {"tv", &Config::tv, 0, inf, false, false,
       "weight of the variant's total-variation term on neighbouring pixels' log-luminance (0 = off; unset: the variant's, fast 0.1)"},
      {"average", &Config::average, 0, 1, false, true,
       "decay of the moving average of the parameters the model renders with (0 = off: the trained parameters)"},
      {"checkpoint_every", &Config::checkpoint_every, 0, inf, false, false, "steps between checkpoints (0: only at the end)"},
      {"subslices", &Config::subslices, 1, 64, false, false,
       "slices per frame interval (boundaries between frames, poses interpolated); windows keep their span in time"},
      {"holdout", &Config::holdout, 0, inf, false, false, "hold out every k-th slice boundary from training (novel views; 0 = none)"},
      {"clamp_poses", &Config::clamp_poses, -inf, inf, false, false, "slice boundaries outside the poses take the nearest pose"},
      {"keep_hot_pixels", &Config::keep_hot_pixels, -inf, inf, false, false,
       "draw the suspected hot pixels too (pixels firing far above their neighbours, as inspect lists them; left out by default)"},
      {"refractory", &Config::refractory, 0, 0.005, false, false,
       "the sensor's refractory period in seconds, fixed (unset: learned with the field, downward from the 0.5 % quantile of the "
       "pixels' intervals between events, which bounds it): an event that came d after the "
       "pixel's previous one stands for d / (d - period) thresholds, and one within 1.5 periods makes its count a lower bound "
       "(0 = counts read as they are)"},
      {"density_per_box", &Config::density_per_box, -inf, inf, false, false,
       "density per unit of the normalised scene box, not per world unit"},
      {"background", &Config::background, 0, inf, false, false,
       "luminance of a backdrop behind the scene, in the frames' linear units, where rays pass all samples unstopped "
       "(an object before a plain background of known brightness; unset: none, the last sample stops every ray)"},
      {"learn_background", &Config::learn_background, -inf, inf, false, false,
       "a backdrop behind the scene whose brightness (one per channel) is learned with the field, where rays pass all samples "
       "unstopped (an object before a plain background of unknown brightness; on by default; --background gives a known one "
       "instead; off: the last sample stops every ray)"},
      {"refine_poses", &Config::refine_poses, -inf, inf, false, false,
       "learn a rigid correction of the pose at every slice boundary with the field (poses only roughly known); the first "
       "boundary's is held, which fixes the scene's frame"},
      {"pose_lr_rotation", &Config::pose_lr_rotation, 0, inf, false, false,
       "Adam's step size for the pose corrections' rotations (radians)"},
      {"pose_lr_translation", &Config::pose_lr_translation, 0, inf, false, false,
       "Adam's step size for the pose corrections' translations (world units)"},
      {"learn_time_offset", &Config::learn_time_offset, -inf, inf, false, false,
       "learn the clock offset between the events and the poses (a boundary at time t takes the poses' pose at t + offset)"},
      {"time_offset_lr", &Config::time_offset_lr, 0, inf, false, false, "Adam's step size for the clock offset (seconds)"},
      {"pose_lr_decay_steps", &Config::pose_lr_decay_steps, 0, inf, true, false,
       "steps over which the pose and offset step sizes fall to a hundredth (then they stay)"},
      {"pose_start", &Config::pose_start, 0, inf, false, false, "steps the field trains on the given poses before they move"},
      {"pose_levels", &Config::pose_levels, 0, 64, false, false,
       "hash-grid levels the pose gradient goes through, the coarsest first (0 = all)"},
      {"pose_prior_rotation", &Config::pose_prior_rotation, 0, inf, false, false,
       "weight of the pull of each pose correction's rotation toward the given pose: a step's loss holds weight/2 · |rotation "
       "vector|² (radians) for every boundary it renders from"},
      {"pose_prior_translation", &Config::pose_prior_translation, 0, inf, false, false,
       "weight of the pull of each pose correction's translation toward the given pose: a step's loss holds weight/2 · "
       "|translation|² (world units) for every boundary it renders from"},
      {"collapse_check_every", &Config::collapse_check_every, 0, inf, false, false,
       "steps between collapse checks (renders almost constant, or the event loss not falling; a multiple of 50; 0 = never)"},
      {"collapse_check_from", &Config::collapse_check_from, 0, inf, false, false, "the first step of a collapse check (a multiple of 50)"},
      {"allow_collapse", &Config::allow_collapse, -inf, inf, false, false, "go on when a collapse check fires"},
      {"shards", &Config::shards, 0, 4096, false, false,
       "shards per step, each its own window and pixels, gradients averaged (0: one per MPI process); one process with N computes "
       "what N processes compute"},
      {"exchange", &Config::exchange, -inf, inf, false, false,
       "how processes sum gradients: dense (the whole buffer), sparse (the blocks some process touched), auto (the fewer bytes)"},
  };
  return rows;
}

/// Adam's settings a Config gives (the learning rate and its decay; β and ε are nn::AdamConfig's).
inline nn::AdamConfig adam_config(const Config& cfg) {
  nn::AdamConfig ac;
  ac.lr = cfg.lr;
  ac.decay = cfg.lr_decay;
  ac.decay_steps = cfg.lr_decay_steps;
  return ac;
}

/// The row called `name`; an Error naming `who` and every setting when there is none.
inline const Setting& setting(std::string_view name, const std::string& who) {
  for (const auto& s : settings())
    if (name == s.name) return s;
  std::string known;
  for (const auto& s : settings()) known.append(known.empty() ? "" : ", ").append(s.name);
  throw Error(who + ": unknown setting '" + std::string(name) + "' (known: " + known + ")");
}

/// Refuses settings no run can use, naming the setting: every number inside its row's interval, far beyond
/// near, the shards a multiple of the processes. train::run calls it.
inline void check(const Config& c) {
  for (const auto& s : settings()) {
    if (!s.numeric()) continue;
    if (const auto* o = std::get_if<std::optional<double> Config::*>(&s.member); o && !(c.**o)) continue;  // unset: the variant's
    const double v = s.number(c);
    if (!s.allows(v)) throw Error("train: " + std::string(s.name) + " must be " + s.range_text() + ", got " + short_number(v));
  }
  if (!(c.far > c.near))
    throw Error("train: far must be greater than near, got near " + short_number(c.near) + " and far " + short_number(c.far));
  if (c.group && c.shard_count() % c.group->size() != 0)
    throw Error("train: the shards per step (" + std::to_string(c.shard_count()) + ") must be a multiple of the processes (" +
                std::to_string(c.group->size()) + ")");
}

/// Every setting of `c` as JSON, as `out/settings.json` records it: each row under its name (the shards as
/// the count a step has), and the processes the run had.
inline nlohmann::json settings_json(const Config& c) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& s : settings()) j[s.name] = s.get(c);
  j["shards"] = c.shard_count();
  j["processes"] = c.group ? c.group->size() : 1;
  return j;
}

/// The Config a settings.json entry (settings_json's object) describes: every setting it names, the rest at
/// their defaults; an Error naming `who` for a key that is no setting or a value of the wrong type.
inline Config config_from_json(const nlohmann::json& j, const std::string& who) {
  require(j.is_object(), who + ": the settings are not a JSON object");
  Config c;
  for (const auto& [key, value] : j.items()) {
    if (key == "processes" || key == "from_step") continue;
    setting(key, who).set(c, value, who);
  }
  return c;
}

}  // namespace evnerf::train
