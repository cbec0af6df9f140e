// Benchmarks, each beside its reference twin measured in the same run:
//   MLP forward+backward (paper network W=256 and W=64): fused tiles vs the plain reference MLP;
//   one tile's matrix products: the kernel (AVX-512 or AVX2) vs Eigen's product on the same operands;
//   a pure-FMA loop (the machine's FP32 peak); events.txt parsing vs a naive ifstream reader; the .npy
//   event cache; the Fast, Paper and Splat training steps; one Fast 240×180 render; the Gaussian rasterizer's
//   whole 346×260 view (tiles) vs its plain reference (every Gaussian at every pixel), and its training pass.
// bench/run.sh runs this and the PyTorch peer and prints the ratios.
#include <benchmark/benchmark.h>
#include <evnerf/evnerf.hpp>
#include <evnerf/model/presets.hpp>
#include <evnerf/nn/detail/reference.hpp>
#include <evnerf/sim/simulator.hpp>
#include <evnerf/splat/rasterizer.hpp>
#include <evnerf/train/trainer.hpp>

#include <fstream>
#include <immintrin.h>

using namespace evnerf;

namespace {

/// The paper's network without encodings (inputs pre-encoded, as the peer's --mode mlp): trunk
/// 63 → 8×W (skip) → W+1 (density + feature), view branch W+27 → W/2 → 1.
template <int W, class Prec = nn::Fp32>
struct PaperNet {
  using Trunk = nn::Mlp<63, W, 8, W + 1, nn::ReLU, nn::Identity, 4, Prec>;
  using View = nn::Mlp<W + 27, W / 2, 1, 1, nn::ReLU, nn::Identity, -1, Prec>;
  static constexpr std::size_t n_params = Trunk::n_params + View::n_params;
  static constexpr double flops_fwdbwd() {
    // 2 FLOP per MAC forward; backward = dW + dX, except dX of the first layer (as the peer counts).
    const double fwd = 2.0 * (Trunk::macs_per_sample() + View::macs_per_sample());
    return 3 * fwd - 2.0 * 63 * W;
  }
};

/// One thread's buffers for run_fused, kept from call to call as the trainer keeps its workspaces from batch
/// to batch (allocated anew, their pages would be faulted in again on every pass).
template <int W, class Prec>
struct FusedScratch {
  using Net = PaperNet<W, Prec>;
  typename Net::Trunk::template Workspace<float> wt;
  typename Net::View::template Workspace<float> wv;
  std::vector<float> vin, dy, dvin, dtr;
};

template <int W, class Prec>
void run_fused(std::vector<float>& params, const std::vector<float>& xe, const std::vector<float>& de, int n,
               nn::ParameterBuffer<float>& pb, int tile, std::vector<FusedScratch<W, Prec>>& scratch) {
  using Net = PaperNet<W, Prec>;
  const int n_tiles = (n + tile - 1) / tile;
  pb.size_accumulators(thread_count());
  scratch.resize(static_cast<std::size_t>(thread_count()));
  parallel_blocks(static_cast<std::size_t>(n_tiles), 1, [&](std::size_t b, std::size_t e, int th) {
    pb.zero_accumulator(th);  // each thread its own, as the trainer does
    auto& [wt, wv, vin, dy, dvin, dtr] = scratch[static_cast<std::size_t>(th)];
    dy.resize(static_cast<std::size_t>(tile));
    float* g = pb.per_thread[th].data();
    for (std::size_t t = b; t < e; ++t) {
      const int j0 = static_cast<int>(t) * tile, m = std::min(tile, n - j0);
      const float* h = Net::Trunk::forward(params.data(), &xe[static_cast<std::size_t>(j0) * 63], m, wt);
      vin.resize(static_cast<std::size_t>(W + 27) * m);
      for (int j = 0; j < m; ++j) {
        std::copy(h + static_cast<std::size_t>(j) * (W + 1) + 1, h + static_cast<std::size_t>(j + 1) * (W + 1),
                  &vin[static_cast<std::size_t>(j) * (W + 27)]);
        std::copy(&de[static_cast<std::size_t>(j0 + j) * 27], &de[static_cast<std::size_t>(j0 + j) * 27] + 27,
                  &vin[static_cast<std::size_t>(j) * (W + 27) + W]);
      }
      Net::View::forward(params.data() + Net::Trunk::n_params, vin.data(), m, wv);
      std::fill(dy.begin(), dy.end(), 1.f);
      dvin.assign(static_cast<std::size_t>(W + 27) * m, 0.f);
      Net::View::backward(params.data() + Net::Trunk::n_params, wv, dy.data(), g + Net::Trunk::n_params, dvin.data());
      dtr.resize(static_cast<std::size_t>(W + 1) * m);
      for (int j = 0; j < m; ++j) {
        dtr[static_cast<std::size_t>(j) * (W + 1)] = 1.f;  // d(sum of density)
        std::copy(&dvin[static_cast<std::size_t>(j) * (W + 27)], &dvin[static_cast<std::size_t>(j) * (W + 27)] + W,
                  &dtr[static_cast<std::size_t>(j) * (W + 1) + 1]);
      }
      Net::Trunk::backward(params.data(), wt, dtr.data(), g, static_cast<float*>(nullptr));
    }
  });
  pb.end_accumulate(std::min(n_tiles, thread_count()));  // the threads parallel_blocks used
}

template <int W, class Prec = nn::Fp32>
void BM_mlp_fused(benchmark::State& st) {
  using Net = PaperNet<W, Prec>;
  const int n = static_cast<int>(st.range(0));
  Rng rng(1);
  std::vector<float> params(Net::n_params), xe(static_cast<std::size_t>(n) * 63), de(static_cast<std::size_t>(n) * 27);
  Net::Trunk::init(params.data(), rng);
  Net::View::init(params.data() + Net::Trunk::n_params, rng);
  for (auto& v : xe) v = rng.uniformf() * 2 - 1;
  for (auto& v : de) v = rng.uniformf() * 2 - 1;
  nn::ParameterBuffer<float> pb(Net::n_params);
  std::vector<FusedScratch<W, Prec>> scratch;
  run_fused<W, Prec>(params, xe, de, n, pb, static_cast<int>(st.range(1)), scratch);  // warm-up, untimed (as the peer's)
  for (auto _ : st) run_fused<W, Prec>(params, xe, de, n, pb, static_cast<int>(st.range(1)), scratch);
  st.counters["samples_per_s"] = benchmark::Counter(double(n), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["gflops"] = benchmark::Counter(n * Net::flops_fwdbwd() / 1e9, benchmark::Counter::kIsIterationInvariantRate);
}

/// The plain reference: whole batch per layer, unfused (float, Eigen), parallel over two halves.
template <int W>
void BM_mlp_reference(benchmark::State& st) {
  using Net = PaperNet<W>;
  const int n = static_cast<int>(st.range(0));
  Rng rng(1);
  std::vector<float> params(Net::Trunk::n_params), xe(static_cast<std::size_t>(n) * 63), dy(static_cast<std::size_t>(n) * (W + 1), 1.f);
  Net::Trunk::init(params.data(), rng);
  for (auto& v : xe) v = rng.uniformf() * 2 - 1;
  for (auto _ : st) {
    parallel_blocks(2, 1, [&](std::size_t b, std::size_t e, int) {
      for (std::size_t h = b; h < e; ++h) {
        const int m = n / 2;
        std::vector<float> x(xe.begin() + static_cast<std::ptrdiff_t>(h * m * 63),
                             xe.begin() + static_cast<std::ptrdiff_t>((h + 1) * m * 63));
        std::vector<float> d(dy.begin(), dy.begin() + static_cast<std::ptrdiff_t>(m) * (W + 1));
        benchmark::DoNotOptimize(nn::reference_mlp_forward_backward<typename Net::Trunk>(params, x, m, d));
      }
    });
  }
  // Trunk only (the view branch is < 15 % of the work): FLOPs counted for the trunk.
  const double trunk_flops = 3 * 2.0 * Net::Trunk::macs_per_sample() - 2.0 * 63 * W;
  st.counters["samples_per_s"] = benchmark::Counter(double(n), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["gflops"] = benchmark::Counter(n * trunk_flops / 1e9, benchmark::Counter::kIsIterationInvariantRate);
}

/// The widest FP32 FMA vector of the build, for BM_fma_peak.
#if defined(__AVX512F__)
struct FmaVec {
  using V = __m512;
  static constexpr int lanes = 16;
  static V set1(float x) { return _mm512_set1_ps(x); }
  static V fma(V a, V b, V c) { return _mm512_fmadd_ps(a, b, c); }
  static void store(float* p, V v) { _mm512_storeu_ps(p, v); }  // not _mm512_reduce_add_ps: GCC 12 warns inside its header
};
#elif defined(__AVX2__) && defined(__FMA__)
struct FmaVec {
  using V = __m256;
  static constexpr int lanes = 8;
  static V set1(float x) { return _mm256_set1_ps(x); }
  static V fma(V a, V b, V c) { return _mm256_fmadd_ps(a, b, c); }
  static void store(float* p, V v) { _mm256_storeu_ps(p, v); }
};
#endif

/// FP32 FMA peak: 12 independent FMA chains of the widest vector (AVX-512, else AVX2) on every thread.
void BM_fma_peak(benchmark::State& st) {
  const long iters = 1 << 22;
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
  using F = FmaVec;
  for (auto _ : st) {
    parallel_blocks(static_cast<std::size_t>(thread_count()), 1, [&](std::size_t, std::size_t, int) {
      typename F::V a[12];
      for (int i = 0; i < 12; ++i) a[i] = F::set1(1.0f + i * 1e-3f);
      const typename F::V m = F::set1(0.999999f), c = F::set1(1e-7f);
      for (long k = 0; k < iters; ++k)
        for (int i = 0; i < 12; ++i) a[i] = F::fma(a[i], m, c);
      float lanes[F::lanes], s = 0;
      for (int i = 0; i < 12; ++i) {
        F::store(lanes, a[i]);
        for (float l : lanes) s += l;
      }
      benchmark::DoNotOptimize(s);
    });
  }
  st.counters["gflops"] =
      benchmark::Counter(double(thread_count()) * iters * 12 * F::lanes * 2 / 1e9, benchmark::Counter::kIsIterationInvariantRate);
#else
  st.SkipWithError("no FMA vectors in this build");
#endif
}

/// One tile's matrix product, the kernel (gemm::product: AVX-512 or AVX2 + FMA) or Eigen's
/// (gemm::eigen_product, the plain path) on the same operands, one thread. Args: m, n, k, and 1 for a
/// weight gradient (C += DZ·Xᵀ, Xᵀ read in place) or 0 for a layer's forward (C = W·X).
template <bool Kernel>
void BM_gemm(benchmark::State& st) {
  const int m = static_cast<int>(st.range(0)), n = static_cast<int>(st.range(1)), k = static_cast<int>(st.range(2));
  const bool wgrad = st.range(3) != 0;
  Rng rng(1);
  std::vector<float> a(static_cast<std::size_t>(m) * k), b(static_cast<std::size_t>(k) * n), c(static_cast<std::size_t>(m) * n, 0.f);
  for (auto* v : {&a, &b})
    for (auto& e : *v) e = rng.uniformf() * 2 - 1;
  // Forward: A = W (m × k), B = X (k × n, column-major). Weight gradient: A = DZ (m × k samples), B = Xᵀ
  // read from X (n × k, column-major: element (s, j) at x[j + s·n]).
  const nn::gemm::Operands<float> op = wgrad ? nn::gemm::Operands<float>{m, n, k, a.data(), m, b.data(), n, 1, c.data(), m}
                                             : nn::gemm::Operands<float>{m, n, k, a.data(), m, b.data(), 1, k, c.data(), m};
  for (auto _ : st) {
    if constexpr (Kernel) {
      if (wgrad) nn::gemm::product<true>(op);
      else nn::gemm::product<false>(op);
    } else {
      if (wgrad) nn::gemm::eigen_product<true>(op);
      else nn::gemm::eigen_product<false>(op);
    }
    benchmark::DoNotOptimize(c.data());
    benchmark::ClobberMemory();
  }
  st.counters["gmacs"] = benchmark::Counter(double(m) * n * k / 1e9, benchmark::Counter::kIsIterationInvariantRate);
}
/// Fast's shapes over one tile of 1024 samples: the density network's first layer (64 × 32) and the colour
/// network's one-row output (1 × 64), forward and weight gradient; the paper network's 256 × 256 layer.
void gemm_shapes(benchmark::internal::Benchmark* b) {
  b->Args({64, 1024, 32, 0})->Args({64, 32, 1024, 1})->Args({1, 1024, 64, 0})->Args({1, 64, 1024, 1});
  b->Args({256, 256, 256, 0})->Args({256, 256, 256, 1});  // the paper network's hidden layer over a tile of 256
}

#if defined(__AVX512BF16__)
/// BF16 peak: independent vdpbf16ps chains (32 multiply-adds each) on every thread; what nn::Bf16 runs on.
void BM_bf16_peak(benchmark::State& st) {
  const long iters = 1 << 22;
  for (auto _ : st) {
    parallel_blocks(static_cast<std::size_t>(thread_count()), 1, [&](std::size_t, std::size_t, int) {
      __m512 a[12];
      for (int i = 0; i < 12; ++i) a[i] = _mm512_set1_ps(i * 1e-3f);
      const __m512bh x = reinterpret_cast<__m512bh>(_mm512_set1_epi32(0x3F7F3F7F));  // bf16 pairs (0.996, 0.996)
      for (long k = 0; k < iters; ++k)
        for (int i = 0; i < 12; ++i) a[i] = _mm512_dpbf16_ps(a[i], x, x);
      alignas(64) float lanes[16];
      float s = 0;
      for (int i = 0; i < 12; ++i) {
        _mm512_store_ps(lanes, a[i]);
        for (float l : lanes) s += l;
      }
      benchmark::DoNotOptimize(s);
    });
  }
  st.counters["gflops"] =
      benchmark::Counter(double(thread_count()) * iters * 12 * 32 * 2 / 1e9, benchmark::Counter::kIsIterationInvariantRate);
}
#endif

std::string synthetic_events_text(std::size_t n) {
  Rng rng(3);
  std::string s;
  char buf[64];
  double t = 0;
  for (std::size_t i = 0; i < n; ++i) {
    t += rng.uniform() * 1e-5;
    const int k = std::snprintf(buf, sizeof buf, "%.9f %d %d %d\n", t, int(rng.below(240)), int(rng.below(180)), int(rng.below(2)));
    s.append(buf, static_cast<std::size_t>(k));
  }
  return s;
}
const std::string& events_text() {
  static const std::string s = synthetic_events_text(2000000);
  return s;
}

void BM_parse_events_fast(benchmark::State& st) {
  const auto& s = events_text();
  for (auto _ : st) benchmark::DoNotOptimize(io::parse_events(s, "bench", 240, 180));
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations() * s.size()));
}
/// The naive reference: std::ifstream >> per token.
void BM_parse_events_naive(benchmark::State& st) {
  const auto& s = events_text();
  const auto path = std::filesystem::temp_directory_path() / "evnerf_bench_events.txt";
  { std::ofstream(path) << s; }
  for (auto _ : st) {
    std::ifstream in(path);
    events::EventStream ev;
    double t;
    int x, y, p;
    while (in >> t >> x >> y >> p) ev.push_back(t, x, y, p ? 1 : -1);
    benchmark::DoNotOptimize(ev);
  }
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations() * s.size()));
}
void BM_event_cache_load(benchmark::State& st) {
  const auto ev = io::parse_events(events_text(), "bench", 240, 180);
  const auto dir = std::filesystem::temp_directory_path() / "evnerf_bench_cache";
  io::save_event_cache(dir, ev, "stamp");
  const std::size_t bytes = ev.size() * (8 + 2 + 2 + 1);
  for (auto _ : st) {
    events::EventStream out;
    benchmark::DoNotOptimize(io::load_event_cache(dir, "stamp", out));
  }
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations() * bytes));
}

/// A recording for training-step benchmarks (planes scene, short).
const TrainingData& bench_data() {
  static const TrainingData td = [] {
    auto spec = sim::load_scene("planes");
    spec.path.duration = 0.3;
    auto rec = sim::Simulator(spec, sim::SensorConfig{}).run();
    io::Dataset d;
    d.camera = rec.camera;
    d.events = rec.events;
    d.trajectory = rec.trajectory;
    d.frames.t = rec.frame_times;
    d.frames.paths.resize(rec.frame_times.size());
    train::Config cfg;
    return train::prepare(d, cfg);
  }();
  return td;
}
/// Whether Model marches rays through a sampler that skips empty space (Gaussians have no sampler).
template <class Model>
constexpr bool skips_samples() {
  if constexpr (requires { Model::sampler_type::skips_samples; }) return Model::sampler_type::skips_samples;
  else return false;
}
/// A model past its occupancy warm-up (the grid active, as in every step after the first 256): trained
/// once per run on the bench recording, then copied by each benchmark.
template <class Model>
const Model& warmed_model() {
  static const Model m = [] {
    const auto& td = bench_data();
    train::Config cfg;
    Model w(td, train::scene_box(td, cfg), 1, nn::AdamConfig{5e-3, 0.9, 0.999, 1e-7, 0.1, 250000});
    if constexpr (skips_samples<Model>())
      for (int s = 0; s < Model::sampler_type::warmup_steps + 2 * Model::sampler_type::update_interval; ++s) w.train_step(td, 1024, 1);
    return w;
  }();
  return m;
}
template <class Model>
void BM_train_step(benchmark::State& st) {
  const auto& td = bench_data();
  Model m = warmed_model<Model>();
  double samples = 0, backward = 0;
  for (auto _ : st) {
    const auto s = m.train_step(td, 1024, 1);
    samples += static_cast<double>(s.samples);
    backward += static_cast<double>(s.backward_samples);
  }
  st.counters["rays_per_s"] = benchmark::Counter(2048, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["samples_per_ray"] = samples / static_cast<double>(st.iterations()) / 2048;
  st.counters["backward_per_ray"] = backward / static_cast<double>(st.iterations()) / 2048;
  if constexpr (skips_samples<Model>()) st.counters["occupied"] = m.sampler().occupied_fraction();
}
/// The same step with every sample evaluated (a fresh model: the grid is not active yet).
template <class Model>
void BM_train_step_cold(benchmark::State& st) {
  const auto& td = bench_data();
  train::Config cfg;
  Model m(td.slices.size(), train::scene_box(td, cfg), 1);
  for (auto _ : st) benchmark::DoNotOptimize(m.train_step(td, 1024, 1));
  st.counters["rays_per_s"] = benchmark::Counter(2048, benchmark::Counter::kIsIterationInvariantRate);
}
void BM_render_fast(benchmark::State& st) {
  const auto& td = bench_data();
  const auto& m = warmed_model<presets::Fast>();
  for (auto _ : st) benchmark::DoNotOptimize(m.render(td.camera, td.pixel_dirs, td.boundary_poses[0]));
}

/// A random Gaussian scene in front of a 346 × 260 camera (grey, degree 1): `n` Gaussians in a slab 2–5
/// units deep, sized so that about 20 overlap a pixel whatever n is (a trained scene's depth complexity).
struct SplatBench {
  using L = splat::Layout<1, 1>;
  std::size_t n;
  std::vector<float> params, px;
  splat::View view;
  explicit SplatBench(std::size_t count) : n(count) {
    view.width = 346, view.height = 260, view.fx = view.fy = 300, view.cx = 173, view.cy = 130;
    Rng rng(17);
    params.resize(n * L::size);
    const double scale = 0.05 * std::sqrt(50000.0 / static_cast<double>(n));
    for (std::size_t i = 0; i < n; ++i) {
      float* g = params.data() + i * L::size;
      const double z = rng.uniform(2, 5);
      g[L::mean] = static_cast<float>(rng.uniform(-0.6, 0.6) * z), g[L::mean + 1] = static_cast<float>(rng.uniform(-0.45, 0.45) * z);
      g[L::mean + 2] = static_cast<float>(z);
      for (int a = 0; a < 3; ++a) g[L::log_scale + a] = static_cast<float>(std::log(scale * rng.uniform(0.3, 1.0)));
      for (int a = 0; a < 4; ++a) g[L::rotation + a] = static_cast<float>(rng.uniform(-1, 1));
      g[L::opacity] = static_cast<float>(rng.uniform(-3, 0));
      for (int k = 0; k < L::sh; ++k) g[L::colour + k] = static_cast<float>(k == 0 ? rng.uniform(0.5, 2) : rng.uniform(-0.3, 0.3));
    }
    for (int y = 0; y < 260; ++y)
      for (int x = 0; x < 346; ++x) px.push_back(static_cast<float>(x + 0.5)), px.push_back(static_cast<float>(y + 0.5));
  }
};
/// A whole view: projection, binning, compositing (Arg: Gaussians). Counters: Gaussian·pixel pairs
/// tested per second, and the mean tested per pixel.
void BM_splat_render(benchmark::State& st) {
  SplatBench b(static_cast<std::size_t>(st.range(0)));
  splat::Projection<float, 1> proj;
  splat::Rasterizer<float, 1> raster;
  const std::size_t P = b.px.size() / 2;
  std::vector<float> c(P), d(P), a(P);
  const float bg = 0.5f;
  double pairs = 0;
  for (auto _ : st) {
    splat::project<SplatBench::L, nn::Softplus>(b.params.data(), b.n, b.view, proj);
    raster.forward(proj, b.view, b.px.data(), P, &bg, c.data(), d.data(), a.data(), false);
    pairs += static_cast<double>(raster.evaluated());
  }
  st.counters["pairs_per_s"] = benchmark::Counter(pairs, benchmark::Counter::kIsRate);
  st.counters["tested_per_px"] = pairs / static_cast<double>(st.iterations()) / static_cast<double>(P);
}
/// The same view by the plain reference: every visible Gaussian tested at every pixel.
void BM_splat_reference(benchmark::State& st) {
  SplatBench b(static_cast<std::size_t>(st.range(0)));
  splat::Projection<float, 1> proj;
  const std::size_t P = b.px.size() / 2;
  std::vector<float> c(P), d(P), a(P);
  const float bg = 0.5f;
  for (auto _ : st) {
    splat::project<SplatBench::L, nn::Softplus>(b.params.data(), b.n, b.view, proj);
    splat::reference_composite(proj, b.px.data(), P, &bg, c.data(), d.data(), a.data());
  }
}
/// A training pass over 4096 scattered pixels of the view: projection, forward kept, backward, projection
/// backward (Arg: Gaussians). Counters: pixels and (Gaussian, pixel) pairs of the forward per second.
void BM_splat_train_pass(benchmark::State& st) {
  SplatBench b(static_cast<std::size_t>(st.range(0)));
  splat::Projection<float, 1> proj;
  splat::ProjectionGrad<float, 1> pg;
  splat::Rasterizer<float, 1> raster;
  Rng rng(3);
  std::vector<float> px;
  for (int k = 0; k < 4096; ++k)
    px.push_back(static_cast<float>(rng.uniform(0, 346))), px.push_back(static_cast<float>(rng.uniform(0, 260)));
  std::vector<float> c(4096), dc(4096, 1e-3f), grads(b.params.size());
  const float bg = 0.5f;
  float dbg = 0;
  double pairs = 0;
  for (auto _ : st) {
    splat::project<SplatBench::L, nn::Softplus>(b.params.data(), b.n, b.view, proj);
    raster.forward(proj, b.view, px.data(), 4096, &bg, c.data(), nullptr, nullptr, true);
    pairs += static_cast<double>(raster.evaluated());
    raster.backward(proj, px.data(), dc.data(), &bg, pg, &dbg);
    std::fill(grads.begin(), grads.end(), 0.0f);
    splat::project_backward<SplatBench::L, nn::Softplus>(b.params.data(), b.n, b.view, proj, pg, grads.data());
    benchmark::DoNotOptimize(grads.data());
  }
  st.counters["px_per_s"] = benchmark::Counter(4096, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["pairs_per_s"] = benchmark::Counter(pairs, benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK(BM_fma_peak)->Unit(benchmark::kMillisecond)->UseRealTime();
#if defined(__AVX512BF16__)
BENCHMARK(BM_bf16_peak)->Unit(benchmark::kMillisecond)->UseRealTime();
#endif
BENCHMARK(BM_mlp_fused<256>)->Args({16384, 256})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mlp_reference<256>)->Args({16384})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mlp_fused<64>)->Args({65536, 256})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mlp_fused<256, nn::Bf16>)->Args({16384, 256})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mlp_fused<64, nn::Bf16>)->Args({65536, 256})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mlp_reference<64>)->Args({65536})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_gemm<true>)->Apply(gemm_shapes)->Unit(benchmark::kMicrosecond)->UseRealTime();
BENCHMARK(BM_gemm<false>)->Apply(gemm_shapes)->Unit(benchmark::kMicrosecond)->UseRealTime();
BENCHMARK(BM_parse_events_fast)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_parse_events_naive)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_event_cache_load)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_train_step<presets::Fast>)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_train_step_cold<presets::Fast>)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_train_step<presets::FastBf16>)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_train_step<presets::Splat>)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_train_step<presets::Paper>)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_train_step<presets::PaperBf16>)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_render_fast)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_splat_render)->Arg(2000)->Arg(50000)->Arg(200000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_splat_reference)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_splat_train_pass)->Arg(50000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
