// render/renderer.hpp — Renderer<Field, Sampler, T>: rays (any number, from any poses) to samples, the field
// over the samples the sampler keeps, compositing forward and backward; whole images with depth and
// opacity. It owns the scene box and the sampler (and so the sampler's state). Two-network samplers run a
// coarse and a fine pass, each with its own network parameters (network n at params + n · Field::n_params);
// behind the networks lie the backdrop's raw values, one per channel, read when the box's backdrop is
// learned (SceneBox::background_learned). Depends on field/, geometry/ and render/.
#pragma once
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "../core/parallel.hpp"
#include "../core/rng.hpp"
#include "../core/types.hpp"
#include "../geometry/camera.hpp"
#include "../geometry/pose.hpp"
#include "compositing.hpp"
#include "sampler.hpp"
#include "scene.hpp"

namespace evnerf::render {

template <class FieldT, Sampler SamplerT, class T = float>
class Renderer {
 public:
  using field_type = FieldT;
  using sampler_type = SamplerT;
  using scalar = T;
  static constexpr int channels = FieldT::channels;
  static constexpr int networks = SamplerT::two_networks ? 2 : 1;
  static constexpr int n_coarse = SamplerT::n_coarse, n_fine = SamplerT::two_networks ? SamplerT::n_fine : 0;
  static constexpr std::size_t field_params = FieldT::n_params;
  /// Where the backdrop's `channels` raw values lie: behind all networks' parameters (the coarse network's
  /// first). A learned backdrop's luminance in channel c is the field's radiance activation of value c, so
  /// that it spans what the field's own samples can show.
  static constexpr std::size_t backdrop_offset = networks * field_params;
  /// Parameters of all networks and the backdrop's raw values.
  static constexpr std::size_t n_params = backdrop_offset + channels;

  /// Backward early termination (samplers that skip): samples behind this transmittance get no gradient.
  static constexpr T kMinTransmittance = T(1e-4);
  /// Forward early termination of evaluation rays: a ray stops behind this transmittance, checked every
  /// kEvalChunk samples.
  static constexpr T kEvalTransmittance = T(1e-4);
  static constexpr int kEvalChunk = 8;
  /// Raw density given to samples that were not evaluated (skipped cells, terminated rays): α = 0.
  static constexpr T kSkippedDensity = T(-1e4);

  /// One network's pass over a batch of rays: depths, inputs, outputs, composites and what backward needs.
  struct Pass {
    typename FieldT::template Workspace<T> ws;
    int S = 0;                                       ///< samples per ray
    std::vector<T> t, noise, pts, dirs;              ///< R×S depths and density noise; 3·R·S points and directions
    std::vector<RayComposite<T>> comp;               ///< one per ray
    std::vector<T> dcolor;                           ///< R×C, dL/dcolor of comp: the caller fills it before backward()
    std::vector<T> dweight;                          ///< R×S, dL/dw of comp's weights (a regulariser), or empty
    std::vector<int> active, keep;                   ///< evaluated samples; of those, the ones that go backward
    std::vector<std::uint64_t> noise_key, noise_at;  ///< per ray: where its density noise is drawn (draw_noise)
    std::vector<T> cpts, cdirs, sig_full, raw_full, cdsigma, cdraw, dsigma, draw, ray_trans;
    std::array<T, channels> background{};  ///< the backdrop behind the rays, per channel (comp's point here)
    std::array<T, channels> black{};       ///< what lies behind a ray that stopped early (zeros)
  };
  /// Scratch of one thread; buffers are reused from batch to batch (no state: any content gives the same result).
  struct Workspace {
    std::array<Pass, networks> pass;
    std::size_t evaluated = 0;         ///< field evaluations so far
    std::size_t backward_samples = 0;  ///< samples run backward so far
    bool early_termination = false;    ///< evaluation rays: stop a ray behind kEvalTransmittance
    /// Training rays: stop a ray behind kMinTransmittance (forward_terminating), where the sampler skips.
    /// Its samples there carry no gradient either way; what changes is the forward's composite, by less
    /// than kMinTransmittance of a ray's luminance, and the time: the samples behind are not evaluated.
    bool training_termination = false;
    /// With training_termination: the transmittance behind which a training ray stops and its samples go
    /// no further backward (kMinTransmittance unless the model sets another, Model::set_ray_termination).
    T training_cut = kMinTransmittance;
    std::vector<T> one;  ///< a ray's fine depths
    /// The backdrop of the last forward (known or learned): its luminance per channel and that luminance's
    /// derivative by its raw value (0 for a known one).
    std::array<T, channels> backdrop{}, dbackdrop_draw{};
    /// When set before a training forward, backward() also gives each ray's gradient for its origin and
    /// direction (world frame) in dorigin and ddir, summed over the passes: through the samples' points and
    /// unit directions, with the depths held (a two-network sampler's fine depths too, as in the parameters'
    /// backward) and the direction's length held (the intervals' lengths depend on it: the gradient is
    /// exact for motions that keep it, a camera's rigid ones). Pose refinement reads it.
    bool ray_grad = false;
    /// The levels of a multiresolution position encoding the rays' gradient goes through (Field's
    /// input_levels): all by default.
    int ray_grad_levels = 1 << 30;
    std::vector<Vec3> origin, dir, dorigin, ddir;
  };

  Renderer() = default;
  explicit Renderer(SceneBox box, SamplerT sampler = {}) : box_(box), sampler_(std::move(sampler)) {
    if constexpr (requires { SamplerT::spacing::check(box.near, box.far); }) SamplerT::spacing::check(box.near, box.far);
  }
  const SceneBox& box() const { return box_; }
  SceneBox& box() { return box_; }
  const SamplerT& sampler() const { return sampler_; }
  SamplerT& sampler() { return sampler_; }

  /// Training forward of R rays: ray r's depths are jittered and its density noise drawn from rng[r] (coarse
  /// depths, coarse noise, then for a fine pass its depths and noise). Every pass's dcolor is zeroed.
  void forward_train(const T* params, const Vec3* origin, const Vec3* dir, Rng* rng, int R, Workspace& w) const {
    forward(params, origin, dir, rng, R, w);
  }
  /// Evaluation forward of R rays: bin-centre depths, no noise; with w.early_termination a ray stops once
  /// its transmittance falls below kEvalTransmittance.
  void forward_eval(const T* params, const Vec3* origin, const Vec3* dir, int R, Workspace& w) const {
    forward(params, origin, dir, nullptr, R, w);
  }
  /// The composites of the last forward's pass `net` (0 coarse, 1 fine); the last pass is the image.
  static const std::vector<RayComposite<T>>& composites(const Workspace& w, int net) { return w.pass[net].comp; }

  /// Backward of the last training forward from every pass's dcolor: adds the gradients of all networks'
  /// parameters, and of a learned backdrop's raw values, to `grads` (laid out as params). With a deferring
  /// field workspace, flush() applies the table gradients that backward() kept back.
  void backward(const T* params, Workspace& w, T* grads) const {
    if (learns_backdrop()) {
      // Every pass shows the backdrop behind its rays with the transmittance they leave (r.rest); a ray
      // that stopped early shows none (composited before zeros).
      std::array<double, channels> d{};
      for (const auto& p : w.pass)
        for (std::size_t r = 0; r < p.comp.size(); ++r) {
          if (p.comp[r].background != p.background.data()) continue;
          for (int c = 0; c < channels; ++c) d[c] += double(p.dcolor[r * channels + c]) * double(p.comp[r].rest);
        }
      for (int c = 0; c < channels; ++c) grads[backdrop_offset + c] += static_cast<T>(d[c] * double(w.dbackdrop_draw[c]));
    }
    if (w.ray_grad) {
      w.dorigin.assign(w.origin.size(), Vec3::Zero());
      w.ddir.assign(w.origin.size(), Vec3::Zero());
    }
    for (int net = 0; net < networks; ++net) {
      w.pass[net].ws.input_grad = w.ray_grad;
      w.pass[net].ws.input_levels = w.ray_grad_levels;
      backward_pass(params + net * field_params, w.pass[net], w, grads + net * field_params);
    }
  }
  /// Whether a backdrop lies behind the samples (known or learned): the last interval is then closed.
  bool has_backdrop() const { return box_.background.has_value() || box_.background_learned; }
  /// Whether the backdrop is learned (its raw values in params get gradients): learned and not known.
  bool learns_backdrop() const { return box_.background_learned && !box_.background; }
  /// The backdrop's luminance in each channel under `params` (laid out as params): the box's known one, the
  /// learned one, or nothing (std::nullopt) when rays stop at their last sample.
  std::optional<std::array<T, channels>> backdrop(const T* params) const {
    if (!has_backdrop()) return std::nullopt;
    std::array<T, channels> b{}, db{};
    backdrop_values(params, b, db);
    return b;
  }
  /// The samples of pass `net` of the last training forward, for a term on them (loss::RenderedValues): the
  /// samples per ray, their depths (rays × samples) and a zeroed buffer for dloss/dweight of every ray's
  /// weights, which backward() adds to the gradient. Call after the forward, before backward().
  struct SampleView {
    int samples;
    const T* depth;
    T* weight_grad;
  };
  static SampleView samples(Workspace& w, int net) {
    auto& p = w.pass[net];
    p.dweight.assign(p.comp.size() * static_cast<std::size_t>(p.S), T(0));
    return {p.S, p.t.data(), p.dweight.data()};
  }
  /// Defers table gradients of every pass to flush() (bit-identical; see Field::Workspace::defer_encoding_grad).
  static void defer_encoding_grad(Workspace& w) {
    for (auto& p : w.pass) p.ws.defer_encoding_grad = true;
  }
  static void flush(Workspace& w) {
    for (auto& p : w.pass) FieldT::flush_encoding_grad(p.ws);
  }
  /// flush() in parts that write to different tables (a hash grid's levels): flush_part(w, q) for every q
  /// in [0, flush_parts), on any threads in any order, then clear_deferred(w), adds what flush(w) adds, bit
  /// for bit (each table gets its passes' additions in pass order, each pass's in the order kept).
  static constexpr int flush_parts = FieldT::encoding_grad_parts;
  static void flush_part(const Workspace& w, int part) {
    for (const auto& p : w.pass) FieldT::flush_encoding_grad_part(p.ws, part);
  }
  static void clear_deferred(Workspace& w) {
    for (auto& p : w.pass) FieldT::clear_deferred(p.ws);
  }
  /// Samples whose table gradients w holds back (over every pass).
  static std::size_t deferred_count(const Workspace& w) {
    std::size_t n = 0;
    for (const auto& p : w.pass) n += FieldT::deferred_count(p.ws);
    return n;
  }

  /// Rows of the image that render() evaluates in one batch (kRenderRows · width rays). At 240 columns, 1, 2
  /// and 4 rows render equally fast and 8 or 16 rows slower (the batch's per-sample arrays leave the cache).
  /// A ray's result does not depend on its batch (tested).
  static constexpr int kRenderRows = 4;

  /// Renders the full image at `pose` (the fine pass where there is one); `pixel_dirs` are
  /// render::pixel_directions(cam). Batches of `rows_per_batch` rows go to the threads as each becomes free
  /// (rows differ in cost: sky against floor), so the image's bits depend on neither the batch size nor the
  /// thread count. With `early_termination` (the default) a ray stops being evaluated once its
  /// transmittance falls below kEvalTransmittance: what lies behind changes a pixel by less than that.
  Rendering render(const T* params, const geometry::Camera& cam, const std::vector<Vec3f>& pixel_dirs, const geometry::Pose& pose,
                   bool early_termination = true, int rows_per_batch = kRenderRows) const {
    Rendering out{Image(cam.width(), cam.height(), channels), Image(cam.width(), cam.height(), 1), Image(cam.width(), cam.height(), 1)};
    const int H = cam.height(), W = cam.width();
    const int G = std::max(1, rows_per_batch);
    const std::size_t batches = static_cast<std::size_t>((H + G - 1) / G);
    std::atomic<std::size_t> next{0};
    parallel_blocks(batches, 1, [&](std::size_t, std::size_t, int) {
      Workspace w;
      w.early_termination = early_termination;
      std::vector<Vec3> origin, dir;
      for (std::size_t g; (g = next.fetch_add(1, std::memory_order_relaxed)) < batches;) {
        const int y0 = static_cast<int>(g) * G, y1 = std::min(H, y0 + G), R = (y1 - y0) * W;
        origin.resize(static_cast<std::size_t>(R));
        dir.resize(static_cast<std::size_t>(R));
        for (int r = 0; r < R; ++r) {
          const auto ray = geometry::Camera::ray_along(pose, pixel_dirs[static_cast<std::size_t>(y0) * W + r].cast<double>());
          origin[r] = ray.origin;
          dir[r] = ray.dir;
        }
        forward_eval(params, origin.data(), dir.data(), R, w);
        const auto& comp = w.pass[networks - 1].comp;
        for (int r = 0; r < R; ++r) {
          const int x = r % W, y = y0 + r / W;
          for (int c = 0; c < channels; ++c) out.luminance.at(x, y, c) = static_cast<float>(comp[r].color[c]);
          out.depth.at(x, y) = static_cast<float>(comp[r].depth);
          out.opacity.at(x, y) = static_cast<float>(comp[r].opacity);
        }
      }
    });
    return out;
  }

  /// The field at n world points seen along unit directions, by the network that makes the image (the fine
  /// one where there are two), for exports: sigma[j] the density as α reads it (per density_length world
  /// units, as SceneBox says), lum[j · channels + c] the luminance. Points outside the box are evaluated as
  /// the field extends there. Parallel over blocks of points; the same for any thread count.
  void probe(const T* params, const Vec3* world, const Vec3* dirs, std::size_t n, float* sigma, float* lum) const {
    const T* net = params + (networks - 1) * field_params;
    const double inv = 1.0 / box_.scale;
    constexpr std::size_t kChunk = 4096;  // the networks' activations for this many points at a time
    parallel_blocks(n, kChunk, [&](std::size_t b, std::size_t e, int) {
      typename FieldT::template Workspace<T> ws;
      std::vector<T> pts(3 * kChunk), ds(3 * kChunk);
      for (std::size_t c0 = b; c0 < e; c0 += kChunk) {
        const std::size_t m = std::min(kChunk, e - c0);
        for (std::size_t j = 0; j < m; ++j) {
          const Vec3 x = (world[c0 + j] - box_.center) * inv;
          for (int d = 0; d < 3; ++d) {
            pts[3 * j + d] = static_cast<T>(x[d]);
            ds[3 * j + d] = static_cast<T>(dirs[c0 + j][d]);
          }
        }
        const T *sg = nullptr, *lm = nullptr;
        FieldT::forward(net, pts.data(), ds.data(), static_cast<int>(m), ws, &sg, &lm);
        for (std::size_t j = 0; j < m; ++j) {
          sigma[c0 + j] = static_cast<float>(FieldT::density_activation::f(sg[j * FieldT::density_net::out_dims]));
          for (int c = 0; c < channels; ++c)
            lum[(c0 + j) * channels + c] = static_cast<float>(FieldT::radiance::activation::f(lm[j * channels + c]));
        }
      }
    });
  }

  /// Lets the sampler refresh its state before training step `step`: `u` carries the step, seed and
  /// visibility; the box and the density of the coarse network (params) are filled in here.
  void update_sampler(const T* params, SamplerUpdate u) {
    u.box = box_;
    u.density = [params](const float* pts, std::size_t n, float* out) {
      parallel_blocks(n, 8192, [&](std::size_t b, std::size_t e, int) {
        typename FieldT::template Workspace<T> ws;
        std::vector<T> p, o;
        for (std::size_t c = b; c < e; c += 4096) {
          const int m = static_cast<int>(std::min<std::size_t>(4096, e - c));
          const T* in;
          T* res;
          if constexpr (std::is_same_v<T, float>) {
            in = pts + 3 * c;
            res = out + c;
          } else {
            p.assign(pts + 3 * c, pts + 3 * (c + m));
            o.resize(static_cast<std::size_t>(m));
            in = p.data();
            res = o.data();
          }
          FieldT::density(params, in, m, ws, res);
          for (int j = 0; j < m; ++j) out[c + j] = static_cast<float>(FieldT::density_activation::f(res[j]));  // σ as α sees it
        }
      });
    };
    sampler_.update(u);
  }

 private:
  /// The backdrop's luminance per channel and its derivative by the raw value: the box's known backdrop
  /// (derivative 0) or the learned raw values in params.
  void backdrop_values(const T* params, std::array<T, channels>& b, std::array<T, channels>& db) const {
    if (box_.background) {
      b.fill(static_cast<T>(*box_.background));
      db.fill(T(0));
    } else if (learns_backdrop()) {
      for (int c = 0; c < channels; ++c) {
        const auto l = ad::value_and_grad(LuminanceOfRaw<typename FieldT::radiance::activation>{},
                                          std::array<double, 1>{double(params[backdrop_offset + c])});
        b[c] = static_cast<T>(l.value);
        db[c] = static_cast<T>(l.grad[0]);
      }
    }
  }
  void forward(const T* params, const Vec3* origin, const Vec3* dir, Rng* rng, int R, Workspace& w) const {
    backdrop_values(params, w.backdrop, w.dbackdrop_draw);
    if (w.ray_grad) {
      w.origin.assign(origin, origin + R);
      w.dir.assign(dir, dir + R);
    }
    Pass& c = w.pass[0];
    c.S = n_coarse;
    c.t.resize(static_cast<std::size_t>(R) * n_coarse);
    reserve_noise(rng, R, c);
    for (int r = 0; r < R; ++r) {
      T* tr = &c.t[static_cast<std::size_t>(r) * n_coarse];
      sampler_.coarse_depths(n_coarse, T(box_.near), T(box_.far), rng ? &rng[r] : nullptr, tr);
      if (rng) skip_noise(rng[r], r, c);
    }
    run_pass(params, origin, dir, R, rng != nullptr, c, w);
    if constexpr (networks == 2) {
      Pass& f = w.pass[1];
      constexpr int S = n_coarse + n_fine;
      f.S = S;
      f.t.resize(static_cast<std::size_t>(R) * S);
      for (int r = 0; r < R; ++r) {
        sampler_.refine(n_coarse, &c.t[static_cast<std::size_t>(r) * n_coarse], c.comp[r].weight.data(), rng ? &rng[r] : nullptr, w.one);
        std::copy(w.one.begin(), w.one.end(), f.t.begin() + static_cast<std::ptrdiff_t>(r) * S);
      }
      reserve_noise(rng, R, f);
      if (rng)
        for (int r = 0; r < R; ++r) skip_noise(rng[r], r, f);
      run_pass(params + field_params, origin, dir, R, rng != nullptr, f, w);
    }
  }

  /// Density noise. Sample k of a ray takes the k-th standard normal of the ray's stream from where its
  /// pass's noise begins (each normal() takes two draws); skip_noise records that place and moves the
  /// stream past the pass's S normals, and draw_noise computes the normals of the samples that are
  /// evaluated only. A sample that is not evaluated has raw density kSkippedDensity; where the density
  /// activation and its slope vanish at kSkippedDensity + n for every normal n (|n| ≤ 37.2, the largest
  /// Rng::normal gives; ReLU, TruncExp and Softplus do), it gets n = 0 instead: the same α, dα/dσ and bits
  /// as drawing every normal, without the log and cos of the samples a trained occupancy grid skips.
  static bool noise_vanishes_when_skipped() {
    static const bool yes = [] {
      for (double n : {-37.5, 0.0, 37.5}) {
        const auto a = ad::value_and_grad([](const auto& x) { return FieldT::density_activation::apply(x); },
                                          std::array<double, 1>{double(kSkippedDensity) + n});
        if (a.value != 0 || a.grad[0] != 0) return false;
      }
      return true;
    }();
    return yes;
  }
  static void reserve_noise(const Rng* rng, int R, Pass& p) {
    p.noise.clear();
    p.noise_key.resize(rng ? static_cast<std::size_t>(R) : 0);
    p.noise_at.resize(rng ? static_cast<std::size_t>(R) : 0);
  }
  static void skip_noise(Rng& rng, int r, Pass& p) {
    p.noise_key[static_cast<std::size_t>(r)] = rng.key();
    p.noise_at[static_cast<std::size_t>(r)] = rng.state();
    rng = Rng::from_state(rng.key(), rng.state() + 2 * static_cast<std::uint64_t>(p.S));
  }
  static T noise_of(const Pass& p, int i) {
    const int r = i / p.S, k = i % p.S;
    Rng g = Rng::from_state(p.noise_key[static_cast<std::size_t>(r)],
                            p.noise_at[static_cast<std::size_t>(r)] + 2 * static_cast<std::uint64_t>(k));
    return static_cast<T>(g.normal());
  }
  /// p.noise for the R×S samples: drawn where evaluated (every sample unless `active_only`), 0 elsewhere.
  static void draw_noise(int R, bool active_only, Pass& p) {
    const int n = R * p.S;
    if (!active_only) {
      p.noise.resize(static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) p.noise[static_cast<std::size_t>(i)] = noise_of(p, i);
      return;
    }
    p.noise.assign(static_cast<std::size_t>(n), T(0));
    for (int i : p.active) p.noise[static_cast<std::size_t>(i)] = noise_of(p, i);
  }

  /// The point at depth t along a ray, in the normalised box (as T), into q[0..3). The one formula of every
  /// sample's position: make_samples and forward_terminating give the same bits.
  void sample_point(const Vec3& origin, const Vec3& dir, T t, T* q) const {
    const Vec3 x = (origin + static_cast<double>(t) * dir - box_.center) * (1.0 / box_.scale);
    for (int d = 0; d < 3; ++d) q[d] = static_cast<T>(x[d]);
  }

  /// Points and unit directions of the pass's R×S samples, in the normalised box.
  void make_samples(const Vec3* origin, const Vec3* dir, int R, Pass& p) const {
    const int S = p.S;
    p.pts.resize(3 * static_cast<std::size_t>(R) * S);
    p.dirs.resize(3 * static_cast<std::size_t>(R) * S);
    for (int r = 0; r < R; ++r) {
      const Vec3 u = dir[r].normalized();
      for (int k = 0; k < S; ++k) {
        const std::size_t i = static_cast<std::size_t>(r) * S + k;
        sample_point(origin[r], dir[r], p.t[i], &p.pts[3 * i]);
        for (int d = 0; d < 3; ++d) p.dirs[3 * i + d] = static_cast<T>(u[d]);
      }
    }
  }

  /// Packs the points and directions of the samples listed in p.active into p.cpts / p.cdirs.
  static void gather_active(Pass& p) {
    const std::size_t m = p.active.size();
    p.cpts.resize(3 * m);
    p.cdirs.resize(3 * m);
    for (std::size_t j = 0; j < m; ++j)
      for (int d = 0; d < 3; ++d) {
        p.cpts[3 * j + d] = p.pts[3 * static_cast<std::size_t>(p.active[j]) + d];
        p.cdirs[3 * j + d] = p.dirs[3 * static_cast<std::size_t>(p.active[j]) + d];
      }
  }

  /// Evaluates the samples p.active and scatters raw density and luminance into p.sig_full/raw_full.
  void evaluate_active(const T* params, Pass& p, Workspace& w) const {
    if (p.active.empty()) return;
    gather_active(p);
    evaluate_packed(params, p, w);
  }
  /// evaluate_active with p.cpts / p.cdirs already packed.
  void evaluate_packed(const T* params, Pass& p, Workspace& w) const {
    const int m = static_cast<int>(p.active.size());
    if (m == 0) return;
    const T *sg = nullptr, *rw = nullptr;
    FieldT::forward(params, p.cpts.data(), p.cdirs.data(), m, p.ws, &sg, &rw);
    w.evaluated += static_cast<std::size_t>(m);
    scatter(p, sg, rw, 0, m);
  }

  /// Forward with early termination, kEvalChunk samples of every live ray at a time. The points are made
  /// here, chunk by chunk and only for live rays (make_samples' formula), and packed straight into p.cpts /
  /// p.cdirs: most of a ray's samples lie behind where it stops.
  /// Evaluation rays stop behind kEvalTransmittance; each chunk is evaluated on its own.
  /// Training rays (Workspace::training_termination) stop behind kMinTransmittance, the transmittance below
  /// which backward_pass drops samples anyway: the chunks are appended to the pass's field workspace
  /// (Field::forward_at), p.active lists the evaluated samples in that order, and their density noise is
  /// drawn as draw_noise would (0 for the rest). A ray's transmittance for stopping includes the noise.
  void forward_terminating(const T* params, const Vec3* origin, const Vec3* dir, int R, bool training, Pass& p, Workspace& w) const {
    const int S = p.S;
    const std::size_t n = static_cast<std::size_t>(R) * S;
    p.sig_full.assign(n, kSkippedDensity);
    p.raw_full.assign(n * channels, T(0));
    p.ray_trans.assign(static_cast<std::size_t>(R), T(1));
    if (training) p.noise.assign(n, T(0));
    const T cut = training ? w.training_cut : kEvalTransmittance;
    // Samples not evaluated have act(kSkippedDensity), which is 0 for the usual activations: α = 0 without exp.
    const bool skip_zero = FieldT::density_activation::f(kSkippedDensity) == 0;
    p.dirs.resize(3 * static_cast<std::size_t>(R));  // one unit direction per ray
    for (int r = 0; r < R; ++r) {
      const Vec3 u = dir[r].normalized();
      for (int d = 0; d < 3; ++d) p.dirs[3 * static_cast<std::size_t>(r) + d] = static_cast<T>(u[d]);
    }
    p.active.clear();
    int held = 0;  // samples in the field workspace (training)
    for (int k0 = 0; k0 < S; k0 += kEvalChunk) {
      const int k1 = std::min(S, k0 + kEvalChunk);
      if (!training) p.active.clear();
      p.cpts.clear();
      p.cdirs.clear();
      for (int r = 0; r < R; ++r) {
        if (p.ray_trans[r] <= cut) continue;
        for (int k = k0; k < k1; ++k) {
          const int i = r * S + k;
          T q[3];
          sample_point(origin[r], dir[r], p.t[static_cast<std::size_t>(i)], q);
          if (!sampler_.evaluates(q)) continue;
          p.active.push_back(i);
          p.cpts.insert(p.cpts.end(), q, q + 3);
          p.cdirs.insert(p.cdirs.end(), &p.dirs[3 * static_cast<std::size_t>(r)], &p.dirs[3 * static_cast<std::size_t>(r)] + 3);
        }
      }
      if (training) {
        const int m = static_cast<int>(p.active.size()) - held;
        const T *sg = nullptr, *rw = nullptr;
        FieldT::forward_at(params, p.cpts.data(), p.cdirs.data(), held, m, p.ws, &sg, &rw);
        w.evaluated += static_cast<std::size_t>(m);
        scatter(p, sg, rw, held, held + m);
        for (int j = held; j < held + m; ++j) p.noise[static_cast<std::size_t>(p.active[j])] = noise_of(p, p.active[j]);
        held += m;
      } else {
        evaluate_packed(params, p, w);
      }
      // Transmittance after this chunk (as composite_forward computes it).
      bool alive = false;
      for (int r = 0; r < R; ++r) {
        if (p.ray_trans[r] <= cut) continue;
        const double dn = dir[r].norm() / box_.density_length;
        for (int k = k0; k < k1; ++k) {
          const std::size_t i = static_cast<std::size_t>(r) * S + k;
          const T nz = training ? p.noise[i] : T(0);
          const double delta = interval_length(S, k, p.t.data() + static_cast<std::size_t>(r) * S, dn, has_backdrop());
          const double alpha =
              skip_zero && p.sig_full[i] == kSkippedDensity && nz == T(0)
                  ? 0.0
                  : 1.0 - std::exp(-(FieldT::density_activation::f(training ? p.sig_full[i] + nz : p.sig_full[i]) * delta));
          p.ray_trans[r] *= static_cast<T>(1.0 - alpha + kTransmittanceEpsilon);
        }
        alive = alive || p.ray_trans[r] > cut;
      }
      if (!alive) break;
    }
  }
  /// Raw density and luminance of workspace samples [from, to) (the samples p.active lists there) into
  /// p.sig_full / p.raw_full.
  static void scatter(Pass& p, const T* sg, const T* rw, int from, int to) {
    constexpr int stride = FieldT::density_net::out_dims;
    for (int j = from; j < to; ++j) {
      const std::size_t i = static_cast<std::size_t>(p.active[j]);
      p.sig_full[i] = sg[static_cast<std::size_t>(j) * stride];
      for (int c = 0; c < channels; ++c) p.raw_full[i * channels + c] = rw[static_cast<std::size_t>(j) * channels + c];
    }
  }

  /// Whether training rays stop early (Workspace::training_termination): only where the sampler skips (its
  /// backward pass drops samples behind kMinTransmittance, and unevaluated samples get no noise, which must
  /// then leave α at 0 as noise_vanishes_when_skipped() checks).
  bool training_terminates(const Workspace& w) const {
    return w.training_termination && sampler_.skipping() && noise_vanishes_when_skipped();
  }
  /// Forward of one network over the pass's R×S samples, compositing each ray into p.comp. Training rays
  /// evaluate every sample the sampler keeps unless training_terminates(w); evaluation rays may terminate
  /// early (w.early_termination).
  void run_pass(const T* params, const Vec3* origin, const Vec3* dir, int R, bool training, Pass& p, Workspace& w) const {
    const int S = p.S;
    const bool terminating = training ? training_terminates(w) : w.early_termination;
    if (!terminating) make_samples(origin, dir, R, p);
    const T *sigma = nullptr, *raw = nullptr;
    int stride = FieldT::density_net::out_dims;
    p.active.clear();
    if (terminating) {
      forward_terminating(params, origin, dir, R, training, p, w);
      sigma = p.sig_full.data();
      raw = p.raw_full.data();
      stride = 1;
    } else if (sampler_.skipping()) {
      const int n = R * S;
      for (int i = 0; i < n; ++i)
        if (sampler_.evaluates(&p.pts[3 * static_cast<std::size_t>(i)])) p.active.push_back(i);
      p.sig_full.assign(static_cast<std::size_t>(n), kSkippedDensity);
      p.raw_full.assign(static_cast<std::size_t>(n) * channels, T(0));
      evaluate_active(params, p, w);
      sigma = p.sig_full.data();
      raw = p.raw_full.data();
      stride = 1;
    } else {
      FieldT::forward(params, p.pts.data(), p.dirs.data(), R * S, p.ws, &sigma, &raw);
      w.evaluated += static_cast<std::size_t>(R) * S;
    }
    const bool skipped = !training || sampler_.skipping();  // samples may sit at kSkippedDensity
    if (training && !terminating) draw_noise(R, sampler_.skipping() && noise_vanishes_when_skipped(), p);
    p.comp.resize(R);
    // The backdrop (known or learned) lies behind a ray's samples, unless the ray stopped early: then what
    // lies behind its stop is not known and adds nothing (less than the cut's share; the same intervals as
    // the stop's).
    const T* background = nullptr;
    if (has_backdrop()) {
      p.background = w.backdrop;
      background = p.background.data();
    }
    const T cut = training ? w.training_cut : kEvalTransmittance;
    for (int r = 0; r < R; ++r) {
      const std::size_t o = static_cast<std::size_t>(r) * S;
      const bool stopped = terminating && p.ray_trans[static_cast<std::size_t>(r)] <= cut;
      composite_forward<T, typename FieldT::density_activation, typename FieldT::radiance::activation>(
          S, channels, sigma + o * stride, stride, raw + o * channels, p.t.data() + o, static_cast<T>(dir[r].norm() / box_.density_length),
          training ? p.noise.data() + o : nullptr, p.comp[r], skipped ? &kSkippedDensity : nullptr,
          stopped && background ? p.black.data() : background);
    }
    p.dcolor.assign(static_cast<std::size_t>(R) * channels, T(0));
    p.dweight.clear();
  }

  void backward_pass(const T* params, Pass& p, Workspace& w, T* grads) const {
    const int R = static_cast<int>(p.comp.size()), S = p.S;
    p.dsigma.resize(static_cast<std::size_t>(R) * S);
    p.draw.resize(static_cast<std::size_t>(R) * S * channels);
    for (int r = 0; r < R; ++r) {
      const std::size_t o = static_cast<std::size_t>(r) * S;
      composite_backward<T>(S, channels, p.comp[r], p.dcolor.data() + static_cast<std::size_t>(r) * channels, p.dsigma.data() + o, 1,
                            p.draw.data() + o * channels, p.dweight.empty() ? nullptr : p.dweight.data() + o);
    }
    if (sampler_.skipping()) {  // only the evaluated samples carry gradient
      // Early termination for the backward pass: a sample behind transmittance < kMinTransmittance has weight
      // and gradients below that fraction of the ray's, so it is dropped: the forward's workspace is
      // compacted to the kept samples (Field::keep_only) and only they go backward.
      p.keep.clear();
      const T cut = training_terminates(w) ? w.training_cut : kMinTransmittance;
      for (int j = 0; j < static_cast<int>(p.active.size()); ++j) {
        const int i = p.active[j];
        if (p.comp[i / S].trans[i % S] > cut) p.keep.push_back(j);
      }
      const int m = static_cast<int>(p.keep.size());
      w.backward_samples += static_cast<std::size_t>(m);
      if (m == 0) return;
      p.cdsigma.resize(static_cast<std::size_t>(m));
      p.cdraw.resize(static_cast<std::size_t>(m) * channels);
      for (int j = 0; j < m; ++j) {
        const std::size_t i = static_cast<std::size_t>(p.active[p.keep[j]]);
        p.cdsigma[j] = p.dsigma[i];
        for (int c = 0; c < channels; ++c) p.cdraw[static_cast<std::size_t>(j) * channels + c] = p.draw[i * channels + c];
      }
      if (m < static_cast<int>(p.active.size())) {
        const T *sg = nullptr, *rw = nullptr;
        FieldT::keep_only(p.ws, p.keep.data(), m, &sg, &rw);
      }
      FieldT::backward(params, p.ws, p.cdsigma.data(), p.cdraw.data(), grads);
      if (w.ray_grad)
        add_ray_grad(
            p, w, [&p](int j) { return p.active[p.keep[j]]; }, m);
      return;
    }
    w.backward_samples += static_cast<std::size_t>(R) * S;
    FieldT::backward(params, p.ws, p.dsigma.data(), p.draw.data(), grads);
    if (w.ray_grad)
      add_ray_grad(
          p, w, [](int j) { return j; }, R * S);
  }
  /// Adds the gradients the field gave for the points and unit directions of its m samples (sample j of its
  /// workspace is sample at(j) of the pass) to their rays' origins and directions (Workspace::ray_grad): a
  /// point (o + t·d − centre) / scale, a unit direction d / |d|.
  template <class At>
  void add_ray_grad(const Pass& p, Workspace& w, At&& at, int m) const {
    const double inv = 1.0 / box_.scale;
    for (int j = 0; j < m; ++j) {
      const int i = at(j);
      const int r = i / p.S;
      const std::size_t o = 3 * static_cast<std::size_t>(j);
      const Vec3 gp(p.ws.dpts[o], p.ws.dpts[o + 1], p.ws.dpts[o + 2]), gu(p.ws.ddirs[o], p.ws.ddirs[o + 1], p.ws.ddirs[o + 2]);
      const Vec3& d = w.dir[static_cast<std::size_t>(r)];
      const double len = d.norm();
      const Vec3 u = d / len;
      w.dorigin[static_cast<std::size_t>(r)] += gp * inv;
      w.ddir[static_cast<std::size_t>(r)] +=
          gp * (inv * static_cast<double>(p.t[static_cast<std::size_t>(i)])) + (gu - u * u.dot(gu)) / len;
    }
  }

  SceneBox box_;
  SamplerT sampler_;
};

}  // namespace evnerf::render
