// tools/weft/output_file.hpp — the files the commands write at the end of a run (tables, CSV):
// checked before the run starts, so a path that cannot be written fails in a second, not
// after the run; then written whole or not at all.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace weftcli {

/// Throws std::invalid_argument naming `option`, `path` and the reason unless `path` can be
/// opened for writing. An existing file is opened for appending and left as it is; a file
/// this call creates is removed again.
inline void checkOutputFile(const std::string& path, const std::string& option) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  const bool existed = std::filesystem::exists(status);
  // A path that exists and is no regular file (/dev/stdout, a pipe: opening a pipe would
  // wait for its reader) is taken as it is; writing it reports its own errors.
  if (existed && !std::filesystem::is_regular_file(status)) return;
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (!f) throw std::invalid_argument(option + " " + path + ": cannot write the file (" + std::strerror(errno) + ")");
  std::fclose(f);
  if (!existed) std::filesystem::remove(path, error);
}

/// Writes `text` to `path` whole or not at all: through path + ".tmp", renamed when complete,
/// so a failure leaves an earlier file as it was. A path that exists and is not a regular
/// file (/dev/stdout, a pipe) is written directly. Throws std::runtime_error naming the path
/// and the reason (a full disk is reported, not taken for success).
inline void writeTextFile(const std::string& path, const std::string& text) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  const bool direct = std::filesystem::exists(status) && !std::filesystem::is_regular_file(status);
  const std::string target = direct ? path : path + ".tmp";
  const auto fail = [&](int code) {
    if (!direct) std::remove(target.c_str());
    throw std::runtime_error("cannot write '" + path + "': " + std::strerror(code ? code : EIO));
  };
  std::FILE* f = std::fopen(target.c_str(), "wb");
  if (!f) fail(errno);
  int code = 0;
  if (!text.empty() && std::fwrite(text.data(), 1, text.size(), f) != text.size()) code = errno ? errno : EIO;
  if (std::fflush(f) != 0 && code == 0) code = errno ? errno : EIO;
  if (std::fclose(f) != 0 && code == 0) code = errno ? errno : EIO;
  if (code != 0) fail(code);
  if (!direct && std::rename(target.c_str(), path.c_str()) != 0) fail(errno);
}

}  // namespace weftcli
