// Output written to a temporary file beside the target and renamed over it on Commit(), so a failed
// run never leaves a half file behind (docs/design.md, Conventions).
#pragma once

#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace dtis::io {

class AtomicFile {
 public:
  explicit AtomicFile(std::string path);  // throws dtis::Error if the folder is not writable
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();  // removes the temporary file unless committed

  void Write(std::string_view text);
  void Commit();  // flush, sync, rename; throws dtis::Error on failure
  const std::string& Path() const { return path_; }

 private:
  std::string path_, temp_;
  std::FILE* file_ = nullptr;
  std::vector<char> buffer_;  // stdio's buffer for file_; outlives it (freed after fclose)
  bool committed_ = false;
};

// Writes `text` as the whole of `path`, atomically.
void WriteFileAtomically(const std::string& path, std::string_view text);

}  // namespace dtis::io
