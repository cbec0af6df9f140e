// dist/mpi.hpp — train::Group on MPI (MPI_COMM_WORLD), for data-parallel training with `mpirun -np N`.
// Only a program that includes this header needs MPI (CMake: EVNERF_MPI=ON links MPI::MPI_CXX); the
// trainer sees the train::Group interface. Depends on train/group.hpp and <mpi.h>.
#pragma once
#include <mpi.h>

#include <climits>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "../train/group.hpp"

namespace evnerf::dist {

/// Whether this process was started by an MPI launcher (mpirun, mpiexec, srun with PMI/PMIx): only then
/// does MpiGroup initialise MPI, so that the same program run on its own starts no MPI runtime at all.
inline bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "PMI_RANK", "MPI_LOCALNRANKS"})
    if (std::getenv(v)) return true;
  return false;
}

/// MPI_COMM_WORLD as a train::Group: MPI is initialised by the constructor (when launched_by_mpi(), else
/// the group is this process alone) and finalised by the destructor. Errors of MPI calls are fatal to
/// the whole job (MPI's default handler), and a process that dies makes the launcher end the others, so
/// no process waits forever on a dead one.
class MpiGroup final : public train::Group {
 public:
  MpiGroup(int& argc, char**& argv) {
    if (!launched_by_mpi()) return;
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    active_ = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    MPI_Comm local;
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local);
    MPI_Comm_size(local, &local_size_);
    MPI_Comm_free(&local);
  }
  ~MpiGroup() override {
    if (active_) MPI_Finalize();
  }
  MpiGroup(const MpiGroup&) = delete;
  MpiGroup& operator=(const MpiGroup&) = delete;

  int rank() const override { return rank_; }
  int size() const override { return size_; }
  int local_size() const override { return local_size_; }

  void sum(float* x, std::size_t n) override { reduce(x, n, MPI_FLOAT, MPI_SUM); }
  void sum(double* x, std::size_t n) override { reduce(x, n, MPI_DOUBLE, MPI_SUM); }
  void bit_or(std::uint64_t* x, std::size_t n) override { reduce(x, n, MPI_UINT64_T, MPI_BOR); }
  void broadcast(std::string& bytes) override {
    if (size_ == 1) return;
    unsigned long long n = bytes.size();
    MPI_Bcast(&n, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
    bytes.resize(static_cast<std::size_t>(n));
    for (std::size_t o = 0; o < n; o += kChunk)
      MPI_Bcast(bytes.data() + o, static_cast<int>(std::min<std::size_t>(kChunk, n - o)), MPI_BYTE, 0, MPI_COMM_WORLD);
  }
  [[noreturn]] void abort(const std::string& message, int code) override {
    std::fprintf(stderr, "%s\n", message.c_str());
    std::fflush(stderr);
    if (active_) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
  }

 private:
  static constexpr std::size_t kChunk = std::size_t{1} << 30;  ///< MPI counts are ints: long buffers go in parts
  template <class T>
  void reduce(T* x, std::size_t n, MPI_Datatype type, MPI_Op op) {
    if (size_ == 1) return;
    for (std::size_t o = 0; o < n; o += kChunk)
      MPI_Allreduce(MPI_IN_PLACE, x + o, static_cast<int>(std::min<std::size_t>(kChunk, n - o)), type, op, MPI_COMM_WORLD);
  }
  bool active_ = false;
  int rank_ = 0, size_ = 1, local_size_ = 1;
};

}  // namespace evnerf::dist
