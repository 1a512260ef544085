#include "dtis/core/file_text.hpp"

#include <sys/stat.h>

#include <fstream>
#include <sstream>

#include "dtis/core/error.hpp"

namespace dtis {

namespace {

// Throws unless `st` is a regular file's.
void RequireRegular(const std::string& path, const struct stat& st) {
  if (S_ISREG(st.st_mode)) return;
  const char* what = S_ISDIR(st.st_mode)    ? "a directory"
                     : S_ISFIFO(st.st_mode) ? "a FIFO"
                     : S_ISSOCK(st.st_mode) ? "a socket"
                                            : "a device";
  throw Error("{}: is {}, not a file; expected a regular file", path, what);
}

}  // namespace

void RequireRegularFile(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) == 0) RequireRegular(path, st);
}

std::optional<std::string> ReadFileText(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return std::nullopt;
  RequireRegular(path, st);
  if (static_cast<std::uintmax_t>(st.st_size) > kMaxTextFileBytes) {
    throw Error("{}: {} bytes, larger than the {} GiB a text input may have", path, st.st_size,
                kMaxTextFileBytes >> 30);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

}  // namespace dtis
