#include "mpm/Particles.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "parallel/Comm.hpp"
#include "parallel/Distribute.hpp"

namespace gen4d::mpm {

void Particles::clear() {
  id.clear();
  x.clear();
  v.clear();
  C.clear();
  F.clear();
  state.clear();
  mass.clear();
  vol0.clear();
  flag.clear();
  material.clear();
  extra.clear();
}

void Particles::reserve(std::size_t n) {
  id.reserve(n);
  x.reserve(3 * n);
  v.reserve(3 * n);
  C.reserve(9 * n);
  F.reserve(9 * n);
  state.reserve(kStateSize * n);
  mass.reserve(n);
  vol0.reserve(n);
  flag.reserve(n);
  material.reserve(n);
  extra.reserve(static_cast<std::size_t>(extra_width) * n);
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
  id.insert(id.end(), o.id.begin(), o.id.end());
  x.insert(x.end(), o.x.begin(), o.x.end());
  v.insert(v.end(), o.v.begin(), o.v.end());
  C.insert(C.end(), o.C.begin(), o.C.end());
  F.insert(F.end(), o.F.begin(), o.F.end());
  state.insert(state.end(), o.state.begin(), o.state.end());
  mass.insert(mass.end(), o.mass.begin(), o.mass.end());
  vol0.insert(vol0.end(), o.vol0.begin(), o.vol0.end());
  flag.insert(flag.end(), o.flag.begin(), o.flag.end());
  material.insert(material.end(), o.material.begin(), o.material.end());
  extra.insert(extra.end(), o.extra.begin(), o.extra.end());
}

void Particles::pack(std::size_t i, double* r) const {
  r[0] = static_cast<double>(id[i]);
  std::copy_n(&x[3 * i], 3, r + 1);
  std::copy_n(&v[3 * i], 3, r + 4);
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
  if (x.size() != 3 * n || v.size() != 3 * n || C.size() != 9 * n || F.size() != 9 * n ||
      state.size() != kStateSize * n || mass.size() != n || vol0.size() != n || flag.size() != n ||
      material.size() != n || extra.size() != static_cast<std::size_t>(extra_width) * n)
    return "the particle arrays disagree in length";
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
  keep_rows(id, 1, keep);
  keep_rows(x, 3, keep);
  keep_rows(v, 3, keep);
  keep_rows(C, 9, keep);
  keep_rows(F, 9, keep);
  keep_rows(state, kStateSize, keep);
  keep_rows(mass, 1, keep);
  keep_rows(vol0, 1, keep);
  keep_rows(flag, 1, keep);
  keep_rows(material, 1, keep);
  keep_rows(extra, extra_width, keep);
}

void Particles::sort_by_id() {
  std::vector<std::size_t> order(size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return id[a] < id[b]; });
  permute_rows(id, 1, order);
  permute_rows(x, 3, order);
  permute_rows(v, 3, order);
  permute_rows(C, 9, order);
  permute_rows(F, 9, order);
  permute_rows(state, kStateSize, order);
  permute_rows(mass, 1, order);
  permute_rows(vol0, 1, order);
  permute_rows(flag, 1, order);
  permute_rows(material, 1, order);
  permute_rows(extra, extra_width, order);
}

std::size_t redistribute(MPI_Comm comm, Particles& p, const std::vector<int>& dest) {
  if (parallel::size(comm) == 1) return 0;
  parallel::RowExchange ex;
  ex.fill_gaps_from_end();
  ex.add(p.id, 1).add(p.x, 3).add(p.v, 3).add(p.C, 9).add(p.F, 9).add(p.state, kStateSize);
  ex.add(p.mass, 1).add(p.vol0, 1).add(p.flag, 1).add(p.material, 1).add(p.extra, p.extra_width);
  return ex.exchange(comm, dest);
}

}  // namespace gen4d::mpm
