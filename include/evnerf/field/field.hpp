// field/field.hpp — the radiance field: density plus `Channels` luminance values at a point seen from a
// direction. Field<PosEnc, DirEnc, DensityNet, ColorNet> chains: encode(position) → DensityNet →
// [raw density | F features]; [features | encode(direction)] → ColorNet → raw luminance (sigmoid is
// applied by the compositor). Depends on nn/ only.
#pragma once
#include <algorithm>
#include <string>
#include <type_traits>
#include <vector>

#include "../nn/encoding.hpp"
#include "../nn/mlp.hpp"

namespace evnerf::field {

/// True for encodings that declare `unit_cube_input = true` (hash grids: inputs in [0, 1]³); the field
/// feeds them (p + 1) / 2, the others the normalised box's [−1, 1]³.
template <class Enc>
constexpr bool wants_unit_cube() {
  if constexpr (requires { Enc::unit_cube_input; }) return Enc::unit_cube_input;
  else return false;
}

/// Encodes n points: the encoding's level-major batch path when it has one (hash grids), else point by
/// point.
template <class Enc, class T>
void encode_batch(const T* params, const T* pts, int n, T* out) {
  if constexpr (requires { Enc::template forward_batch<T>(params, pts, n, out); }) {
    Enc::forward_batch(params, pts, n, out);
  } else {
    for (int j = 0; j < n; ++j)
      Enc::forward(params, pts + 3 * static_cast<std::size_t>(j), out + static_cast<std::size_t>(j) * Enc::out_dims);
  }
}
/// Table gradients of n points (no input gradient); batch path when the encoding has one.
template <class Enc, class T>
void encode_backward_batch(const T* params, const T* pts, int n, const T* dy, T* dparams) {
  if constexpr (requires { Enc::template backward_batch<T>(pts, n, dy, dparams); }) {
    Enc::backward_batch(pts, n, dy, dparams);
  } else {
    for (int j = 0; j < n; ++j)
      Enc::backward(params, pts + 3 * static_cast<std::size_t>(j), dy + static_cast<std::size_t>(j) * Enc::out_dims, dparams,
                    static_cast<T*>(nullptr));
  }
}

/// How many parts an encoding's batch table gradients split into, each adding to tables of its own (a hash
/// grid's levels; 1 for any other encoding).
template <class Enc>
constexpr int encode_backward_parts() {
  if constexpr (requires { Enc::batch_parts; }) return Enc::batch_parts;
  else return 1;
}
/// Part `part` of encode_backward_batch: the parts together add exactly what it adds, and different parts
/// write to different tables, so threads may apply different parts at once.
template <class Enc, class T>
void encode_backward_batch_part(const T* params, const T* pts, int n, const T* dy, T* dparams, int part) {
  if constexpr (requires { Enc::template backward_batch_levels<T>(pts, n, dy, dparams, 0, 1); })
    Enc::backward_batch_levels(pts, n, dy, dparams, part, part + 1);
  else encode_backward_batch<Enc>(params, pts, n, dy, dparams);
}

/// What the colour network's raw output means: the activation the compositor applies per sample, and the ε
/// of the log the event loss takes of the composited luminance, log(ℓ + ε).
/// The paper's: a sigmoid, luminance in (0, 1), ε = 1e-3. It can express log changes of at most
/// log(1 + ε) − log(ε) = 6.9 nats, less than a scene of high dynamic range asks for.
struct SigmoidRadiance {
  using activation = nn::Sigmoid;
  static constexpr double log_eps = 1e-3;
  static constexpr const char* name = "sigmoid";
};
/// Ours: radiance exp(raw) (truncated at e^15), composited linearly like any radiance. Its log has no floor
/// but ε = 1e-4 (the simulator's dark end), so any range is within reach; its scale is free, which the
/// log-affine evaluation ignores anyway.
struct ExpRadiance {
  using activation = nn::TruncExp;
  static constexpr double log_eps = 1e-4;
  static constexpr const char* name = "exp";
};
template <class R>
concept RadiancePolicy = nn::Activation<typename R::activation> && requires {
  { R::log_eps } -> std::convertible_to<double>;
  { R::name } -> std::convertible_to<const char*>;
};

/// `DensityAct` turns the raw density (plus training noise) into σ ≥ 0: nn::ReLU as in NeRF and the
/// paper, nn::TruncExp as in Instant-NGP (large densities within reach of a small network). `Radiance`
/// turns the colour output into radiance (SigmoidRadiance, ExpRadiance).
template <nn::Encoding PosEnc, nn::Encoding DirEnc, class DensityNet, class ColorNet, class DensityAct = nn::ReLU,
          RadiancePolicy Radiance = SigmoidRadiance>
struct Field {
  static_assert(nn::Activation<DensityAct>, "Field: DensityAct must be an activation type (nn::ReLU, nn::TruncExp, ...).");
  static_assert(PosEnc::in_dims == 3, "Field: the position encoding must take 3-D points.");
  static_assert(DirEnc::in_dims == 3, "Field: the direction encoding must take 3-D directions.");
  static_assert(DensityNet::in_dims == PosEnc::out_dims,
                "Field: DensityNet's input width must equal the position encoding's output width.");
  static_assert(DensityNet::out_dims >= 2, "Field: DensityNet must output a density and at least one feature.");
  static_assert(ColorNet::in_dims == DensityNet::out_dims - 1 + DirEnc::out_dims,
                "Field: ColorNet's input width must equal DensityNet's features plus the direction encoding.");
  static_assert(std::is_same_v<typename ColorNet::output_activation, nn::Identity>,
                "Field: ColorNet must end in nn::Identity: the compositor applies the Radiance policy's activation "
                "to its raw output (another output activation would apply one twice).");
  static_assert(std::is_same_v<typename DensityNet::output_activation, nn::Identity>,
                "Field: DensityNet must end in nn::Identity: the density activation is the Field's DensityAct parameter.");

  using pos_encoding = PosEnc;
  using dir_encoding = DirEnc;
  using density_net = DensityNet;
  using color_net = ColorNet;
  using density_activation = DensityAct;
  using radiance = Radiance;
  static constexpr int channels = ColorNet::out_dims;
  static constexpr int features = DensityNet::out_dims - 1;
  static constexpr int pos_in = PosEnc::out_dims, col_in = ColorNet::in_dims;
  static constexpr std::size_t pos_offset = 0, density_offset = PosEnc::n_params, color_offset = PosEnc::n_params + DensityNet::n_params;
  static constexpr std::size_t n_params = color_offset + ColorNet::n_params;
  /// The weights through which the radiance depends on the view direction: the colour network's first-layer
  /// columns that take the direction encoding's outputs, less those that are constant (DirEnc's
  /// `constant_outputs`, if it names any: SphericalHarmonics' band 0, whose weights act as biases). Offsets
  /// within the field's parameters, [view_begin, view_end); all zero, the radiance depends on the position
  /// alone.
  static constexpr int dir_constant_outputs = [] {
    if constexpr (requires { DirEnc::constant_outputs; }) return static_cast<int>(DirEnc::constant_outputs);
    else return 0;
  }();
  /// Whether view_begin..view_end are known: the colour network lays out its first layer as nn::Mlp does
  /// (column-major weights first, `layer_out(0)` rows). A colour network of your own without it still
  /// compiles; its view range is empty.
  static constexpr bool view_weights_known = requires { ColorNet::layer_out(0); };
  static constexpr std::size_t view_rows = [] {
    if constexpr (view_weights_known) return static_cast<std::size_t>(ColorNet::layer_out(0));
    else return std::size_t{0};
  }();
  static constexpr std::size_t view_begin = color_offset + static_cast<std::size_t>(features + dir_constant_outputs) * view_rows;
  static constexpr std::size_t view_end = color_offset + static_cast<std::size_t>(col_in) * view_rows;
  /// The field's architecture: encodings, networks, density activation (what a checkpoint must match).
  static std::string architecture() {
    std::string a = "position ";
    a.append(PosEnc::name()).append(", direction ").append(DirEnc::name()).append(", density ").append(DensityNet::name());
    a.append(", colour ").append(ColorNet::name()).append(", density activation ").append(DensityAct::name);
    if constexpr (!std::is_same_v<Radiance, SigmoidRadiance>) a.append(", radiance ").append(Radiance::name);
    return a;
  }
  /// Multiply-adds per sample through both networks (forward).
  static constexpr std::size_t macs_per_sample() { return DensityNet::macs_per_sample() + ColorNet::macs_per_sample(); }

  template <class T>
  static void init(T* p, Rng& rng) {
    PosEnc::init(p + pos_offset, rng);
    DensityNet::init(p + density_offset, rng);
    ColorNet::init(p + color_offset, rng);
  }

  template <class T>
  struct Workspace {
    std::vector<T> points, enc, col_in, dcol_in, denc, dout, dirs;
    /// When set, backward() also gives the loss's gradient for each sample's point (in the normalised box
    /// [−1, 1]³, as forward() took it) and unit direction: dpts and ddirs, 3×n each, in the order of the
    /// samples the workspace holds (after keep_only, the kept ones). Pose refinement reads them.
    bool input_grad = false;
    std::vector<T> dpts, ddirs;
    /// With input_grad: the levels of a multiresolution position encoding (one that has input_backward,
    /// nn::HashGrid) the points' gradient goes through, coarsest first; all of them by default.
    int input_levels = 1 << 30;
    typename DensityNet::template Workspace<T> dens;
    typename ColorNet::template Workspace<T> col;
    int n = 0;
    /// Deferred table gradients: when set, backward() keeps the points and their encoding gradients
    /// and flush_encoding_grad() applies them in one batch. A hash grid then visits each level's table
    /// once for many tiles instead of once per tile, while every table entry still receives the same
    /// additions in the same order (the result is bit-identical).
    bool defer_encoding_grad = false;
    std::vector<T> deferred_points, deferred_denc;
    const T* deferred_params = nullptr;
    T* deferred_to = nullptr;
  };
  /// Points held by a deferring workspace before backward() flushes on its own (about 9 MB for 16×2 features).
  static constexpr std::size_t max_deferred_points = 1 << 16;

  /// Evaluates n samples. `pts` are 3×n points in the normalised scene box [−1, 1]³, `dirs` 3×n unit
  /// directions. Returns pointers to raw density (stride DensityNet::out_dims) and raw luminance (C×n).
  template <class T>
  static void forward(const T* params, const T* pts, const T* dirs, int n, Workspace<T>& ws, const T** sigma, const T** lum) {
    ws.n = 0;
    ws.dens.n = ws.col.n = 0;
    forward_at(params, pts, dirs, 0, n, ws, sigma, lum);
  }

  /// Evaluates n more samples after the `at` the workspace holds from earlier calls since forward(), which
  /// stay: a batch evaluated in pieces (rays that stop at different depths, Renderer's training
  /// termination). `pts` and `dirs` are the new samples' (3×n each). Afterwards the workspace holds at + n
  /// samples, as one forward() of all of them leaves it, bit for bit, and the returned pointers cover all.
  template <class T>
  static void forward_at(const T* params, const T* pts, const T* dirs, int at, int n, Workspace<T>& ws, const T** sigma, const T** lum) {
    require(at >= 0 && n >= 0 && ws.n >= at, "Field::forward_at: the workspace holds fewer than `at` samples");
    const int total = at + n;
    ws.n = total;
    grow(ws.points, 3 * static_cast<std::size_t>(total));
    grow(ws.enc, static_cast<std::size_t>(pos_in) * total);
    grow(ws.col_in, static_cast<std::size_t>(col_in) * total);
    grow(ws.dirs, 3 * static_cast<std::size_t>(total));
    std::copy(dirs, dirs + 3 * static_cast<std::size_t>(n), ws.dirs.begin() + 3 * static_cast<std::ptrdiff_t>(at));
    for (int j = 0; j < n; ++j) {
      T* q = &ws.points[3 * static_cast<std::size_t>(at + j)];
      for (int d = 0; d < 3; ++d) q[d] = wants_unit_cube<PosEnc>() ? (pts[3 * j + d] + T(1)) * T(0.5) : pts[3 * j + d];
    }
    if (n > 0)
      encode_batch<PosEnc>(params + pos_offset, ws.points.data() + 3 * static_cast<std::size_t>(at), n,
                           ws.enc.data() + static_cast<std::size_t>(pos_in) * at);
    const T* h = DensityNet::forward_at(params + density_offset, ws.enc.data(), at, n, ws.dens);
    for (int j = 0; j < n; ++j) {
      T* c = &ws.col_in[static_cast<std::size_t>(at + j) * col_in];
      std::copy(h + static_cast<std::size_t>(at + j) * DensityNet::out_dims + 1,
                h + static_cast<std::size_t>(at + j + 1) * DensityNet::out_dims, c);
      DirEnc::forward(static_cast<const T*>(nullptr), dirs + 3 * j, c + features);
    }
    *sigma = h;
    *lum = ColorNet::forward_at(params + color_offset, ws.col_in.data(), at, n, ws.col);
  }
  /// Buffers only grow: a workspace reused for batches of varying size is not zeroed again.
  template <class T>
  static void grow(std::vector<T>& v, std::size_t size) {
    if (v.size() < size) v.resize(size);
  }

  /// Keeps samples keep[0..m) (increasing) of the last forward: afterwards the workspace and the outputs
  /// are those forward() gives for the kept samples alone, without evaluating anything again (the
  /// encodings and the networks' activations are compacted in place).
  template <class T>
  static void keep_only(Workspace<T>& ws, const int* keep, int m, const T** sigma, const T** lum) {
    for (int j = 0; j < m; ++j) {
      const auto src = static_cast<std::size_t>(keep[j]), dst = static_cast<std::size_t>(j);  // keep[j] ≥ j
      std::copy_n(&ws.points[3 * src], 3, &ws.points[3 * dst]);
      std::copy_n(&ws.dirs[3 * src], 3, &ws.dirs[3 * dst]);
      std::copy_n(&ws.enc[src * pos_in], pos_in, &ws.enc[dst * pos_in]);
      std::copy_n(&ws.col_in[src * col_in], col_in, &ws.col_in[dst * col_in]);
    }
    ws.n = m;
    DensityNet::keep_samples(ws.dens, keep, m);
    ColorNet::keep_samples(ws.col, keep, m);
    *sigma = ws.dens.output.data();
    *lum = ws.col.output.data();
  }

  /// Applies the table gradients a deferring workspace holds (see Workspace::defer_encoding_grad).
  template <class T>
  static void flush_encoding_grad(Workspace<T>& ws) {
    if constexpr (PosEnc::n_params > 0) {
      const int n = static_cast<int>(ws.deferred_points.size() / 3);
      if (n > 0) encode_backward_batch<PosEnc>(ws.deferred_params, ws.deferred_points.data(), n, ws.deferred_denc.data(), ws.deferred_to);
    }
    clear_deferred(ws);
  }

  /// The parts deferred table gradients split into (encode_backward_parts): flush_encoding_grad_part(ws, q)
  /// for every q, then clear_deferred(ws), adds exactly what flush_encoding_grad(ws) adds.
  static constexpr int encoding_grad_parts = encode_backward_parts<PosEnc>();
  template <class T>
  static std::size_t deferred_count(const Workspace<T>& ws) {
    return ws.deferred_points.size() / 3;
  }
  /// Applies part `part` of the table gradients a deferring workspace holds, and leaves them held. Parts
  /// write to different tables, so threads may apply different parts (of one workspace or several) at once.
  template <class T>
  static void flush_encoding_grad_part(const Workspace<T>& ws, int part) {
    if constexpr (PosEnc::n_params > 0) {
      const int n = static_cast<int>(ws.deferred_points.size() / 3);
      if (n > 0)
        encode_backward_batch_part<PosEnc>(ws.deferred_params, ws.deferred_points.data(), n, ws.deferred_denc.data(), ws.deferred_to, part);
    }
  }
  /// Drops the table gradients a deferring workspace holds (after every part was applied).
  template <class T>
  static void clear_deferred(Workspace<T>& ws) {
    ws.deferred_points.clear();
    ws.deferred_denc.clear();
    ws.deferred_params = nullptr;
    ws.deferred_to = nullptr;
  }

  /// Raw density only (no colour network) of n points in [−1, 1]³, written to out[j]; for occupancy grids.
  template <class T>
  static void density(const T* params, const T* pts, int n, Workspace<T>& ws, T* out) {
    ws.points.resize(3 * static_cast<std::size_t>(n));
    ws.enc.resize(static_cast<std::size_t>(pos_in) * n);
    for (int j = 0; j < n; ++j) {
      T* q = &ws.points[3 * static_cast<std::size_t>(j)];
      for (int d = 0; d < 3; ++d) q[d] = wants_unit_cube<PosEnc>() ? (pts[3 * j + d] + T(1)) * T(0.5) : pts[3 * j + d];
    }
    encode_batch<PosEnc>(params + pos_offset, ws.points.data(), n, ws.enc.data());
    const T* h = DensityNet::forward(params + density_offset, ws.enc.data(), n, ws.dens);
    for (int j = 0; j < n; ++j) out[j] = h[static_cast<std::size_t>(j) * DensityNet::out_dims];
  }

  /// Backward for the samples of the last forward: dsigma (n, unit stride) and dlum (C×n) are gradients
  /// w.r.t. the raw outputs. Adds parameter gradients to dparams.
  template <class T>
  static void backward(const T* params, Workspace<T>& ws, const T* dsigma, const T* dlum, T* dparams) {
    const int n = ws.n;
    ws.dcol_in.assign(static_cast<std::size_t>(col_in) * n, T(0));
    // Only the features' rows of the colour network's input gradient are used (the view encoding is data),
    // unless the directions' gradient is asked for (input_grad).
    ColorNet::backward(params + color_offset, ws.col, dlum, dparams + color_offset, ws.dcol_in.data(), ws.input_grad ? col_in : features);
    ws.dout.resize(static_cast<std::size_t>(DensityNet::out_dims) * n);
    for (int j = 0; j < n; ++j) {
      T* o = &ws.dout[static_cast<std::size_t>(j) * DensityNet::out_dims];
      o[0] = dsigma[j];
      std::copy(&ws.dcol_in[static_cast<std::size_t>(j) * col_in], &ws.dcol_in[static_cast<std::size_t>(j) * col_in] + features, o + 1);
    }
    if (ws.input_grad) {
      ws.denc.assign(static_cast<std::size_t>(pos_in) * n, T(0));
      DensityNet::backward(params + density_offset, ws.dens, ws.dout.data(), dparams + density_offset, ws.denc.data());
      input_backward(params, ws);
      if constexpr (PosEnc::n_params > 0) table_backward(params, ws, dparams);
      return;
    }
    if constexpr (PosEnc::n_params > 0) {
      ws.denc.assign(static_cast<std::size_t>(pos_in) * n, T(0));
      DensityNet::backward(params + density_offset, ws.dens, ws.dout.data(), dparams + density_offset, ws.denc.data());
      table_backward(params, ws, dparams);
    } else {
      DensityNet::backward(params + density_offset, ws.dens, ws.dout.data(), dparams + density_offset, static_cast<T*>(nullptr));
    }
  }
  /// The gradients for the samples' points and directions (Workspace::input_grad) from ws.denc and the
  /// colour network's full input gradient: through the encodings' input gradients, and (p + 1) / 2 for an
  /// encoding that takes the unit cube.
  template <class T>
  static void input_backward(const T* params, Workspace<T>& ws) {
    const int n = ws.n;
    ws.dpts.assign(3 * static_cast<std::size_t>(n), T(0));
    ws.ddirs.assign(3 * static_cast<std::size_t>(n), T(0));
    for (int j = 0; j < n; ++j) {
      const std::size_t o = 3 * static_cast<std::size_t>(j);
      T dx[3] = {};
      const T* dy = &ws.denc[static_cast<std::size_t>(j) * pos_in];
      if constexpr (requires { PosEnc::input_backward(params, ws.points.data(), dy, dx, 1); })
        PosEnc::input_backward(params + pos_offset, &ws.points[o], dy, dx, ws.input_levels);
      else PosEnc::backward(params + pos_offset, &ws.points[o], dy, static_cast<T*>(nullptr), dx);
      for (int d = 0; d < 3; ++d) ws.dpts[o + d] = wants_unit_cube<PosEnc>() ? dx[d] * T(0.5) : dx[d];
      DirEnc::backward(static_cast<const T*>(nullptr), &ws.dirs[o], &ws.dcol_in[static_cast<std::size_t>(j) * col_in + features],
                       static_cast<T*>(nullptr), &ws.ddirs[o]);
    }
  }
  /// The position encoding's table gradients from ws.denc: at once, or held back in a deferring workspace.
  template <class T>
  static void table_backward(const T* params, Workspace<T>& ws, T* dparams) {
    const int n = ws.n;
    if (!ws.defer_encoding_grad) {
      encode_backward_batch<PosEnc>(params + pos_offset, ws.points.data(), n, ws.denc.data(), dparams + pos_offset);
      return;
    }
    if (ws.deferred_to && (ws.deferred_to != dparams + pos_offset || ws.deferred_params != params + pos_offset))
      flush_encoding_grad(ws);  // another network's tables: theirs first
    ws.deferred_params = params + pos_offset;
    ws.deferred_to = dparams + pos_offset;
    ws.deferred_points.insert(ws.deferred_points.end(), ws.points.begin(), ws.points.begin() + 3 * static_cast<std::ptrdiff_t>(n));
    ws.deferred_denc.insert(ws.deferred_denc.end(), ws.denc.begin(), ws.denc.begin() + static_cast<std::ptrdiff_t>(pos_in) * n);
    if (ws.deferred_points.size() / 3 >= max_deferred_points) flush_encoding_grad(ws);
  }
};

/// A Field with its networks' input and output widths derived: the density network takes the position
/// encoding's features and gives a density and `Features` features; the colour network takes those and the
/// direction encoding's features and gives `Channels` raw luminances. Both end in nn::Identity (the density
/// activation is `DensityAct`, the compositor applies `Radiance`'s), their hidden layers use `Act`, and
/// `Prec` is their product precision.
template <nn::Encoding PosEnc, nn::Encoding DirEnc, nn::MlpShape DensityShape, int Features, nn::MlpShape ColourShape, int Channels = 1,
          class Act = nn::ReLU, class Prec = nn::Fp32, class DensityAct = nn::ReLU, class Radiance = SigmoidRadiance>
using FieldOf = Field<PosEnc, DirEnc, nn::MlpOf<PosEnc::out_dims, DensityShape, 1 + Features, Act, nn::Identity, Prec>,
                      nn::MlpOf<Features + DirEnc::out_dims, ColourShape, Channels, Act, nn::Identity, Prec>, DensityAct, Radiance>;

}  // namespace evnerf::field
