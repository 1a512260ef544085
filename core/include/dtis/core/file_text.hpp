// A whole file as text, for the readers that parse it in memory (jobs, machines, setpoint files)
// and the report that embeds plotly.js. Each caller says in its own error what it expected.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace dtis {

// Input files are regular files: a directory, a device (/dev/zero), a FIFO or a socket given as
// one is an error naming it, never read (a device may never end, a FIFO may block forever).
// Throws dtis::Error, also for a path that cannot be followed (a loop of symbolic links: "cannot
// open: too many levels of symbolic links"); a path that does not exist passes (the reader says
// it cannot open it).
void RequireRegularFile(const std::string& path);

// Text inputs are read whole: larger than this (about 18 hours of 5-axis setpoints at 1 ms) they
// are refused.
inline constexpr std::uintmax_t kMaxTextFileBytes = std::uintmax_t{4} << 30;

// A finite number as the text files dtis reads write them (LinuxCNC INI files, tool tables): an
// optional leading '+', then a decimal std::from_chars reads, making up the whole of `text`.
std::optional<double> ParseFiniteNumber(std::string_view text);

// The file's bytes, or nothing when it cannot be opened. Throws dtis::Error when it is not a
// regular file or larger than kMaxTextFileBytes.
std::optional<std::string> ReadFileText(const std::string& path);

}  // namespace dtis
