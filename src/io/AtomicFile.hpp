//! Files written through a temporary beside them and a rename, so a reader never sees a
//! partial file.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace gen4d::io {

//! `.NAME.tmp` beside `path`; `.NAME.PID.tmp` with `with_pid` (writers that may race).
std::string temp_beside(const std::string& path, bool with_pid = false);

//! Renames `temp` onto `path`, removing `temp` when that fails; "" on success, else
//! "PATH: cannot rename TEMP: WHY".
std::string try_rename_into_place(const std::string& temp, const std::string& path);

//! Writes `bytes` to `temp`, then renames it onto `path`; "" on success, else a message naming
//! `path` (the temporary is removed).
std::string try_write_atomically(const std::string& path, std::string_view bytes,
                                 const std::string& temp);

//! try_write_atomically through temp_beside(path), throwing RuntimeError with its message.
void write_atomically(const std::string& path, std::string_view bytes, bool with_pid = false);

//! Why writing `needed` more bytes to `path` fails or would fail, for a message: "no space
//! left on device (N bytes free in DIR)" when its file system has less than `needed` free (less
//! than 1 MiB for `needed` 0: after a failed write), "the file size limit (ulimit -f) of N
//! bytes" when the file would pass it, else "".
std::string write_failure_cause(const std::string& path, std::uintmax_t needed = 0);

}  // namespace gen4d::io
