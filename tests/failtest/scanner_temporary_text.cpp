// expect: use of deleted function
// A LineScanner views its text; built on a temporary string it would read freed memory (AddressSanitizer
// found this once, in the reader of linear/log_offset.txt). The constructor taking a temporary is deleted.
#include <string>

#include <evnerf/io/text.hpp>

std::string contents() { return "1 2 3\n"; }

int main() {
  evnerf::io::LineScanner s(contents(), "file.txt");
  return s.next_line() ? 0 : 1;
}
