// io/text.hpp — a fast line/field scanner for whitespace-separated numeric text files, with errors that
// name the file, the line and the field. Depends on core/ only.
#pragma once
#include <charconv>
#include <cmath>
#include <string>
#include <string_view>
#include <system_error>

#include "../core/error.hpp"

namespace evnerf::io {

/// Walks the lines of an in-memory text, skipping blank lines and '#' comments. Fields are parsed with
/// std::from_chars (no locale, no iostreams), so a multi-hundred-MB events.txt parses at memory speed.
class LineScanner {
 public:
  LineScanner(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}
  /// The scanner views its text: a temporary string would be gone before the first line is read.
  LineScanner(std::string&& text, std::string file) = delete;

  /// Moves to the next non-blank, non-comment line; false at the end.
  bool next_line() {
    while (pos_ < text_.size()) {
      const std::size_t end = text_.find('\n', pos_);
      const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
      line_ = text_.substr(pos_, stop - pos_);
      if (!line_.empty() && line_.back() == '\r') line_.remove_suffix(1);
      pos_ = stop + 1;
      ++line_no_;
      cur_ = 0;
      field_ = 0;
      skip_space();
      if (cur_ < line_.size() && line_[cur_] != '#') return true;
    }
    return false;
  }
  std::size_t line_number() const { return line_no_; }
  std::string_view line() const { return line_; }
  const std::string& file() const { return file_; }

  /// A field as messages show it: at most 40 characters (a megabyte of digits is not echoed back).
  static std::string shown(std::string_view tok) {
    return tok.size() <= 40 ? std::string(tok) : std::string(tok.substr(0, 40)) + "… (" + std::to_string(tok.size()) + " characters)";
  }
  [[noreturn]] void fail(const std::string& what) const {
    std::string shown(line_.substr(0, 80));
    throw Error(file_, line_no_, what + " (line: \"" + shown + "\")");
  }

  bool at_end_of_line() {
    skip_space();
    return cur_ >= line_.size();
  }
  /// Next field as a finite double; errors on a missing, non-numeric or non-finite field.
  double real(const char* name) {
    std::string_view tok = token(name);
    double v = 0;
    auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec == std::errc::result_out_of_range) fail(std::string("field '") + name + "' is out of range");
    if (ec != std::errc() || p != tok.data() + tok.size()) fail(std::string("field '") + name + "' is not a number: '" + shown(tok) + "'");
    if (!std::isfinite(v)) fail(std::string("field '") + name + "' is not finite: '" + shown(tok) + "'");
    return v;
  }
  /// Next field as an integer.
  long long integer(const char* name) {
    std::string_view tok = token(name);
    long long v = 0;
    auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc() || p != tok.data() + tok.size())
      fail(std::string("field '") + name + "' is not an integer: '" + shown(tok) + "'");
    return v;
  }
  /// Next field as raw text.
  std::string_view word(const char* name) { return token(name); }
  /// The next field without taking it ("" at the end of the line).
  std::string_view peek_word() {
    const std::size_t at = cur_, field = field_;
    const std::string_view w = at_end_of_line() ? std::string_view{} : token("");
    cur_ = at, field_ = field;
    return w;
  }
  /// The remainder of the line (trimmed), e.g. a file name that may contain spaces.
  std::string_view rest(const char* name) {
    skip_space();
    if (cur_ >= line_.size()) fail(std::string("line is truncated: field '") + name + "' is missing");
    std::string_view r = line_.substr(cur_);
    while (!r.empty() && (r.back() == ' ' || r.back() == '\t')) r.remove_suffix(1);
    cur_ = line_.size();
    return r;
  }
  void expect_end() {
    if (!at_end_of_line()) fail("unexpected extra field '" + shown(token("extra")) + "'");
  }

 private:
  void skip_space() {
    while (cur_ < line_.size() && (line_[cur_] == ' ' || line_[cur_] == '\t' || line_[cur_] == ',')) ++cur_;
  }
  std::string_view token(const char* name) {
    skip_space();
    if (cur_ >= line_.size()) fail(std::string("line is truncated: field '") + name + "' is missing");
    const std::size_t b = cur_;
    while (cur_ < line_.size() && line_[cur_] != ' ' && line_[cur_] != '\t' && line_[cur_] != ',') ++cur_;
    ++field_;
    return line_.substr(b, cur_ - b);
  }
  std::string_view text_;
  std::string file_;
  std::string_view line_;
  std::size_t pos_ = 0, cur_ = 0, line_no_ = 0, field_ = 0;
};

}  // namespace evnerf::io
