//! Rank-aware logging: info on rank 0 only, warnings and errors on every rank.
#pragma once

#include <fmt/format.h>

#include <string>

namespace gen4d::log {

void set_rank(int rank);
int rank();
void set_quiet(bool quiet);

void info_str(const std::string& msg);
void warn_str(const std::string& msg);
void error_str(const std::string& msg);

template <class... A>
void info(fmt::format_string<A...> f, A&&... a) {
  info_str(fmt::format(f, std::forward<A>(a)...));
}
template <class... A>
void warn(fmt::format_string<A...> f, A&&... a) {
  warn_str(fmt::format(f, std::forward<A>(a)...));
}
template <class... A>
void error(fmt::format_string<A...> f, A&&... a) {
  error_str(fmt::format(f, std::forward<A>(a)...));
}

}  // namespace gen4d::log
