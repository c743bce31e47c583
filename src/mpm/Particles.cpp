#include "mpm/Particles.hpp"

#include <algorithm>
#include <numeric>

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
}

void Particles::push_back(std::int64_t gid, const double* pos, const double* vel, double m,
                          double v0, const double* init_state) {
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
}

void Particles::append_packed(const double* r) {
  id.push_back(static_cast<std::int64_t>(r[0]));
  x.insert(x.end(), r + 1, r + 4);
  v.insert(v.end(), r + 4, r + 7);
  C.insert(C.end(), r + 7, r + 16);
  F.insert(F.end(), r + 16, r + 25);
  state.insert(state.end(), r + 25, r + 25 + kStateSize);
  mass.push_back(r[25 + kStateSize]);
  vol0.push_back(r[26 + kStateSize]);
  flag.push_back(static_cast<std::uint8_t>(r[27 + kStateSize]));
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
}

std::size_t redistribute(MPI_Comm comm, Particles& p,
                         const std::function<int(std::size_t)>& owner) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  if (size == 1) return 0;
  const std::size_t n = p.size();
  std::vector<int> dest(n);
  std::vector<int> send_count(size, 0), recv_count(size, 0);
  std::vector<std::uint8_t> keep(n, 1);
  std::size_t sent = 0;
  for (std::size_t i = 0; i < n; ++i) {
    dest[i] = owner(i);
    if (dest[i] != rank) {
      keep[i] = 0;
      ++send_count[dest[i]];
      ++sent;
    }
  }
  MPI_Alltoall(send_count.data(), 1, MPI_INT, recv_count.data(), 1, MPI_INT, comm);
  constexpr int R = Particles::kRecord;
  std::vector<int> sdispl(size, 0), rdispl(size, 0), scount(size), rcount(size);
  for (int r = 0; r < size; ++r) {
    scount[r] = send_count[r] * R;
    rcount[r] = recv_count[r] * R;
    if (r > 0) {
      sdispl[r] = sdispl[r - 1] + scount[r - 1];
      rdispl[r] = rdispl[r - 1] + rcount[r - 1];
    }
  }
  std::vector<double> sendbuf(static_cast<std::size_t>(sdispl[size - 1] + scount[size - 1]));
  std::vector<double> recvbuf(static_cast<std::size_t>(rdispl[size - 1] + rcount[size - 1]));
  std::vector<int> cursor = sdispl;
  for (std::size_t i = 0; i < n; ++i) {
    if (keep[i]) continue;
    p.pack(i, &sendbuf[static_cast<std::size_t>(cursor[dest[i]])]);
    cursor[dest[i]] += R;
  }
  MPI_Alltoallv(sendbuf.data(), scount.data(), sdispl.data(), MPI_DOUBLE, recvbuf.data(),
                rcount.data(), rdispl.data(), MPI_DOUBLE, comm);
  p.compact(keep);
  const std::size_t received = recvbuf.size() / R;
  p.reserve(p.size() + received);
  for (std::size_t k = 0; k < received; ++k) p.append_packed(&recvbuf[k * R]);
  return sent;
}

}  // namespace gen4d::mpm
