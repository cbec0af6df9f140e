// io/image_io.hpp — PNG read (stb_image) and atomic PNG write (stb_image_write), float images in [0, 1].
// Depends on core/ and stb only.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <stb_image.h>
#include <stb_image_write.h>

#include "../core/error.hpp"
#include "../core/fileio.hpp"
#include "../core/types.hpp"

namespace evnerf::io {

/// The largest image evnerf decodes, in pixels (a header announcing more is refused before decoding).
inline constexpr long long kMaxImagePixels = 1LL << 26;

namespace detail {
/// stb_image's decode of checked bytes, refusing a header that announces more than kMaxImagePixels.
inline Image decode_checked(std::string_view bytes, const std::string& file, int want_channels) {
  int w = 0, h = 0, c = 0;
  const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
  const int len = static_cast<int>(bytes.size());
  if (!stbi_info_from_memory(data, len, &w, &h, &c)) throw Error(file, 0, std::string("cannot decode image: ") + stbi_failure_reason());
  if (w <= 0 || h <= 0) throw Error(file, 0, "cannot decode image: its header gives no size");
  if (static_cast<long long>(w) * h > kMaxImagePixels)
    throw Error(file, 0,
                "image header announces " + std::to_string(w) + "x" + std::to_string(h) + " pixels (at most " +
                    std::to_string(kMaxImagePixels) + " are accepted)");
  Image img;
  auto convert = [&](auto* px, float full_scale) {
    if (!px) throw Error(file, 0, std::string("cannot decode image: ") + stbi_failure_reason());
    const int ch = want_channels ? want_channels : c;
    img = Image(w, h, ch);
    for (std::size_t i = 0; i < img.data.size(); ++i) img.data[i] = px[i] / full_scale;
    stbi_image_free(px);
  };
  if (stbi_is_16_bit_from_memory(data, len)) convert(stbi_load_16_from_memory(data, len, &w, &h, &c, want_channels), 65535.f);
  else convert(stbi_load_from_memory(data, len, &w, &h, &c, want_channels), 255.f);
  return img;
}
}  // namespace detail

/// Decodes a PNG (8 or 16 bit) held in memory as float in [0, 1] with
/// `want_channels` channels (0 = as stored). Errors name `file`: undecodable data, or a header announcing
/// more than kMaxImagePixels pixels (refused before anything is allocated).
inline Image decode_png(std::string_view bytes, const std::string& file, int want_channels = 0) {
  require(want_channels >= 0 && want_channels <= 4, "decode_png: want_channels must be 0 … 4");
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw Error(file, 0, "image file of " + std::to_string(bytes.size()) + " bytes is too large to decode");
  // PNG only: stb_image's other decoders (TGA, PIC, PSD, …) trust headers of a few bytes (a 34-byte input took
  // 10 s in its TGA path, found by tests/fuzz), and no recording or texture uses them.
  if (bytes.size() < 8 || bytes.substr(0, 8) != "\x89PNG\r\n\x1a\n")
    throw Error(file, 0, "cannot decode image: not a PNG file (no PNG signature)");
  // A PNG's chunks must fit in the file: stb_image grows its buffer to a chunk's announced length before it
  // finds the data missing (2 GB for a 100-byte file).
  // Nor can the compressed pixels be fewer than deflate's best ratio (1032:1) allows for the size the header
  // announces: a 1 kB file that claims 8000x8000 pixels is refused before 256 MB are allocated for them.
  if (bytes.size() >= 8 && bytes.substr(0, 8) == "\x89PNG\r\n\x1a\n") {
    std::uint64_t idat = 0, raw = 0;
    for (std::size_t at = 8; at + 8 <= bytes.size();) {
      const auto byte = [&](std::size_t i) { return std::uint64_t{static_cast<unsigned char>(bytes[at + i])}; };
      const std::uint64_t len = (byte(0) << 24) | (byte(1) << 16) | (byte(2) << 8) | byte(3);
      if (len + 12 > bytes.size() - at)
        throw Error(file, 0,
                    "cannot decode image: truncated or corrupt PNG (a chunk of " + std::to_string(len) + " bytes at byte " +
                        std::to_string(at) + ", " + std::to_string(bytes.size() - at) + " bytes remain)");
      const std::string_view type = bytes.substr(at + 4, 4);
      if (type == "IHDR" && len >= 10) {
        const std::uint64_t w = (byte(8) << 24) | (byte(9) << 16) | (byte(10) << 8) | byte(11);
        const std::uint64_t h = (byte(12) << 24) | (byte(13) << 16) | (byte(14) << 8) | byte(15);
        const std::uint64_t depth = byte(16), colour = byte(17);
        const std::uint64_t samples = colour == 2 ? 3 : colour == 4 ? 2 : colour == 6 ? 4 : 1;
        raw = h * (1 + (w * samples * std::max<std::uint64_t>(depth, 1) + 7) / 8);
      }
      if (type == "IDAT") idat += len;
      if (type == "IEND") break;
      at += 12 + len;
    }
    if (raw > 0 && raw > 1032 * idat + 4096)
      throw Error(file, 0,
                  "cannot decode image: truncated or corrupt PNG (" + std::to_string(idat) + " bytes of compressed pixels cannot " +
                      "hold the " + std::to_string(raw) + " bytes its header announces)");
  }
  return detail::decode_checked(bytes, file, want_channels);
}

/// Decodes a PNG (decode_png), a baseline or progressive JPEG, an uncompressed BMP, or (when `file` ends in
/// .tga) a TGA, the formats mesh files' textures come in, as float in [0, 1]; `extension` stands in for the
/// file's (".tga" for a TGA held in memory without a name). A TGA has no signature: its header is checked
/// against the file's size first (an uncompressed image must be all there; run-length packets expand at most
/// 128-fold), and a BMP's rows must all be in the file, so a short file never decodes into a large image.
inline Image decode_image(std::string_view bytes, const std::string& file, int want_channels = 0, std::string extension = {}) {
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw Error(file, 0, "image file of " + std::to_string(bytes.size()) + " bytes is too large to decode");
  if (bytes.size() >= 3 && bytes.substr(0, 3) == "\xFF\xD8\xFF") return detail::decode_checked(bytes, file, want_channels);
  if (bytes.size() >= 8 && bytes.substr(0, 8) == "\x89PNG\r\n\x1a\n") return decode_png(bytes, file, want_channels);
  if (extension.empty()) extension = std::filesystem::path(file).extension().string();
  for (auto& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".tga") {
    auto b = [&](std::size_t i) { return std::uint64_t{static_cast<unsigned char>(bytes[i])}; };
    if (bytes.size() < 18)
      throw Error(file, 0, "cannot decode image: a TGA header is 18 bytes, the file has " + std::to_string(bytes.size()));
    const std::uint64_t id = b(0), cmap = b(1), type = b(2), cmap_len = b(5) | (b(6) << 8), cmap_bits = b(7);
    const std::uint64_t w = b(12) | (b(13) << 8), h = b(14) | (b(15) << 8), bits = b(16);
    if (type != 1 && type != 2 && type != 3 && type != 9 && type != 10 && type != 11)
      throw Error(file, 0, "cannot decode image: TGA image type " + std::to_string(type) + " (1-3 and 9-11 are read)");
    if (w == 0 || h == 0 || (bits != 8 && bits != 15 && bits != 16 && bits != 24 && bits != 32))
      throw Error(file, 0,
                  "cannot decode image: TGA header gives " + std::to_string(w) + "x" + std::to_string(h) + " pixels of " +
                      std::to_string(bits) + " bits");
    const std::uint64_t head = 18 + id + (cmap ? cmap_len * ((cmap_bits + 7) / 8) : 0), pixels = w * h;
    const std::uint64_t body = bytes.size() > head ? bytes.size() - head : 0, need = pixels * ((bits + 7) / 8);
    if (type < 9 ? body < need : body * 128 < pixels)
      throw Error(file, 0,
                  "cannot decode image: truncated TGA (" + std::to_string(body) + " bytes of pixel data for " + std::to_string(w) + "x" +
                      std::to_string(h) + " pixels)");
    return detail::decode_checked(bytes, file, want_channels);
  }
  if (bytes.size() >= 2 && bytes.substr(0, 2) == "BM") {
    // A BMP's header is checked against the file's size: the rows its header announces must all be there.
    // Only uncompressed rows are read (stb_image reads no run-length BMP either).
    auto u = [&](std::size_t at, int n) {
      std::uint64_t v = 0;
      for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
      return v;
    };
    if (bytes.size() < 26)
      throw Error(file, 0, "cannot decode image: a BMP header is at least 26 bytes, the file has " + std::to_string(bytes.size()));
    const std::uint64_t offset = u(10, 4), header = u(14, 4);
    std::uint64_t w = 0, h = 0, bits = 0, compression = 0;
    if (header == 12) {
      w = u(18, 2), h = u(20, 2), bits = u(24, 2);
    } else if (header >= 40 && bytes.size() >= 34) {
      w = u(18, 4);
      const auto sh = static_cast<std::int32_t>(u(22, 4));  // negative: rows stored top-down
      h = static_cast<std::uint64_t>(sh < 0 ? -static_cast<std::int64_t>(sh) : sh);
      bits = u(28, 2), compression = u(30, 4);
    } else {
      throw Error(file, 0, "cannot decode image: BMP info header of " + std::to_string(header) + " bytes (12 or at least 40 are read)");
    }
    if (compression != 0 && compression != 3)
      throw Error(file, 0,
                  "cannot decode image: compressed BMP (compression " + std::to_string(compression) + "; uncompressed rows are read)");
    if (w == 0 || h == 0 || w >= (1u << 31) || (bits != 1 && bits != 4 && bits != 8 && bits != 16 && bits != 24 && bits != 32))
      throw Error(file, 0,
                  "cannot decode image: BMP header gives " + std::to_string(w) + "x" + std::to_string(h) + " pixels of " +
                      std::to_string(bits) + " bits");
    const std::uint64_t row = (w * bits + 31) / 32 * 4;
    if (offset > bytes.size() || (bytes.size() - offset) / row < h)
      throw Error(file, 0,
                  "cannot decode image: truncated BMP (" + std::to_string(bytes.size() - std::min<std::uint64_t>(offset, bytes.size())) +
                      " bytes of pixel data for " + std::to_string(w) + "x" + std::to_string(h) + " pixels)");
    return detail::decode_checked(bytes, file, want_channels);
  }
  throw Error(file, 0, "cannot decode image: not a PNG, JPEG, TGA or BMP file");
}

/// Loads a PNG file (see decode_png).
inline Image read_png(const std::filesystem::path& path, int want_channels = 0) {
  return decode_png(read_file(path), path.string(), want_channels);
}

namespace detail {
/// A float image's values clamped to [0, 1] as 8-bit samples (non-finite as 0), and the stb writers' sink
/// that appends their output to a std::string.
inline std::vector<unsigned char> to_bytes(const Image& img) {
  std::vector<unsigned char> px(img.data.size());
  for (std::size_t i = 0; i < px.size(); ++i) {
    const float v = std::isfinite(img.data[i]) ? std::clamp(img.data[i], 0.f, 1.f) : 0.f;
    px[i] = static_cast<unsigned char>(std::lround(v * 255.f));
  }
  return px;
}
inline void append_to_string(void* ctx, void* data, int size) {
  static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), static_cast<std::size_t>(size));
}
}  // namespace detail

/// Writes a float image (values clamped to [0, 1]) as an 8-bit PNG, atomically.
inline void write_png(const std::filesystem::path& path, const Image& img) {
  require(img.width > 0 && img.height > 0 && (img.channels == 1 || img.channels == 3 || img.channels == 4),
          "write_png: image must be 1, 3 or 4 channels and non-empty");
  const auto px = detail::to_bytes(img);
  std::string out;
  if (!stbi_write_png_to_func(detail::append_to_string, &out, img.width, img.height, img.channels, px.data(), img.width * img.channels))
    throw Error(path.string(), 0, "PNG encoding failed");
  write_file_atomic(path, out);
}

/// A float image (values clamped to [0, 1], 1 or 3 channels) as the bytes of a baseline JPEG file of
/// `quality` 1..100 (what the viewer sends: a 346 × 260 frame in a few kilobytes).
inline std::string encode_jpeg(const Image& img, int quality = 90) {
  require(img.width > 0 && img.height > 0 && (img.channels == 1 || img.channels == 3),
          "encode_jpeg: image must be 1 or 3 channels and non-empty");
  require(quality >= 1 && quality <= 100, "encode_jpeg: quality must be 1..100");
  const auto px = detail::to_bytes(img);
  std::string out;
  if (!stbi_write_jpg_to_func(detail::append_to_string, &out, img.width, img.height, img.channels, px.data(), quality))
    throw Error("encode_jpeg: JPEG encoding failed");
  return out;
}

/// Maps values in [lo, hi] to colours for depth maps: a piecewise-linear ramp through dark blue, cyan,
/// yellow and dark red (near = blue, far = red); non-finite values stay black.
inline Image colorize(const Image& grey, float lo, float hi) {
  static constexpr float stops[5][3] = {
      {0.05f, 0.03f, 0.35f}, {0.10f, 0.55f, 0.95f}, {0.45f, 0.95f, 0.45f}, {0.98f, 0.80f, 0.15f}, {0.60f, 0.05f, 0.05f}};
  Image out(grey.width, grey.height, 3);
  const float span = hi > lo ? hi - lo : 1.f;
  for (std::size_t i = 0; i < grey.pixels(); ++i) {
    const float v = grey.data[i];
    if (!std::isfinite(v)) continue;
    const float x = std::clamp((v - lo) / span, 0.f, 1.f) * 4.f;
    const int k = std::min(3, static_cast<int>(x));
    const float f = x - static_cast<float>(k);
    for (int c = 0; c < 3; ++c) out.data[3 * i + c] = (1 - f) * stops[k][c] + f * stops[k + 1][c];
  }
  return out;
}

/// Places images side by side (converted to `channels`), with a 2-pixel gap.
inline Image montage(const std::vector<Image>& imgs, int channels = 1) {
  int w = 0, h = 0;
  for (auto& im : imgs) {
    w += im.width + 2;
    h = std::max(h, im.height);
  }
  Image out(std::max(0, w - 2), h, channels, 1.f);
  int x0 = 0;
  for (auto& im : imgs) {
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x)
        for (int c = 0; c < channels; ++c) out.at(x0 + x, y, c) = im.at(x, y, std::min(c, im.channels - 1));
    x0 += im.width + 2;
  }
  return out;
}

}  // namespace evnerf::io
