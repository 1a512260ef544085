#include "dtis/io/atomic_file.hpp"

#include <fcntl.h>
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
  // What is there already (following a symbolic link, as writing it would).
  struct stat st {};
  if (::stat(path_.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) {
      throw Error("{}: is a folder; give a file name for the output", path_);
    }
    if (S_ISBLK(st.st_mode) || S_ISSOCK(st.st_mode)) {
      throw Error("{}: is a {}, not a file; give a file name for the output", path_,
                  S_ISBLK(st.st_mode) ? "block device" : "socket");
    }
    if (!S_ISREG(st.st_mode)) {
      OpenInPlace();
      return;
    }
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
  Buffer();
}

// A device or a FIFO: renaming a file over it would replace it (a FIFO's reader would wait for
// ever, /dev/null would become a file), so it is opened and written as it is. Opening a FIFO waits
// for its reader, as any program writing one does.
void AtomicFile::OpenInPlace() {
  in_place_ = true;
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw Error("{}: cannot open it for writing ({})", path_, std::strerror(errno));
  file_ = fdopen(fd, "wb");
  if (!file_) {
    ::close(fd);
    throw Error("{}: cannot open it for writing ({})", path_, std::strerror(errno));
  }
  Buffer();
}

// Each file its own buffer: several may be open at once (a run's setpoints and limiters).
void AtomicFile::Buffer() {
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
  if (in_place_) {
    // Neither synced nor renamed: a device or a FIFO takes what is written as it comes.
    const bool flushed = std::fflush(file_) == 0;
    const int flush_errno = errno;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!flushed || !closed) {
      throw Error("{}: write failed ({})", path_, std::strerror(flushed ? errno : flush_errno));
    }
    committed_ = true;
    return;
  }
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

void CommitTogether(const std::vector<AtomicFile*>& files) {
  for (AtomicFile* f : files) {
    if (f && f->InPlace()) f->Commit();
  }
  for (AtomicFile* f : files) {
    if (f && !f->InPlace()) f->Commit();
  }
}

void WriteFileAtomically(const std::string& path, std::string_view text) {
  AtomicFile out(path);
  out.Write(text);
  out.Commit();
}

}  // namespace dtis::io
