// Output written to a temporary file beside the target and renamed over it on Commit(), so a failed
// run never leaves a half file behind (docs/design.md, Conventions). A target that exists and is
// not a regular file (a device such as /dev/null, a FIFO) is written in place instead, never
// renamed over; a block device, a socket or a folder is refused.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace dtis::io {

class AtomicFile {
 public:
  // Throws dtis::Error if the folder is not writable, or an in-place target cannot be opened. A
  // FIFO's open waits for its reader.
  explicit AtomicFile(std::string path);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();  // removes the temporary file unless committed

  void Write(std::string_view text);
  // Flush, sync, rename (in place: flush and close); throws dtis::Error naming the file on failure.
  void Commit();
  const std::string& Path() const { return path_; }
  // Written straight to the target (a device or a FIFO): what Write wrote cannot be taken back.
  bool InPlace() const { return in_place_; }

 private:
  void OpenInPlace();
  void Buffer();

  std::string path_, temp_;
  std::FILE* file_ = nullptr;
  std::vector<char> buffer_;  // stdio's buffer for file_; outlives it (freed after fclose)
  bool committed_ = false;
  bool in_place_ = false;
};

// Commits several outputs that land together: those written in place first, since they cannot be
// taken back, so that a failed write there leaves none of the others behind. Null entries are
// skipped.
void CommitTogether(const std::vector<AtomicFile*>& files);

// Writes `text` as the whole of `path`, atomically.
void WriteFileAtomically(const std::string& path, std::string_view text);

}  // namespace dtis::io
