// Data-parallel steps: shards summed across processes equal one process computing both, and the
// gradient exchange (dense, sparse, auto).
#include <barrier>
#include <bit>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <variant>
#include <thread>
#include <tuple>

#include <sys/resource.h>

#include <evnerf/sim/simulator.hpp>
#include <evnerf/train/trainer.hpp>
#include <evnerf/model/variants.hpp>

#include "common.hpp"
#include "tiny_models.hpp"

using namespace evnerf;
namespace fs = std::filesystem;
using evtest::Fixture;

TEST_CASE("data-parallel steps: two processes' shards, summed, equal one process computing both, bit for bit") {
  Fixture f;
  const auto box = train::scene_box(f.td, f.cfg);
  // One process, two shards per step; and the two halves of the same step as two processes would compute
  // them: rank 1's gradients are taken first (its own step is discarded), rank 0 adds them as the exchange.
  TinyWindow one(f.td.slices.size(), box, 7), r0(f.td.slices.size(), box, 7), r1;
  std::vector<float> g1;
  std::vector<double> t1;
  for (int s = 0; s < 5; ++s) {
    r1.deserialize(r0.serialize("tiny", {}), "mem");
    r1.train_step(f.td, 128, 3, 0, StepShards{2, 1, 2}, [&](std::vector<float>& g, std::vector<double>& t) { g1 = g, t1 = t; });
    const auto a = one.train_step(f.td, 128, 3, 0, StepShards{2, 0, 1}, [](std::vector<float>&, std::vector<double>&) {});
    const auto b = r0.train_step(f.td, 128, 3, 0, StepShards{2, 0, 2}, [&](std::vector<float>& g, std::vector<double>& t) {
      REQUIRE(g.size() == g1.size());
      for (std::size_t i = 0; i < g.size(); ++i) g[i] += g1[i];
      for (std::size_t i = 0; i < t.size(); ++i) t[i] += t1[i];
    });
    CHECK(a.loss == b.loss);
    CHECK(a.rays == b.rays);
    CHECK(a.rays == 2 * 2 * 128);
    REQUIRE(one.params().values == r0.params().values);
  }
  // A second shard is another draw: a two-shard step is not the one-shard step, and its loss is the mean.
  TinyWindow single(f.td.slices.size(), box, 7), two(f.td.slices.size(), box, 7);
  const auto s1 = single.gradients(f.td, 128, 3, 0, 0);
  const auto s2 = single.gradients(f.td, 128, 3, 0, 1);
  const auto both = two.train_step(f.td, 128, 3, 0, StepShards{2, 0, 1}, [](std::vector<float>&, std::vector<double>&) {});
  CHECK(both.loss == doctest::Approx(0.5 * (s1.loss + s2.loss)).epsilon(1e-12));
  CHECK(s1.loss != s2.loss);
  // One shard through the data-parallel path is the plain step.
  TinyWindow plain(f.td.slices.size(), box, 7), path(f.td.slices.size(), box, 7);
  for (int s = 0; s < 3; ++s) {
    plain.train_step(f.td, 128, 3);
    path.train_step(f.td, 128, 3, 0, StepShards{}, [](std::vector<float>&, std::vector<double>&) {});
  }
  CHECK(plain.params().values == path.params().values);
  CHECK_THROWS_WITH(path.train_step(f.td, 128, 3, 0, StepShards{3, 0, 2}, [](std::vector<float>&, std::vector<double>&) {}),
                    doctest::Contains("shards per step (3) must be a positive multiple of the processes (2)"));
}

namespace {
// Two threads as a train::Group (each thread one rank), for testing the exchange without MPI: every
// collective meets at a barrier and combines rank 0's buffer with rank 1's in that order.
struct Pair {
  std::barrier<> meet{2};
  const void* buf[2] = {nullptr, nullptr};
};
class ThreadGroup final : public train::Group {
 public:
  ThreadGroup(Pair& p, int rank) : p_(p), rank_(rank) {}
  int rank() const override { return rank_; }
  int size() const override { return 2; }
  void sum(float* x, std::size_t n) override {
    all(x, n, [](float a, float b) { return a + b; });
  }
  void sum(double* x, std::size_t n) override {
    all(x, n, [](double a, double b) { return a + b; });
  }
  void bit_or(std::uint64_t* x, std::size_t n) override {
    all(x, n, [](std::uint64_t a, std::uint64_t b) { return a | b; });
  }
  void broadcast(std::string& bytes) override {
    all(&bytes, 1, [](const std::string& a, const std::string&) { return a; });
  }
  [[noreturn]] void abort(const std::string& m, int) override { throw std::runtime_error(m); }

 private:
  template <class T, class Op>
  void all(T* x, std::size_t n, Op op) {
    p_.buf[rank_] = x;
    p_.meet.arrive_and_wait();
    const T* a = static_cast<const T*>(p_.buf[0]);
    const T* b = static_cast<const T*>(p_.buf[1]);
    std::vector<T> r(n);
    for (std::size_t i = 0; i < n; ++i) r[i] = op(a[i], b[i]);
    p_.meet.arrive_and_wait();
    std::copy(r.begin(), r.end(), x);
    p_.meet.arrive_and_wait();
  }
  Pair& p_;
  int rank_;
};
}  // namespace

TEST_CASE("gradient exchange: dense, sparse and auto give the same sums, sparse sends only the touched blocks") {
  constexpr std::size_t n = 16 * 40 + 5;  // a partial last block
  auto grads_of = [&](int rank) {
    std::vector<float> g(n, 0.0f);
    for (std::size_t i = 0; i < n; ++i)
      if ((rank == 0 && (i < 40 || i + 3 >= n)) || (rank == 1 && i >= 100 && i < 130)) g[i] = 0.25f * float(i % 7) + float(rank) + 0.5f;
    return g;
  };
  std::vector<float> expect(n);
  for (std::size_t i = 0; i < n; ++i) expect[i] = grads_of(0)[i] + grads_of(1)[i];
  for (auto mode : {train::Exchange::Dense, train::Exchange::Sparse, train::Exchange::Auto}) {
    CAPTURE(int(mode));
    Pair p;
    std::vector<float> got[2];
    std::vector<double> totals[2];
    double bytes[2] = {0, 0};
    long sparse[2] = {0, 0};
    bool same[2] = {false, false}, differ[2] = {true, true};
    auto work = [&](int rank) {
      ThreadGroup g(p, rank);
      train::GradientExchange ex(&g, mode);
      got[rank] = grads_of(rank);
      totals[rank] = {1.0 + rank, 10.0 * rank};
      ex(got[rank], totals[rank]);
      bytes[rank] = ex.bytes();
      sparse[rank] = ex.sparse_steps();
      same[rank] = g.same(42);
      differ[rank] = g.same(std::uint64_t(rank));
    };
    std::thread t1(work, 1);
    work(0);
    t1.join();
    for (int r = 0; r < 2; ++r) {
      CHECK(got[r] == expect);
      CHECK(totals[r] == std::vector<double>{3.0, 10.0});
      CHECK(same[r]);
      CHECK_FALSE(differ[r]);  // every rank learns that the values differ
    }
    // Touched blocks: 0..2 and the partial last one (40) of rank 0, 6..8 of rank 1: 7 of 41 blocks.
    const double bitmap = 8, sparse_bytes = 2 * 8 + bitmap + 7 * 16 * 4, dense_bytes = 2 * 8 + double(n) * 4;
    CHECK(bytes[0] == (mode == train::Exchange::Dense ? dense_bytes : sparse_bytes));
    CHECK(sparse[0] == (mode == train::Exchange::Dense ? 0 : 1));
  }
}
