// Event HDF5 files (io::read_hdf5_checked: event_utils/HQF and DSEC layouts), as io::load reads them. The
// input is written to a file in /dev/shm (the reader opens paths); the HDF5 library itself is Debian's,
// uninstrumented, so the coverage guiding the fuzzer is that of evnerf's reader (in this process, after the
// child's check passed), while ASan checks every buffer evnerf hands the library. A file read whole is read
// again through a time window, which must give the same events (DSEC files skip there through ms_to_idx).
//
// A sanitizer report in the child exits with 99 (run.sh sets ASan's exitcode), and goes to a file of its own
// (a fork handler sets the child's report path). Where the report's first frame outside the sanitizer
// runtime is in libhdf5 or one of its filter plugins, it is the library's defect on a corrupt file, which
// the child exists to contain: the input is kept under HDF5_DEFECTS (run.sh: $OUT/hdf5/libhdf5_defects/)
// with its report, and it counts as a refused file. A report anywhere else (evnerf's code) is a finding.
#include <dlfcn.h>
#include <pthread.h>
#include <sanitizer/common_interface_defs.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <evnerf/io/hdf5.hpp>

#include "fuzz.hpp"

namespace {

std::string report_stem() { return "/dev/shm/evnerf_fuzz_hdf5_child_" + std::to_string(getpid()); }

// Registered once, in the parent: each forked child writes its sanitizer report under the parent's stem.
const bool kChildReports = [] {
  static std::string stem;
  stem = report_stem();
  pthread_atfork(nullptr, nullptr, [] { __sanitizer_set_report_path(stem.c_str()); });
  return true;
}();

// Debian's HDF5 Blosc plugins call blosc_init(), which allocates Blosc's global context and its mutex once
// per process; only blosc_destroy() frees them, and the plugins never call it. libhdf5 unloads its plugins at
// exit, libblosc with them, and LeakSanitizer's check at exit then found the two blocks unreferenced (after
// an hour's run, from one Blosc file's read in this process). Held open here, libblosc's globals stay mapped
// and still point to them.
const bool kBloscNamed = [] {
  dlopen("libblosc.so.1", RTLD_NOW | RTLD_NODELETE);  // absent: no plugin can load it either
  return true;
}();

// Whether a report's first frame outside the sanitizer runtime lies in libhdf5 or an HDF5 filter plugin. The
// runtime's frames: its named functions, and the interceptors linked into this executable, which carry no
// source line (`in strdup (/path/fuzz_hdf5+0x…)`, where evnerf's frames name their file and line).
bool in_the_library(const std::string& report) {
  static const std::string self = "(" + std::filesystem::read_symlink("/proc/self/exe").string() + "+0x";
  std::istringstream in(report);
  for (std::string line; std::getline(in, line);) {
    const auto hash = line.find_first_not_of(' ');
    if (hash == std::string::npos || line[hash] != '#' || line.find(" 0x") == std::string::npos) continue;
    if (line.find("__interceptor_") != std::string::npos || line.find("__asan") != std::string::npos ||
        line.find("__sanitizer") != std::string::npos || line.find("libclang_rt") != std::string::npos ||
        line.find(self) != std::string::npos)
      continue;
    return line.find("libhdf5") != std::string::npos || line.find("/hdf5/serial/plugins/") != std::string::npos;
  }
  return false;
}

// The children's report files, read and removed: their texts, one a file.
std::vector<std::string> take_reports() {
  namespace fs = std::filesystem;
  const std::string stem = fs::path(report_stem()).filename().string();
  std::vector<std::string> texts;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/dev/shm", ec)) {
    if (e.path().filename().string().rfind(stem + ".", 0) != 0) continue;
    std::ifstream f(e.path());
    std::stringstream text;
    text << f.rdbuf();
    texts.push_back(text.str());
    fs::remove(e.path(), ec);
  }
  return texts;
}

// The child's reports, read and removed; true when every error report is the library's (and there is one).
// A file that holds only warnings (an allocation the sanitizer refused, which the library reports as an
// error of its own) decides nothing.
bool library_defect(const std::uint8_t* data, std::size_t size) {
  namespace fs = std::filesystem;
  std::string all;
  bool any = false, library = true;
  std::error_code ec;
  for (const auto& text : take_reports()) {
    all += text;
    if (text.find("ERROR: ") == std::string::npos) continue;
    any = true;
    library = library && in_the_library(text);
  }
  if (!any || !library) {
    std::fputs(all.c_str(), stderr);  // into the run's log, with the finding
    return false;
  }
  if (const char* dir = std::getenv("HDF5_DEFECTS")) {
    fs::create_directories(dir, ec);
    char name[32];
    std::snprintf(name, sizeof name, "%016zx", std::hash<std::string_view>{}(std::string_view(reinterpret_cast<const char*>(data), size)));
    std::ofstream(fs::path(dir) / (std::string(name) + ".h5"), std::ios::binary)
        .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    std::ofstream(fs::path(dir) / (std::string(name) + ".txt")) << all;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)kChildReports;
  (void)kBloscNamed;
  const std::string path = evfuzz::to_file(data, size, "recording.h5");
  if (path.empty()) return 0;
  take_reports();  // what earlier inputs' children left (warnings only: an error report is taken at once)
  evfuzz::run([&] {
    // As io::load reads: in a child first, so that the HDF5 library's own crashes on corrupt files become
    // an Error.
    evnerf::io::Hdf5Recording rec;
    try {
      rec = evnerf::io::read_hdf5_checked(path, 0, 0);
    } catch (const evnerf::Error& e) {
      if (std::string(e.what()).find("exit status 99") != std::string::npos && !library_defect(data, size))
        evfuzz::broken("a sanitizer reported in the child, in evnerf's code");
      throw;
    }
    evfuzz::expect(rec.events.size() > 0 && rec.width > 0 && rec.height > 0, "an empty recording was accepted");
    for (std::size_t i = 0; i < rec.events.size(); ++i)
      evfuzz::expect(rec.events.x[i] < rec.width && rec.events.y[i] < rec.height, "event outside the sensor");
    evfuzz::expect(rec.frames.size() == rec.frame_times.size(), "frames and times differ in number");
    // A time window (the middle third of the events' span): DSEC's ms_to_idx, checked by the whole read,
    // makes the reader skip to the window; what it returns must be exactly the whole read's events there.
    const auto& t = rec.events.t;
    const double a = t[t.size() / 3], b = t[2 * t.size() / 3];
    if (!(a < b)) return;
    const auto w = evnerf::io::read_hdf5(path, 0, 0, a, b);
    const auto i0 = static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), a) - t.begin());
    const auto i1 = static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), b) - t.begin());
    evfuzz::expect(w.events.size() == i1 - i0, "a time window read other events than the whole read has there");
    for (std::size_t i = 0; i < w.events.size(); ++i)
      evfuzz::expect(w.events.t[i] == t[i0 + i] && w.events.x[i] == rec.events.x[i0 + i] && w.events.y[i] == rec.events.y[i0 + i] &&
                         w.events.polarity[i] == rec.events.polarity[i0 + i],
                     "a time window read other events than the whole read has there");
  });
  // Every file, dataset, group, type, space and attribute the reader opened is closed again, whatever
  // happened. (Memory the HDF5 library keeps or loses inside itself on a corrupt file is its own:
  // lsan.supp.)
  evfuzz::expect(H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL) == 0, "an HDF5 handle was left open");
  return 0;
}
