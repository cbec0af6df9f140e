// core/progress.hpp — a one-line terminal progress bar with ETA and user fields.
// Depends on the standard library only.
#pragma once
#include <chrono>
#include <cstdio>
#include <string>
#include <unistd.h>

namespace evnerf {

class Progress {
 public:
  Progress(long total, std::string label, bool enabled = true)
      : total_(total), label_(std::move(label)), enabled_(enabled),
        tty_(::isatty(::fileno(stderr))), start_(clock::now()) {}

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
    std::fprintf(stderr, "%s%s [%s] %ld/%ld %5.1fs eta %5.1fs %s%s", tty_ ? "\r" : "", label_.c_str(), bar.c_str(),
                 done, total_, el, eta, extra.c_str(), tty_ ? "\033[K" : "\n");
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

}  // namespace evnerf
