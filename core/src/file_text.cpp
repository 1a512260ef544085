#include "dtis/core/file_text.hpp"

#include <sys/stat.h>

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
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

// Throws for a path that stat() could not follow for another reason than its absence (a loop of
// symbolic links, a folder on the way that cannot be searched): the reason, in lower case.
void RequireReachable(const std::string& path, int error) {
  if (error == ENOENT) return;
  std::string why = std::strerror(error);
  if (!why.empty()) why[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(why[0])));
  throw Error("{}: cannot open: {}", path, why);
}

}  // namespace

void RequireRegularFile(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return RequireReachable(path, errno);
  RequireRegular(path, st);
}

std::optional<std::string> ReadFileText(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) {
    RequireReachable(path, errno);
    return std::nullopt;
  }
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

std::optional<double> ParseFiniteNumber(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

}  // namespace dtis
