// The request lines of `dtis serve` (serve.hpp): parsed into a command, and error replies that are
// always one valid JSON line, whatever bytes the request held. No other dependency than JSON, so
// that the fuzz target (fuzz/fuzz_request.cpp) builds it alone.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace dtis::io {

struct ServeRequest {
  enum class Command { kSubmit, kStatus, kPause, kResume, kAbort, kShutdown };
  Command command = Command::kStatus;
  std::string job;  // kSubmit: the job file
};

// One request line (without its newline): a JSON object with a string "cmd" naming a command,
// each key once, nested at most kMaxRequestDepth deep. Throws dtis::Error with the text of the
// error reply ("malformed request: ...", "duplicate key \"cmd\" ...", "unknown command ...").
ServeRequest ParseServeRequest(std::string_view line);
inline constexpr int kMaxRequestDepth = 8;

// {"ok":false,"error":MESSAGE} on one line, bytes of MESSAGE that are not UTF-8 replaced by
// U+FFFD. Never throws (a fixed reply if even that cannot be built).
std::string ServeErrorReply(std::string_view message) noexcept;

}  // namespace dtis::io
