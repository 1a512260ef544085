// G-code through LinuxCNC's own interpreter: the dtis-rs274 program (tools/rs274) runs it and
// writes its canonical machining calls as text records, read here into moves. Internal to io.
#pragma once

#include <sys/types.h>

#include <array>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "dtis/io/cancel.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/tool_table.hpp"

namespace dtis::io {

// The dtis-rs274 program: $DTIS_RS274, else next to the running program, else where the build
// put it; empty when none is found.
std::string Rs274Program();

// "<file>:<line>: the program runs more than N blocks ...; <remedy>"
// (GcodeReadOptions::max_blocks).
std::string TooManyBlocks(const std::string& file, long line, const GcodeReadOptions& options);

class Rs274Reader {
 public:
  // Starts the interpreter on the file at `path`, with the tool table `tools` (none: every tool
  // number exists, without offsets), from where `start` says the machine is and with its
  // parameters (the work offsets). Throws dtis::Error when the file cannot be read or dtis-rs274
  // cannot be started. `cancel` (which must outlive the reader), once requested, kills the
  // interpreter: Next() then throws. The interpreter executes at most options.max_blocks blocks.
  explicit Rs274Reader(const std::string& path, std::shared_ptr<const ToolTable> tools = nullptr,
                       Cancel* cancel = nullptr, const GcodeStart& start = {},
                       const GcodeReadOptions& options = {});
  // Reads records already written (`records` must outlive the reader); `name` names the program.
  Rs274Reader(std::string_view records, const std::string& name);
  ~Rs274Reader();  // stops the interpreter if it is still running
  Rs274Reader(const Rs274Reader&) = delete;
  Rs274Reader& operator=(const Rs274Reader&) = delete;

  // The next move; nothing at the program's end. Throws dtis::Error "<file>:<line>: <LinuxCNC's
  // message>" at a block the interpreter refuses.
  std::optional<GcodeMove> Next();
  const std::string& File() const { return file_; }
  const std::array<bool, 3>& UsesRotary() const { return uses_rotary_; }
  const std::vector<std::pair<std::string, int>>& Notes() const { return notes_; }

 private:
  [[noreturn]] void Fail(int line, const std::string& what);
  [[noreturn]] void BadRecord(const std::string& why);
  void Note(const std::string& what);
  // A move of `kind` from record `line` with rotary positions `abc`, carrying what the records
  // before it set (feed, path control, a dwell).
  GcodeMove Move(int line, GcodeMove::Kind kind, const double* abc);
  // Waits for the interpreter to exit; a message when it did not exit as it should.
  std::string Reap();
  // The next record into record_; false at the end of the output.
  bool NextRecord();

  std::string file_;
  GcodeReadOptions options_;
  pid_t pid_ = -1;
  std::FILE* out_ = nullptr;
  Cancel::Hook kill_on_cancel_;           // reset before the interpreter is reaped
  std::optional<std::string_view> text_;  // records given as text, what is left of them
  std::string record_;
  long records_ = 0;
  bool ended_ = false;
  // What the records set for the moves that follow.
  double feed_mm_min_ = 0.0, tolerance_mm_ = 0.0;
  bool stop_ = false, rest_next_ = false;
  double dwell_next_ = 0.0;  // seconds of G4 since the last move
  std::array<bool, 3> uses_rotary_{};
  std::vector<std::pair<std::string, int>> notes_;
};

}  // namespace dtis::io
