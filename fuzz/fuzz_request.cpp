// libFuzzer target for `dtis serve`'s request lines (io/src/serve_request.cpp): any line either
// parses into a command or throws dtis::Error, and the error reply built from that error is one
// line of valid JSON, {"ok":false,"error":...}, whatever bytes the line held. Nothing else may
// escape: an exception that escaped once ended the daemon (std::terminate) mid-job.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "dtis/core/error.hpp"
#include "dtis/io/serve_request.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view line(reinterpret_cast<const char*>(data), size);
  std::string reply;
  try {
    const dtis::io::ServeRequest request = dtis::io::ParseServeRequest(line);
    if (request.command == dtis::io::ServeRequest::Command::kSubmit &&
        request.job.find('\0') != std::string::npos) {
      std::abort();  // a path with a NUL would name another file than the one given
    }
    return 0;
  } catch (const dtis::Error& e) {
    reply = dtis::io::ServeErrorReply(e.what());
  }
  // The reply is what a client reads: one line, valid JSON (UTF-8), an error with its message.
  if (reply.find('\n') != std::string::npos) std::abort();
  const auto parsed = nlohmann::json::parse(reply, nullptr, /*allow_exceptions=*/false);
  if (!parsed.is_object() || parsed.value("ok", true) || !parsed.contains("error") ||
      !parsed["error"].is_string()) {
    std::abort();
  }
  return 0;
}
