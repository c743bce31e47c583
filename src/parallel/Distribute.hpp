//! The one path that moves per-item data between ranks: rows of several columns (particles,
//! splats, embedded points, id blocks of output files) sent together by one all-to-all.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>

namespace gen4d::parallel {

//! Columns are std::vectors of trivially copyable values, `width` values per row, all holding
//! the same number of rows. exchange() sends row i to rank dest[i]; afterwards every column holds
//! the rows this rank kept (dest[i] == rank), in their order, followed by the received rows in
//! source-rank order (each source's rows in its order). Deterministic for a given distribution.
//! A row travels as one packed record of its columns' bytes (MPI_BYTE): one MPI_Alltoall of the
//! row counts, one MPI_Allreduce of the size check, one MPI_Alltoallv of the records. Columns of
//! width 0 are left alone (an attribute a run does not use).
//!
//!   parallel::RowExchange ex;
//!   ex.add(p.id, 1);
//!   ex.add(p.x, 3);
//!   ex.exchange(comm, dest);
class RowExchange {
 public:
  RowExchange();
  ~RowExchange();
  RowExchange(const RowExchange&) = delete;
  RowExchange& operator=(const RowExchange&) = delete;

  //! Registers `column` (`width` values per row; std::logic_error for a negative width). The
  //! vector is referenced, not copied: it must outlive exchange().
  template <class T>
  RowExchange& add(std::vector<T>& column, int width) {
    static_assert(std::is_trivially_copyable_v<T>, "columns hold trivially copyable values");
    check_width(width);
    add_column(std::make_unique<Column<T>>(column, width));
    return *this;
  }

  //! Collective. dest.size() must equal the row count of every column and every dest[i] be a
  //! rank of `comm` (std::logic_error otherwise, before any communication). RuntimeError on
  //! every rank, with nothing moved, when a rank would send or receive 2^31 bytes or more (MPI's
  //! int counts). Returns the number of rows this rank sent away.
  std::size_t exchange(MPI_Comm comm, const std::vector<int>& dest);

  //! Lets the kept rows lose their order: the last kept rows move into the gaps the sent ones
  //! leave (work in proportion to the rows sent, not to all rows). Still deterministic.
  RowExchange& fill_gaps_from_end() {
    fill_from_end_ = true;
    return *this;
  }

 private:
  struct ColumnBase {
    virtual ~ColumnBase() = default;
    virtual std::size_t rows() const = 0;
    virtual std::size_t row_bytes() const = 0;
    virtual const unsigned char* row(std::size_t i) const = 0;
    //! Keeps rows with keep[i] != 0 in order, then appends `n` rows read from `packed` records of
    //! `stride` bytes at byte `offset` within each record.
    virtual void rebuild(const std::vector<std::uint8_t>& keep, const unsigned char* packed,
                         std::size_t n, std::size_t stride, std::size_t offset) = 0;
    //! Appends `n` rows read from `packed` records (as rebuild, every row kept).
    virtual void append(const unsigned char* packed, std::size_t n, std::size_t stride,
                        std::size_t offset) = 0;
    //! Copies row `from` onto row `to`; keeps the first `rows` rows.
    virtual void move_row(std::size_t from, std::size_t to) = 0;
    virtual void truncate(std::size_t rows) = 0;
  };
  template <class T>
  struct Column;
  void add_column(std::unique_ptr<ColumnBase> c);
  static void check_width(int width);
  std::vector<std::unique_ptr<ColumnBase>> columns_;
  bool fill_from_end_ = false;
};

template <class T>
struct RowExchange::Column final : RowExchange::ColumnBase {
  Column(std::vector<T>& v, int w) : data(v), width(static_cast<std::size_t>(w)) {}
  std::size_t rows() const override { return width ? data.size() / width : 0; }
  std::size_t row_bytes() const override { return width * sizeof(T); }
  const unsigned char* row(std::size_t i) const override {
    return reinterpret_cast<const unsigned char*>(data.data() + i * width);
  }
  void rebuild(const std::vector<std::uint8_t>& keep, const unsigned char* packed, std::size_t n,
               std::size_t stride, std::size_t offset) override;
  void append(const unsigned char* packed, std::size_t n, std::size_t stride,
              std::size_t offset) override;
  void move_row(std::size_t from, std::size_t to) override {
    std::memcpy(data.data() + to * width, data.data() + from * width, width * sizeof(T));
  }
  void truncate(std::size_t rows) override { data.resize(rows * width); }
  std::vector<T>& data;
  std::size_t width;
};

template <class T>
void RowExchange::Column<T>::rebuild(const std::vector<std::uint8_t>& keep,
                                     const unsigned char* packed, std::size_t n, std::size_t stride,
                                     std::size_t offset) {
  std::size_t out = 0;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    if (out != i)
      for (std::size_t k = 0; k < width; ++k) data[out * width + k] = data[i * width + k];
    ++out;
  }
  data.resize(out * width);
  append(packed, n, stride, offset);
}

template <class T>
void RowExchange::Column<T>::append(const unsigned char* packed, std::size_t n, std::size_t stride,
                                    std::size_t offset) {
  const std::size_t out = rows();
  data.resize((out + n) * width);
  for (std::size_t r = 0; r < n; ++r)
    std::memcpy(data.data() + (out + r) * width, packed + r * stride + offset, width * sizeof(T));
}

}  // namespace gen4d::parallel
