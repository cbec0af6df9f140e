// view/server.hpp — a view::Session on a loopback port, through cpp-httplib (Debian's libcpp-httplib-dev:
// a maintained HTTP/1.1 server whose request parsing, keep-alive and timeouts we would otherwise write and
// harden ourselves). Routes: GET / and the page's other files (view/page/, built into the program),
// GET /info (Session::info as JSON), GET /frame?pose=…&scale=…&show=… (a JPEG; its server time in the
// X-Frame-Ms header; a request the session refuses gets 400 and the reason). It listens on 127.0.0.1
// only: nothing beyond this machine reaches it. Depends on view/session.hpp and cpp-httplib.
#pragma once
#include <csignal>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <httplib.h>

#include "session.hpp"

namespace evnerf::view {

/// One file of the page: its path under / ("index.html" is also /), its media type, its bytes.
struct PageFile {
  std::string path, type;
  std::string_view bytes;
};

/// Serves `session` and `page` on 127.0.0.1:`port` (0: a free port the system picks) until the process
/// ends. `ready(port)` is called once the port is bound, before the first request is answered. A port that
/// cannot be bound (in use, or not allowed) is an Error naming it; a client that goes away mid-frame ends
/// only its own connection.
inline void serve(const Session& session, const std::vector<PageFile>& page, int port, const std::function<void(int)>& ready) {
  std::signal(SIGPIPE, SIG_IGN);  // a closed tab's socket fails the write; it must not end the process
  httplib::Server server;
  server.set_payload_max_length(1 << 16);  // the page sends no bodies: a request is its line and headers
  // SO_REUSEADDR (a viewer restarted at once finds its port free of the last one's closing connections),
  // without the SO_REUSEPORT cpp-httplib adds by default, which would let two viewers share one port.
  server.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  for (const auto& f : page) {
    const auto handler = [&f](const httplib::Request&, httplib::Response& res) {
      res.set_content(f.bytes.data(), f.bytes.size(), f.type.c_str());
      res.set_header("Cache-Control", "no-store");
    };
    server.Get("/" + f.path, handler);
    if (f.path == "index.html") server.Get("/", handler);
  }
  const std::string info = session.info().dump();
  server.Get("/info", [&info](const httplib::Request&, httplib::Response& res) { res.set_content(info, "application/json"); });
  server.Get("/frame", [&session](const httplib::Request& req, httplib::Response& res) {
    try {
      const auto r = parse_frame_request([&req](const std::string& name) -> std::optional<std::string> {
        if (!req.has_param(name.c_str())) return std::nullopt;
        return req.get_param_value(name.c_str());
      });
      auto f = session.frame(r);
      res.set_header("X-Frame-Ms", std::to_string(f.ms));
      res.set_header("X-Frame-Size", std::to_string(f.width) + "x" + std::to_string(f.height));
      res.set_header("Cache-Control", "no-store");
      res.set_content(std::move(f.jpeg), "image/jpeg");
    } catch (const std::exception& e) {
      res.status = 400;
      res.set_content(e.what(), "text/plain");
    }
  });
  const std::string host = "127.0.0.1";
  int bound = port;
  if (port == 0) bound = server.bind_to_any_port(host);
  else if (!server.bind_to_port(host, port)) bound = -1;
  if (bound <= 0)
    throw Error(host + ":" + std::to_string(port) + ": cannot listen there (the port is in use, or not allowed); pass another --port");
  ready(bound);
  if (!server.listen_after_bind()) throw Error(host + ":" + std::to_string(bound) + ": the server stopped accepting connections");
}

}  // namespace evnerf::view
