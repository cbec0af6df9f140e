// core/parallel.hpp — thread count control and a deterministic parallel_for over blocks (OpenMP, static).
// Depends on the standard library and OpenMP only.
#pragma once
#include <algorithm>
#include <cstddef>
#include <omp.h>
#include <vector>

namespace evnerf {

/// Number of threads evnerf uses (defaults to OpenMP's). Set once at start-up.
inline int& thread_count_ref() {
  static int n = omp_get_max_threads();
  return n;
}
inline int thread_count() { return thread_count_ref(); }
inline void set_thread_count(int n) { thread_count_ref() = std::max(1, n); }
/// Sets the thread count for a scope and restores the caller's on exit (n ≤ 0 leaves it as it is).
class ScopedThreadCount {
 public:
  explicit ScopedThreadCount(int n) : saved_(thread_count()) {
    if (n > 0) set_thread_count(n);
  }
  ~ScopedThreadCount() { set_thread_count(saved_); }
  ScopedThreadCount(const ScopedThreadCount&) = delete;
  ScopedThreadCount& operator=(const ScopedThreadCount&) = delete;

 private:
  int saved_;
};

/// Calls fn(begin, end, thread) for contiguous blocks of [0, n). The split depends only on n, the thread
/// count and `min_per_thread`, so per-thread partial results reduce in a fixed order. Below
/// `min_per_thread` items per thread it runs on fewer threads (threading tiny work makes it slower).
template <class Fn>
void parallel_blocks(std::size_t n, std::size_t min_per_thread, Fn&& fn) {
  const int max_t = thread_count();
  const int t = static_cast<int>(std::clamp<std::size_t>(n / std::max<std::size_t>(1, min_per_thread), 1, static_cast<std::size_t>(max_t)));
  if (t <= 1) {
    fn(std::size_t{0}, n, 0);
    return;
  }
#pragma omp parallel num_threads(t)
  {
    const int id = omp_get_thread_num();
    const std::size_t b = n * id / t, e = n * (id + 1) / t;
    fn(b, e, id);
  }
}

/// Calls fn(j) once for every job j in [0, n), on up to thread_count() threads, each thread a contiguous
/// run of jobs of about equal total cost (cost(j) ≥ 0: a job goes to the thread whose share of the total
/// holds its cost's midpoint). Which thread runs a job depends on n, the costs and the thread count only;
/// meant for jobs that write to memory of their own, whose results then do not depend on it at all.
template <class Cost, class Fn>
void parallel_jobs_by_cost(std::size_t n, Cost&& cost, Fn&& fn) {
  if (n == 0) return;
  const int t = static_cast<int>(std::min<std::size_t>(n, static_cast<std::size_t>(std::max(1, thread_count()))));
  if (t <= 1) {
    for (std::size_t j = 0; j < n; ++j) fn(j);
    return;
  }
  std::vector<double> mid(n);
  double total = 0;
  for (std::size_t j = 0; j < n; ++j) {
    const double c = std::max(0.0, static_cast<double>(cost(j)));
    mid[j] = total + 0.5 * c;
    total += c;
  }
  auto owner = [&](std::size_t j) {
    const double share = total > 0 ? mid[j] / total : (static_cast<double>(j) + 0.5) / static_cast<double>(n);
    return std::min(t - 1, static_cast<int>(share * t));
  };
  parallel_blocks(static_cast<std::size_t>(t), 1, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t id = b; id < e; ++id)
      for (std::size_t j = 0; j < n; ++j)
        if (owner(j) == static_cast<int>(id)) fn(j);
  });
}

/// Elementwise parallel loop: fn(i) for i in [0, n).
template <class Fn>
void parallel_for(std::size_t n, std::size_t min_per_thread, Fn&& fn) {
  parallel_blocks(n, min_per_thread, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t i = b; i < e; ++i) fn(i);
  });
}

}  // namespace evnerf
