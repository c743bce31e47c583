//! Byte packing of small metadata records for one MPI_Bcast from the rank that read them.
#pragma once

#include <cstddef>
#include <cstring>
#include <string>

namespace gen4d::io::bytes {

//! Appends the bytes of a trivially copyable value.
template <class T>
void put(std::string& buffer, const T& value) {
  buffer.append(reinterpret_cast<const char*>(&value), sizeof value);
}
//! Appends a length-prefixed string.
inline void put(std::string& buffer, const std::string& text) {
  put(buffer, text.size());
  buffer += text;
}

//! Reads back, in order, what put() appended.
struct Unpacker {
  const std::string& buffer;
  std::size_t pos = 0;
  template <class T>
  void get(T& value) {
    std::memcpy(&value, buffer.data() + pos, sizeof value);
    pos += sizeof value;
  }
  void get(std::string& text) {
    std::size_t n = 0;
    get(n);
    text = buffer.substr(pos, n);
    pos += n;
  }
};

}  // namespace gen4d::io::bytes
