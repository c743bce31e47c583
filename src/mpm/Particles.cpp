#include "mpm/Particles.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "parallel/Comm.hpp"
#include "parallel/Distribute.hpp"

namespace gen4d::mpm {

void Particles::clear() {
  for_each_column([](int, auto& a) { a.clear(); }, *this);
}

void Particles::reserve(std::size_t n) {
  for_each_column([n](int width, auto& a) { a.reserve(static_cast<std::size_t>(width) * n); },
                  *this);
}

void Particles::push_back(std::int64_t gid, const double* pos, const double* vel, double m,
                          double v0, const double* init_state, const double* extra_values) {
  id.push_back(gid);
  x.insert(x.end(), pos, pos + 3);
  v.insert(v.end(), vel, vel + 3);
  C.insert(C.end(), 9, 0.0);
  static constexpr double kI[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  F.insert(F.end(), kI, kI + 9);
  state.insert(state.end(), init_state, init_state + kStateSize);
  mass.push_back(m);
  vol0.push_back(v0);
  flag.push_back(0);
  material.push_back(0);
  if (extra_values)
    extra.insert(extra.end(), extra_values, extra_values + extra_width);
  else
    extra.insert(extra.end(), static_cast<std::size_t>(extra_width), 0.0);
}

void Particles::append(const Particles& o) {
  if (o.extra_width != extra_width)
    throw std::logic_error(
        fmt::format("Particles::append: extra width {} onto {}", o.extra_width, extra_width));
  for_each_column([](int, auto& a, const auto& b) { a.insert(a.end(), b.begin(), b.end()); }, *this,
                  o);
}

void Particles::pack_motion(std::size_t i, double* r) const {
  r[0] = static_cast<double>(id[i]);
  std::copy_n(&x[3 * i], 3, r + 1);
  std::copy_n(&v[3 * i], 3, r + 4);
}

void Particles::pack(std::size_t i, double* r) const {
  pack_motion(i, r);
  std::copy_n(&C[9 * i], 9, r + 7);
  std::copy_n(&F[9 * i], 9, r + 16);
  std::copy_n(&state[kStateSize * i], kStateSize, r + 25);
  r[25 + kStateSize] = mass[i];
  r[26 + kStateSize] = vol0[i];
  r[27 + kStateSize] = flag[i];
  r[28 + kStateSize] = material[i];
}

std::string Particles::inconsistency() const {
  const std::size_t n = size();
  if (extra_width < 0) return fmt::format("negative extra width {}", extra_width);
  bool consistent = true;
  for_each_column(
      [&](int width, const auto& a) {
        consistent = consistent && a.size() == static_cast<std::size_t>(width) * n;
      },
      *this);
  if (!consistent) return "the particle arrays disagree in length";
  return "";
}

namespace {
template <class T>
void keep_rows(std::vector<T>& a, int width, const std::vector<std::uint8_t>& keep) {
  std::size_t out = 0;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    if (out != i)
      std::copy_n(a.begin() + static_cast<long>(width * i), width,
                  a.begin() + static_cast<long>(width * out));
    ++out;
  }
  a.resize(width * out);
}
template <class T>
void permute_rows(std::vector<T>& a, int width, const std::vector<std::size_t>& order) {
  std::vector<T> b(a.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    std::copy_n(a.begin() + static_cast<long>(width * order[i]), width,
                b.begin() + static_cast<long>(width * i));
  a.swap(b);
}
}  // namespace

void Particles::compact(const std::vector<std::uint8_t>& keep) {
  for_each_column([&](int width, auto& a) { keep_rows(a, width, keep); }, *this);
}

void Particles::sort_by_id() {
  std::vector<std::size_t> order(size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return id[a] < id[b]; });
  for_each_column([&](int width, auto& a) { permute_rows(a, width, order); }, *this);
}

std::size_t redistribute(MPI_Comm comm, Particles& p, const std::vector<int>& dest) {
  if (parallel::size(comm) == 1) return 0;
  parallel::RowExchange ex;
  ex.fill_gaps_from_end();
  for_each_column([&](int width, auto& a) { ex.add(a, width); }, p);
  return ex.exchange(comm, dest);
}

}  // namespace gen4d::mpm
