#include "dtis/io/serve_request.hpp"

#include <nlohmann/json.hpp>
#include <set>
#include <vector>

#include "dtis/core/error.hpp"

namespace dtis::io {
namespace {

using json = nlohmann::ordered_json;

// Replaces what is not UTF-8 by U+FFFD, so that a request's bytes quoted in a message can be sent
// back as JSON.
std::string Utf8(std::string_view text) {
  // A JSON string of the text, dumped with invalid bytes replaced, then read back.
  const std::string quoted =
      json(std::string(text)).dump(-1, ' ', false, json::error_handler_t::replace);
  return json::parse(quoted).get<std::string>();
}

}  // namespace

ServeRequest ParseServeRequest(std::string_view line) {
  // Keys seen in each object being read, innermost last: a key given twice is refused (JSON
  // leaves it open, and keeping the last one made {"cmd":"status","cmd":"shutdown"} a shutdown).
  std::vector<std::set<std::string>> keys;
  const json::parser_callback_t check = [&keys](int depth, json::parse_event_t event,
                                                json& parsed) {
    if (depth > kMaxRequestDepth) {
      throw Error("malformed request: nested deeper than {} levels", kMaxRequestDepth);
    }
    switch (event) {
      case json::parse_event_t::object_start:
        keys.emplace_back();
        break;
      case json::parse_event_t::object_end:
        if (!keys.empty()) keys.pop_back();
        break;
      case json::parse_event_t::key:
        if (!keys.empty() && !keys.back().insert(parsed.get<std::string>()).second) {
          throw Error("malformed request: duplicate key \"{}\" (each key once)",
                      Utf8(parsed.get<std::string>()));
        }
        break;
      default:
        break;
    }
    return true;
  };
  json request;
  try {
    request = json::parse(line.begin(), line.end(), check);
  } catch (const json::exception& e) {
    throw Error("malformed request: {}", Utf8(e.what()));
  }
  if (!request.is_object() || !request.contains("cmd") || !request["cmd"].is_string()) {
    throw Error("expected an object with a string \"cmd\"");
  }
  const std::string cmd = request["cmd"].get<std::string>();
  ServeRequest r;
  if (cmd == "submit") {
    if (!request.contains("job") || !request["job"].is_string()) {
      throw Error("submit needs \"job\": the path of a job file");
    }
    r.command = ServeRequest::Command::kSubmit;
    r.job = request["job"].get<std::string>();
    if (r.job.find('\0') != std::string::npos) {
      throw Error("submit: \"job\" holds a NUL character; expected the path of a job file");
    }
  } else if (cmd == "status") {
    r.command = ServeRequest::Command::kStatus;
  } else if (cmd == "pause") {
    r.command = ServeRequest::Command::kPause;
  } else if (cmd == "resume") {
    r.command = ServeRequest::Command::kResume;
  } else if (cmd == "abort") {
    r.command = ServeRequest::Command::kAbort;
  } else if (cmd == "shutdown") {
    r.command = ServeRequest::Command::kShutdown;
  } else {
    throw Error("unknown command '{}' (submit, status, pause, resume, abort, shutdown)", cmd);
  }
  return r;
}

std::string ServeErrorReply(std::string_view message) noexcept {
  try {
    const json reply = {{"ok", false}, {"error", std::string(message)}};
    return reply.dump(-1, ' ', false, json::error_handler_t::replace);
  } catch (...) {
    return R"({"ok":false,"error":"the reply could not be built"})";
  }
}

}  // namespace dtis::io
