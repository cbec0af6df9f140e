// io/video.hpp — H.264 MP4 videos through Debian's ffmpeg: raw RGB frames piped into an `ffmpeg` process
// (libx264, yuv420p, the widely played profile), written to a temporary file and renamed into place once
// ffmpeg has finished well, so a video is whole or absent. What `render --video` writes. Depends on core/.
#pragma once
#include <algorithm>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "../core/error.hpp"
#include "../core/types.hpp"

namespace evnerf::io {

/// `s` quoted for the POSIX shell (single quotes; a quote inside as '\'').
inline std::string shell_quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// Whether an `ffmpeg` that runs is on the PATH.
inline bool ffmpeg_available() { return std::system("ffmpeg -hide_banner -version > /dev/null 2>&1") == 0; }

/// An MP4 file being written: frames of width × height (RGB in [0, 1]; made even for yuv420p by repeating
/// the last column or row) at `fps` frames a second. finish() closes it and moves it into place; a writer
/// destroyed unfinished leaves nothing behind.
class Mp4Writer {
 public:
  Mp4Writer(const std::filesystem::path& path, int width, int height, double fps)
      : path_(path), tmp_(path.string() + ".tmp.mp4"), w_(width + width % 2), h_(height + height % 2) {
    require(width > 0 && height > 0 && std::isfinite(fps) && fps > 0, path.string() + ": a video needs a size and a positive frame rate");
    const std::string cmd = "ffmpeg -hide_banner -loglevel error -nostdin -y -f rawvideo -pix_fmt rgb24 -s " + std::to_string(w_) + "x" +
                            std::to_string(h_) + " -r " + std::to_string(fps) +
                            " -i - -c:v libx264 -preset medium -crf 18 -pix_fmt yuv420p -movflags +faststart -f mp4 " +
                            shell_quoted(tmp_.string());
    // A write to an ffmpeg that has died must fail, not end this process: SIGPIPE is ignored meanwhile.
    old_pipe_ = std::signal(SIGPIPE, SIG_IGN);
    pipe_ = popen(cmd.c_str(), "w");
    if (!pipe_) {
      std::signal(SIGPIPE, old_pipe_);
      throw Error(path.string(), 0, "cannot start ffmpeg (install Debian's ffmpeg package)");
    }
  }
  Mp4Writer(const Mp4Writer&) = delete;
  Mp4Writer& operator=(const Mp4Writer&) = delete;
  ~Mp4Writer() {
    if (pipe_) {
      pclose(pipe_);
      std::error_code ec;
      std::filesystem::remove(tmp_, ec);
    }
    std::signal(SIGPIPE, old_pipe_);
  }
  /// Appends one frame (1 or 3 channels, the size given; values clamped to [0, 1]).
  void frame(const Image& img) {
    require(pipe_ != nullptr, path_.string() + ": the video is already finished");
    require(img.width + img.width % 2 == w_ && img.height + img.height % 2 == h_ && (img.channels == 1 || img.channels == 3),
            path_.string() + ": a frame of another size or channel count than the video's");
    std::vector<unsigned char> px(static_cast<std::size_t>(w_) * h_ * 3);
    for (int y = 0; y < h_; ++y)
      for (int x = 0; x < w_; ++x)
        for (int c = 0; c < 3; ++c) {
          const float v = img.at(std::min(x, img.width - 1), std::min(y, img.height - 1), img.channels == 3 ? c : 0);
          px[(static_cast<std::size_t>(y) * w_ + x) * 3 + c] =
              static_cast<unsigned char>(std::lround(255.f * (std::isfinite(v) ? std::clamp(v, 0.f, 1.f) : 0.f)));
        }
    if (std::fwrite(px.data(), 1, px.size(), pipe_) != px.size())
      throw Error(path_.string(), 0, "ffmpeg stopped taking frames (its message is above)");
    ++frames_;
  }
  /// Closes the stream, waits for ffmpeg and moves the file into place; an Error when ffmpeg failed.
  void finish() {
    const int status = pclose(pipe_);
    pipe_ = nullptr;
    std::error_code ec;
    if (status != 0) {
      std::filesystem::remove(tmp_, ec);
      throw Error(path_.string(), 0, "ffmpeg failed (exit status " + std::to_string(status) + "; its message is above)");
    }
    std::filesystem::rename(tmp_, path_, ec);
    if (ec) throw Error(path_.string(), 0, "cannot move the finished video into place: " + ec.message());
  }
  int frames() const { return frames_; }

 private:
  std::filesystem::path path_, tmp_;
  int w_ = 0, h_ = 0, frames_ = 0;
  FILE* pipe_ = nullptr;
  void (*old_pipe_)(int) = SIG_DFL;
};

}  // namespace evnerf::io
