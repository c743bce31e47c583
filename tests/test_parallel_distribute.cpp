// parallel::RowExchange: rows of mixed columns reach their destinations complete and in the
// documented order, and a round trip restores every rank's rows.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "parallel/Distribute.hpp"

using gen4d::parallel::RowExchange;

namespace {

int comm_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int comm_size() {
  int s = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &s);
  return s;
}

//! Rows of one rank: rank 1 holds none; ids rank * 1000 + i.
struct Rows {
  std::vector<std::int64_t> id;
  std::vector<double> x;          // 3 per row
  std::vector<std::uint8_t> tag;  // 1 per row
  std::vector<float> unused;      // width 0: must be left alone
};

Rows rows_of(int rank) {
  Rows r;
  const int n = rank == 1 ? 0 : 11 + 6 * rank;
  for (int i = 0; i < n; ++i) {
    const std::int64_t g = 1000 * rank + i;
    r.id.push_back(g);
    r.x.insert(r.x.end(), {0.1 * static_cast<double>(g), -1.0 / (1.0 + static_cast<double>(g)),
                           static_cast<double>(g) * 1e300});
    r.tag.push_back(static_cast<std::uint8_t>((g * 37) % 251));
  }
  r.unused = {1.5f, 2.5f};
  return r;
}

int destination(std::int64_t id, int size) {
  return static_cast<int>((id * 7 + id / 1000 + 3) % size);
}

//! Appends row i of `from` to `to`.
void append_row(Rows& to, const Rows& from, std::size_t i) {
  to.id.push_back(from.id[i]);
  to.x.insert(to.x.end(), from.x.begin() + static_cast<long>(3 * i),
              from.x.begin() + static_cast<long>(3 * i + 3));
  to.tag.push_back(from.tag[i]);
}

std::size_t send_rows(Rows& r, const std::vector<int>& dest) {
  RowExchange ex;
  ex.add(r.id, 1).add(r.x, 3).add(r.tag, 1).add(r.unused, 0);
  return ex.exchange(MPI_COMM_WORLD, dest);
}

void expect_equal(const Rows& a, const Rows& b) {
  ASSERT_EQ(a.id.size(), b.id.size());
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.tag, b.tag);
  ASSERT_EQ(a.x.size(), b.x.size());
  for (std::size_t k = 0; k < a.x.size(); ++k) EXPECT_EQ(a.x[k], b.x[k]) << "value " << k;
}

}  // namespace

TEST(RowExchange, RowsArriveCompleteInDocumentedOrder) {
  const int rank = comm_rank(), size = comm_size();
  Rows mine = rows_of(rank);
  std::vector<int> dest(mine.id.size());
  std::size_t leaving = 0;
  for (std::size_t i = 0; i < dest.size(); ++i) {
    dest[i] = destination(mine.id[i], size);
    leaving += dest[i] != rank;
  }
  // Expected: the kept rows in order, then each source rank's rows for this rank in order.
  Rows expected;
  for (std::size_t i = 0; i < mine.id.size(); ++i)
    if (dest[i] == rank) append_row(expected, mine, i);
  for (int src = 0; src < size; ++src) {
    if (src == rank) continue;
    const Rows theirs = rows_of(src);
    for (std::size_t i = 0; i < theirs.id.size(); ++i)
      if (destination(theirs.id[i], size) == rank) append_row(expected, theirs, i);
  }
  EXPECT_EQ(send_rows(mine, dest), leaving);
  expect_equal(mine, expected);
  EXPECT_EQ(mine.unused, (std::vector<float>{1.5f, 2.5f}));
  // Every row exists exactly once over all ranks.
  long long held = static_cast<long long>(mine.id.size()), total = 0, all = 0;
  MPI_Allreduce(&held, &total, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  for (int r = 0; r < size; ++r) all += static_cast<long long>(rows_of(r).id.size());
  EXPECT_EQ(total, all);
  if (size > 1) {
    long long moved = static_cast<long long>(leaving), any = 0;
    MPI_Allreduce(&moved, &any, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_GT(any, 0);  // the test really moves rows
  }
}

// fill_gaps_from_end: the kept rows (in some order) then the received ones in the documented
// order; every row complete (its columns still belong together).
TEST(RowExchange, GapsFilledFromTheEndKeepEveryRowWhole) {
  const int rank = comm_rank(), size = comm_size();
  Rows mine = rows_of(rank);
  std::vector<int> dest(mine.id.size());
  std::vector<std::int64_t> kept;
  for (std::size_t i = 0; i < dest.size(); ++i) {
    dest[i] = destination(mine.id[i], size);
    if (dest[i] == rank) kept.push_back(mine.id[i]);
  }
  Rows received;
  for (int src = 0; src < size; ++src) {
    if (src == rank) continue;
    const Rows theirs = rows_of(src);
    for (std::size_t i = 0; i < theirs.id.size(); ++i)
      if (destination(theirs.id[i], size) == rank) append_row(received, theirs, i);
  }
  RowExchange ex;
  ex.add(mine.id, 1).add(mine.x, 3).add(mine.tag, 1).add(mine.unused, 0).fill_gaps_from_end();
  ex.exchange(MPI_COMM_WORLD, dest);
  ASSERT_EQ(mine.id.size(), kept.size() + received.id.size());
  std::vector<std::int64_t> first(mine.id.begin(),
                                  mine.id.begin() + static_cast<long>(kept.size()));
  std::sort(first.begin(), first.end());
  EXPECT_EQ(first, kept);  // kept ids are ascending in rows_of
  const Rows all = [&] {
    Rows r;
    for (int src = 0; src < size; ++src) {
      const Rows theirs = rows_of(src);
      for (std::size_t i = 0; i < theirs.id.size(); ++i) append_row(r, theirs, i);
    }
    return r;
  }();
  for (std::size_t k = 0; k < mine.id.size(); ++k) {
    const auto at = std::find(all.id.begin(), all.id.end(), mine.id[k]) - all.id.begin();
    EXPECT_EQ(mine.tag[k], all.tag[static_cast<std::size_t>(at)]) << "row " << k;
    for (int d = 0; d < 3; ++d)
      EXPECT_EQ(mine.x[3 * k + d], all.x[3 * static_cast<std::size_t>(at) + d]) << "row " << k;
    if (k >= kept.size()) EXPECT_EQ(mine.id[k], received.id[k - kept.size()]);
  }
  EXPECT_EQ(mine.unused, (std::vector<float>{1.5f, 2.5f}));
}

TEST(RowExchange, RoundTripRestoresTheRows) {
  const int rank = comm_rank(), size = comm_size();
  const Rows original = rows_of(rank);
  Rows r = original;
  std::vector<int> dest(r.id.size());
  for (std::size_t i = 0; i < dest.size(); ++i) dest[i] = destination(r.id[i], size);
  send_rows(r, dest);
  // Back to the rank each id came from.
  dest.assign(r.id.size(), 0);
  for (std::size_t i = 0; i < dest.size(); ++i) dest[i] = static_cast<int>(r.id[i] / 1000);
  send_rows(r, dest);
  std::vector<std::size_t> order(r.id.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return r.id[a] < r.id[b]; });
  Rows sorted;
  for (std::size_t i : order) append_row(sorted, r, i);
  expect_equal(sorted, original);
}

TEST(RowExchange, EveryRowToOneRankAndNothingToSend) {
  const int rank = comm_rank(), size = comm_size();
  Rows r = rows_of(rank);
  send_rows(r, std::vector<int>(r.id.size(), size - 1));
  long long expected = 0;
  for (int s = 0; s < size; ++s) expected += static_cast<long long>(rows_of(s).id.size());
  EXPECT_EQ(static_cast<long long>(r.id.size()), rank == size - 1 ? expected : 0);
  // A second exchange where every rank keeps everything changes nothing.
  const Rows before = r;
  EXPECT_EQ(send_rows(r, std::vector<int>(r.id.size(), rank)), 0u);
  expect_equal(r, before);
}

TEST(RowExchange, MisshapedInputIsALogicError) {
  const int rank = comm_rank();
  Rows r = rows_of(0);
  std::vector<int> short_dest(r.id.size() - 1, rank);
  RowExchange ex;
  ex.add(r.id, 1).add(r.x, 3);
  EXPECT_THROW(ex.exchange(MPI_COMM_WORLD, short_dest), std::logic_error);
  std::vector<int> bad(r.id.size(), rank);
  bad[2] = comm_size();
  EXPECT_THROW(ex.exchange(MPI_COMM_WORLD, bad), std::logic_error);
  RowExchange neg;
  EXPECT_THROW(neg.add(r.x, -1), std::logic_error);
}
