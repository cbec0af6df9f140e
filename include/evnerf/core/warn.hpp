// core/warn.hpp — warnings: what evnerf reads and can still use, but a user should know of (a texture it
// could not find, a recording cut short). One process-wide sink: stderr by default ("evnerf: warning: …"),
// or a handler the embedding code sets (tests collect them; Python could turn them into its warnings).
// Depends on the standard library only.
#pragma once
#include <cstdio>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace evnerf {

/// Receives each warning's text (one line, no trailing newline).
using WarningHandler = std::function<void(const std::string&)>;

namespace detail {
struct WarningSink {
  std::mutex lock;
  WarningHandler handler;  ///< empty: stderr
};
inline WarningSink& warning_sink() {
  static WarningSink sink;
  return sink;
}
}  // namespace detail

/// Sends `message` to the handler, or to stderr as "evnerf: warning: <message>". Safe from any thread;
/// warnings are delivered one at a time.
inline void warn(const std::string& message) {
  auto& s = detail::warning_sink();
  std::lock_guard<std::mutex> hold(s.lock);
  if (s.handler) {
    s.handler(message);
  } else {
    std::fprintf(stderr, "evnerf: warning: %s\n", message.c_str());
    std::fflush(stderr);
  }
}

/// Routes warnings to `handler` (empty: back to stderr) and returns the handler that was set.
inline WarningHandler set_warning_handler(WarningHandler handler) {
  auto& s = detail::warning_sink();
  std::lock_guard<std::mutex> hold(s.lock);
  return std::exchange(s.handler, std::move(handler));
}

/// Collects the warnings raised while it lives (a scope's own; restores the handler before it).
class WarningCollector {
 public:
  WarningCollector() : previous_(set_warning_handler([this](const std::string& m) { messages_.push_back(m); })) {}
  ~WarningCollector() { set_warning_handler(std::move(previous_)); }
  WarningCollector(const WarningCollector&) = delete;
  WarningCollector& operator=(const WarningCollector&) = delete;
  const std::vector<std::string>& messages() const { return messages_; }

 private:
  std::vector<std::string> messages_;
  WarningHandler previous_;
};

}  // namespace evnerf
