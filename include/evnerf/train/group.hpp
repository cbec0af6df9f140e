// train/group.hpp — the processes of a data-parallel training run, as the trainer sees them: a Group sums
// buffers across its processes, ORs bitmaps, broadcasts rank 0's bytes and stops them all. dist/mpi.hpp
// implements it on MPI; the trainer needs nothing else of MPI, so a program without MPI compiles this. Also
// GradientExchange, the per-step sum of the gradients (the whole buffer, or only the blocks some process
// touched). Depends on core/ only.
#pragma once
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "../core/error.hpp"

namespace evnerf::train {

/// The processes of one data-parallel run. Every call is collective: every process makes the same calls in
/// the same order, and each returns when all have made it. A process that dies or throws must not leave
/// the others waiting: implementations stop the whole group (abort) rather than return an error.
class Group {
 public:
  virtual ~Group() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Processes of the group on this machine (they share its cores).
  virtual int local_size() const { return 1; }
  /// Element-wise sums over the processes, in place; every process gets the same bits.
  virtual void sum(float* x, std::size_t n) = 0;
  virtual void sum(double* x, std::size_t n) = 0;
  /// Element-wise bitwise OR over the processes, in place.
  virtual void bit_or(std::uint64_t* x, std::size_t n) = 0;
  /// Rank 0's `bytes` on every process.
  virtual void broadcast(std::string& bytes) = 0;
  /// Ends every process of the group with `code` (after `message` on standard error); never returns.
  [[noreturn]] virtual void abort(const std::string& message, int code) = 0;

  /// Whether every process holds the same `value` (each process learns it: a differing value is seen by
  /// every process, since a value that differs from another's differs from their OR or its complement's).
  bool same(std::uint64_t value) {
    std::uint64_t v[2] = {value, ~value};
    bit_or(v, 2);
    return v[0] == value && v[1] == ~value;
  }
};

/// How a step's gradients travel: the whole buffer, only the blocks of kBlock values that some process
/// touched (a bitmap of blocks first, then the union's values), or whichever is fewer bytes this step.
enum class Exchange { Auto, Dense, Sparse };

/// The per-step sum of a data-parallel step (EvNerf::train_step's `exchange`): first the statistics and
/// slice counts (doubles), then the gradients. Sparse: a block of kBlock values travels when it is non-zero
/// on some process; every other block is zero on every process, so the result is the dense sum's, bit for
/// bit. Counts what it sent.
class GradientExchange {
 public:
  static constexpr std::size_t kBlock = 16;  ///< values per block: 64 bytes of float, a cache line

  /// A null group: one process, nothing to sum.
  GradientExchange(Group* g, Exchange mode) : g_(g), mode_(mode) {}

  template <class Scalar>
  void operator()(std::vector<Scalar>& grads, std::vector<double>& totals) {
    if (!g_) return;
    const auto t0 = std::chrono::steady_clock::now();
    g_->sum(totals.data(), totals.size());
    bytes_ += totals.size() * sizeof(double);
    const std::size_t n = grads.size(), blocks = (n + kBlock - 1) / kBlock;
    bool sparse = false;
    if (mode_ != Exchange::Dense) {
      bits_.assign((blocks + 63) / 64, 0);
      for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t e = std::min(n, (b + 1) * kBlock);
        for (std::size_t i = b * kBlock; i < e; ++i)
          if (grads[i] != Scalar(0)) {
            bits_[b / 64] |= std::uint64_t{1} << (b % 64);
            break;
          }
      }
      g_->bit_or(bits_.data(), bits_.size());
      bytes_ += bits_.size() * sizeof(std::uint64_t);
      std::size_t used = 0;
      for (auto w : bits_) used += static_cast<std::size_t>(__builtin_popcountll(w));
      last_fraction_ = blocks ? double(used) / double(blocks) : 0.0;
      // Auto: the union's values when they are fewer bytes than the whole buffer (the bitmap is already paid).
      sparse = mode_ == Exchange::Sparse || used * kBlock < n;
      if (sparse) {
        auto& packed = buffer<Scalar>();
        packed.resize(used * kBlock);
        std::size_t o = 0;
        for_each_block([&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i, ++o) packed[o] = i < n ? grads[i] : Scalar(0);
        });
        g_->sum(packed.data(), packed.size());
        o = 0;
        for_each_block([&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i, ++o)
            if (i < n) grads[i] = packed[o];
        });
        bytes_ += used * kBlock * sizeof(Scalar);
      }
    }
    if (!sparse) {
      g_->sum(grads.data(), n);
      bytes_ += n * sizeof(Scalar);
    }
    ++steps_;
    sparse_steps_ += sparse ? 1 : 0;
    seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// Totals since the last reset(): bytes this process sent into the sums (each buffer counted once, as
  /// a message size; an allreduce moves about twice that over the wire), seconds in the exchange, steps and
  /// how many of them went sparse, and the last step's fraction of blocks in the union.
  double bytes() const { return double(bytes_); }
  double seconds() const { return seconds_; }
  long steps() const { return steps_; }
  long sparse_steps() const { return sparse_steps_; }
  double last_fraction() const { return last_fraction_; }
  void reset() { bytes_ = 0, seconds_ = 0, steps_ = sparse_steps_ = 0; }

 private:
  template <class F>
  void for_each_block(F&& f) const {
    for (std::size_t w = 0; w < bits_.size(); ++w)
      for (std::uint64_t m = bits_[w]; m; m &= m - 1) {
        const std::size_t b = w * 64 + static_cast<std::size_t>(__builtin_ctzll(m));
        f(b * kBlock, (b + 1) * kBlock);
      }
  }
  template <class Scalar>
  std::vector<Scalar>& buffer() {
    if constexpr (std::is_same_v<Scalar, float>) return packed_f_;
    else return packed_d_;
  }

  Group* g_;
  Exchange mode_;
  std::vector<std::uint64_t> bits_;
  std::vector<float> packed_f_;
  std::vector<double> packed_d_;
  std::size_t bytes_ = 0;
  double seconds_ = 0, last_fraction_ = 0;
  long steps_ = 0, sparse_steps_ = 0;
};

}  // namespace evnerf::train
