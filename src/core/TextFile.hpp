//! Reading small input files whole and splitting their text for the line-based readers.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace gen4d {

//! The bytes of `path`. InputError "PATH: is a directory, not a WHAT", "PATH: cannot open the
//! WHAT" or "PATH: cannot read the WHAT".
std::string read_whole_file(const std::string& path, std::string_view what);

//! The lines of a text one at a time, without their "\n" or "\r\n"; the last may lack its
//! newline.
class LineReader {
 public:
  explicit LineReader(const std::string& text) : text_(text) {}
  //! The next line into `line`; false at the end of the text.
  bool next(std::string& line);
  //! 1-based number of the line last read (0 before the first).
  long number() const { return number_; }
  //! Offset of the first byte after the line last read.
  std::size_t position() const { return pos_; }

 private:
  const std::string& text_;
  std::size_t pos_ = 0;
  long number_ = 0;
};

//! A token from a file quoted for a one-line message: at most 40 characters, unprintable ones
//! as '?', "..." when cut.
std::string quote_token(const std::string& token);

//! The whitespace-separated tokens of `line`.
std::vector<std::string> split_whitespace(const std::string& line);
//! `text` with each character the table lists replaced by its text (XML entities, JSON
//! escapes); other characters below 0x20 as `control` formats them when it is given.
std::string escaped(std::string_view text,
                    std::initializer_list<std::pair<char, std::string_view>> table,
                    std::string (*control)(char) = nullptr);

//! Parses the whole token as a double within range; false otherwise (inf and nan spelt out
//! are accepted: callers that need a finite value check it).
bool parse_double(const std::string& token, double& value);

}  // namespace gen4d
