// core/progress.hpp — a one-line terminal progress bar with ETA and user fields, and the line a long file
// read shows (ReadProgressLine). Depends on the standard library only.
#pragma once
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <unistd.h>

namespace evnerf {

class Progress {
 public:
  Progress(long total, std::string label, bool enabled = true)
      : total_(total), label_(std::move(label)), enabled_(enabled), tty_(::isatty(::fileno(stderr))), start_(clock::now()) {}

  /// Shows step `done` of total with extra text (e.g. "loss 0.12  rays/s 5e4"). Redraws at most 5×/s
  /// on a terminal, every 10 % otherwise.
  void update(long done, const std::string& extra = {}) {
    if (!enabled_) return;
    auto now = clock::now();
    const double el = seconds(now);
    const bool last = done >= total_;
    if (tty_) {
      if (!last && el - last_draw_ < 0.2) return;
    } else {
      const long decile = total_ > 0 ? done * 10 / total_ : 0;
      if (!last && decile == last_decile_) return;
      last_decile_ = decile;
    }
    last_draw_ = el;
    const double frac = total_ > 0 ? static_cast<double>(done) / total_ : 1.0;
    const double eta = frac > 0 ? el * (1 - frac) / frac : 0;
    const int w = 24, filled = static_cast<int>(frac * w);
    std::string bar(filled, '#');
    bar.resize(w, '.');
    std::fprintf(stderr, "%s%s [%s] %ld/%ld %5.1fs eta %5.1fs %s%s", tty_ ? "\r" : "", label_.c_str(), bar.c_str(), done, total_, el, eta,
                 extra.c_str(), tty_ ? "\033[K" : "\n");
    if (tty_ && last) std::fputc('\n', stderr);
    std::fflush(stderr);
  }
  double elapsed() const { return seconds(clock::now()); }

 private:
  using clock = std::chrono::steady_clock;
  double seconds(clock::time_point t) const { return std::chrono::duration<double>(t - start_).count(); }
  long total_;
  std::string label_;
  bool enabled_, tty_;
  clock::time_point start_;
  double last_draw_ = -1;
  long last_decile_ = -1;
};

/// What a long read of one file shows on `out` (stderr): nothing for a read done within `delay` seconds
/// (most reads), then "reading FILE: 37 % (1.07 of 2.88 GB) 4.1 s, eta 7.0 s" every `every` seconds, as
/// one line redrawn on a terminal and as separate lines otherwise, and a last line at the end. Callable as
/// a ReadProgress (done, total bytes). `now` (seconds) is the steady clock unless a test gives its own.
class ReadProgressLine {
 public:
  explicit ReadProgressLine(std::string file, std::FILE* out = stderr, double delay = 1.0, double every = 1.0,
                            std::function<double()> now = {})
      : file_(std::move(file)), out_(out), delay_(delay), every_(every), now_(now ? std::move(now) : steady_seconds()),
        tty_(::isatty(::fileno(out))), start_(now_()) {}
  void operator()(std::uint64_t done, std::uint64_t total) {
    const double el = now_() - start_;
    const bool last = total > 0 && done >= total;
    if (el < delay_ || (!last && shown_ && el - last_draw_ < every_) || (last && finished_)) return;
    shown_ = true, finished_ = last, last_draw_ = el;
    const double frac = total > 0 ? static_cast<double>(done) / static_cast<double>(total) : 0;
    const double gb = 1e-9;
    char eta[32] = "";
    if (!last && frac > 0) std::snprintf(eta, sizeof eta, ", eta %.1f s", el * (1 - frac) / frac);
    std::fprintf(out_, "%sreading %s: %.0f %% (%.2f of %.2f GB) %.1f s%s%s", tty_ ? "\r" : "", file_.c_str(), 100 * frac,
                 static_cast<double>(done) * gb, static_cast<double>(total) * gb, el, eta,
                 !tty_  ? "\n"
                 : last ? "\033[K\n"
                        : "\033[K");
    std::fflush(out_);
  }

 private:
  static std::function<double()> steady_seconds() {
    return [] { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); };
  }
  std::string file_;
  std::FILE* out_;
  double delay_, every_;
  std::function<double()> now_;
  bool tty_, shown_ = false, finished_ = false;
  double start_, last_draw_ = 0;
};

}  // namespace evnerf
