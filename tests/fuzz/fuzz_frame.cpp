// The viewer's frame query (view/request.hpp): the input cut at '&' into name=value pairs, as a browser
// sends them (no percent-decoding: cpp-httplib decodes before the parser sees a value).
#include <evnerf/view/request.hpp>

#include <map>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string in(evfuzz::text(data, size));
  std::map<std::string, std::string> q;
  for (std::size_t at = 0; at <= in.size();) {
    const std::size_t end = std::min(in.find('&', at), in.size());
    const std::string item = in.substr(at, end - at);
    const std::size_t eq = item.find('=');
    if (eq != std::string::npos) q[item.substr(0, eq)] = item.substr(eq + 1);
    at = end + 1;
  }
  evfuzz::run([&] {
    const auto r = evnerf::view::parse_frame_request([&](const std::string& k) -> std::optional<std::string> {
      const auto it = q.find(k);
      if (it == q.end()) return std::nullopt;
      return it->second;
    });
    evfuzz::expect(r.scale >= 1 && r.scale <= evnerf::view::kMaxScale, "scale out of range");
    evfuzz::expect(std::abs(r.pose.q.norm() - 1) < 1e-9 && r.pose.t.allFinite(), "pose not a rigid motion");
  });
  return 0;
}
