// A whole file as text, for the readers that parse it in memory (jobs, machines, setpoint files)
// and the report that embeds plotly.js. Each caller says in its own error what it expected.
#pragma once

#include <optional>
#include <string>

namespace dtis {

// The file's bytes, or nothing when it cannot be opened.
std::optional<std::string> ReadFileText(const std::string& path);

}  // namespace dtis
