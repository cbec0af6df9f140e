// Event HDF5 files (io::read_hdf5_checked: event_utils/HQF and DSEC layouts), as io::load reads them. The
// input is written to a file in /dev/shm (the reader opens paths); the HDF5 library itself is Debian's,
// uninstrumented, so the coverage guiding the fuzzer is that of evnerf's reader (in this process, after the
// child's check passed), while ASan checks every buffer evnerf hands the library. A file read whole is read
// again through a time window, which must give the same events (DSEC files skip there through ms_to_idx).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include <evnerf/io/hdf5.hpp>

#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = evfuzz::to_file(data, size, "recording.h5");
  if (path.empty()) return 0;
  evfuzz::run([&] {
    // As io::load reads: in a child first, so that the HDF5 library's own crashes on corrupt files become
    // an Error. A sanitizer report in the child (in our code or at the library's calls into libc) exits
    // with 99 (run.sh sets ASan's exitcode): that is a finding, not a refusal.
    evnerf::io::Hdf5Recording rec;
    try {
      rec = evnerf::io::read_hdf5_checked(path, 0, 0);
    } catch (const evnerf::Error& e) {
      if (std::string(e.what()).find("exit status 99") != std::string::npos) evfuzz::broken("a sanitizer reported in the child");
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
