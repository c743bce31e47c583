//! Files written through a temporary beside them and a rename, so a reader never sees a
//! partial file.
#pragma once

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

}  // namespace gen4d::io
