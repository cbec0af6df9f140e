// evnerf — the command-line tool: inspect, simulate, baselines, train, render, eval.
#include <evnerf/evnerf.hpp>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: evnerf <command> [args]\n"
               "  inspect <folder>                 summary of an IJRR-layout recording\n");
  return 2;
}

int cmd_inspect(const std::vector<std::string>& a) {
  if (a.size() != 1) return usage();
  auto d = evnerf::io::load_ijrr(a[0]);
  std::printf("recording     %s%s\n", a[0].c_str(), d.from_cache ? " (events from cache)" : "");
  std::fputs(evnerf::io::format_summary(evnerf::io::summarize(d)).c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  std::vector<std::string> args(argv + 2, argv + argc);
  try {
    if (cmd == "inspect") return cmd_inspect(args);
    return usage();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evnerf %s: error: %s\n", cmd.c_str(), e.what());
    return 1;
  }
}
