// core/rng.hpp — seedable, counter-based random numbers: the same (seed, stream, counter) gives the same
// value on every thread count. Depends on the standard library only.
#pragma once
#include <cmath>
#include <cstdint>

namespace evnerf {

/// SplitMix64 finaliser: a bijective 64-bit mixer.
constexpr std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// The top 53 bits of `bits` as a double uniform in [0, 1) (for hashed, keyed draws; Rng::uniform's map).
constexpr double unit_double(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

/// Counter-based generator. Derive independent streams with `split(k)`; each draw advances a counter,
/// so a stream's sequence depends only on its seed, never on scheduling.
class Rng {
 public:
  explicit constexpr Rng(std::uint64_t seed = 0) : key_(mix64(seed ^ 0x5EEDull)) {}
  constexpr Rng split(std::uint64_t stream) const { return Rng(key_, mix64(stream + 0x1234567ull)); }

  constexpr std::uint64_t next_u64() { return mix64(key_ ^ mix64(counter_++)); }
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return unit_double(next_u64()); }
  float uniformf() { return static_cast<float>(next_u64() >> 40) * 0x1.0p-24f; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [0, n) (Lemire's multiply-shift; bias < 2^-32 for n < 2^32).
  std::uint64_t below(std::uint64_t n) {
    __extension__ using u128 = unsigned __int128;
    return static_cast<std::uint64_t>((static_cast<u128>(next_u64()) * n) >> 64);
  }
  /// Standard normal (Box–Muller, one value per call: simple and deterministic).
  double normal() {
    double u1 = uniform(), u2 = uniform();
    if (u1 < 1e-300) u1 = 1e-300;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }
  std::uint64_t state() const { return counter_; }
  std::uint64_t key() const { return key_; }
  static constexpr Rng from_state(std::uint64_t key, std::uint64_t counter) { return Rng(key, counter, 0); }

 private:
  constexpr Rng(std::uint64_t key, std::uint64_t stream) : key_(mix64(key ^ stream)) {}
  constexpr Rng(std::uint64_t key, std::uint64_t counter, int) : key_(key), counter_(counter) {}
  std::uint64_t key_;
  std::uint64_t counter_ = 0;
};

}  // namespace evnerf
