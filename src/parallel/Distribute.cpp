#include "parallel/Distribute.hpp"

#include <fmt/format.h>

#include <climits>
#include <stdexcept>

#include "core/Error.hpp"

namespace gen4d::parallel {

RowExchange::RowExchange() = default;
RowExchange::~RowExchange() = default;

void RowExchange::add_column(std::unique_ptr<ColumnBase> c) {
  columns_.push_back(std::move(c));
}

void RowExchange::check_width(int width) {
  if (width < 0)
    throw std::logic_error(fmt::format("RowExchange: negative column width {}", width));
}

std::size_t RowExchange::exchange(MPI_Comm comm, const std::vector<int>& dest) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const std::size_t n = dest.size();
  std::size_t stride = 0;
  std::vector<std::size_t> offset;
  for (const auto& c : columns_) {
    if (c->row_bytes() > 0 && c->rows() != n)
      throw std::logic_error(
          fmt::format("RowExchange: a column holds {} rows, the destinations {}", c->rows(), n));
    offset.push_back(stride);
    stride += c->row_bytes();
  }
  std::vector<long long> rows_to(static_cast<std::size_t>(size), 0);
  std::vector<std::uint8_t> keep(n, 1);
  std::size_t sent = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int d = dest[i];
    if (d < 0 || d >= size)
      throw std::logic_error(
          fmt::format("RowExchange: destination {} of row {} is not a rank of "
                      "the {} ranks",
                      d, i, size));
    if (d == rank) continue;
    keep[i] = 0;
    ++rows_to[static_cast<std::size_t>(d)];
    ++sent;
  }
  if (size == 1) return 0;

  // Counts in rows, as 64-bit integers: the byte counts and displacements MPI takes are ints,
  // checked below on both sides before any byte moves.
  std::vector<long long> rows_from(static_cast<std::size_t>(size), 0);
  MPI_Alltoall(rows_to.data(), 1, MPI_LONG_LONG, rows_from.data(), 1, MPI_LONG_LONG, comm);
  const long long limit = stride > 0 ? INT_MAX / static_cast<long long>(stride) : LLONG_MAX;
  long long out_rows = 0, in_rows = 0;
  for (int r = 0; r < size; ++r) {
    out_rows += rows_to[static_cast<std::size_t>(r)];
    in_rows += rows_from[static_cast<std::size_t>(r)];
  }
  int too_many = out_rows > limit || in_rows > limit ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &too_many, 1, MPI_INT, MPI_MAX, comm);
  if (too_many)
    throw RuntimeError(fmt::format(
        "row exchange: a rank sends or receives more than {} rows of {} bytes, beyond what one "
        "MPI all-to-all can address (2^31 bytes); this rank sends {} and receives {} rows",
        limit, stride, out_rows, in_rows));

  std::vector<int> scount(static_cast<std::size_t>(size)), rcount(scount.size()),
      sdispl(scount.size(), 0), rdispl(scount.size(), 0);
  for (std::size_t r = 0; r < scount.size(); ++r) {
    scount[r] = static_cast<int>(rows_to[r] * static_cast<long long>(stride));
    rcount[r] = static_cast<int>(rows_from[r] * static_cast<long long>(stride));
    if (r > 0) {
      sdispl[r] = sdispl[r - 1] + scount[r - 1];
      rdispl[r] = rdispl[r - 1] + rcount[r - 1];
    }
  }
  std::vector<unsigned char> sendbuf(static_cast<std::size_t>(out_rows) * stride),
      recvbuf(static_cast<std::size_t>(in_rows) * stride);
  std::vector<std::size_t> cursor(sdispl.begin(), sdispl.end());
  for (std::size_t i = 0; i < n; ++i) {
    if (keep[i]) continue;
    unsigned char* record = sendbuf.data() + cursor[static_cast<std::size_t>(dest[i])];
    for (std::size_t c = 0; c < columns_.size(); ++c)
      if (columns_[c]->row_bytes() > 0)
        std::memcpy(record + offset[c], columns_[c]->row(i), columns_[c]->row_bytes());
    cursor[static_cast<std::size_t>(dest[i])] += stride;
  }
  // Some MPI builds reject null buffers even for zero counts.
  unsigned char nothing = 0;
  MPI_Alltoallv(sendbuf.empty() ? &nothing : sendbuf.data(), scount.data(), sdispl.data(), MPI_BYTE,
                recvbuf.empty() ? &nothing : recvbuf.data(), rcount.data(), rdispl.data(), MPI_BYTE,
                comm);
  if (fill_from_end_ && sent > 0) {
    // Close the gaps with the last kept rows, then every row is kept.
    std::size_t end = n;
    for (std::size_t gap = 0; gap < end; ++gap) {
      if (keep[gap]) continue;
      while (end > gap + 1 && !keep[end - 1]) --end;
      if (end <= gap + 1) {
        end = gap;
        break;
      }
      --end;
      for (const auto& c : columns_)
        if (c->row_bytes() > 0) c->move_row(end, gap);
    }
    for (const auto& c : columns_)
      if (c->row_bytes() > 0) c->truncate(end);
  }
  const bool all_kept = sent == 0 || fill_from_end_;
  for (std::size_t c = 0; c < columns_.size(); ++c) {
    if (columns_[c]->row_bytes() == 0) continue;
    if (all_kept)
      columns_[c]->append(recvbuf.data(), static_cast<std::size_t>(in_rows), stride, offset[c]);
    else
      columns_[c]->rebuild(keep, recvbuf.data(), static_cast<std::size_t>(in_rows), stride,
                           offset[c]);
  }
  return sent;
}

}  // namespace gen4d::parallel
