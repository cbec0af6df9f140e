// sim/mesh.hpp — triangle meshes in simulated scenes. Any file assimp reads (glTF 1/2, Collada, OBJ, PLY,
// FBX, 3DS, …) with its node transforms applied, normalised into a sphere (MeshPlacement); albedo from the
// material's base or diffuse colour, vertex colours and base-colour textures (PNG, JPEG, TGA or BMP, on disk
// or embedded, found as model viewers find them: resolve_texture; one not found is warned of once and its
// material keeps its base colour), the textures mip-mapped and sampled at the pixel's footprint so that fine
// texture does not alias into spurious events; rays cast through Embree 3's BVH as streams. Compiled where
// CMake found libassimp-dev and libembree-dev (EVNERF_HAVE_MESH); sim/scene.hpp includes it and its `mesh`
// directive calls load_mesh. Depends on sim/scene.hpp, io/image_io.hpp, core/warn.hpp, assimp and Embree.
#pragma once
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../core/warn.hpp"
#include "../io/image_io.hpp"
#include "scene.hpp"

namespace evnerf::sim {

/// sRGB-encoded value (texture files) to linear albedo.
inline double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

/// A texture as a pyramid of linear RGB levels, each the 2×2 box filter of the one before, sampled
/// trilinearly (bilinear within a level, linear between the two levels around the footprint) with
/// repeating coordinates. Texture coordinates follow assimp's: v = 0 is the image's bottom row.
class MipTexture {
 public:
  /// `img`: RGB in [0, 1]; `srgb`: the values are sRGB-encoded (image files) and are linearised.
  MipTexture(const Image& img, bool srgb) {
    require(img.channels >= 3 && img.width > 0 && img.height > 0, "MipTexture: an RGB image is needed");
    Level l{img.width, img.height, std::vector<float>(static_cast<std::size_t>(img.width) * img.height * 3)};
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        for (int k = 0; k < 3; ++k) {
          const double v = img.at(x, y, k);
          l.rgb[(static_cast<std::size_t>(y) * img.width + x) * 3 + k] = static_cast<float>(srgb ? srgb_to_linear(v) : v);
        }
    levels_.push_back(std::move(l));
    while (levels_.back().w > 1 || levels_.back().h > 1) {
      const Level& a = levels_.back();
      Level b{std::max(1, (a.w + 1) / 2), std::max(1, (a.h + 1) / 2), {}};
      b.rgb.resize(static_cast<std::size_t>(b.w) * b.h * 3);
      for (int y = 0; y < b.h; ++y)
        for (int x = 0; x < b.w; ++x)
          for (int k = 0; k < 3; ++k) {
            double s = 0;
            for (int dy = 0; dy < 2; ++dy)
              for (int dx = 0; dx < 2; ++dx) s += a.at(std::min(2 * x + dx, a.w - 1), std::min(2 * y + dy, a.h - 1), k);
            b.rgb[(static_cast<std::size_t>(y) * b.w + x) * 3 + k] = static_cast<float>(s / 4);
          }
      levels_.push_back(std::move(b));
    }
  }
  int width() const { return levels_.front().w; }
  int height() const { return levels_.front().h; }
  std::size_t levels() const { return levels_.size(); }

  /// Linear RGB at (u, v) for a footprint of `fw` texture units (1 = the whole texture).
  Vec3 sample(double u, double v, double fw) const {
    const double texels = std::max(fw * std::max(width(), height()), 1.0);
    const double lod = std::min(std::log2(texels), static_cast<double>(levels_.size() - 1));
    const auto l0 = static_cast<std::size_t>(lod);
    const double f = lod - static_cast<double>(l0);
    const Vec3 a = bilinear(levels_[l0], u, v);
    if (f <= 0 || l0 + 1 >= levels_.size()) return a;
    return (1 - f) * a + f * bilinear(levels_[l0 + 1], u, v);
  }

 private:
  struct Level {
    int w, h;
    std::vector<float> rgb;
    double at(int x, int y, int k) const { return rgb[(static_cast<std::size_t>(y) * w + x) * 3 + k]; }
  };
  static int wrap(long long i, int n) {
    const long long m = i % n;
    return static_cast<int>(m < 0 ? m + n : m);
  }
  static Vec3 bilinear(const Level& l, double u, double v) {
    const double x = (u - std::floor(u)) * l.w - 0.5, y = (1 - (v - std::floor(v))) * l.h - 0.5;
    const double fx0 = std::floor(x), fy0 = std::floor(y);
    const auto x0 = static_cast<long long>(fx0), y0 = static_cast<long long>(fy0);
    const double fx = x - fx0, fy = y - fy0;
    Vec3 c = Vec3::Zero();
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const int xx = wrap(x0 + dx, l.w), yy = wrap(y0 + dy, l.h);
        const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
        for (int k = 0; k < 3; ++k) c[k] += w * l.at(xx, yy, k);
      }
    return c;
  }
  std::vector<Level> levels_;
};

namespace detail {
inline std::string ascii_lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// The entry of folder `dir` named `name`: that name itself if it exists, else the first by name of those that
/// differ from it only in ASCII case.
inline std::optional<std::filesystem::path> entry_any_case(const std::filesystem::path& dir, const std::string& name) {
  std::error_code ec;
  if (std::filesystem::exists(dir / name, ec)) return dir / name;
  const std::string want = ascii_lower(name);
  std::optional<std::filesystem::path> best;
  for (auto it = std::filesystem::directory_iterator(dir, ec); !ec && it != std::filesystem::directory_iterator(); it.increment(ec))
    if (ascii_lower(it->path().filename().string()) == want && (!best || it->path() < *best)) best = it->path();
  return best;
}

/// `rel`'s components ('/'-separated; "." and ".." as usual) walked from `dir`, each matched in any case.
inline std::optional<std::filesystem::path> walk_any_case(std::filesystem::path dir, const std::string& rel) {
  std::size_t at = 0;
  while (at <= rel.size()) {
    const std::size_t end = std::min(rel.find('/', at), rel.size());
    const std::string part = rel.substr(at, end - at);
    at = end + 1;
    if (part.empty() || part == ".") continue;
    if (part == "..") {
      dir = dir.parent_path();
      continue;
    }
    auto next = entry_any_case(dir, part);
    if (!next) return std::nullopt;
    dir = *next;
  }
  std::error_code ec;
  if (!std::filesystem::is_regular_file(dir, ec)) return std::nullopt;
  return dir;
}
}  // namespace detail

/// The file a mesh's texture name means, found as model viewers find it, or nothing. The name as written
/// (Windows separators read as '/', Blender's leading "//" as the model's folder), relative to the model's
/// folder or absolute, each component matched in any case (a 3DS file's "TEST.PNG" is "test.png"); then
/// the name's last component in the model's folder (absolute paths from the author's machine, such as
/// "C:\models\top.tga", where the file lies beside the model). A placeholder assimp gives when a file
/// names no texture of its own (a name beginning with '$', as an MD2 model's "$texture_dummy.bmp") means the
/// skin beside the model: the image whose name is the model's (sydney.md2: sydney.bmp), else the first by name
/// that begins with it (faerie.md2: faerie2.bmp).
inline std::optional<std::filesystem::path> resolve_texture(const std::filesystem::path& model, const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path folder = model.parent_path().empty() ? fs::path(".") : model.parent_path();
  std::error_code ec;
  if (name.empty()) return std::nullopt;
  if (name[0] == '$') {
    const std::string stem = detail::ascii_lower(model.stem().string());
    std::optional<fs::path> exact, prefixed;
    for (auto it = fs::directory_iterator(folder, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
      const fs::path& p = it->path();
      const std::string ext = detail::ascii_lower(p.extension().string()), s = detail::ascii_lower(p.stem().string());
      if (!(ext == ".bmp" || ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tga") || !fs::is_regular_file(p, ec)) continue;
      if (s == stem && (!exact || p < *exact)) exact = p;
      if (s.starts_with(stem) && (!prefixed || p < *prefixed)) prefixed = p;
    }
    return exact ? exact : prefixed;
  }
  std::string rel = name;
  std::replace(rel.begin(), rel.end(), '\\', '/');
  if (rel.starts_with("//")) rel = rel.substr(2);  // Blender: relative to the .blend file
  const bool drive = rel.size() >= 2 && rel[1] == ':' && std::isalpha(static_cast<unsigned char>(rel[0]));
  if (!drive && rel[0] == '/' && fs::is_regular_file(rel, ec)) return fs::path(rel);
  if (!drive)
    if (auto p = detail::walk_any_case(folder, rel)) return p;
  const std::string last = rel.substr(rel.find_last_of('/') == std::string::npos ? 0 : rel.find_last_of('/') + 1);
  if (auto p = detail::entry_any_case(folder, last); p && fs::is_regular_file(*p, ec)) return p;
  return std::nullopt;
}

/// A triangle mesh: positions in scene units after the placement, per-vertex normals, texture coordinates
/// and colours, per-triangle material; rays go through an Embree BVH built once.
class Mesh final : public Surface {
 public:
  struct Material {
    Vec3 colour = Vec3::Ones();  ///< linear albedo factor
    int texture = -1;            ///< index into textures(), or none
  };

  /// Loads `where.file` with assimp and places it (see MeshPlacement). Errors name the file: one assimp
  /// cannot read, one without triangles, a texture found but undecodable, coordinates that are not finite
  /// or span no volume. A texture not found (resolve_texture) is a warning, once a name.
  static std::shared_ptr<const Mesh> load(const MeshPlacement& where) {
    const std::string file = where.file.string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(where.file, ec)) throw Error(file, 0, "no such mesh file");
    Assimp::Importer importer;
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    const aiScene* sc =
        importer.ReadFile(file, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_GenSmoothNormals |
                                    aiProcess_PreTransformVertices | aiProcess_SortByPType | aiProcess_ValidateDataStructure);
    if (!sc) {
      const std::string why = importer.GetErrorString();
      if (why.find("No meshes remaining") != std::string::npos)  // what is left after points and lines are taken out
        throw Error(file, 0, "the file holds no triangles (points, lines or nothing)");
      throw Error(file, 0, "assimp cannot read it: " + why);
    }
    auto mesh = std::shared_ptr<Mesh>(new Mesh());
    Mesh& m = *mesh;
    m.file_ = file;
    // Materials and their textures; a texture that is not found is named once.
    std::set<std::string> missing;
    for (unsigned i = 0; i < sc->mNumMaterials; ++i) {
      const aiMaterial* mat = sc->mMaterials[i];
      Material out;
      aiString tex;
      const bool has_tex =
          mat->GetTexture(aiTextureType_BASE_COLOR, 0, &tex) == AI_SUCCESS || mat->GetTexture(aiTextureType_DIFFUSE, 0, &tex) == AI_SUCCESS;
      aiColor4D c;
      if (mat->Get(AI_MATKEY_BASE_COLOR, c) == AI_SUCCESS) out.colour = Vec3(c.r, c.g, c.b);  // glTF: the factor multiplies the texture
      else if (!has_tex && mat->Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS) out.colour = Vec3(c.r, c.g, c.b);
      if (has_tex) {
        if (auto img = load_texture(sc, tex.C_Str(), where.file, file)) {
          out.texture = static_cast<int>(m.textures_.size());
          m.textures_.emplace_back(*img, true);
        } else {
          if (mat->Get(AI_MATKEY_BASE_COLOR, c) != AI_SUCCESS && mat->Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS)
            out.colour = Vec3(c.r, c.g, c.b);
          if (missing.insert(tex.C_Str()).second)
            warn(file + ": texture '" + std::string(tex.C_Str()) + "' not found beside the model (material " + std::to_string(i) +
                 " and any other that uses it show their base colour)");
        }
      }
      if (!out.colour.allFinite() || out.colour.minCoeff() < 0)
        throw Error(file, 0, "material " + std::to_string(i) + " has a colour that is negative or not finite");
      m.materials_.push_back(out);
    }
    if (m.materials_.empty()) m.materials_.push_back(Material{Vec3(0.8, 0.8, 0.8), -1});
    // Triangles of every mesh (node transforms applied by aiProcess_PreTransformVertices).
    for (unsigned k = 0; k < sc->mNumMeshes; ++k) {
      const aiMesh* am = sc->mMeshes[k];
      if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
      const auto base = static_cast<std::uint32_t>(m.pos_.size());
      for (unsigned v = 0; v < am->mNumVertices; ++v) {
        const aiVector3D& p = am->mVertices[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
          throw Error(file, 0,
                      "mesh " + std::to_string(k) + " ('" + std::string(am->mName.C_Str()) + "'): vertex " + std::to_string(v) +
                          " has a coordinate that is not finite");
        m.pos_.emplace_back(p.x, p.y, p.z);
        m.nrm_.push_back(am->mNormals && std::isfinite(am->mNormals[v].x) ? Vec3(am->mNormals[v].x, am->mNormals[v].y, am->mNormals[v].z)
                                                                          : Vec3::Zero());
        m.uv_.push_back(am->mTextureCoords[0] ? Eigen::Vector2d(am->mTextureCoords[0][v].x, am->mTextureCoords[0][v].y)
                                              : Eigen::Vector2d::Zero());
        m.col_.push_back(am->mColors[0] ? Vec3(am->mColors[0][v].r, am->mColors[0][v].g, am->mColors[0][v].b) : Vec3::Ones());
      }
      const auto material = std::min<std::uint32_t>(am->mMaterialIndex, static_cast<std::uint32_t>(m.materials_.size() - 1));
      for (unsigned f = 0; f < am->mNumFaces; ++f) {
        const aiFace& face = am->mFaces[f];
        if (face.mNumIndices != 3) continue;
        for (int j = 0; j < 3; ++j) m.idx_.push_back(base + face.mIndices[j]);
        m.tri_material_.push_back(material);
      }
    }
    if (m.tri_material_.empty()) throw Error(file, 0, "the file holds no triangles (points, lines or nothing)");
    m.place(where);
    m.build();
    return mesh;
  }

  ~Mesh() override {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
  }
  Mesh(const Mesh&) = delete;
  Mesh& operator=(const Mesh&) = delete;

  std::size_t triangles() const { return tri_material_.size(); }
  std::size_t vertices() const { return pos_.size(); }
  const std::vector<Material>& materials() const { return materials_; }
  const std::vector<MipTexture>& textures() const { return textures_; }
  const std::string& file() const { return file_; }
  /// The bounding box of the placed vertices.
  Vec3 lower() const { return lo_; }
  Vec3 upper() const { return hi_; }

  void intersect(const Vec3& o, std::span<const Vec3> dirs, double pix_angle, std::span<Hit> hits) const override {
    thread_local std::vector<RTCRayHit> rays;
    rays.resize(dirs.size());
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      RTCRayHit& r = rays[i];
      r.ray.org_x = static_cast<float>(o.x());
      r.ray.org_y = static_cast<float>(o.y());
      r.ray.org_z = static_cast<float>(o.z());
      r.ray.dir_x = static_cast<float>(dirs[i].x());
      r.ray.dir_y = static_cast<float>(dirs[i].y());
      r.ray.dir_z = static_cast<float>(dirs[i].z());
      r.ray.tnear = 1e-6f;
      r.ray.tfar = std::isfinite(hits[i].t) ? static_cast<float>(hits[i].t) : INFINITY;
      r.ray.time = 0;
      r.ray.mask = ~0u;
      r.ray.id = static_cast<unsigned>(i);
      r.ray.flags = 0;
      r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    rtcIntersect1M(scene_, &ctx, rays.data(), static_cast<unsigned>(rays.size()), sizeof(RTCRayHit));
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      const RTCRayHit& r = rays[i];
      if (r.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      hits[i] = shade_hit(r.hit.primID, r.hit.u, r.hit.v, r.ray.tfar, dirs[i], pix_angle);
    }
  }

 private:
  Mesh() = default;

  /// A texture named `name`, embedded in the scene or a file found by resolve_texture; nothing when no file
  /// is found (the material then keeps its base colour). A file found but undecodable is an error.
  static std::optional<Image> load_texture(const aiScene* sc, const std::string& name, const std::filesystem::path& model,
                                           const std::string& file) {
    if (const aiTexture* t = sc->GetEmbeddedTexture(name.c_str())) {
      const std::string what = file + " (embedded texture '" + name + "')";
      if (t->mHeight == 0)  // compressed: mWidth bytes of a PNG or JPEG file
        return io::decode_image(std::string_view(reinterpret_cast<const char*>(t->pcData), t->mWidth), what, 3,
                                std::string(".") + t->achFormatHint);
      if (static_cast<long long>(t->mWidth) * t->mHeight > io::kMaxImagePixels) throw Error(what, 0, "the texture is too large");
      Image img(static_cast<int>(t->mWidth), static_cast<int>(t->mHeight), 3);
      for (std::size_t i = 0; i < static_cast<std::size_t>(t->mWidth) * t->mHeight; ++i) {
        img.data[3 * i] = t->pcData[i].r / 255.f;
        img.data[3 * i + 1] = t->pcData[i].g / 255.f;
        img.data[3 * i + 2] = t->pcData[i].b / 255.f;
      }
      return img;
    }
    const auto path = resolve_texture(model, name);
    if (!path) return std::nullopt;
    try {
      return io::decode_image(read_file(*path), path->string(), 3);
    } catch (const Error& e) {
      throw Error(file, 0, "texture '" + name + "': " + e.message());
    }
  }

  /// Scales and moves the vertices into the placement's sphere and turns the file's up axis to -y.
  void place(const MeshPlacement& where) {
    Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
    if (where.up == "+y") turn = Eigen::Vector3d(1, -1, -1).asDiagonal();  // 180° about x
    else if (where.up == "+z") turn << 1, 0, 0, 0, 0, -1, 0, 1, 0;         // +90° about x: +z → -y
    else if (where.up != "-y") throw Error(file_, 0, "the up axis must be +y, +z or -y, not '" + where.up + "'");
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    for (const auto& p : pos_) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const Vec3 mid = 0.5 * (lo + hi);
    double r = 0;
    for (const auto& p : pos_) r = std::max(r, (p - mid).norm());
    if (!(r > 1e-30) || !std::isfinite(r) || !((hi - lo).maxCoeff() > 1e-9 * r))
      throw Error(file_, 0, "the vertices span no volume (all at one point): the mesh cannot be normalised into a sphere");
    const double s = where.radius / r;
    for (auto& p : pos_) p = where.centre + s * (turn * (p - mid));
    for (auto& n : nrm_) n = turn * n;
    lo_ = Vec3::Constant(INFINITY);
    hi_ = Vec3::Constant(-INFINITY);
    for (const auto& p : pos_) {
      lo_ = lo_.cwiseMin(p);
      hi_ = hi_.cwiseMax(p);
    }
    // Texture units per scene unit of each triangle: the footprint of a pixel in texture coordinates.
    const std::size_t nt = tri_material_.size();
    uv_per_length_.resize(nt);
    for (std::size_t t = 0; t < nt; ++t) {
      const auto a = idx_[3 * t], b = idx_[3 * t + 1], c = idx_[3 * t + 2];
      const double area = (pos_[b] - pos_[a]).cross(pos_[c] - pos_[a]).norm();
      const Eigen::Vector2d e1 = uv_[b] - uv_[a], e2 = uv_[c] - uv_[a];
      const double uv_area = std::abs(e1.x() * e2.y() - e1.y() * e2.x());
      uv_per_length_[t] = area > 0 ? std::sqrt(uv_area / area) : 0.0;
    }
  }

  void build() {
    device_ = rtcNewDevice("verbose=0");
    if (!device_) throw Error(file_, 0, "Embree could not create a device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), pos_.size()));
    auto* ix =
        static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles()));
    if (!v || !ix) {
      rtcReleaseGeometry(g);
      throw Error(file_, 0, "Embree could not allocate the mesh's buffers");
    }
    for (std::size_t i = 0; i < pos_.size(); ++i)
      for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(pos_[i][k]);
    std::copy(idx_.begin(), idx_.end(), ix);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene_, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene_);
    if (const RTCError e = rtcGetDeviceError(device_); e != RTC_ERROR_NONE)
      throw Error(file_, 0, "Embree could not build the mesh's BVH (error " + std::to_string(static_cast<int>(e)) + ")");
  }

  Hit shade_hit(unsigned tri, float bu, float bv, float t, const Vec3& d, double pix_angle) const {
    const auto a = idx_[3 * tri], b = idx_[3 * tri + 1], c = idx_[3 * tri + 2];
    const double w1 = bu, w2 = bv, w0 = 1 - w1 - w2;
    Hit h;
    h.t = t;
    Vec3 ng = (pos_[b] - pos_[a]).cross(pos_[c] - pos_[a]);
    ng.normalize();
    Vec3 n = w0 * nrm_[a] + w1 * nrm_[b] + w2 * nrm_[c];
    n = n.squaredNorm() > 1e-24 ? Vec3(n.normalized()) : ng;
    if (ng.dot(d) > 0) {  // the side the ray sees
      ng = -ng;
      n = -n;
    }
    if (n.dot(ng) < 0) n = ng;  // a shading normal facing away from the face it shades
    h.normal = n;
    const Material& m = materials_[tri_material_[tri]];
    Vec3 albedo = m.colour.cwiseProduct(w0 * col_[a] + w1 * col_[b] + w2 * col_[c]);
    if (m.texture >= 0) {
      const Eigen::Vector2d uv = w0 * uv_[a] + w1 * uv_[b] + w2 * uv_[c];
      const double dn = d.norm();
      const double footprint = pix_angle * t * dn / std::max(0.05, std::abs(ng.dot(d)) / dn);
      albedo = albedo.cwiseProduct(textures_[static_cast<std::size_t>(m.texture)].sample(uv.x(), uv.y(), footprint * uv_per_length_[tri]));
    }
    h.albedo = albedo;
    return h;
  }

  std::string file_;
  std::vector<Vec3> pos_, nrm_, col_;
  std::vector<Eigen::Vector2d> uv_;
  std::vector<std::uint32_t> idx_, tri_material_;
  std::vector<double> uv_per_length_;
  std::vector<Material> materials_;
  std::vector<MipTexture> textures_;
  Vec3 lo_ = Vec3::Zero(), hi_ = Vec3::Zero();
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

inline std::shared_ptr<const Surface> load_mesh(const MeshPlacement& where) { return Mesh::load(where); }

}  // namespace evnerf::sim
