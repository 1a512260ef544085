#include "dtis/io/tool_table.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <unordered_map>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"

namespace dtis::io {
namespace {

constexpr std::string_view kOffsetWords = "XYZABCUVW";  // ToolEntry::offset's order

class LineReader {
 public:
  LineReader(const std::string& file, int line) : file_(file), line_(line) {}
  template <typename... Args>
  [[noreturn]] void Fail(fmt::format_string<Args...> format, Args&&... args) const {
    throw Error("{}:{}: {}", file_, line_, fmt::format(format, std::forward<Args>(args)...));
  }

 private:
  const std::string& file_;
  int line_;
};

int ToolNumber(const LineReader& at, char letter, double value, std::string_view word) {
  if (value != std::floor(value) || value < 0 || value > std::numeric_limits<int>::max()) {
    at.Fail("{}: expected a whole number from 0 to {}, got '{}'", letter,
            std::numeric_limits<int>::max(), word);
  }
  return static_cast<int>(value);
}

ToolEntry ParseLine(std::string_view text, const LineReader& at) {
  ToolEntry entry;
  bool seen[26] = {};
  std::size_t i = 0;
  while (i < text.size()) {
    if (std::isspace(static_cast<unsigned char>(text[i]))) {
      ++i;
      continue;
    }
    std::size_t end = i;
    while (end < text.size() && !std::isspace(static_cast<unsigned char>(text[end]))) ++end;
    const std::string_view word = text.substr(i, end - i);
    i = end;
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(word[0])));
    static constexpr std::string_view kWords = "TPXYZABCUVWDIJQ";
    if (kWords.find(letter) == std::string_view::npos) {
      at.Fail(
          "'{}': expected a word T P X Y Z A B C U V W D I J Q, or ';' before a comment "
          "(a LinuxCNC tool table, one tool per line: T1 P1 Z50 D6 ;comment)",
          word);
    }
    if (seen[letter - 'A']) at.Fail("{} appears twice", letter);
    seen[letter - 'A'] = true;
    const std::optional<double> number = ParseFiniteNumber(word.substr(1));
    if (!number) at.Fail("{}: expected a number, got '{}'", letter, word.substr(1));
    const double value = *number;
    if (letter == 'T') {
      entry.tool = ToolNumber(at, letter, value, word.substr(1));
    } else if (letter == 'P') {
      entry.pocket = ToolNumber(at, letter, value, word.substr(1));
    } else if (letter == 'D') {
      if (!(value >= 0.0 && value <= kMaxToolOffset)) {
        at.Fail("D: expected a diameter from 0 to {:g} mm, got {}", kMaxToolOffset, value);
      }
      entry.diameter = value;
    } else if (const std::size_t k = kOffsetWords.find(letter); k != std::string_view::npos) {
      if (!(std::abs(value) <= kMaxToolOffset)) {
        at.Fail("{}: expected an offset within ±{:g} mm, got {}", letter, kMaxToolOffset, value);
      }
      entry.offset[k] = value;
    }
    // I J Q (lathe tools' angles and orientation): read, not used by a mill.
  }
  if (!seen['T' - 'A']) at.Fail("expected a tool number (T word)");
  if (!seen['P' - 'A']) entry.pocket = entry.tool;
  return entry;
}

}  // namespace

ToolTable ParseToolTable(std::string_view text, const std::string& source_name) {
  ToolTable table;
  table.file = source_name;
  std::unordered_map<int, int> line_of_tool;
  int line = 0;
  while (!text.empty()) {
    ++line;
    const std::size_t end = text.find('\n');
    std::string_view content = text.substr(0, end);
    text.remove_prefix(end == std::string_view::npos ? text.size() : end + 1);
    content = content.substr(0, content.find(';'));
    if (!content.empty() && content.back() == '\r') content.remove_suffix(1);
    if (content.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    const LineReader at(source_name, line);
    if (content.find("TOOLNO") != std::string_view::npos) {
      at.Fail(
          "this is the tool table format of LinuxCNC before 2.4 (TOOLNO POCKET LENGTH "
          "DIAMETER columns); write one tool per line as T1 P1 Z0.511 D0.125 ;comment");
    }
    ToolEntry entry = ParseLine(content, at);
    entry.line = line;
    if (const auto [it, inserted] = line_of_tool.emplace(entry.tool, line); !inserted) {
      at.Fail("tool T{} is already in the table, on line {}", entry.tool, it->second);
    }
    table.tools.push_back(entry);
  }
  return table;
}

ToolTable LoadToolTable(const std::string& path) {
  const std::optional<std::string> text = ReadFileText(path);
  if (!text) throw Error("{}: cannot open the tool table: {}", path, std::strerror(errno));
  return ParseToolTable(*text, path);
}

}  // namespace dtis::io
