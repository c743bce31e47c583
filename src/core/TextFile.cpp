#include "core/TextFile.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"

namespace gen4d {

std::string read_whole_file(const std::string& path, std::string_view what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(fmt::format("{}: is a directory, not a {}", path, what));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the {}", path, what));
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) throw InputError(fmt::format("{}: cannot read the {}", path, what));
  return buf.str();
}

bool LineReader::next(std::string& line) {
  if (pos_ >= text_.size()) return false;
  std::size_t end = text_.find('\n', pos_);
  if (end == std::string::npos) end = text_.size();
  line.assign(text_, pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  pos_ = end + 1;
  ++number_;
  return true;
}

std::string quote_token(const std::string& token) {
  std::string out = token.substr(0, 40);
  for (char& c : out)
    if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
  return "'" + out + (token.size() > 40 ? "...'" : "'");
}

std::vector<std::string> split_whitespace(const std::string& line) {
  std::vector<std::string> tokens;
  std::istringstream in(line);
  std::string t;
  while (in >> t) tokens.push_back(t);
  return tokens;
}

bool parse_double(const std::string& token, double& value) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  value = std::strtod(begin, &end);
  return end != begin && *end == '\0' && errno != ERANGE;
}

std::string escaped(std::string_view text,
                    std::initializer_list<std::pair<char, std::string_view>> table,
                    std::string (*control)(char)) {
  std::string out;
  for (char c : text) {
    const auto* hit = std::find_if(table.begin(), table.end(),
                                   [c](const auto& entry) { return entry.first == c; });
    if (hit != table.end())
      out += hit->second;
    else if (control && static_cast<unsigned char>(c) < 0x20)
      out += control(c);
    else
      out += c;
  }
  return out;
}

}  // namespace gen4d
