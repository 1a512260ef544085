#include "dtis/io/atomic_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "dtis/core/error.hpp"

namespace dtis::io {

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  const std::filesystem::path target(path_);
  if (std::filesystem::is_directory(target)) {
    throw Error("{}: is a folder; give a file name for the output", path_);
  }
  std::string name = target.filename().string();
  name.insert(0, 1, '.');
  name.append(".tmp-XXXXXX");
  std::string pattern = (target.parent_path() / name).string();
  const int fd = mkstemp(pattern.data());
  if (fd < 0) {
    throw Error("{}: cannot create an output file there ({})", path_, std::strerror(errno));
  }
  temp_ = pattern;
  file_ = fdopen(fd, "wb");
  if (!file_) {
    ::close(fd);
    std::remove(temp_.c_str());
    throw Error("{}: cannot open the temporary output file", path_);
  }
  // Each file its own buffer: several may be open at once (a run's setpoints and limiters).
  buffer_.resize(1 << 16);
  std::setvbuf(file_, buffer_.data(), _IOFBF, buffer_.size());
}

AtomicFile::~AtomicFile() {
  if (file_) std::fclose(file_);
  if (!committed_ && !temp_.empty()) std::remove(temp_.c_str());
}

void AtomicFile::Write(std::string_view text) {
  if (std::fwrite(text.data(), 1, text.size(), file_) != text.size()) {
    throw Error("{}: write failed ({})", path_, std::strerror(errno));
  }
}

void AtomicFile::Commit() {
  if (std::fflush(file_) != 0 || fsync(fileno(file_)) != 0) {
    throw Error("{}: write failed ({})", path_, std::strerror(errno));
  }
  std::fclose(file_);
  file_ = nullptr;
  // mkstemp creates 0600; give the output the usual permissions.
  const mode_t mask = umask(0);
  umask(mask);
  std::filesystem::permissions(temp_, static_cast<std::filesystem::perms>(0666 & ~mask));
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    throw Error("{}: cannot move the output in place ({})", path_, std::strerror(errno));
  }
  committed_ = true;
}

void WriteFileAtomically(const std::string& path, std::string_view text) {
  AtomicFile out(path);
  out.Write(text);
  out.Commit();
}

}  // namespace dtis::io
